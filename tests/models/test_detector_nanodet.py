"""The shipped NanoDet ONNX file: checksum, parity with TensorFlow, any size, geometry, errors."""

from __future__ import annotations

import hashlib
import importlib.resources

import cv2
import numpy as np
import pytest

from models.detector import Detections, available_detectors, create_detector
from models.detector.base import DEFAULT_DETECTOR
from models.detector.nanodet import DEFAULT_MODEL, INPUT_NAME, OUTPUT_NAME, WEIGHTS_DIR
from models.detector.preprocessing import box_iou
from models.detector.validation import NO_PEOPLE, person_frame, photo
from models.errors import MomlocError


@pytest.fixture(scope="module")
def detector():
    return create_detector("nanodet")


def test_nanodet_is_the_registered_default():
    assert DEFAULT_DETECTOR == "nanodet"
    assert {"nanodet", "ssdlite", "yolov8"} <= set(available_detectors())
    assert create_detector().kind == "nanodet"


def test_shipped_model_matches_its_checksum_and_names_both_licences():
    expected, name = (WEIGHTS_DIR / "nanodet_person.onnx.sha256").read_text().split()
    assert name == DEFAULT_MODEL.name
    assert hashlib.sha256(DEFAULT_MODEL.read_bytes()).hexdigest() == expected
    licence = (WEIGHTS_DIR / "LICENSE.nanodet.txt").read_text()
    assert "MIT License" in licence and "Apache License" in licence
    resource = importlib.resources.files("models.detector.weights") / "nanodet_person.onnx"
    assert resource.is_file()


def test_onnxruntime_reproduces_the_tensorflow_graph(detector):
    """tools/convert_nanodet.py stored TensorFlow's outputs of the original TF.js graph on a fixed
    batch at the network's native 416×416; the shipped ONNX must reproduce them."""
    reference = np.load(WEIGHTS_DIR / "nanodet_reference.npz")
    noise = np.random.default_rng(int(reference["noise_seed"])).integers(
        0, 256, reference["astronaut"].shape, dtype=np.uint8
    )
    batch = np.stack([reference["astronaut"], noise])
    (ours,) = detector.session.run([OUTPUT_NAME], {INPUT_NAME: batch})
    expected = reference["person"]
    assert ours.shape == expected.shape == (2, 52 * 52 + 26 * 26 + 13 * 13, 5)
    np.testing.assert_allclose(ours[..., 0], expected[..., 0], atol=1e-4)
    confident = expected[..., 0] > 0.05
    np.testing.assert_allclose(ours[..., 1:][confident], expected[..., 1:][confident], atol=1e-3)
    assert expected[0, :, 0].max() > 0.7  # the astronaut is found by the original graph


@pytest.mark.parametrize("height", [100, 200, 320])
def test_boxes_come_back_in_original_frame_pixels(detector, height):
    frame, truth = person_frame("camera", height, anchor=(0.8, 0.6))
    (found,) = detector.detect([frame])
    assert len(found) == 1
    assert box_iou(truth, found.boxes)[0, 0] > 0.7
    assert found.boxes.dtype == np.float32 and found.scores.dtype == np.float32


@pytest.mark.parametrize("size", [(320, 256), (416, 320), (256, 192), (640, 480)])
def test_any_input_size_that_is_a_multiple_of_32(size):
    frame, truth = person_frame("astronaut", 220, anchor=(0.3, 1.0))
    (found,) = create_detector("nanodet", input_size=size).detect([frame])
    assert box_iou(truth, found.boxes).max() > 0.7


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
    assert detector.detect([]) == []


def test_photographs_without_people_give_no_boxes(detector):
    found = detector.detect([photo(name) for name in NO_PEOPLE])
    assert sum(len(d) for d in found) <= 1  # at most one false box over seven photographs
    assert all(isinstance(d, Detections) for d in found)


def test_bad_options_and_files_fail_with_one_line(tmp_path):
    with pytest.raises(MomlocError, match="multiples of 32"):
        create_detector("nanodet", input_size=(300, 256))
    with pytest.raises(MomlocError, match="file not found"):
        create_detector("nanodet", model_path=tmp_path / "absent.onnx")
    corrupt = tmp_path / "corrupt.onnx"
    corrupt.write_bytes(b"not a model")
    with pytest.raises(MomlocError, match="not a loadable ONNX model"):
        create_detector("nanodet", model_path=corrupt)
    ssd = WEIGHTS_DIR / "ssdlite_pedestrian.onnx"
    with pytest.raises(MomlocError, match="not a NanoDet person model"):
        create_detector("nanodet", model_path=ssd)

"""The shipped NanoDet ONNX file: checksum, any size, geometry, errors (parity with TensorFlow
under every runtime: test_detector_runtimes.py)."""

from __future__ import annotations

import hashlib
import importlib.resources

import cv2
import numpy as np
import pytest

from common.errors import MomlocError
from models.detector import Detections, available_detectors, create_detector
from models.detector.base import DEFAULT_DETECTOR
from models.detector.nanodet import DEFAULT_MODEL, WEIGHTS_DIR
from models.detector.preprocessing import box_iou, input_for_frame
from models.detector.validation import NO_PEOPLE, person_frame, photo


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
        cv2.resize(person_frame("camera", 300, anchor=(0.7, 0.5))[0], (1280, 720)),  # own input
    ]
    batched = detector.detect(frames)
    for frame, together in zip(frames, batched, strict=True):
        (alone,) = detector.detect([frame])
        np.testing.assert_allclose(together.boxes, alone.boxes, atol=1e-3)
        np.testing.assert_allclose(together.scores, alone.scores, atol=1e-5)
    assert [len(d) for d in batched] == [1, 1, 1, 1]
    assert detector.detect([]) == []


@pytest.mark.parametrize(
    ("frame_size", "max_shrink", "expected"),
    [
        ((640, 480), 3.0, (320, 256)),  # a webcam frame: the input as set
        ((640, 480), 2.0, (320, 256)),  # shrinks 2.0 x 1.875: within the limit
        ((1024, 768), 3.0, (352, 256)),  # 1024 / 3 = 341.3 -> next multiple of 32
        ((1920, 1080), 3.0, (640, 384)),
        ((1920, 1080), 2.0, (960, 544)),
        ((1280, 720), 3.0, (448, 256)),  # 240 rows would be below the set height: kept
        ((1920, 1080), None, (320, 256)),  # growth off
        ((200, 100), 3.0, (320, 256)),  # small frames are enlarged into the set input
    ],
)
def test_input_grows_with_frames_that_would_shrink_too_much(frame_size, max_shrink, expected):
    assert input_for_frame((320, 256), frame_size, max_shrink) == expected


def test_a_high_resolution_frame_keeps_its_small_people():
    """People 130 px tall in a 1920x1080 frame: squeezed into 320x256 they are 31 px tall and
    six times narrower and the detector finds none; at 640x384 it finds all three."""
    frame = np.full((1080, 1920, 3), person_frame("astronaut", 130)[0][0, 0], np.uint8)
    truth = []
    for seed, (x, y) in enumerate([(0, 0), (640, 300), (1280, 600)]):
        tile, box = person_frame("astronaut", 130, anchor=(0.5, 0.8), seed=seed)
        frame[y : y + 480, x : x + 640] = tile
        truth.append(box + np.array([x, y, x, y]))
    (fixed,) = create_detector("nanodet", max_shrink=None).detect([frame])
    (grown,) = create_detector("nanodet").detect([frame])
    assert len(fixed) == 0 or box_iou(np.array(truth), fixed.boxes).max() < 0.5
    assert len(grown) == 3
    assert (box_iou(np.array(truth), grown.boxes).max(axis=1) > 0.6).all()


def test_photographs_without_people_give_no_boxes(detector):
    found = detector.detect([photo(name) for name in NO_PEOPLE])
    assert sum(len(d) for d in found) <= 1  # at most one false box over seven photographs
    assert all(isinstance(d, Detections) for d in found)


def test_bad_options_and_files_fail_with_one_line(tmp_path):
    with pytest.raises(MomlocError, match="multiples of 32"):
        create_detector("nanodet", input_size=(300, 256))
    with pytest.raises(MomlocError, match=r"max_shrink 0\.5 must be at least 1"):
        create_detector("nanodet", max_shrink=0.5)
    with pytest.raises(MomlocError, match="file not found"):
        create_detector("nanodet", model_path=tmp_path / "absent.onnx")
    corrupt = tmp_path / "corrupt.onnx"
    corrupt.write_bytes(b"not a model")
    for runtime in ("onnxruntime", "auto"):
        with pytest.raises(MomlocError, match="not a loadable ONNX model"):
            create_detector("nanodet", model_path=corrupt, runtime=runtime)
    ssd = WEIGHTS_DIR / "ssdlite_pedestrian.onnx"
    with pytest.raises(MomlocError, match="not a NanoDet person model"):
        create_detector("nanodet", model_path=ssd)

"""YOLOv8 output decoding, driven through real onnxruntime with tiny models built here.

The model ignores its pixels and emits a known [N, 4 + C, A] tensor, so every expected box can be
computed by hand: class filter, score threshold, NMS and the letterbox undo are all exercised.
"""

from __future__ import annotations

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper, numpy_helper

from common.errors import MomlocError
from models.detector import create_detector

NET = 64  # network input size: a 640×480 frame letterboxes to 64×48 at scale 0.1, pad y 8
CLASSES = 80


def raw_output() -> np.ndarray:
    """[4 + C, A]: anchor columns (cx, cy, w, h in network pixels, class scores)."""
    anchors = [
        ((32, 32, 10, 20), 0, 0.90),  # person A
        ((33, 32, 10, 20), 0, 0.80),  # duplicate of A, removed by NMS
        ((10, 20, 8, 8), 2, 0.95),  # a car: wrong class
        ((50, 40, 6, 12), 0, 0.30),  # person below threshold
        ((12, 30, 6, 16), 0, 0.60),  # person B
        ((40, 20, 10, 10), 5, 0.85),  # a bus that also scores 0.7 as person: a bus
    ]
    raw = np.zeros((4 + CLASSES, 120), np.float32)  # A > 4 + C, as in real exports
    for column, (box, cls, score) in enumerate(anchors):
        raw[:4, column] = box
        raw[4 + cls, column] = score
    raw[4 + 0, 2] = 0.1  # the car is a little person-ish, still below threshold
    raw[4 + 0, 5] = 0.7
    return raw


def build_model(path, raw: np.ndarray, batch: int | str = "N", channels: int = 3, transpose=False):
    """images [batch, channels, NET, NET] float → output = raw broadcast to the batch size."""
    table = raw.T if transpose else raw
    nodes = [
        helper.make_node("Shape", ["images"], ["shape"]),
        helper.make_node("Slice", ["shape", "start", "stop"], ["n"]),
        helper.make_node("Concat", ["n", "tail"], ["out_shape"], axis=0),
        helper.make_node("Expand", ["table", "out_shape"], ["output0"]),
    ]
    initializers = [
        numpy_helper.from_array(np.array([0], np.int64), "start"),
        numpy_helper.from_array(np.array([1], np.int64), "stop"),
        numpy_helper.from_array(np.array(table.shape, np.int64), "tail"),
        numpy_helper.from_array(table[None].astype(np.float32), "table"),
    ]
    graph = helper.make_graph(
        nodes,
        "tiny_yolo",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [batch, channels, NET, NET])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, [batch, *table.shape])],
        initializers,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, path)
    return path


def expected_boxes() -> np.ndarray:
    """Persons A and B in 640×480 frame pixels: (net - pad) / 0.1 with pad (0, 8)."""
    net = np.array([[27, 22, 37, 42], [9, 22, 15, 38]], np.float32)
    return (net - np.array([0, 8, 0, 8])) / 0.1


@pytest.mark.parametrize("transpose", [False, True])
def test_decodes_class_threshold_nms_and_letterbox(tmp_path, transpose):
    model = build_model(tmp_path / "yolo.onnx", raw_output(), transpose=transpose)
    detector = create_detector("yolov8", model_path=model, score_threshold=0.4)
    frames = [np.zeros((480, 640, 3), np.uint8), np.full((480, 640, 3), 200, np.uint8)]
    results = detector.detect(frames)
    assert len(results) == 2
    for found in results:
        np.testing.assert_allclose(found.boxes, expected_boxes(), atol=1e-3)
        np.testing.assert_allclose(found.scores, [0.9, 0.6], atol=1e-6)
    assert "64x64" in detector.describe()


def test_threshold_and_nms_options_change_the_result(tmp_path):
    model = build_model(tmp_path / "yolo.onnx", raw_output())
    loose = create_detector("yolov8", model_path=model, score_threshold=0.2, iou_threshold=0.95)
    (found,) = loose.detect([np.zeros((480, 640, 3), np.uint8)])
    np.testing.assert_allclose(found.scores, [0.9, 0.8, 0.6, 0.3], atol=1e-6)


def test_single_class_view_keeps_what_the_full_model_calls_a_bus(tmp_path):
    """With only the person row there is no rival class, so the 0.7 anchor becomes a person."""
    raw = raw_output()[:5]
    detector = create_detector("yolov8", model_path=build_model(tmp_path / "p.onnx", raw))
    (found,) = detector.detect([np.zeros((480, 640, 3), np.uint8)])
    np.testing.assert_allclose(found.scores, [0.9, 0.7, 0.6], atol=1e-6)


def test_other_frame_size_maps_to_its_own_pixels(tmp_path):
    """A 320×320 frame fills the 64×64 input without padding: boxes scale by 5 exactly."""
    detector = create_detector("yolov8", model_path=build_model(tmp_path / "y.onnx", raw_output()))
    (found,) = detector.detect([np.zeros((320, 320, 3), np.uint8)])
    np.testing.assert_allclose(found.boxes[0], np.array([27, 22, 37, 42]) * 5, atol=1e-3)


def test_fixed_batch_one_export_runs_per_frame(tmp_path):
    model = build_model(tmp_path / "yolo_b1.onnx", raw_output(), batch=1)
    detector = create_detector("yolov8", model_path=model)
    results = detector.detect([np.zeros((480, 640, 3), np.uint8)] * 3)
    assert [len(found) for found in results] == [2, 2, 2]


def test_wrong_models_fail_at_load(tmp_path):
    with pytest.raises(MomlocError, match="set model_path"):
        create_detector("yolov8")
    grey = build_model(tmp_path / "grey.onnx", raw_output(), channels=1)
    with pytest.raises(MomlocError, match=r"expected one image input \[N, 3, H, W\]"):
        create_detector("yolov8", model_path=grey)
    with pytest.raises(MomlocError, match="person class 80 does not exist"):
        create_detector(
            "yolov8", model_path=build_model(tmp_path / "y.onnx", raw_output()), person_class=80
        )
    garbage = tmp_path / "garbage.onnx"
    garbage.write_bytes(b"\x08\x07not a model" * 50)
    with pytest.raises(MomlocError, match="not a loadable ONNX model"):
        create_detector("yolov8", model_path=garbage)
    with pytest.raises(MomlocError, match="not an SSD detector"):
        create_detector("ssdlite", model_path=tmp_path / "y.onnx")


def test_model_that_loads_but_cannot_run_fails_at_start(tmp_path):
    """Declared [N, 84, A] but its Reshape is impossible for a 3×64×64 input."""
    graph = helper.make_graph(
        [helper.make_node("Reshape", ["images", "shape"], ["output0"])],
        "broken",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, ["N", 3, NET, NET])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, ["N", 84, 120])],
        [numpy_helper.from_array(np.array([-1, 84, 7], np.int64), "shape")],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.save(model, tmp_path / "broken.onnx")
    with pytest.raises(MomlocError, match="fails on a test frame") as error:
        create_detector("yolov8", model_path=tmp_path / "broken.onnx")
    assert "\n" not in str(error.value)

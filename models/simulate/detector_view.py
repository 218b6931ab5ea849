"""What a detector *should* find in a rendered frame, and which of its boxes found whom.

Shared by the rendering benchmark (``bench/detector/render_recall.py``), the rendered-recall test,
``tools/make_demo_model.py`` and ``bench/detector/highres_localization.py`` (which label real
detector boxes with the simulator's truth through :func:`detector_dataset`), so all count people the
same way:

- the **reference box** of a person is the true box of the projected body clipped to the image;
- ``visible`` is the fraction of the true box's area inside the image (truncation);
- ``occluded`` is the fraction of the clipped box covered by the clipped boxes of people nearer
  to the camera (boxes, not silhouettes: an upper bound, cheap and renderer-independent);
- a person is **clear** when ``visible >= 0.9`` and ``occluded < 0.2``: recall is reported on
  clear people by box height, because truncated and hidden people are missed by any detector and
  would make the figure measure the scene instead of the drawing.

Detections are matched one-to-one to reference boxes by maximum total IoU (Hungarian), a match
counting only at IoU >= ``min_iou``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import linear_sum_assignment

from models.data.dataset import MomDataset

if TYPE_CHECKING:
    from models.detector.base import PersonDetector
    from models.simulate.scene import Scene

CLEAR_VISIBLE = 0.9
CLEAR_OCCLUDED = 0.2


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU [A, B] of boxes a [A, 4] and b [B, 4] (xmin, ymin, xmax, ymax)."""
    ix = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    iy = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    inter = np.clip(ix, 0, None) * np.clip(iy, 0, None)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.nan_to_num(inter / (area_a[:, None] + area_b[None] - inter))


@dataclass(frozen=True)
class CameraTruth:
    """People seen by one camera in one frame (rows index the scene's people).

    ``boxes`` [P, 4] reference boxes (clipped; NaN when not in view), ``seen`` [P] bool,
    ``visible`` [P] and ``occluded`` [P] fractions, ``depth`` [P] metres (mid-hip).
    """

    boxes: np.ndarray
    seen: np.ndarray
    visible: np.ndarray
    occluded: np.ndarray
    depth: np.ndarray

    @property
    def clear(self) -> np.ndarray:
        return self.seen & (self.visible >= CLEAR_VISIBLE) & (self.occluded < CLEAR_OCCLUDED)

    @property
    def heights(self) -> np.ndarray:
        return self.boxes[:, 3] - self.boxes[:, 1]


def camera_truth(
    true_boxes: np.ndarray, depth: np.ndarray, image_size: tuple[int, int]
) -> CameraTruth:
    """Reference boxes and visibility from one camera's true boxes [P, 4] and depths [P]."""
    w, h = image_size
    seen = np.isfinite(true_boxes).all(1)
    raw = np.where(seen[:, None], true_boxes, 0.0)
    clipped = np.clip(raw, 0, [w, h, w, h])
    area = np.maximum((raw[:, 2] - raw[:, 0]) * (raw[:, 3] - raw[:, 1]), 1e-9)
    inside = (clipped[:, 2] - clipped[:, 0]) * (clipped[:, 3] - clipped[:, 1])
    visible = np.where(seen, inside / area, 0.0)
    seen &= inside > 1.0
    occluded = np.zeros(len(raw))
    for p in np.flatnonzero(seen):
        x0, y0, x1, y1 = np.floor(clipped[p]).astype(int)
        x1, y1 = max(x1, x0 + 1), max(y1, y0 + 1)
        mask = np.zeros((y1 - y0, x1 - x0), bool)
        for q in np.flatnonzero(seen & (depth < depth[p])):
            a = np.floor(clipped[q] - [x0, y0, x0, y0]).astype(int)
            mask[max(a[1], 0) : max(a[3], 0), max(a[0], 0) : max(a[2], 0)] = True
        occluded[p] = mask.mean()
    boxes = np.where(seen[:, None], clipped, np.nan)
    return CameraTruth(boxes, seen, visible, occluded, np.asarray(depth, float))


def match(truth_boxes: np.ndarray, detections: np.ndarray, min_iou: float = 0.5) -> np.ndarray:
    """For each reference box [P, 4] (NaN rows ignored) the index of its detection, or -1."""
    out = np.full(len(truth_boxes), -1)
    rows = np.flatnonzero(np.isfinite(truth_boxes).all(1))
    if rows.size == 0 or len(detections) == 0:
        return out
    iou = box_iou(truth_boxes[rows], np.asarray(detections, float))
    r, c = linear_sum_assignment(-iou)
    good = iou[r, c] >= min_iou
    out[rows[r[good]]] = c[good]
    return out


def detector_dataset(
    scene: Scene, frames: range, detector: PersonDetector, progress: bool = False
) -> MomDataset:
    """Rows of detector boxes on the drawn frames of ``scene``, labelled with the true positions.

    Every frame's cameras are drawn and sent through ``detector`` (``detect(images)``, one result
    with ``boxes`` per image); each detection is labelled with the person whose reference box it
    overlaps most (one-to-one, IoU >= 0.5, :func:`match`). Detections matching nobody are dropped;
    a person the detector misses in a camera is NaN there; a person no camera found has no row.
    """
    sizes = [camera.image_size for camera in scene.cameras]
    world, boxes, frame_ids, tracks = [], [], [], []
    for count, f in enumerate(frames):
        obs = scene.observe(f)
        images = [scene.render(f, k) for k in range(scene.num_cameras)]
        found = detector.detect(images)
        rows = np.full((len(obs.track), scene.num_cameras, 4), np.nan, np.float32)
        hips = obs.joints[:, 11:13].mean(1)
        for k, detections in enumerate(found):
            depth = scene.cameras[k].project_depth(hips)[1]
            truth = camera_truth(obs.true_boxes[:, k], depth, sizes[k])
            hit = match(truth.boxes, detections.boxes)
            rows[hit >= 0, k] = detections.boxes[hit[hit >= 0]]
        seen = np.isfinite(rows).all(-1).any(-1)
        world.append(obs.world[seen, :2])
        boxes.append(rows[seen])
        frame_ids.append(np.full(int(seen.sum()), f))
        tracks.append(obs.track[seen])
        if progress and count % 200 == 0:
            print(f"  frame {count}/{len(frames)}", file=sys.stderr, flush=True)
    return MomDataset(
        world=np.concatenate(world),
        boxes=np.concatenate(boxes),
        frame=np.concatenate(frame_ids),
        track=np.concatenate(tracks),
        image_size=np.array(sizes, np.int32),
    )

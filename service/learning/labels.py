"""Self-labels: the moments of a running room that are good enough to learn from.

A person seen by two or more cameras is localized far better than by one (two views fix the
point like a triangulation; ``bench/results/stream_accuracy.md``, "2 views" against "1 view"),
and such a moment pairs every camera's box with a floor position: exactly the row a floor-mark
recording holds, without anyone standing on a mark. :func:`select_labels` picks those moments from
one frame set's :class:`~service.stages.FrameResult`; the rest of :mod:`service.learning` stores
them (:mod:`service.learning.store`) and learns from them.

A self-label is only as good as the position it carries, so every rule below rejects a moment
that *could* be wrong, at the price of fewer labels (a walking room gives thousands a minute):

- the track is confirmed and measured in this frame set (not coasting on its prediction);
- it is seen by at least ``min_views`` cameras, none of which the camera-moved check has raised
  (a bumped camera's box sits where the model does not expect it);
- the position's covariance is small (largest std ``max_std_m``): the localizer itself says how
  sure it is;
- the association cost (RMS reprojection error, :mod:`service.tracking.association`) is low:
  a high cost means the boxes of the tuple hardly agree on one person;
- nobody else is close: no other person within ``min_separation_m`` on the floor and no other box
  overlapping any of its boxes (occlusion and swapped boxes happen exactly there);
- at most one label per track every ``min_interval_s``: consecutive frames are near copies, and
  a person standing still would otherwise fill the store with one position.

**Beyond the set-up area.** The chain keeps people outside the area the model was set up on out of
tracking (``tracking.outside_area``, :mod:`service.pipeline.chain`), yet people walk everywhere,
and the floor beyond the marks is exactly where a model set up on a few marks is weakest. Learning
only from tracked people confined the labels to the marks' hull (the first measured room,
``bench/results/self_learning_before.md``: no improvement was ever served). So the untracked
associations beyond the area (``FrameResult.outside``) may give labels too, under the same rules
(two or more cameras agreeing with a small covariance, low cost, alone, no overlap) with the
track's two replaced by ones that need no track: the moment is *confirmed* when the previous frame
set (at most ``BEYOND_GAP_S`` earlier) had an association beyond the area within ``BEYOND_STEP_M``
of it (a ghost pairing of two people's boxes rarely repeats at the same place), and the rate rule
holds per place (no other label beyond the area within ``min_separation_m`` in the last
``min_interval_s``). Their labels carry track ``-1``. A model the room serves after learning from
them is set up on their positions too, so its area grows with them (:mod:`models.mom.setup_area`
fits the area on every training row).

Every rejection is counted by reason (``/v1/health`` ``learning.rejected``), so a room that
learns nothing says why.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from service.stages import Association, FrameResult

KEYPOINT_JOINTS = 17  # COCO-17
BEYOND_STEP_M = 0.3  # a person moves less between two frame sets (1.5 m/s at 5 fps)
BEYOND_GAP_S = 0.5  # frame sets further apart do not confirm each other
BEYOND_TRACK = -1  # the track id of labels from beyond the set-up area


@dataclass(frozen=True)
class LabelRules:
    """Thresholds of :func:`select_labels` (``learning`` settings, ``service.settings``)."""

    min_views: int = 2
    max_std_m: float = 0.15
    max_cost: float = 40.0  # normalised px (association's scale; its match limit is 100)
    min_separation_m: float = 1.0
    min_interval_s: float = 0.5


@dataclass
class LabelBatch:
    """Self-labels as arrays (one row per person and moment), the store's unit.

    ``boxes`` [N, K, 4] and ``keypoints`` [N, K, 17, 3] are NaN where a camera did not see the
    person (keypoints also where the detector gives none); ``world`` [N, 2] metres and
    ``covariance`` [N, 2, 2] m² are the serving model's fused position; ``t`` capture time (s),
    ``track`` the tracker's id, ``cost`` the association cost.
    """

    t: np.ndarray
    track: np.ndarray
    world: np.ndarray
    covariance: np.ndarray
    boxes: np.ndarray
    keypoints: np.ndarray
    cost: np.ndarray

    @property
    def n(self) -> int:
        return len(self.t)

    @property
    def num_cameras(self) -> int:
        return int(self.boxes.shape[1])

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: getattr(self, name) for name in FIELDS}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> LabelBatch:
        return cls(**{name: np.asarray(arrays[name]) for name in FIELDS})

    @classmethod
    def concat(cls, batches: list[LabelBatch]) -> LabelBatch:
        return cls(**{n: np.concatenate([getattr(b, n) for b in batches]) for n in FIELDS})

    def subset(self, rows: np.ndarray) -> LabelBatch:
        return LabelBatch(**{name: getattr(self, name)[rows] for name in FIELDS})

    def views(self) -> np.ndarray:
        """[N, K] bool: which cameras saw each label's person."""
        return np.isfinite(self.boxes).all(axis=-1)

    def std_m(self) -> np.ndarray:
        """[N] the largest standard deviation of each position (metres)."""
        return np.sqrt(np.linalg.eigvalsh(self.covariance.astype(np.float64))[:, -1].clip(0))


FIELDS = ("t", "track", "world", "covariance", "boxes", "keypoints", "cost")


@dataclass
class Selection:
    """What one frame set gave: the labels kept and the moments rejected, by reason."""

    labels: LabelBatch | None
    rejected: Counter[str] = field(default_factory=Counter)


@dataclass
class BeyondMemory:
    """What the rules for moments beyond the set-up area keep between frame sets (module
    docstring): the previous frame set's positions beyond the area, and the recent labels
    there (time, position)."""

    previous_t: float = -np.inf
    previous: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    labelled: list[tuple[float, np.ndarray]] = field(default_factory=list)


def select_labels(
    result: FrameResult,
    rules: LabelRules,
    moved: set[int],
    last_label: dict[int, float],
    beyond: BeyondMemory | None = None,
) -> Selection:
    """The self-labels of one frame set (module docstring); updates ``last_label`` (track id ->
    time of its last label) for the rate rule, and ``beyond`` for the moments beyond the set-up
    area (None: those give no labels)."""
    rejected: Counter[str] = Counter()
    rows: list[tuple[int, Association]] = []
    everyone = [*result.associations, *(result.outside if beyond is not None else [])]
    positions = np.array([np.asarray(a.world, float)[:2] for a in everyone]).reshape(-1, 2)
    for track in result.tracks:
        if track.coasting or track.frame != result.snapshot.seq or track.association is None:
            rejected["coasting"] += 1
            continue
        index = track.association
        a = result.associations[index]
        reason = _reject(a, index, positions, result, rules, moved)
        if reason is None and result.t_capture - last_label.get(track.id, -np.inf) < (
            rules.min_interval_s
        ):
            reason = "rate"
        if reason is not None:
            rejected[reason] += 1
            continue
        last_label[track.id] = result.t_capture
        rows.append((int(track.id), a))
    if beyond is not None:
        rows += _beyond(result, rules, moved, positions, beyond, rejected)
    if not rows:
        return Selection(None, rejected)
    return Selection(_batch(rows, result), rejected)


def _beyond(
    result: FrameResult,
    rules: LabelRules,
    moved: set[int],
    positions: np.ndarray,
    memory: BeyondMemory,
    rejected: Counter[str],
) -> list[tuple[int, Association]]:
    """Labels from the untracked associations beyond the set-up area (module docstring)."""
    t = result.t_capture
    first = len(result.associations)  # their index in ``positions``
    here = positions[first:]
    recent = t - memory.previous_t <= BEYOND_GAP_S
    memory.labelled = [(s, xy) for s, xy in memory.labelled if t - s < rules.min_interval_s]
    rows = []
    for i, a in enumerate(result.outside):
        reason = _reject(a, first + i, positions, result, rules, moved, inside_only=False)
        xy = here[i]
        if reason is None and not (
            recent
            and len(memory.previous)
            and np.linalg.norm(memory.previous - xy, axis=1).min() <= BEYOND_STEP_M
        ):
            reason = "unconfirmed"
        if reason is None and any(
            np.linalg.norm(xy - seen) < rules.min_separation_m for _, seen in memory.labelled
        ):
            reason = "rate"
        if reason is not None:
            rejected[f"beyond_{reason}"] += 1
            continue
        memory.labelled.append((t, xy))
        rows.append((BEYOND_TRACK, a))
    memory.previous_t, memory.previous = t, here.copy()
    return rows


def _reject(
    a: Association,
    index: int,
    positions: np.ndarray,
    result: FrameResult,
    rules: LabelRules,
    moved: set[int],
    *,
    inside_only: bool = True,
) -> str | None:
    if len(a.cameras) < max(rules.min_views, 1 if inside_only else 2):
        return "views"
    if moved & set(a.cameras):
        return "camera_moved"
    if inside_only and not a.inside:
        return "outside_area"
    if a.covariance is None or not np.all(np.isfinite(a.covariance)):
        return "no_covariance"
    if float(np.sqrt(max(np.linalg.eigvalsh(np.asarray(a.covariance, float))[-1], 0.0))) > (
        rules.max_std_m
    ):
        return "covariance"
    if not np.isfinite(a.cost) or a.cost > rules.max_cost:
        return "cost"
    others = np.delete(positions, index, axis=0)
    if len(others) and np.linalg.norm(others - positions[index], axis=1).min() < (
        rules.min_separation_m
    ):
        return "crowded"
    if _overlapped(a, result):
        return "overlap"
    return None


def _overlapped(a: Association, result: FrameResult) -> bool:
    """Whether another box of one of its cameras touches one of this person's boxes."""
    for k, j in enumerate(a.detection_index):
        if j is None:
            continue
        boxes = np.asarray(result.detections[k].boxes, float).reshape(-1, 4)
        mine = boxes[j]
        others = np.delete(boxes, j, axis=0)
        if not len(others):
            continue
        apart = (
            (others[:, 2] <= mine[0])
            | (others[:, 0] >= mine[2])
            | (others[:, 3] <= mine[1])
            | (others[:, 1] >= mine[3])
        )
        if not apart.all():
            return True
    return False


def _batch(rows: list[tuple[int, Association]], result: FrameResult) -> LabelBatch:
    k = len(result.detections)
    keypoints = np.full((len(rows), k, KEYPOINT_JOINTS, 3), np.nan, np.float32)
    for i, (_, a) in enumerate(rows):
        for camera, j in enumerate(a.detection_index):
            points = result.detections[camera].keypoints
            if j is not None and points is not None and points.shape[1:] == keypoints.shape[2:]:
                keypoints[i, camera] = points[j]
    return LabelBatch(
        t=np.full(len(rows), result.t_capture, np.float64),
        track=np.array([track for track, _ in rows], np.int64),
        world=np.stack([np.asarray(a.world, np.float32)[:2] for _, a in rows]),
        covariance=np.stack([np.asarray(a.covariance, np.float32) for _, a in rows]),
        boxes=np.stack([np.asarray(a.boxes, np.float32) for _, a in rows]),
        keypoints=keypoints,
        cost=np.array([a.cost for _, a in rows], np.float32),
    )

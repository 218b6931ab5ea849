"""Lone-view bias compensation: what one camera's box alone gets wrong about a tracked person.

A person seen by one camera is localized from one box: the bearing is good, the range rests on
the box's size and bottom edge and is biased by whatever that box gets wrong about *this*
person: their height against the average the localizer learned, their posture, clothes that
the detector cuts short. That error persists while the person stays in view, and it is what
makes the served position jump when a second camera comes or goes (a 2-view fix replaces the
lone view's biased range, or the other way round).

While two or more cameras see a track, each camera's box is also localized *alone* (the MoM
encoder supports missing views: the same call the association's ``max_view_gap_m`` gate makes)
and, per track and camera, :class:`ViewBias` keeps a running estimate of the offset of that
lone-view position from the fused one. When only that camera sees the person, the offset is
subtracted before the tracker update.

Estimate (per track and camera): the offsets are stored in the camera's line-of-sight frame
(``along``, ``across``, :func:`service.tracking.view_geometry.line_of_sight`) at the fused position,
so a range bias stays a range bias when the person walks round the camera (where the line of sight
is degenerate: the floor frame). Samples are weighted by their frame time and decay with
``time_constant_s``; the estimate is ``S / (W + prior_s)``: a zero-offset prior worth ``prior_s``
seconds of samples, so a track seen by two cameras for a few frames gets a shrunk offset, and an
offset not refreshed fades towards zero as its weight decays (an old offset is less trustworthy:
posture changes, and the range bias of a height error grows with distance). On top, the *transient*
part: the detector's edge errors are correlated in time, so right after the second camera leaves,
the lone view is still off by about its last measured offset; the estimate starts at the last sample
and relaxes to ``S / (W + prior_s)`` with ``transient_s``.

Why it is kept, in short (figures, seeds and every rejected variant:
``bench/results/tracking_filters.md``): a lone view's range error has a persistent part per
person and camera (height and the like) and a part that decorrelates within about half a
second like the detector's edges, so only the first is learnable; the tracker already trusts a
lone view little along its line of sight, so a better range moves the served position by
millimetres and the gain is mostly fewer id switches. With the tracker's likelihood assignment
and served coasting it is a wash over the five stream scenes, kept for the one-person scene
and the fewer id switches. Rejected: other time constants and priors, matching lone views to
tracks on their uncorrected positions, correcting only unambiguous tracks, the along-sight
component alone, a per-camera prior, trusting a corrected lone view more, guessing among held
tracks, and applying the offset after the tracker's own assignment.

Which track a single-view position will feed is decided by the tracker's assignment, after the
correction. The correction therefore guesses it: the previous frame's served tracks, predicted
to now with their velocity, are matched one to one to this frame's positions (Hungarian on the
distance, a single-view position corrected by each candidate track's offset, within
``gate_m``); the tracker sees the corrected positions, so the guess and its assignment agree
except in ties. After the update, the tracks' ``association`` (the index of the association
that fed them, which the caller puts in each position's :class:`~service.stages.Origin`) says
which track each two-view association fed, and its lone-view offsets are learned for that
track.

Cost: one extra batched ``localize`` call per frame set (the multi-view associations' boxes
alone) plus line-of-sight probes of the decoder: 1.6 ms per frame set on indoor-2cam with
3 people (run_stream, 300 frames, 2 cores, loaded), beside the tracker's own time.

:class:`ViewBias` is one stage of the chain (:mod:`service.pipeline.chain`), which calls it
round the tracker: :meth:`ViewBias.correct` before the update, :meth:`ViewBias.learn` after it.
The live pipeline and the offline runs both run that chain, so the bench scores what the daemon
serves. Example::

    bias = ViewBias()
    positions = bias.correct(t, associations, positions, runtime)
    tracks = tracker.update(t, positions, origins, covariances=covariances, coverage=coverage)
    bias.learn(t, associations, runtime, tracks)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from service.stages import Association, LocalizationModel, Track
from service.tracking.view_geometry import line_of_sight

_FAR = 1e9
MAX_FRAME_WEIGHT_S = 0.2  # one sample never weighs more than this (a stalled pipeline)


@dataclass
class _Offset:
    """One (track, camera) estimate: decayed sums of the weighted samples and of the weights."""

    total: np.ndarray  # [2] along, across (m·s)
    weight: float  # s
    t: float  # time of the last sample
    last: np.ndarray  # [2] the last sample itself


class ViewBias:
    """Per track and camera offset of the lone-view position from the fused one (module
    docstring): :meth:`correct` before the tracker update, :meth:`learn` after it."""

    def __init__(
        self,
        time_constant_s: float = 3.0,
        prior_s: float = 0.5,
        gate_m: float = 1.0,
        forget_s: float = 30.0,
        transient_s: float = 0.4,
    ) -> None:
        if time_constant_s <= 0 or prior_s < 0 or gate_m <= 0:
            raise ValueError("time_constant_s and gate_m must be positive, prior_s >= 0")
        self.time_constant_s = float(time_constant_s)
        self.prior_s = float(prior_s)
        self.gate_m = float(gate_m)
        self.forget_s = float(forget_s)
        self.transient_s = float(transient_s)
        self._offsets: dict[tuple[int, int], _Offset] = {}
        self._tracks: list[Track] = []
        self._time: float | None = None

    # -- one frame ---------------------------------------------------------------------------

    def correct(
        self,
        t: float,
        associations: Sequence[Association],
        positions: np.ndarray,
        runtime: LocalizationModel | None,
    ) -> np.ndarray:
        """``positions`` [P, 2] with each single-view one minus the offset of the track it is
        expected to feed (module docstring); the others unchanged."""
        out = np.array(positions, dtype=np.float64).reshape(-1, 2)
        if not self._tracks or not len(out) or self._time is None:
            return out
        dt = max(0.0, float(t) - self._time)
        predicted = np.array([[tr.x + tr.vx * dt, tr.y + tr.vy * dt] for tr in self._tracks])
        cost = np.full((len(out), len(self._tracks)), _FAR)
        shifted: dict[tuple[int, int], np.ndarray] = {}
        for i, a in enumerate(associations):
            for j, tr in enumerate(self._tracks):
                z = out[i]
                if len(a.cameras) == 1:
                    offset = self.offset(tr.id, int(a.cameras[0]), float(t), runtime, z)
                    if offset is not None:
                        z = shifted[(i, j)] = out[i] - offset
                d = float(np.linalg.norm(z - predicted[j]))
                if d <= self.gate_m:
                    cost[i, j] = d
        rows, cols = linear_sum_assignment(cost)
        for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
            if cost[r, c] < _FAR and (r, c) in shifted:
                out[r] = shifted[(r, c)]
        return out

    def learn(
        self,
        t: float,
        associations: Sequence[Association],
        runtime: LocalizationModel | None,
        tracks: Sequence[Track],
    ) -> None:
        """Fold this frame's lone-view offsets of the multi-view associations into the tracks
        they fed; remember the served tracks for the next :meth:`correct`."""
        t = float(t)
        frame_s = MAX_FRAME_WEIGHT_S if self._time is None else t - self._time
        frame_s = float(np.clip(frame_s, 0.0, MAX_FRAME_WEIGHT_S))
        fed = []
        for tr in tracks:
            index = None if tr.coasting else tr.association
            if index is not None and 0 <= index < len(associations):
                a = associations[index]
                if len(a.cameras) >= 2:
                    fed.append((tr.id, a))
        if fed and runtime is not None:
            lone = lone_view_positions([a for _, a in fed], runtime)
            for (track_id, a), views in zip(fed, lone, strict=True):
                fused = np.asarray(a.world, dtype=np.float64)[:2]
                for k, xy in views.items():
                    if np.isfinite(xy).all():
                        sample = _to_sight(runtime, k, fused, xy - fused)
                        self._fold(track_id, k, t, sample, frame_s)
        self._offsets = {key: o for key, o in self._offsets.items() if t - o.t <= self.forget_s}
        self._tracks = list(tracks)
        self._time = t

    # -- the estimate ------------------------------------------------------------------------

    def offset(
        self,
        track_id: int,
        camera: int,
        t: float,
        runtime: LocalizationModel | None,
        world: np.ndarray,
    ) -> np.ndarray | None:
        """Floor offset [2] (m) of camera ``camera``'s lone view of track ``track_id`` at
        ``world``, or None when never learned."""
        o = self._offsets.get((int(track_id), int(camera)))
        if o is None:
            return None
        age = max(0.0, float(t) - o.t)
        decay = float(np.exp(-age / self.time_constant_s))
        sight = o.total * decay / (o.weight * decay + self.prior_s)
        if self.transient_s > 0:
            sight = sight + (o.last - sight) * float(np.exp(-age / self.transient_s))
        return _from_sight(runtime, int(camera), np.asarray(world, float)[:2], sight)

    def _fold(self, track_id: int, camera: int, t: float, sample: np.ndarray, w: float) -> None:
        _fold(self._offsets, (int(track_id), int(camera)), t, sample, w, self.time_constant_s)


def _fold(
    table: dict[tuple[int, int], _Offset],
    key: tuple[int, int],
    t: float,
    sample: np.ndarray,
    w: float,
    tau: float,
) -> None:
    o = table.get(key)
    if o is None:
        table[key] = _Offset(sample * w, w, t, sample)
        return
    decay = float(np.exp(-max(0.0, t - o.t) / tau))
    o.total = o.total * decay + sample * w
    o.weight = o.weight * decay + w
    o.t = t
    o.last = sample


def lone_view_positions(
    associations: Sequence[Association], runtime: LocalizationModel
) -> list[dict[int, np.ndarray]]:
    """Per association, ``{camera: floor position [2]}`` of each of its boxes localized alone
    (the other views masked), one batched model call; NaN where the model cannot."""
    rows, keys = [], []
    with_keypoints = runtime.observation == "keypoints"
    for i, a in enumerate(associations):
        for k in a.cameras:
            rows.append((i, int(k)))
            keys.append(k)
    out: list[dict[int, np.ndarray]] = [{} for _ in associations]
    if not rows:
        return out
    num_cameras = int(runtime.num_cameras)
    boxes = np.full((len(rows), num_cameras, 4), np.nan, dtype=np.float32)
    points = None
    if with_keypoints and associations[0].keypoints is not None:
        shape = (len(rows), num_cameras, *np.asarray(associations[0].keypoints).shape[1:])
        points = np.full(shape, np.nan, dtype=np.float32)
    for r, (i, k) in enumerate(rows):
        boxes[r, k] = associations[i].boxes[k]
        if points is not None and associations[i].keypoints is not None:
            points[r, k] = np.asarray(associations[i].keypoints)[k]
    world = runtime.localize(boxes) if points is None else runtime.localize(boxes, points)
    world = np.asarray(world, dtype=np.float64).reshape(len(rows), 2)
    for r, (i, k) in enumerate(rows):
        out[i][k] = world[r]
    return out


def _sight_frame(runtime: LocalizationModel | None, camera: int, world: np.ndarray) -> np.ndarray:
    """Rows: the unit floor vectors along and across camera ``camera``'s line of sight at
    ``world`` (the identity without a model or where it is degenerate)."""
    if runtime is None:
        return np.eye(2)
    along = line_of_sight(runtime, camera, world)
    if along is None:
        return np.eye(2)
    return np.array([along, [-along[1], along[0]]])


def _to_sight(
    runtime: LocalizationModel | None, camera: int, world: np.ndarray, v: np.ndarray
) -> np.ndarray:
    return _sight_frame(runtime, camera, world) @ v


def _from_sight(
    runtime: LocalizationModel | None, camera: int, world: np.ndarray, v: np.ndarray
) -> np.ndarray:
    return _sight_frame(runtime, camera, world).T @ v

"""Multi-person tracking on the floor: persistent ids, Kalman smoothing, velocity.

Design
------
Each track is a motion model on the state ``[x, y, vx, vy]`` in metres and metres per second
(:mod:`service.tracking.motion`): by default a two-model IMM, *standing still* or *walking* at a
constant velocity with white-acceleration process noise (``accel_std`` m/s²), so uncertainty grows
with the real time between updates: the filter is driven by capture timestamps, not frame counts,
and copes with a pipeline that drops frames. ``motion="cv"`` is the constant-velocity filter alone.

Every update:

1. all tracks are predicted to time ``t``;
2. detections are assigned to tracks with the Hungarian algorithm (``scipy``) on the Euclidean
   distance between the predicted and measured position (``assign_cost="euclidean"``) or, in
   ``RECOMMENDED``, on ``-2 log`` of the measurement's likelihood under the track
   (``"likelihood"``: ``d² + log det S`` with ``S = P + R``, the predicted position covariance
   plus the measurement's), so a lone view's box, whose range is poorly known, is paired along
   its camera's line of sight and not across it; a pair farther apart than the gate is never
   assigned. The gate is ``gate_m`` plus ``gate_growth_mps`` per second the track has been
   unseen, because a coasting track's prediction drifts from where the person really went;
3. matched tracks are corrected with the measurement's own covariance when the localizer gives
   one (``covariances``: the floor prior's GLS covariance, long along a lone camera's line of
   sight, so a single view moves the track across its line of sight and hardly along it; the
   eigenvalues are bounded to ``min/max_measurement_std_m``), otherwise the isotropic
   ``measurement_std_m``; an innovation beyond ``robust_chi2`` (squared Mahalanobis) inflates
   that covariance by d² / robust_chi2, so one wild box moves a track less; unmatched
   detections start new *tentative* tracks;
4. tracks unseen for more than ``max_missing_s`` are dropped.

Output policy (documented for API users):

- a track is reported once it has been seen in every frame for ``confirm_s`` (0.3 s; time, not
  frames, so it means the same at any pipeline rate), so that a brief split association (one
  person reported twice for a few frames) does not create a ghost id (a shorter wait tripled
  the id switches: ``bench/results/tracker_tuning.md``). A track only ever seen by *one*
  camera waits ``confirm_single_s`` (1 s): a detector's false positive is a single view;
- a track never seen by two cameras at once that spends more than ``ghost_s`` (0.5 s) where
  another camera should see it (``coverage``, e.g.
  :func:`service.tracking.view_geometry.covering_cameras`) but reports nothing is not reported: a
  person is seen by a second camera sooner or later, a false positive at a fixed place never is.
  A track whose last measurement was a body lying on the floor (``Origin.standing`` false) is
  expected only by cameras that see the floor under it (``coverage(world, lying)``);
- while a person is unseen (occlusion, detector miss) the track *coasts* on its prediction and is
  still reported for ``serve_coast_s`` (0.5 s in ``RECOMMENDED``), with ``coasting=True`` and a
  confidence that falls linearly to 0 at ``max_missing_s``. A track whose last measurement was a
  body lying on the floor (``Origin.standing`` false) coasts standing still: each such
  measurement stops its filter (``settle`` in :mod:`service.tracking.motion`), because a
  faller's track ran on at the speed of the fall, or of the jump its first lying position made,
  1.5 m off the body within a second (a fall of the simulated lounge reported 6 s late,
  ``bench/results/falls.md``). After ``serve_coast_s`` the track is held but not reported until
  ``max_missing_s``, and the id is kept if the person reappears within the
  (growing) gate, so a 1 s occlusion does not change the id;
- with ``doubt_outside`` the ghost check also doubts a single-view track whose own camera
  should *not* see it where it is (``coverage``): a box localized where the camera that
  reported it cannot see a person is a false box localized from its odd size and place;
- a person seen by two cameras (``multi_view``) whose measured positions of the last
  ``still_window_s`` (10 s, spanning at least ``still_after_s``, 5 s) lie, for a share of at least
  ``still_share`` (0.6), within ``still_radius_m`` (0.5 m) of their median is *still* when last
  seen (:mod:`service.tracking.stillness`: why a median of measurements and not the filtered
  track): unseen, their track is held at that median (the still place, velocity 0), served and
  kept for ``hold_still_s`` (15 s in ``RECOMMENDED``) instead of ``serve_coast_s`` /
  ``max_missing_s``, and only a detection within ``still_gate_m`` (1 m) of the place takes it
  back (a reappearing person re-identified where they sat; a false box across the room does
  not drag the held track away); a measurement within ``CLAIM_M`` (0.25 m) of the place is
  the held track's whatever another track's cost. One camera's lone view within that gate
  keeps the track seen but held at its place (near a seated person it is as often a false box
  as them); two cameras release it. A track measured within ``still_guard_m`` (1.2 m) of
  another's still place becomes ``multi_view`` only after ``still_multi_view_s`` (1 s) of two
  views: a false box of each camera paired for one frame beside a seated person stays under
  the ghost check. A new track within ``still_radius_m`` of the place where a still person's
  track ended (the place it was held at, or the one its person was last judged to have left)
  less than ``hold_still_s`` ago takes that track's id: the person back where they sat is the
  person who sat there. Why: a seated or standing person is the one a detector loses for seconds
  (half hidden, still, low contrast), and each loss used to end their id and empty their zone
  (issue 27: an hour on the sofa with dropouts of seconds, ``bench/results/still_presence.md``,
  ``bench/results/still_presence_chain.md``). The price is a person who stood still and then
  left unseen (out of view) is served where they stood for up to 15 s, one who walks off seen
  by one camera only is served at their place for their first metre (then their lone views
  start a new id), and a person appearing beside a still one is served after ~1 s, not 0.3 s;
  the walking scenes' MOTA is in the same files;
- ``confidence`` is a running detection rate (exponential average of seen / unseen frame sets
  over ``rate_time_s`` seconds, so the same at any frame rate) times the coasting factor, in 0..1;
- a track counts as seen by two cameras (``multi_view``: no longer subject to the single-view
  confirmation and ghost check) once two cameras have reported it together for ``multi_view_s``
  in all, not at the first such frame: one mispaired box (a persisting false positive paired
  with the other camera's real box in a frame where its own camera missed the person) is
  enough to make a ghost a person for good. Longer waits keep real people seen by one camera
  hidden longer.

Why ``RECOMMENDED`` differs from the constructor's defaults (the former tracker, which tests of
single mechanisms rely on): each setting was kept only where the stream benchmark
(``bench/serving/stream_accuracy.py``, its cause breakdown ``bench/serving/stream_breakdown.py``)
or the real CMC room (``bench.real.cmc.evaluate``) measured it better. The figures, the rejected
values and the order of the changes are in ``bench/results/tracker_tuning.md`` and
``bench/results/real_cmc_chain_tuning.md``; the reasons, in short:

- a served coasting track stops at ``serve_coast_s``: a walker's prediction is mostly > 0.5 m off
  after ~0.5 s, and a served position that far off costs a false positive *and* a miss where
  not serving it costs the miss only (a covariance-based serving rule hid good single-view
  tracks early, their covariance being long along the line of sight from the start);
- the likelihood cost with a 1.5 m gate cut id switches; a wider Euclidean gate alone let tracks
  take other people's boxes; ``gate_growth_mps`` 0.5 and ``robust_chi2`` 16 lowered jitter;
- ``measurement_scale`` 9, learned from there (``adapt_scale_s`` 10 s,
  :mod:`service.tracking.noise_scale`): how far the localizer's covariances can be trusted
  depends on the room. In the real CMC crowd they are ~3x overconfident in std, and trusted as
  given, tracks of people passing each other swapped ids even with the true association; in
  rooms whose people stand apart the fixed 9 followed walkers' turns late. The scale settles
  where the tracker's innovations fit the scaled covariances (5-6 in the real crowd; its floor,
  3, in the simulated rooms);
- ``birth_clearance_m`` 0.8: a person whose boxes split into two clusters is not a second
  person; no track is born that close to a confirmed or just-measured one (to a still track
  held unseen: its place, where the assignment expects it, not its coasting filter);
- ``merge_m`` 0.35 / ``merge_s`` 0.5: two tracks that stay that close for half a second are one
  person fed by both halves of a split association; the younger is dropped (0.8 m merged real
  neighbours in a crowd); a held still track whose person walked off takes the younger's state
  instead (:meth:`Tracker._merge_shadows`).

No filter setting reaches a 1 cm standing jitter: the jitter is made of jumps when a second
camera comes or goes (a lone view's range bias, which :mod:`service.tracking.view_bias`
corrects), not of noise. Tried and not kept (details in the results file): trusting a
measurement with a pose as if two cameras had seen it, confirming a single-view track once it
has moved, resetting the ghost doubt on any two-camera frame.

``origins`` (one :class:`~service.stages.Origin` per position) are passed through: the track a
position feeds takes its cameras, and its frame, association, cost and set-up area flag.

Example::

    tracker = Tracker(fps_hint=30)
    tracks = tracker.update(t, positions, [Origin(cameras=(0, 1))] * len(positions),
                            covariances=[a.covariance for a in associations])
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from service.stages import Coverage, Origin, Track, TrackAnchor
from service.tracking.image_continuity import (
    LABEL_GROWTH_HPS,
    LABEL_STD_H,
    ImageContinuity,
    ViewMemory,
)
from service.tracking.motion import ConstantVelocity, StandOrWalk
from service.tracking.noise_scale import NoiseScale
from service.tracking.stillness import StillMemory, StillRule

_CLAIMED = -1e6  # a held still track's own place (Tracker._claims)
CLAIM_M = 0.25  # within this of a held still place a measurement is that track's
_UNASSIGNED = 1e9
# What the stream benchmark measured best (bench/results/tracker_tuning.md); the daemon's
# pipeline uses them (with covariances and coverage from service.tracking.measurements). The
# constructor keeps the former tracker's defaults, which tests of single mechanisms rely on.
RECOMMENDED: dict[str, Any] = {
    "motion": "imm",
    "accel_std": 1.0,
    "confirm_single_s": 1.0,
    "ghost_s": 0.5,
    "robust_chi2": 16.0,
    "multi_view_s": 0.1,
    "serve_coast_s": 0.5,
    "gate_m": 1.5,
    "gate_growth_mps": 0.5,
    "assign_cost": "likelihood",
    "doubt_outside": True,
    # the real CMC room, 10 people at 4 fps (bench/results/real_cmc_chain_tuning.md)
    "measurement_scale": 9.0,  # where it starts; learned from the innovations:
    "adapt_scale_s": 10.0,  # service.tracking.noise_scale
    "birth_clearance_m": 0.8,
    "merge_m": 0.35,
    "merge_s": 0.5,
    # issue 27: a still person lost for seconds keeps their id and their zone
    # (bench/results/still_presence.md, with the walking scenes' MOTA with and without it)
    "hold_still_s": 15.0,
    # each camera's box centre continues the track's (service.tracking.image_continuity)
    "image_std_h": 0.15,
    "image_growth_hps": 0.3,
    "image_cap": 4.0,
}
ASSIGN_COSTS = ("euclidean", "likelihood")
MOTION_MODELS = {"cv": ConstantVelocity, "imm": StandOrWalk}


@dataclass
class _State:
    id: int
    motion: ConstantVelocity | StandOrWalk
    born: float
    last_seen: float
    hits: int = 1
    rate: float = 1.0
    confirmed: bool = False
    multi_view: bool = False  # seen by two cameras at once for ``multi_view_s`` in all
    multi_view_time: float = 0.0  # seconds seen by two or more cameras at once
    doubted_s: float = 0.0  # time single-view while another camera should have seen it
    shadowed_s: float = 0.0  # time spent within merge_m of an older track
    still: StillMemory = field(default_factory=StillMemory)  # measured positions, still place
    cameras: list[int] = field(default_factory=list)
    origin: Origin = field(default_factory=Origin)  # of the position that last fed it
    views: ViewMemory = field(default_factory=ViewMemory)  # last box per camera


class Tracker:
    """Kalman (IMM) tracker with Hungarian assignment (see the module docstring)."""

    def __init__(
        self,
        fps_hint: float = 30.0,
        max_missing_s: float = 1.5,
        *,
        gate_m: float = 1.0,
        gate_growth_mps: float = 1.0,
        measurement_std_m: float = 0.12,
        accel_std: float = 2.0,
        confirm_s: float = 0.3,
        rate_time_s: float = 0.32,
        motion: str = "cv",
        measurement_scale: float = 1.0,
        adapt_scale_s: float = 0.0,
        min_measurement_std_m: float = 0.03,
        max_measurement_std_m: float = 3.0,
        confirm_single_s: float | None = None,
        stand_std_m: float = 0.03,
        stand_s: float = 2.0,
        walk_s: float = 10.0,
        ghost_s: float = 0.0,
        robust_chi2: float = 0.0,
        multi_view_s: float = 0.0,
        serve_coast_s: float | None = None,
        assign_cost: str = "euclidean",
        doubt_outside: bool = False,
        birth_clearance_m: float = 0.0,
        merge_s: float = 0.0,
        merge_m: float = 0.0,
        hold_still_s: float = 0.0,
        still_after_s: float = 5.0,
        still_radius_m: float = 0.5,
        still_window_s: float = 10.0,
        still_share: float = 0.6,
        still_gate_m: float = 1.0,
        still_guard_m: float = 1.2,
        still_multi_view_s: float = 1.0,
        image_std_h: float = 0.0,
        image_growth_hps: float = 0.6,
        image_cap: float = 16.0,
    ) -> None:
        if fps_hint <= 0 or max_missing_s <= 0 or gate_m <= 0:
            raise ValueError("fps_hint, max_missing_s and gate_m must be positive")
        self.fps_hint = float(fps_hint)
        self.max_missing_s = float(max_missing_s)
        self.gate_m = float(gate_m)
        self.gate_growth_mps = float(gate_growth_mps)
        self.measurement_var = float(measurement_std_m) ** 2
        self.accel_var = float(accel_std) ** 2
        self.confirm_s = max(0.0, float(confirm_s))
        self.rate_time_s = max(1e-6, float(rate_time_s))
        if motion not in MOTION_MODELS:
            raise ValueError(f"motion {motion!r}: expected one of {sorted(MOTION_MODELS)}")
        self.motion = motion
        self.noise_scale = NoiseScale(float(measurement_scale), float(adapt_scale_s))
        self.min_measurement_var = float(min_measurement_std_m) ** 2
        self.max_measurement_var = float(max_measurement_std_m) ** 2
        if confirm_single_s is None:
            confirm_single_s = self.confirm_s
        self.confirm_single_s = max(self.confirm_s, float(confirm_single_s))
        self.ghost_s = float(ghost_s)
        self.robust_chi2 = float(robust_chi2)
        self.multi_view_s = max(0.0, float(multi_view_s))
        if assign_cost not in ASSIGN_COSTS:
            raise ValueError(f"assign_cost {assign_cost!r}: expected one of {ASSIGN_COSTS}")
        self.assign_cost = assign_cost
        self.doubt_outside = bool(doubt_outside)
        self.birth_clearance_m = max(0.0, float(birth_clearance_m))
        self.merge_s = max(0.0, float(merge_s))
        self.merge_m = max(0.0, float(merge_m))
        self.serve_coast_s = self.max_missing_s if serve_coast_s is None else float(serve_coast_s)
        self.hold_still_s = max(0.0, float(hold_still_s))
        self.still_rule = StillRule(
            float(still_after_s),
            float(still_window_s),
            float(still_radius_m),
            float(still_share),
            leave_m=float(still_gate_m),  # beyond the gate that takes a held track back: left
            leave_seen_m=float(still_radius_m),  # ... or, two cameras seeing, beyond the radius
        )
        self.still_gate_m = float(still_gate_m)
        self.still_guard_m = float(still_guard_m)
        self.still_multi_view_s = max(self.multi_view_s, float(still_multi_view_s))
        self._still_places: list[tuple[int, np.ndarray]] = []  # (id, place) before this update
        self.image = ImageContinuity(
            max(0.0, float(image_std_h)), float(image_growth_hps), float(image_cap)
        )
        self._frame_dt = 1.0 / self.fps_hint
        self._motion_options = (
            {"stand_std": stand_std_m, "stand_s": stand_s, "walk_s": walk_s}
            if motion == "imm"
            else {}
        )
        self._tracks: list[_State] = []
        self._next_id = 1
        # id -> (place, when dropped) of still people whose tracks ended (:meth:`_returning_id`)
        self._lost_places: dict[int, tuple[np.ndarray, float]] = {}
        self._time: float | None = None
        self._previous_time: float | None = None  # of the update before the latest

    @property
    def time(self) -> float | None:
        """Time of the last update (seconds), ``None`` before the first one."""
        return self._time

    def reset(self) -> None:
        """Forget every track (ids keep increasing so clients never see an id reused)."""
        self._tracks.clear()
        self._lost_places.clear()
        self._time = None
        self._previous_time = None

    def update(
        self,
        t: float,
        positions: np.ndarray,
        origins: Sequence[Origin] | None = None,
        covariances: Sequence[np.ndarray | None] | np.ndarray | None = None,
        coverage: Coverage | None = None,
    ) -> list[Track]:
        """Fold the detections of time ``t`` (``positions`` [P, 2] metres) into the tracks.

        ``covariances`` (optional, one [2, 2] m² or ``None`` per position): the localizer's
        uncertainty of each measurement; ``None`` (or a non-finite one) means the isotropic
        ``measurement_std_m``. ``coverage`` (optional): floor positions [N, 2] → [N, K] bool,
        which cameras should see a person standing there (used with ``ghost_s``).
        ``origins[i].boxes`` (optional, [K, 4] px, NaN where camera k does not see the person):
        the association's boxes, for the image continuity cost (``image_std_h`` > 0,
        :mod:`service.tracking.image_continuity`).
        """
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        keep = np.all(np.isfinite(positions), axis=1)
        given = list(origins) if origins is not None else [Origin()] * len(positions)
        if len(given) != len(positions):
            raise ValueError(f"{len(given)} origins for {len(positions)} positions")
        noise = self._noise(covariances, len(positions), given)
        positions, noise = positions[keep], noise[keep]
        kept = [o for o, k in zip(given, keep, strict=True) if k]

        dt = 1.0 / self.fps_hint if self._time is None else float(t) - self._time
        if dt < 0:  # out-of-order frame set: treat as simultaneous rather than rewinding
            dt = 0.0
        self._frame_dt = dt
        self._previous_time = self._time
        self._time = float(t) if self._time is None else max(self._time, float(t))
        for track in self._tracks:
            self._predict(track, dt)
        self._still_places = [
            (tr.id, tr.still.place)
            for tr in self._tracks
            if self._still(tr) and tr.still.place is not None  # (narrowed for the types)
        ]

        boxes = [o.boxes for o in kept]
        rows, cols = self._assign(positions, noise, self._time, boxes)
        matched_tracks = set(rows.tolist())
        for r, c in zip(rows, cols, strict=True):
            self._correct(self._tracks[r], positions[c], noise[c], kept[c], self._time)
        for i, track in enumerate(self._tracks):
            if i not in matched_tracks:
                track.rate *= 1.0 - self._rate_weight(dt)
        self.noise_scale.step(dt)
        for c in self._births(positions, set(cols.tolist())):
            self._tracks.append(self._spawn(positions[c], noise[c], kept[c], self._time))
        if coverage is not None and self.ghost_s > 0:
            self._doubt(coverage, dt)
        if self.merge_s > 0 and self.merge_m > 0:
            self._merge_shadows(dt)

        alive = [
            (self._time - tr.last_seen) <= self._max_missing(tr)
            and (tr.confirmed or tr.last_seen == self._time)
            for tr in self._tracks
        ]
        self._remember_lost_places([tr for tr, a in zip(self._tracks, alive, strict=True) if not a])
        self._tracks = [tr for tr, a in zip(self._tracks, alive, strict=True) if a]
        return self.tracks()

    def tracks(self) -> list[Track]:
        """The reportable tracks (confirmed ones, coasting included), sorted by id."""
        return [
            self._report(tr)
            for tr in sorted(self._tracks, key=lambda s: s.id)
            if tr.confirmed and not self._ghost(tr) and self._servable(tr)
        ]

    def anchors(self, t: float) -> list[TrackAnchor]:
        """The reportable tracks predicted to time ``t`` (their state is not changed): where
        the association expects the people it already tracks (``service.tracking.association``)."""
        now = self._time if self._time is not None else float(t)
        out = []
        for tr in self._tracks:
            if not (tr.confirmed and not self._ghost(tr) and self._servable(tr)):
                continue
            motion = copy.deepcopy(tr.motion)
            motion.predict(max(0.0, float(t) - now))
            held = self._held_place(tr, now)
            mean = motion.mean[:2] if held is None else held
            cameras = 1 + max(tr.views.seen, default=-1)
            image_x, image_std = tr.views.predict(cameras, float(t), LABEL_STD_H, LABEL_GROWTH_HPS)
            unseen = max(0.0, float(t) - tr.last_seen)
            out.append(
                TrackAnchor(
                    mean.copy(), motion.cov[:2, :2].copy(), image_x, image_std, unseen, tr.id
                )
            )
        return out

    def hidden(self) -> list[tuple[Track, str]]:
        """The tracks held but not reported, each with why: ``"tentative"`` (not confirmed
        yet) or ``"ghost"`` (the ghost check). For diagnostics
        (``bench/serving/stream_breakdown.py`` attributes the stream's misses to them)."""
        return [
            (self._report(tr), self._why_hidden(tr))
            for tr in sorted(self._tracks, key=lambda s: s.id)
            if not tr.confirmed or self._ghost(tr) or not self._servable(tr)
        ]

    def _why_hidden(self, tr: _State) -> str:
        if not tr.confirmed:
            return "tentative"
        return "ghost" if self._ghost(tr) else "coasting"

    def _servable(self, tr: _State) -> bool:
        """Seen now, or coasting for at most ``serve_coast_s``, or a still person unseen for
        at most ``hold_still_s`` (module docstring)."""
        now = self._time if self._time is not None else 0.0
        limit = self.hold_still_s if self._still(tr) else self.serve_coast_s
        return now - tr.last_seen <= max(limit, self.serve_coast_s) + 1e-9

    def _still(self, tr: _State) -> bool:
        """A person seen by two cameras who was still when last seen
        (:mod:`service.tracking.stillness`): held through ``hold_still_s`` of misses."""
        return self.hold_still_s > 0 and tr.multi_view and tr.still.place is not None

    def _held_place(self, tr: _State, update_t: float | None) -> np.ndarray | None:
        """Where a still track is held (its still place) at the update of time ``update_t``:
        when unseen then, or when its last measurement was one camera's lone view within
        ``still_gate_m`` of the place. ``None`` for a track not still or seen by two cameras:
        that one is where its filter says (a still person who gets up and walks, seen, is
        followed by the filter).

        Why a lone view does not move a still track: its range is poorly known, and near a
        seated person it is as often a detector's false box or a fragment of them as the
        person (issue 27, ``bench/results/still_presence_chain.md``: one camera's persisting
        false box 0.8 m off took the held track and its filter, given the jump as a velocity,
        carried it out of the sofa's zone). The median of the window already takes the lone
        views in; the place moves when they keep saying the person moved. The price: a still
        person who walks off seen by one camera only is served at their place for their first
        ``still_gate_m``, then their lone views start a new track. Rejected: holding only after
        a dropout (a still track seen by two cameras, then one, followed by the filter): the
        hour through the chain fell to 99.34 % and 3 id changes (results file)."""
        if update_t is None or not self._still(tr):
            return None
        if update_t > tr.last_seen:
            return tr.still.place
        return tr.still.place if self._lone_near_place(tr) else None

    def _lone_near_place(self, tr: _State) -> bool:
        """Last fed by one camera's view within ``still_gate_m`` of the still place."""
        place = tr.still.place
        if len(tr.cameras) != 1 or place is None or not tr.still.points:
            return False
        return bool(np.hypot(*(np.asarray(tr.still.points[-1]) - place)) <= self.still_gate_m)

    def _max_missing(self, tr: _State) -> float:
        return max(self.max_missing_s, self.hold_still_s) if self._still(tr) else self.max_missing_s

    def _report(self, tr: _State) -> Track:
        now = self._time if self._time is not None else 0.0
        missing = now - tr.last_seen
        mean = tr.motion.mean
        held = self._held_place(tr, self._time)
        if held is not None:  # a still person unseen: at their place, not moving
            mean = np.array([held[0], held[1], 0.0, 0.0])
        coast = max(0.0, 1.0 - missing / self._max_missing(tr))
        return Track(
            id=tr.id,
            x=float(mean[0]),
            y=float(mean[1]),
            vx=float(mean[2]),
            vy=float(mean[3]),
            confidence=float(np.clip(tr.rate * coast, 0.0, 1.0)),
            cameras=list(tr.cameras) if missing == 0 else [],
            coasting=missing > 0,
            age_s=float(now - tr.born),
            frame=tr.origin.frame,
            association=tr.origin.association,
            cost=tr.origin.cost,
            inside=tr.origin.inside,
        )

    # -- filters -------------------------------------------------------------------------------

    def _noise(
        self,
        covariances: Sequence[np.ndarray | None] | np.ndarray | None,
        count: int,
        origins: Sequence[Origin],
    ) -> np.ndarray:
        """Measurement covariance [P, 2, 2] per position (isotropic default where not given),
        times the learned scale; a lying body's (``Origin.standing`` false) at least times the
        starting one: the localizer was set up on standing people, and its covariance says
        nothing of how far off a lying body's box puts them (a lone camera's lying box, trusted
        at the scale learned on walkers, dragged a fallen person's track 1.5 m along its line of
        sight: ``bench/results/tracker_tuning.md``). Seated people are not exempt: in the real
        crowd a half-hidden walker's box reads seated, and exempting those cost the learned
        scale its gain there (same file)."""
        out = np.tile(np.eye(2) * self.measurement_var, (count, 1, 1))
        if covariances is None:
            return out
        if len(covariances) != count:
            raise ValueError(f"{len(covariances)} covariances for {count} positions")
        for i, c in enumerate(covariances):
            if c is None:
                continue
            scale = self.noise_scale.value
            if not origins[i].standing:
                scale = max(scale, self.noise_scale.initial)
            c = np.asarray(c, dtype=np.float64).reshape(2, 2) * scale
            if not np.isfinite(c).all():
                continue
            # Bound the eigenvalues: a near-singular covariance would lock the track on one axis.
            w, v = np.linalg.eigh((c + c.T) / 2)
            w = np.clip(w, self.min_measurement_var, self.max_measurement_var)
            out[i] = (v * w) @ v.T
        return out

    def _predict(self, track: _State, dt: float) -> None:
        track.motion.predict(dt)

    def _correct(
        self, track: _State, z: np.ndarray, r: np.ndarray, origin: Origin, t: float
    ) -> None:
        nu = z - track.motion.mean[:2]
        d2 = float(nu @ np.linalg.solve(track.motion.cov[:2, :2] + r, nu))
        if track.confirmed and origin.standing:
            self.noise_scale.observe(d2)
        track.motion.correct(z, self._robust(r, d2))
        if not origin.standing:
            track.motion.settle()
        track.last_seen = t
        track.hits += 1
        if self.hold_still_s > 0:
            track.still.remember(t, z, self.still_rule, len(origin.cameras))
        weight = self._rate_weight(self._frame_dt)
        track.rate = track.rate * (1.0 - weight) + weight
        track.cameras = [int(k) for k in origin.cameras]
        track.views.remember(origin.boxes, t)
        self._count_views(track, self._frame_dt, z)
        self._confirm(track, t)
        track.origin = origin

    def _births(self, positions: np.ndarray, assigned: set[int]) -> list[int]:
        """The unassigned positions that start tracks: none closer than ``birth_clearance_m``
        to a confirmed track or to a track measured this update (a second cluster of a person
        already tracked, not a second person: two people do not stand in one spot).

        A still track held unseen is where the assignment expected it, its still place, not
        where its filter coasts: after its person walked off seen by one camera, the filter
        crept along behind them while the assignment, holding the track at the place, admitted
        nothing beyond ``still_gate_m`` of it, so the walker was neither assigned nor born for
        seconds, served nowhere (a missed fall of the simulated lounge, then standing 3 s on
        the spot, 1.3 m from where they had lain: ``bench/results/falls.md``). On 2026-12-05
        births were kept clear of both, because a birth beside the filter left the held track
        at the place, a phantom; since then the shadow merge gives the held id the walker's new
        track (:meth:`_merge_shadows`)."""
        free = [c for c in range(len(positions)) if c not in assigned]
        if self.birth_clearance_m <= 0 or not free or not self._tracks:
            return free
        held = [
            self._expected_at(tr)
            for tr in self._tracks
            if tr.confirmed or tr.last_seen == self._time
        ]
        if not held:
            return free
        gap = np.linalg.norm(positions[free][:, None] - np.stack(held)[None], axis=2).min(axis=1)
        return [c for c, d in zip(free, gap.tolist(), strict=True) if d >= self.birth_clearance_m]

    def _expected_at(self, tr: _State) -> np.ndarray:
        """Where this update found ``tr``: its filter if measured now, else where the
        assignment expected it (:meth:`_assign`: a held still track's place)."""
        held = None if tr.last_seen == self._time else self._held_place(tr, self._previous_time)
        return tr.motion.mean[:2] if held is None else held

    def _merge_shadows(self, dt: float) -> None:
        """Drop a track that has stayed within ``merge_m`` of an older one for
        ``merge_s``: two tracks on one person (fed by the two halves of a split association)
        that would otherwise both be served; the older id is kept. When the older one is a
        held still track whose person walked off (:meth:`_walked_off`) and the younger is seen
        now, the older takes the younger's state. Until 2026-12-05 the younger was dropped
        there too and the older stayed held at its place: the person was served nowhere, and
        a phantom sat at the place for ``hold_still_s`` (a missed fall of the simulated lounge;
        ``bench/results/falls.md``)."""
        kept: list[_State] = []
        for tr in sorted(self._tracks, key=lambda s: s.id):
            older = next(
                (
                    o
                    for o in kept
                    if np.linalg.norm(tr.motion.mean[:2] - o.motion.mean[:2]) < self.merge_m
                ),
                None,
            )
            tr.shadowed_s = tr.shadowed_s + dt if older is not None else 0.0
            if tr.shadowed_s <= self.merge_s:
                kept.append(tr)
            elif older is not None and tr.last_seen == self._time and self._walked_off(older):
                _take_over(older, tr)
        self._tracks = kept

    def _walked_off(self, tr: _State) -> bool:
        """A held still track (unseen now) whose filter has left the still gate: it followed
        its person's last lone views away from the place (:meth:`_held_place` keeps serving
        it there), so a new track where the filter went is that person."""
        place = tr.still.place
        return (
            self._time is not None
            and tr.last_seen < self._time
            and self._still(tr)
            and place is not None
            and float(np.linalg.norm(tr.motion.mean[:2] - place)) > self.still_gate_m
        )

    def _rate_weight(self, dt: float) -> float:
        """Weight of this update in the detection rate: an exponential average over time
        (``rate_time_s``), so confidence means the same at 4 and at 30 frame sets a second
        (0.32 s is the former per-frame weight 0.1 at 30 fps)."""
        return float(1.0 - np.exp(-max(dt, 0.0) / self.rate_time_s))

    def _robust(self, r: np.ndarray, d2: float) -> np.ndarray:
        """Measurement covariance inflated by d² / robust_chi2 when the innovation's squared
        Mahalanobis distance d² exceeds ``robust_chi2`` (a Huber-like weight: one wild box
        moves a track less)."""
        if self.robust_chi2 <= 0:
            return r
        return r * (d2 / self.robust_chi2) if d2 > self.robust_chi2 else r

    def _confirm(self, track: _State, t: float) -> None:
        # Tentative tracks die at their first miss, so surviving confirm_s means seen throughout.
        # single-view until seen by two cameras for multi_view_s; no camera info: confirm_s
        single = len(track.cameras) >= 1 and not track.multi_view
        wait = self.confirm_single_s if single else self.confirm_s
        track.confirmed = track.confirmed or t - track.born >= wait - 1e-9

    def _doubt(self, coverage: Coverage, dt: float) -> None:
        """Single-view tracks accumulate the time a camera that should see them reports
        nothing there (a detector's false positive is seen by one camera only). A track last
        fed a lying body is expected only where a camera sees the floor under it (a camera
        beside a body on the floor sees over it); its own camera, which reported it, may see
        it standing or lying."""
        doubtful = [tr for tr in self._tracks if not tr.multi_view]
        if not doubtful or dt <= 0:
            return
        where = np.stack([tr.motion.mean[:2] for tr in doubtful])
        lying = np.array([not tr.origin.standing for tr in doubtful])
        standing = np.asarray(coverage(where))
        covered = standing.copy()
        if lying.any():  # only the lying rows are judged again, by the floor under them
            covered[lying] = np.asarray(coverage(where[lying], np.ones(int(lying.sum()), bool)))
        for tr, row, upright in zip(doubtful, covered, standing, strict=True):
            seen = set(tr.cameras) if tr.last_seen == self._time else set()
            should = set(np.flatnonzero(row).tolist())
            could = should | set(np.flatnonzero(upright).tolist())
            if seen and (should - seen or (self.doubt_outside and not could & seen)):
                tr.doubted_s += dt

    def _count_views(self, track: _State, dt: float, z: np.ndarray) -> None:
        if len(track.cameras) > 1:
            track.multi_view_time += dt
        track.multi_view = track.multi_view or (
            len(track.cameras) > 1
            and track.multi_view_time >= self._multi_view_wait(track, z) - 1e-9
        )

    def _multi_view_wait(self, track: _State, z: np.ndarray) -> float:
        """``multi_view_s``; ``still_multi_view_s`` for a track measured (at ``z``) within
        ``still_guard_m`` of another track's still place. Why: beside a seated person whom the
        detector has lost, each camera's false boxes (and fragments of the person) are paired
        by the association into a two-camera "person" for a frame now and then; one such frame
        made the track multi-view, exempt from the ghost check, and it was served in the
        seated person's zone for seconds (issue 27, ``bench/results/still_presence_chain.md``).
        A real second person there is seen by both cameras for longer."""
        for other, place in self._still_places:
            if other != track.id and np.hypot(*(z - place)) <= self.still_guard_m:
                return self.still_multi_view_s
        return self.multi_view_s

    def _claims(self, held: list[np.ndarray | None], positions: np.ndarray) -> np.ndarray:
        """[T, P]: position p lies within ``CLAIM_M`` of track t's held place. Such a
        measurement is that still person back where they sat, whatever another track's cost:
        a false track that had walked in beside the place on false pairs took the sitter's
        fixes from their held id, whose covariance had grown while held, and both were served
        for the 15 s hold (``bench/results/still_presence_chain.md``, 1513 s: the fix was
        0.01 m from the place). A quarter metre, not the still radius (0.5 m): someone
        standing beside a seated person (handing them a cup) can be half a metre from their
        place, nobody stands on it."""
        claims = np.zeros((len(held), len(positions)), dtype=bool)
        for t, place in enumerate(held):
            if place is not None:
                claims[t] = np.linalg.norm(positions - place, axis=1) <= CLAIM_M
        return claims

    def _ghost(self, track: _State) -> bool:
        """Not (yet) a multi-view track, and longer than ``ghost_s`` unseen by a camera that
        should see it: a detector's false positive, not reported."""
        return not track.multi_view and track.doubted_s > self.ghost_s > 0

    def _spawn(self, z: np.ndarray, r: np.ndarray, origin: Origin, t: float) -> _State:
        # Unknown velocity: a walking person is within ~2 m/s, so start with that spread.
        motion = MOTION_MODELS[self.motion](
            z, r, float(np.sqrt(self.accel_var)), **self._motion_options
        )
        state = _State(
            id=self._returning_id(z, t),
            motion=motion,
            born=t,
            last_seen=t,
            cameras=[int(k) for k in origin.cameras],
            origin=origin,
        )
        if self.hold_still_s > 0:
            state.still.remember(t, z, self.still_rule, len(origin.cameras))
        state.views.remember(origin.boxes, t)
        # credited for one frame interval, as measured (the hint before a second update)
        self._count_views(state, self._frame_dt if self._frame_dt > 0 else 1.0 / self.fps_hint, z)
        self._confirm(state, t)
        return state

    def _remember_lost_places(self, dropped: list[_State]) -> None:
        """Keep, for ``hold_still_s``, where each dropped track's person was last still: the
        place they were held at or the one they were last judged to have left
        (:attr:`StillMemory.left`). Why: during a seated person's dropout a persisting false
        box of each camera, paired 1 m from them, took their held track away (two cameras
        release a hold), it was dropped there 1.5 s later, and when the sitter reappeared 3 s
        after that a new id started on the sofa (the seated hour on the AMD machine, 1665 s:
        ``bench/results/still_presence_chain.md``). Not chosen: a narrower gate for the
        two-camera fix that releases a hold. That pair lay just inside the 1 m gate (1.01 m
        from the sitter), and a person who got up during a dropout may be seen anywhere."""
        if self.hold_still_s <= 0 or self._time is None:
            return
        now = self._time
        self._lost_places = {
            ident: lost
            for ident, lost in self._lost_places.items()
            if now - lost[1] <= self.hold_still_s
        }
        for tr in dropped:
            place = tr.still.place if tr.still.place is not None else tr.still.left
            if tr.confirmed and tr.multi_view and place is not None:
                self._lost_places[tr.id] = (place.copy(), now)

    def _returning_id(self, z: np.ndarray, t: float) -> int:
        """The id of a new track at ``z``: that of a still person whose track ended within
        ``hold_still_s`` and whose place lies within ``still_radius_m`` of ``z`` (nobody else
        of them alive), else a new one. A person back where they sat is the person who sat
        there; a new id would change the id of someone who never left their seat. The track
        itself is new: its ``age_s`` starts again, and it is confirmed as any new track is."""
        alive = {tr.id for tr in self._tracks}
        near = [
            (float(np.linalg.norm(z - place)), ident)
            for ident, (place, dropped) in self._lost_places.items()
            if ident not in alive
            and t - dropped <= self.hold_still_s
            and np.linalg.norm(z - place) <= self.still_rule.radius_m
        ]
        if near:
            return min(near)[1]
        self._next_id += 1
        return self._next_id - 1

    def _assign(
        self,
        positions: np.ndarray,
        noise: np.ndarray,
        now: float,
        boxes: Sequence[np.ndarray | None] = (),
    ) -> tuple[np.ndarray, np.ndarray]:
        empty = np.zeros(0, dtype=int)
        if not self._tracks or not len(positions):
            return empty, empty
        # a still person held unseen is expected at their still place, within still_gate_m
        held = [self._held_place(tr, self._previous_time) for tr in self._tracks]
        predicted = np.stack(
            [
                tr.motion.mean[:2] if h is None else h
                for tr, h in zip(self._tracks, held, strict=True)
            ]
        )
        nu = positions[None, :, :] - predicted[:, None, :]  # [T, P, 2]
        dist = np.linalg.norm(nu, axis=2)
        missing = np.array([now - tr.last_seen for tr in self._tracks])
        gate = np.array([
            self.gate_m + self.gate_growth_mps * m if h is None else self.still_gate_m
            for m, h in zip(missing.tolist(), held, strict=True)
        ])  # fmt: skip
        admit = dist <= gate[:, None]
        cost = dist
        if self.assign_cost == "likelihood":
            # -2 log N(z; predicted, P + R) up to a constant: a lone view's long range error
            # costs little along its line of sight, much across it (module docstring).
            s = np.stack([tr.motion.cov[:2, :2] for tr in self._tracks])[:, None] + noise[None]
            d2 = np.einsum("tpi,tpij,tpj->tp", nu, np.linalg.inv(s), nu)
            cost = d2 + np.log(np.linalg.det(s))
        if self.image.enabled and len(boxes) == len(positions):
            # each camera's box centre against the track's last one there, moved on by its
            # image velocity (service.tracking.image_continuity)
            cost = cost + self.image.cost([tr.views for tr in self._tracks], boxes, now)
        # Tentative tracks lose ties to confirmed ones: a small penalty keeps ids stable.
        penalty = np.array([0.0 if tr.confirmed else 0.05 for tr in self._tracks])
        cost = np.where(admit, cost + penalty[:, None], _UNASSIGNED)
        cost = np.where(self._claims(held, positions), _CLAIMED, cost)
        rows, cols = linear_sum_assignment(cost)
        ok = cost[rows, cols] < _UNASSIGNED
        return rows[ok], cols[ok]


def _take_over(older: _State, younger: _State) -> None:
    """``older`` continues ``younger``'s track (its filter, views, still memory, last fix)."""
    older.motion, older.still, older.views = younger.motion, younger.still, younger.views
    older.last_seen, older.rate = younger.last_seen, younger.rate
    older.cameras, older.origin = younger.cameras, younger.origin

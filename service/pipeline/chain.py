"""One frame set's detections to tracks: associate, gate on the set-up area, correct, track.

The daemon's :class:`~service.pipeline.live.Pipeline`, ``momloc track`` (which drives that pipeline)
and the stream benchmarks (:mod:`service.offline.stream_eval`) all run this one object, so a figure
in
``bench/results/`` is a figure of the code that serves. Before it existed the benchmarks rebuilt
the chain by hand and a fix to one copy could silently leave the other behind.

Per frame set (time ``t``, one :class:`~models.detector.base.Detections` per camera):

0. **postures**: a seated or lying person's box is replaced by the box a standing person at the
   same place would give (the model was set up on standing people), and every box gets a
   posture that the track carries, smoothed, into the snapshot (:mod:`service.tracking.posture`;
   ``postures=False``: boxes as detected); after the association, a person whose cameras all
   see a compact box is read as a body on the floor where only that makes the views agree
   (:mod:`service.tracking.posture_views`), and a compact box read seated as one where only
   that keeps a tracked person in place (:mod:`service.tracking.posture_continuity`);
1. **associate** the boxes of all cameras into people (:mod:`service.tracking.association`), with
   the tracker's served tracks predicted to ``t`` as anchors (a tracked person's fragments fold
   into one association; ``track_anchors=False``: the boxes alone); each association says
   whether it lies in the model's set-up area (:mod:`models.mom.setup_area`);
2. **the set-up area**: ``outside_area="drop"`` (default) keeps people outside the area the model
   was set up on out of tracking and out of every output: the model was never taught there and
   zones, counts and automations are drawn inside. ``"flag"`` tracks them too and serves them
   with ``outside: true`` (the map shows them; zones and MQTT leave them out unless asked).
   The dropped ones stay readable as :attr:`Chain.outside` until the next call: the learning
   room learns from people beyond the area (:mod:`service.learning.labels`);
3. **correct** single-view positions by their track's lone-view offset
   (:mod:`service.tracking.view_bias`) and **track** with each position's covariance and the
   cameras' coverage (:mod:`service.tracking.measurements`, :mod:`service.tracking.tracker`);
   a track served beyond the set-up area is outside as in step 2, whatever fed it
   (:func:`gate_tracks_to_area`).

The chain keeps per-model state (the lone-view offsets): :meth:`Chain.new_model` forgets it when
the model is swapped.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from functools import partial
from typing import Literal

import numpy as np

from models.detector.base import Detections
from models.mom.setup_area import SetupArea
from service.stages import (
    AreaAware,
    AssociateStage,
    Association,
    LocalizationModel,
    Origin,
    Track,
    TrackAnchor,
    TrackStage,
)
from service.tracking.association import DEFAULT_MAX_ERROR_PX
from service.tracking.association import associate as associate_people
from service.tracking.measurements import coverage_function, measurement_covariances
from service.tracking.posture import (
    LYING,
    SITTING,
    STANDING,
    BoxPostures,
    PostureSmoother,
    cut_off,
)
from service.tracking.posture import normalise as normalise_postures
from service.tracking.posture_agreement import agree as agree_postures
from service.tracking.posture_continuity import reread_lying
from service.tracking.posture_views import lying_by_views
from service.tracking.recurring_boxes import RecurringBoxes
from service.tracking.view_bias import ViewBias

STOOD_S = 2.0  # a track's sure standing place is kept this long (:meth:`Chain._stood_at`): a
# fall's drop (the fall rules' ``max_drop_s``)
STOOD_SURE = 0.75  # ... a standing posture this sure (the fall rules' ``standing_confidence``)

OutsideArea = Literal["drop", "flag"]
OUTSIDE_AREA_POLICIES: tuple[OutsideArea, ...] = ("drop", "flag")


class Chain:
    """Associate → set-up area → lone-view correction → tracker (module docstring)."""

    def __init__(
        self,
        tracker: TrackStage,
        *,
        associate: AssociateStage | None = None,
        max_error_px: float = DEFAULT_MAX_ERROR_PX,
        outside_area: OutsideArea = "drop",
        use_covariance: bool = True,
        view_bias: ViewBias | Literal[True] | None = True,
        postures: bool = True,
        track_anchors: bool = True,
    ) -> None:
        if outside_area not in OUTSIDE_AREA_POLICIES:
            raise ValueError(f"outside_area {outside_area!r}: expected one of drop, flag")
        self.tracker = tracker
        self.associate: AssociateStage = associate if associate is not None else associate_people
        self.max_error_px = float(max_error_px)
        self.outside_area: OutsideArea = outside_area
        self.use_covariance = use_covariance
        # lone-view offsets (service.tracking.view_bias); None: single views are not corrected
        self.view_bias: ViewBias | None = ViewBias() if view_bias is True else view_bias
        self.timings_ms: dict[str, float] = {}  # of the last call, per step
        self.outside: list[Association] = []  # of the last call: dropped beyond the set-up area
        # seated and lying boxes read as standing ones, and each track's posture
        # (service.tracking.posture); False: boxes as detected, no posture
        self.postures = postures
        self.posture_smoother = PostureSmoother()
        # where each camera keeps reading lying: no evidence of a body on the floor there
        # (service.tracking.recurring_boxes)
        self.recurring_boxes = RecurringBoxes()
        # the tracks claim their boxes before the rest is clustered (service.tracking.association)
        self.track_anchors = track_anchors
        # per track id: when and where it last read standing for sure (:meth:`_stood_at`)
        self._stood: dict[int, tuple[float, np.ndarray]] = {}
        # per track id: when an association last fed it (a stood place's ``unseen_s``)
        self._fed: dict[int, float] = {}

    def new_model(self) -> None:
        """Forget what was learned about the former model's localizer (lone-view offsets)."""
        if self.view_bias is not None:
            self.view_bias = ViewBias()

    def __call__(
        self,
        t: float,
        detections: Sequence[Detections],
        runtime: LocalizationModel | None,
        delivered: Sequence[bool],
        seq: int = 0,
    ) -> tuple[list[Association], list[Track]]:
        """The associations fed to the tracker (those it serves, in the order of each track's
        ``association``) and the tracks after time ``t``. Without a model: no people,
        the tracker still ages its tracks."""
        started = time.perf_counter()
        associations: list[Association] = []
        self.outside = []
        box_postures: BoxPostures | None = None
        if runtime is not None:
            detected, area = detections, getattr(runtime, "setup_area", None)
            if self.postures:
                detections, box_postures = normalise_postures(
                    detections, area, runtime.image_sizes, partial(self.recurring_boxes.update, t)
                )
            anchors = self._anchors(t)
            found = self.associate(
                detections, runtime, max_error_px=self.max_error_px, anchors=anchors
            )
            if box_postures is not None:  # one posture per person (its boxes' vote)
                found = agree_postures(found, detected, box_postures, area, runtime)
                found = lying_by_views(found, detected, box_postures, area, runtime)
                found = reread_lying(
                    found, detected, box_postures, area, runtime, anchors + self._stood_at(t)
                )
                doubtful = [
                    a
                    for a in found
                    if _doubtful(a, box_postures, detected, area, runtime.image_sizes)
                ]
                _outside_as_detected(doubtful, detected, runtime, area)
            associations = gate_to_area(found, runtime, self.outside_area)
            if len(associations) < len(found):
                self.outside = [a for a in found if not a.inside]
        associated = time.perf_counter()
        postures = (  # one per association: its boxes' vote
            [box_postures.of(a.detection_index) for a in associations]
            if box_postures is not None
            else []
        )
        origins = [
            Origin(
                cameras=tuple(int(c) for c in a.cameras),
                frame=seq,
                association=i,
                cost=a.cost,
                inside=a.inside,
                boxes=a.boxes,
                standing=not postures or postures[i][0] != LYING,
            )
            for i, a in enumerate(associations)
        ]
        covariances = (
            measurement_covariances(associations, runtime) if self.use_covariance else None
        )
        coverage = coverage_function(runtime, delivered)
        positions = np.array([np.asarray(a.world, float)[:2] for a in associations]).reshape(-1, 2)
        if self.view_bias is not None:  # single views minus their track's lone-view offset
            positions = self.view_bias.correct(t, associations, positions, runtime)
        tracks = self.tracker.update(
            t, positions, origins, covariances=covariances, coverage=coverage
        )
        if self.view_bias is not None:  # learn the offsets from what fed each track
            self.view_bias.learn(t, associations, runtime, tracks)
        if self.postures:
            self._smooth_postures(t, tracks, postures)
        if runtime is not None:
            tracks = gate_tracks_to_area(tracks, runtime, self.outside_area)
        self.timings_ms = {
            "associate": (associated - started) * 1e3,
            "track": (time.perf_counter() - associated) * 1e3,
        }
        return associations, tracks

    def _anchors(self, t: float) -> list[TrackAnchor]:
        """The tracker's served tracks predicted to ``t`` (``Tracker.anchors``), which claim
        their boxes in the association before the rest is clustered; none when switched off
        or from a tracker that cannot predict."""
        anchors = getattr(self.tracker, "anchors", None)
        return list(anchors(t)) if self.track_anchors and callable(anchors) else []

    def _stood_at(self, t: float) -> list[TrackAnchor]:
        """Where tracks read standing for sure (posture confidence ≥ ``STOOD_SURE``) within the
        last ``STOOD_S``: besides each track's predicted position, the places the lone-view
        continuity reading (:func:`~service.tracking.posture_continuity.reread_lying`) keeps
        a person near. Why: a lying body's lone view read seated is put metres along its
        camera's line of sight, but the first such reads are often only 0.5-0.8 m off, under
        the rule's jump, and they drag the track; each later read is then near the dragged
        track and the body was never read lying (a miss of the simulated lounge's falls,
        ``bench/results/falls.md``). Where the person last stood does not move. Each place is
        as stale as its track (``unseen_s``: since an association last fed it), so the reading
        drops it with the track (its ``HELD_S``)."""
        return [
            TrackAnchor(
                xy.copy(), np.zeros((2, 2)), unseen_s=t - self._fed.get(i, when), track_id=i
            )
            for i, (when, xy) in self._stood.items()
            if t - when <= STOOD_S
        ]

    def _smooth_postures(
        self, t: float, tracks: list[Track], postures: list[tuple[str, float]]
    ) -> None:
        """Each served track's posture (``Track.posture``: label and confidence), averaged over
        time from the postures of the associations that fed it (``postures``, one per
        association of this frame set); a coasting track keeps the last one. A track whose
        boxes read standing now and whose posture is sure of it has its place remembered
        (:meth:`_stood_at`; the smoothed posture alone lags a drop by a few frames)."""
        smoother = self.posture_smoother
        for track in tracks:
            fed = track.association if not track.coasting else None
            seen = postures[fed] if fed is not None and fed < len(postures) else None
            label, sure = track.posture = (
                smoother.update(track.id, t, *seen) if seen else smoother.current(track.id)
            )
            if seen:
                self._fed[track.id] = t
            if seen and seen[0] == label == STANDING and sure >= STOOD_SURE:
                self._stood[track.id] = (t, np.array([track.x, track.y], np.float64))
        alive = {track.id for track in tracks} | set(self.tracker_ids())
        smoother.forget(alive)
        self._stood = {i: place for i, place in self._stood.items() if i in alive}
        self._fed = {i: when for i, when in self._fed.items() if i in alive}

    def tracker_ids(self) -> list[int]:
        """Ids the tracker still holds (served or not): their postures are kept."""
        hidden = getattr(self.tracker, "hidden", None)
        return [track.id for track, _ in hidden()] if callable(hidden) else []


def _doubtful(
    association: Association,
    postures: BoxPostures,
    detected: Sequence[Detections],
    area: SetupArea | None,
    image_sizes: np.ndarray,
) -> bool:
    """Whether the posture step's replacement of ``association`` is to be judged by its boxes
    as detected (:func:`_outside_as_detected`): a seated person always, a lying one when every
    box of it read as lying may be a person cut off by the image border
    (:func:`~service.tracking.posture.cut_off`: at the border and narrower than a body's length).

    Why: the lying replacement puts the body's floor point at the box centre, which holds only
    for a box that holds the whole body. A walker whose legs are below the frame leaves a short
    box that reads as lying, and on the real CMC room (nobody lies there) nearly all lying
    replacements were such boxes, at the bottom edge, of people beyond the set-up area. A lying
    body that the image holds is not judged as detected: its low wide box read as a standing
    person's is put far beyond them, and a fall must not vanish (``tests/e2e/test_falls.py``).
    Rejected: every lying replacement judged as detected (the real room's best figures, 0.6-1.2
    points of MOTA above this rule, but a fall's box read as a standing person's is put beyond
    the body and the fall vanishes); the border alone (0.6 points above this rule on the real
    room, but a fallen person near a camera, cut by the frame, is judged as a walker's torso).
    Figures: ``bench/results/real_cmc_chain_tuning.md``."""
    label = postures.of(association.detection_index)[0]
    if label != LYING:
        return label == SITTING
    cut = [
        bool(cut_off(detected[k].boxes[i], area, k, image_sizes[k])[0])
        for k, i in enumerate(association.detection_index)
        if i is not None
        and k < len(detected)
        and i < min(len(detected[k].boxes), len(postures.labels[k]))
        and postures.labels[k][i] == LYING
    ]
    return bool(cut) and all(cut)


def _outside_as_detected(
    associations: list[Association],
    detected: Sequence[Detections],
    runtime: LocalizationModel,
    area: SetupArea | None,
) -> None:
    """Mark outside the set-up area every one of the (doubtful: :func:`_doubtful`)
    ``associations`` whose boxes the posture step replaced and whose boxes *as detected* are
    localized outside its floor area.

    Why: a box cut by a person in front or by the image border, or a detector's fragment of a
    body, is short like a seated or lying person's, and its standing replacement reaches to a
    floor point nearer the camera; on the real CMC room such boxes of people beyond the area
    were carried into it and served (``bench/results/real_cmc_chain_tuning.md``). A person
    really seated in the area is in it as detected too: their box bottom is the feet or a
    table, a little nearer the camera than their hips, and the area has a margin. Only the
    floor position is judged: the image check
    (:meth:`~models.mom.setup_area.SetupArea.boxes_in_region`) wants a standing person's
    height, which a seated box never has (it dropped the demo's sofa sitter).
    """
    if area is None:
        return
    replaced, as_detected = [], []
    for a in associations:
        boxes = _as_detected(a, detected) if a.inside else None
        if boxes is not None and not np.array_equal(
            boxes, a.boxes.astype(np.float32), equal_nan=True
        ):
            replaced.append(a)
            as_detected.append(boxes)
    if not replaced:
        return
    world = np.asarray(runtime.localize(np.stack(as_detected)), float)
    for a, flag in zip(replaced, area.contains(world).tolist(), strict=True):
        a.inside = bool(flag)


def _as_detected(association: Association, detected: Sequence[Detections]) -> np.ndarray:
    """The association's boxes [K, 4] as the detector returned them."""
    boxes = np.array(association.boxes, dtype=np.float32, copy=True)
    for k, i in enumerate(association.detection_index):
        if i is not None and k < len(detected) and i < len(detected[k].boxes):
            boxes[k] = detected[k].boxes[i]
    return boxes


def gate_to_area(
    associations: list[Association], runtime: AreaAware, outside_area: OutsideArea
) -> list[Association]:
    """Mark each association inside or outside the model's set-up area (one already marked
    outside stays so); drop the outside ones unless they are to be served flagged
    (``outside_area="flag"``)."""
    if not associations:
        return associations
    boxes = np.stack([a.boxes for a in associations])
    world = np.stack([np.asarray(a.world, float)[:2] for a in associations])
    inside = np.asarray(runtime.inside(boxes, world), dtype=bool)
    for a, flag in zip(associations, inside.tolist(), strict=True):
        a.inside = a.inside and bool(flag)
    if outside_area == "flag":
        return associations
    return [a for a in associations if a.inside]


def gate_tracks_to_area(
    tracks: list[Track], runtime: LocalizationModel, outside_area: OutsideArea
) -> list[Track]:
    """Mark a track served beyond the model's set-up area outside, whatever association fed
    it; drop it unless flagged (``outside_area="flag"``). Why: the associations are gated, but
    a track's served position is its filter, which a lone view's offset correction or its own
    velocity carries past the area's edge; zones, counts and falls must not see it there. In
    the simulated lounge's daily life a crouch beside the wall, read lying by one camera, was
    served 0.7 m beyond the area (outside the room) and raised a false fall; no fall event of
    the 96 simulated falls was beyond the area (``bench/results/falls.md``)."""
    if not tracks:
        return tracks
    unseen = np.full((len(tracks), runtime.num_cameras, 4), np.nan)
    world = np.array([[tr.x, tr.y] for tr in tracks], dtype=np.float64)
    inside = np.asarray(runtime.inside(unseen, world), dtype=bool)
    for track, flag in zip(tracks, inside.tolist(), strict=True):
        track.inside = track.inside and bool(flag)
    return tracks if outside_area == "flag" else [tr for tr in tracks if tr.inside]


def served_inside(track: Track) -> bool:
    """Whether a served track is inside the set-up area (the association that last fed it)."""
    return track.inside

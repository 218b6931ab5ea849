"""A compact box is read as a body on the floor when only that reading keeps a tracked person
where their track is.

Why: a body lying along a camera's line of sight gives that camera a short, compact box, the
shape of a seated person's or a squat's (:mod:`service.tracking.posture`), and seen by that
camera alone it reads sitting. The seated conversion keeps the box's top as a head 0.64 of a
standing height above the floor, but the top of that box is the far end of a body on the floor,
so the person was put 1.5-2 m beyond where they lay: in the simulated lounge's held-out falls,
lone views of lying bodies that read sitting were put 1.68 m off (median) by the seated
conversion and 0.22 m off by the lying one (from the box centre), and those read lying by their
keypoints 1.72 and 0.46 m (``bench/results/falls.md``; since 2026-12-07 night a box read lying
by its keypoints is converted as lying in the first place, :mod:`service.tracking.posture`). The
fallen person then either left their track, or dragged it metres away, and the fall was not
reported.

What tells the two readings apart is where the person was a moment ago: nobody moves a metre
and more while sitting down, squatting or falling. So an association whose boxes were converted
from their top (read seated) is converted again as a body on the
floor (:func:`~service.tracking.posture.standing_boxes` with ``lying``), and that reading is
taken, with the posture ``lying``, when it lands within ``NEAR_M`` of a tracked person's
predicted position or of where a track last stood for sure in the last 2 s (both given as
:class:`~service.stages.TrackAnchor`; the chain's ``Chain._stood_at``: the first seated reads
of a fall, under the jump, drag the track, never the place it stood) from which the seated
reading is more than ``JUMP_M`` away, by a margin of ``GAP_M``, and no other association is
already near that track. A person who sits down where they stood is nearer their track as
seated; a squat's two readings are both within a metre or so of it; a new person (no track
near) is left alone.

The lying reading here is from the box's centre (``CENTRE``), not from
:data:`~service.tracking.posture.LYING_FOOT` down it as for a box that reads lying by its shape:
the rule's bounds were measured on the centre, and from 0.7 down the two readings of a compact
box lie 0.2 of its height closer together, the rule took fewer of a fallen body's lengthwise
views, their seated readings put the body 1.2 m off, and the simulated lounge's lying person was
served in 65 % of their frames instead of 98 % (``bench/results/falls.md``).

A track no camera has seen for longer than ``HELD_S`` (1.5 s) is no anchor. The tracker
serves a track unseen for longer than its ``serve_coast_s`` (0.5 s) only while its still hold
keeps it (``hold_still_s``), at the place it was last still, and after a second or two that is
no longer where a person was a moment ago. ``HELD_S`` is this rule's own bound, measured here,
not a tracker setting: it stays put when a user changes how long the tracker keeps ids. In the
simulated lounge's daily life such a held track was a phantom (a duplicate of a crouching
person's track, dragged off them and held unseen for 2.2 s), and the re-read fed it a lying
body: a false fall (``bench/results/falls.md``). A faller's track unseen for a second while they
go down still anchors the body; 0.5 s instead of 1.5 s took a second false fall away and made a
fall 5.8 s late (its faller's track unseen for 1.1 s). Nor is where such a track last stood
(the chain gives each place the time since an association last fed its track): in held-out
daily life a sitter got up and walked off, their track was held at the sofa where it had just
read standing, and 1.8 s later a false box read sitting was re-read lying there, a false fall.

Nor is an association re-read whose seated reading lies within ``NEAR_M`` of another tracked
person (an anchor of another track: :class:`~service.stages.TrackAnchor`'s ``track_id``; one of
unknown track counts as another's): that box continues them, and its lying reading beside
someone else's track is the wrong person on the floor. In held-out daily life of the simulated
lounge (seed 4301), a person on a chair seen by one camera read seated 0.06-0.23 m from their
own track and lying 1.2 m off, 0.4 m from the track of a person on the sofa: re-read, it was a
false fall there (``bench/results/falls.md``). A body on the floor reads seated 1.5-2 m along its
camera's line of sight, where another person is seldom tracked. The faller's own track, dragged
towards its seated reads, is no one else's: the place it stood still anchors the lying reading.

A box narrower than ``MIN_WIDTH`` (0.2) of a standing person's height at its place is not
re-read: a body on the floor is at least as wide in the image as its shoulders seen end-on
(:data:`~service.tracking.posture.LYING_MIN_WIDTH`, whose 0.15 is for a box read lying by its
shape and leaves room for a child). Of the held bodies' boxes read sitting in the simulated
lounge, 0.75 % of the lying ones and none of the crouches' are narrower; a held-out daily-life
false fall was a false box 0.17-0.20 of the height wide, re-read lying beside a track dragged
off a person sitting down (``bench/results/falls.md``).

Measured on held bodies of the simulated lounge with the true position standing in for the
track's (seeds 1-8 of the fall bench and 2 × 20 min of its daily life, each box localized alone;
``bench/results/falls.md``): the rule takes 69 % of the lone views of lying bodies read
sitting (and took 85 % of those read lying by their keypoints, converted from their top until
2026-12-07), 0.3 % of the squats' boxes and none of the sitters'. Rejected: a lower
``JUMP_M`` (1.0 m with ``NEAR_M`` 0.6 and no margin took 4 % of the squats' boxes, each a step
towards a false fall: a squat goes down as fast as a fall).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from models.detector.base import Detections
from models.mom.setup_area import SetupArea
from service.stages import Association, TrackAnchor
from service.tracking.posture import (
    LYING,
    SITTING,
    BoxPostures,
    standing_boxes,
    standing_height_at,
)
from service.tracking.posture_agreement import Relocalizing

JUMP_M = 1.2  # the seated reading this far from the track: no sitting down does that
NEAR_M = 0.6  # ... and the lying reading this near it
GAP_M = 1.0  # ... nearer by at least this much
SURE_GAP_M = 0.5  # beyond GAP_M, the lying read's confidence grows to 1 over this
CENTRE = 0.5  # the lying reading's floor point: the box centre (module docstring)
HELD_S = 1.5  # a track unseen longer is no anchor (docstring: measured, not the tracker's)
MIN_WIDTH = 0.2  # of a standing person's height there: narrower, no body seen end-on (docstring)


def reread_lying(
    associations: Sequence[Association],
    detected: Sequence[Detections],
    postures: BoxPostures,
    area: SetupArea | None,
    runtime: Relocalizing,
    anchors: Sequence[TrackAnchor],
) -> list[Association]:
    """``associations`` with each one read as a body on the floor where only that reading keeps
    a tracked person in place (module docstring); ``postures`` is updated to say ``lying`` for
    the boxes of each association so read."""
    out = list(associations)
    anchors = [a for a in anchors if a.unseen_s <= HELD_S]
    if area is None or not anchors or runtime.observation != "bbox" or not out:
        return out
    tracked = np.stack([np.asarray(a.xy, np.float64)[:2] for a in anchors])
    where = np.stack([np.asarray(a.world, np.float64)[:2] for a in out])
    for n, association in enumerate(out):
        boxes = _from_the_top(association, detected, postures, area)
        if boxes is None:
            continue
        rows = np.full_like(np.asarray(association.boxes, np.float64), np.nan)
        for k, box in boxes.items():
            rows[k] = standing_boxes(box[None], np.array([LYING], dtype=object), area, k, CENTRE)[0]
        lying = np.asarray(runtime.localize(rows[None]), np.float64)[0]
        if not np.isfinite(lying).all():
            continue
        near = np.linalg.norm(tracked - lying, axis=1)
        track = int(np.argmin(near))
        seated = float(np.linalg.norm(where[n] - tracked[track]))
        others = np.delete(np.linalg.norm(where - tracked[track], axis=1), n)
        if not (
            near[track] < NEAR_M
            and seated > JUMP_M
            and seated - near[track] > GAP_M
            and not (others < NEAR_M).any()
            and not _someone_else_there(where[n], tracked, anchors, track)
        ):
            continue
        covariance = np.asarray(runtime.covariance(rows[None]), np.float64)[0]
        out[n] = dataclasses.replace(association, boxes=rows, world=lying, covariance=covariance)
        where[n] = lying
        sure = 0.5 + 0.5 * min(max((seated - near[track] - GAP_M) / SURE_GAP_M, 0.0), 1.0)
        for k in boxes:
            index = association.detection_index[k]
            assert index is not None
            postures.labels[k][index] = LYING
            postures.confidence[k][index] = round(sure, 3)
    return out


def _someone_else_there(
    seated: np.ndarray, tracked: np.ndarray, anchors: Sequence[TrackAnchor], track: int
) -> bool:
    """Whether the seated reading ``seated`` lies within ``NEAR_M`` of an anchor of another
    track than anchor ``track``'s (anchors of unknown track count as another's): that reading
    continues a tracked person (module docstring)."""
    owner = anchors[track].track_id
    near = np.linalg.norm(tracked - seated, axis=1) < NEAR_M
    return any(
        near[i] and (owner is None or a.track_id != owner)
        for i, a in enumerate(anchors)
        if i != track
    )


def _from_the_top(
    association: Association,
    detected: Sequence[Detections],
    postures: BoxPostures,
    area: SetupArea,
) -> dict[int, np.ndarray] | None:
    """The association's boxes as detected, by camera, when none of them reads standing or is
    narrower than ``MIN_WIDTH`` and at least one was converted from its top (read sitting: its
    replacement is the seated one); else None."""
    boxes = postures.low(association.detection_index, detected)
    if not boxes:
        return None
    from_top = False
    for k, box in boxes.items():
        expected = standing_height_at(box, area, k)
        if expected is not None and box[2] - box[0] < MIN_WIDTH * float(expected[0]):
            return None
        seated = standing_boxes(box[None], np.array([SITTING], dtype=object), area, k)[0]
        from_top |= bool(np.allclose(association.boxes[k], seated, atol=0.5))
    return boxes if from_top else None

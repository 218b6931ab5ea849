"""Posture from the box shape, and the box a standing person at the same place would give.

Why: the localizer is trained on people standing and walking (set-up marks, walks), so it reads
a box's bottom as the feet and its height as a person's. A seated person's box ends at the feet
0.4-0.5 m ahead of the hips, or at a table top when the legs are hidden; a lying person's box is
low and wide. Fed as they are, the model put a seated person 0.2-0.5 m toward the camera and a
lying one 0.6-1.2 m off (``bench/results/postures.md``).

What is known without calibration: the set-up area's per-camera height model
(:class:`models.mom.setup_area.CameraRegion.expected_height`: how tall a person standing at each
foot pixel looks). Per box, ``ratio`` = box height / expected height at its bottom centre and
``aspect`` = width / height:

- **standing**: ratio ≥ ``SEATED_RATIO``; left as it is;
- **lying**: ratio below ``LYING_RATIO``, or a flat box (aspect ≥ ``LYING_FLAT_ASPECT``)
  below ``SEATED_RATIO``: the body lies on the floor, so its middle is on the floor, a standing
  box there replaces it. That floor point is ``LYING_FOOT`` (0.7) of the way down the box, not
  its centre: the box's bottom is the body's near end on the floor, its top the far end lifted
  by the body's thickness, and perspective shrinks the far half, so the floor under the body's
  middle is seen below the box's centre. Until 2026-12-06 the centre was used. Lone views of
  the lying bodies of the fall bench's lounge (seeds 601-608), each localized alone: those read
  lying 0.41 m off (median; p90 0.55 m) from the centre, 0.22 m (p90 0.31 m) from 0.7 down;
  their compact lengthwise boxes (read sitting; converted as lying where only that makes an
  association's views agree, :mod:`service.tracking.posture_views`) 0.33 m and 0.18 m (from 0.6-0.8
  down, flat ones 0.19-0.27 m, compact ones 0.18-0.20 m). The re-read of a lone compact box
  (:mod:`service.tracking.posture_continuity`) keeps the centre its bounds were measured on. It
  is a figure of simulated bodies, to be checked on
  real people lying down, as ``SEATED_TOP`` is. A box that is short but not flat is *not* lying
  above 0.33 of the height: a squat to pick something up (pelvis at 0.2 of the height, trunk
  bent forward) is a compact box 0.4-0.6 of the height and 0.6-1.3 times as wide as tall, and
  until 2026-12-04 its 0.33-0.45 reads (one crouch box in twenty) were lying and every false
  fall the bench had. Held bodies of the bench's rooms (seeds 1-4, 5 fps): 4.8 % of crouch
  boxes read lying below 0.45, 0.1 % below 0.33, for 57 % and 50 % of lying boxes; what is
  lost is a body lying obliquely, short and not flat, which the other view mostly sees flat
  (:meth:`BoxPostures.of`). A box as wide as tall (aspect 1-1.5) at 0.45-0.6 is not lying
  either: a person seated side-on in an armchair gives exactly that box (the
  simulated lounge's armchair: 0.47-0.6 tall, aspect 1.0-1.3, one read in seven), while only one
  lying read in twenty has it (lying bodies are mostly far shorter or flatter). Read as lying,
  the armchair sitter was put 0.5 m off and, sitting down, raised false falls (``lying`` a
  moment after ``standing``: ``bench/results/falls.md``). Until 2026-12-04 such a box was lying
  below 0.6 of the height;
  A box short enough to read lying but narrower than ``LYING_MIN_WIDTH`` (0.15) of a standing
  person's height at its place is no body on the floor, whatever it is (a detector's false box,
  a head over a sofa back): ``unknown``, localized as detected. A body lying on the floor is at
  least as wide in the image as its shoulders, 0.2-0.26 of a standing adult's height, when seen
  end-on, and far wider in any other view; 0.15 leaves room for a child. Measured on the
  simulated lounge (fall bench, seeds 601-608 and half an hour of daily life,
  ``bench/results/falls.md``): no box of a fallen body that reads lying is narrower than 0.25 of
  the height (99 % are 0.58 or wider), and 86 % of the false boxes that read lying are narrower
  than 0.15 (the detector's false boxes are person-shaped, 0.3-0.6 as wide as tall, so a short
  one is narrow);
  until 2026-12-06 they read lying, and one camera's lone view of one for 1.5 s was a false fall;
- **sitting** (crouching too: both are a short, wider box): the head is ``SEATED_TOP`` of a
  standing person's height above the floor, so the feet of a standing person with the same head
  pixel are found by a fixed-point search on the height model, and that standing box replaces
  the seated one. Keeping the top and not the bottom is what makes hidden legs harmless. The
  simulated seated body's top is at 0.715 of its standing height; 0.64 is what the simulated
  lounge measured best (per-frame median 0.09 m against 0.29 m at 0.715 and 0.62 m at 0.8):
  the fitted height model reads standing people there ~14 % short, and the factor absorbs that.
  It is a figure of one simulated room, to be checked on real seated people.

A box within ``BORDER_PX`` of the image border is left as it is (``unknown``): a person cut
off by the frame edge is short for another reason. Unless what is left of it is a body on the
floor (:func:`cut_postures`): cut by the bottom or top edge, a flat box a body's length wide
(``WHOLE_BODY_WIDTH``); cut by a side only (the height is whole), a box that reads lying. A
fallen person near a camera is often cut so (a sixth of the lying frames in the simulated
lounge, where the other camera sees them lengthwise), and a walker's torso cut by the frame is
neither that wide nor that low. A real detector's box of a cut person ends a
little inside the edge, up to ``CUT_MARGIN`` of the image side (:func:`at_border`): the chain
does not trust a lying box there unless it is a body's length wide (:func:`cut_off`,
:mod:`service.pipeline.chain`).

The thresholds were read off the simulated ratios and aspects of each posture (the bench prints
them); the confidence is how far the box is from the nearest threshold, scaled to 0.5..1.

**Keypoints, when the detections carry them** (a pose estimator is optional: the box rules
above are what every detector gets): a box that reads sitting whose two shoulders are both
more than ``HEAD_DOWN`` of the box height below both hips in the image reads lying
(:func:`head_down`; joints under ``KEYPOINT_FOUND`` confidence, a pose estimator's guess at
hidden ones, do not count). That is a body lying along the camera's line of sight head
towards it: the nearer end of a body on the floor is lower in the image, and such a body's
box is short and compact like a squat's, the missed falls' commonest cause. No sitter or
squat has the shoulders below the hips. Held bodies of the fall bench's rooms (seeds 1-4, boxes
the box rules read sitting, 5-10 fps): 46 % of the lying bodies' boxes have the cue (the
others lie feet towards the camera, or the pose is missing: 32 %, short boxes), against
0.05 % of the sitters' (38 of 83608, gross keypoint errors) and 0.02 % of the squats' (1 of
4544). Such a box is converted as any lying box, from ``LYING_FOOT`` down it. Until
2026-12-07 it was converted as its shape says (seated, from its top), which on 2026-12-04 put
the lying person 0.36 m off per frame (median) against 0.46 m from the box centre; since the
lying floor point moved to 0.7 down the box, the lying conversion is far better. Lone views of
such boxes of the fall bench's bodies (seeds 601-620, each localized alone), seated
conversion against lying: 1.52 m off (median; every one over 1 m) against 0.08 m (p90 0.15 m);
with the other camera's box, 0.52 m against 0.09 m. A fallen person whom only that camera saw
was put 1.2-1.7 m towards it, where no track was, the tracker's ghost check doubted the lone
view, and no fall came (``bench/results/falls.md``, 2026-12-07 night). A compact box read
sitting by its shape alone is converted again, from its centre, when only that keeps a tracked
person in place (:mod:`service.tracking.posture_continuity`, after the association).
Rejected: the feet-towards-the-camera half by the legs' length in the image against
the trunk's (hip to ankle 1.2 trunks or more: 15 % of the lying boxes, and 14 % of the
squats', whose trunk bent forward is short in the image and whose ankles a pose estimator
misplaces in a third of the frames); the hips as the floor point (a pose estimator guesses
hidden legs, and the box rules are needed without one anyway).

A model without a height model (trained before the set-up area, e.g. an old demo model) gets
``unknown`` and its boxes unchanged. Rejected: the aspect ratio alone (a standing person's box
is 0.2-0.6 wide per unit height, a seated one's 0.5-1.1: they overlap).
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from models.detector.base import Detections
from models.mom.setup_area import SetupArea

STANDING, SITTING, LYING, UNKNOWN = "standing", "sitting", "lying", "unknown"
SEATED_RATIO = 0.78  # box height / a standing person's there: below, not standing
SEATED_ASPECT = 0.45  # ... and at least this wide per unit height (an occluded walker's
# visible upper half is short too, but narrow)
LYING_RATIO = 0.33  # below, lying whatever the width (a squat is 0.4-0.6: module docstring)
LYING_FLAT_ASPECT = 1.5  # wider than any seated box measured
LYING_SURE_ASPECT = 1.0  # a lying box's confidence grows with its width beyond this
LYING_MIN_WIDTH = 0.15  # of a standing person's height there: narrower, no body on the floor
SEATED_TOP = 0.64  # a seated head's top over the expected standing height (module docstring)
LYING_FOOT = 0.7  # a lying box's floor point, this far down from its top (module docstring)
BORDER_PX = 2.0  # a box this close to the image border may be cut off: not judged
CUT_MARGIN = 0.02  # of the image's width / height: a real detector's box of a person cut by
# the frame edge ends this near it (bench/results/real_cmc_chain_tuning.md)
WHOLE_BODY_WIDTH = 0.8  # a lying box at the border this wide (of a standing person's height
# there) is a body across the view, not a torso cut by the frame (:func:`cut_off`)
STANDING_ASPECT = 0.4  # width of the standing box that replaces a seated or lying one
SMOOTHING_S = 1.0  # a track's posture: evidence averaged over this time
HEAD_DOWN = 0.05  # of the box height: both shoulders this far below both hips reads lying
KEYPOINT_FOUND = 0.5  # a joint's confidence from which it counts (a guessed hidden one is lower)
SHOULDERS, HIPS = (5, 6), (11, 12)  # COCO-17


@dataclass(frozen=True)
class BoxPostures:
    """Per camera: the posture [M] and its confidence [M] of each detection.

    One view that reads lying makes the person lying: a body on the floor seen lengthwise is
    short and narrow, i.e. seated, to that camera while the camera across it sees it flat, and
    the vote of the two was a toss-up that kept the fall's posture confidence under the fall
    rule's floor for seconds. Since a lying read needs a box under a third of a standing height
    or flat (:func:`classify`), a squat or a seated person gives one in a thousand boxes, and
    the track's smoothing (:class:`PostureSmoother`) absorbs those."""

    labels: list[np.ndarray]
    confidence: list[np.ndarray]

    def of(self, detection_index: Sequence[int | None]) -> tuple[str, float]:
        """The posture of an association (its boxes' per camera indices): the label with the
        most confidence summed over its boxes, and the mean confidence of that label."""
        votes: dict[str, list[float]] = defaultdict(list)
        for k, i in enumerate(detection_index):
            if i is not None and k < len(self.labels) and i < len(self.labels[k]):
                votes[str(self.labels[k][i])].append(float(self.confidence[k][i]))
        if not votes:
            return UNKNOWN, 0.0
        if LYING in votes:  # a view across the body outvotes views along it (class docstring)
            return LYING, round(float(np.mean(votes[LYING])), 3)
        label = max(votes, key=lambda name: sum(votes[name]))
        total = sum(sum(v) for v in votes.values())
        return label, round(sum(votes[label]) / max(total, 1e-9) * float(np.mean(votes[label])), 3)

    def low(
        self, detection_index: Sequence[int | None], detected: Sequence[Detections]
    ) -> dict[int, np.ndarray] | None:
        """An association's boxes as ``detected`` (before the posture stage), by camera, when
        every one of them reads sitting or lying; else None (the posture steps after the
        association judge only such people)."""
        boxes: dict[int, np.ndarray] = {}
        for k, i in enumerate(detection_index):
            if i is None or k >= len(detected) or i >= len(detected[k].boxes):
                continue
            if str(self.labels[k][i]) not in (SITTING, LYING):
                return None
            boxes[k] = np.asarray(detected[k].boxes[i], np.float64)
        return boxes


def classify(ratio: np.ndarray, aspect: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Labels [N] and confidences [N] from height ratios and aspects (module docstring)."""
    ratio, aspect = np.asarray(ratio, float), np.asarray(aspect, float)
    short = ratio < SEATED_RATIO
    lying = (ratio < LYING_RATIO) | (short & (aspect >= LYING_FLAT_ASPECT))
    no_body = lying & (ratio * aspect < LYING_MIN_WIDTH)  # narrower than a body on the floor
    lying &= ~no_body
    standing = ~lying & ~no_body & ((ratio >= SEATED_RATIO) | (aspect < SEATED_ASPECT))
    labels = np.where(lying, LYING, np.where(standing, STANDING, SITTING)).astype(object)
    labels[no_body] = UNKNOWN
    margin = np.where(
        standing,
        (ratio - SEATED_RATIO) / 0.15,
        np.where(
            lying,
            np.maximum(LYING_RATIO - ratio, aspect - LYING_SURE_ASPECT) / 0.3,
            np.minimum(SEATED_RATIO - ratio, np.abs(ratio - LYING_RATIO)) / 0.15,
        ),
    )
    sure = np.round(0.5 + 0.5 * np.clip(np.nan_to_num(margin), 0.0, 1.0), 3)
    return labels, np.where(no_body, 0.0, sure)


def standing_height_at(boxes: np.ndarray, area: SetupArea | None, camera: int) -> np.ndarray | None:
    """The height [M] px a person standing at each box's bottom centre would have in camera
    ``camera`` (boxes [M, 4]); None without that camera's height model."""
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    region = None if area is None or camera >= len(area.cameras) else area.cameras[camera]
    bottom = np.stack([0.5 * (boxes[:, 0] + boxes[:, 2]), boxes[:, 3]], 1)
    return None if region is None else region.expected_height(bottom)


def standing_boxes(
    boxes: np.ndarray,
    labels: np.ndarray,
    area: SetupArea,
    camera: int,
    lying_foot: float = LYING_FOOT,
) -> np.ndarray:
    """The boxes [M, 4] a standing person at the same floor point would give camera ``camera``:
    seated ones from their top, lying ones from ``lying_foot`` of the way down them (module
    docstring)."""
    region = area.cameras[camera] if camera < len(area.cameras) else None
    out = np.array(boxes, dtype=np.float64, copy=True)
    if region is None or region.height_model is None or not len(out):
        return out
    u = 0.5 * (out[:, 0] + out[:, 2])
    foot = np.where(labels == LYING, out[:, 1] + lying_foot * (out[:, 3] - out[:, 1]), out[:, 3])
    seated = labels == SITTING
    if seated.any():  # y_top = y_foot - SEATED_TOP * h(y_foot)
        below_top = region.foot_row(u[seated], out[seated, 1], SEATED_TOP, start=foot[seated])
        assert below_top is not None
        foot[seated] = below_top
    height = region.expected_height(np.stack([u, foot], 1))
    assert height is not None
    half = 0.5 * STANDING_ASPECT * height
    replaced = np.stack([u - half, foot - height, u + half, foot], 1)
    return np.where(((labels == SITTING) | (labels == LYING))[:, None], replaced, out)


def head_down(boxes: np.ndarray, keypoints: np.ndarray) -> np.ndarray:
    """How far [M] both shoulders are below both hips in the image, in units of the box height
    (NaN unless all four are found with confidence ``KEYPOINT_FOUND``), for boxes [M, 4] and
    their COCO-17 keypoints [M, 17, 3]. Positive: the body lies head towards the camera
    (module docstring)."""
    points = np.asarray(keypoints, np.float64).reshape(len(boxes), -1, 3)
    if points.shape[1] <= max(HIPS):
        return np.full(len(boxes), np.nan)
    joints = points[:, SHOULDERS + HIPS]
    found = (np.isfinite(joints).all(-1) & (joints[..., 2] >= KEYPOINT_FOUND)).all(-1)
    gap = joints[:, :2, 1].min(-1) - joints[:, 2:, 1].max(-1)
    height = np.maximum(boxes[:, 3] - boxes[:, 1], 1e-6)
    return np.where(found, gap / height, np.nan)


def box_postures(
    boxes: np.ndarray,
    area: SetupArea | None,
    camera: int,
    image_size: np.ndarray | None = None,
    keypoints: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Labels [M] and confidences [M] of one camera's boxes [M, 4] (NaN rows stay ``unknown``,
    as do boxes at the border of an image of ``image_size`` (width, height); everything
    ``unknown`` without a height model). With their COCO-17 ``keypoints`` [M, 17, 3], a box
    that reads sitting with the shoulders below the hips reads lying (:func:`head_down`)."""
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    expected = standing_height_at(boxes, area, camera)
    if expected is None or not len(boxes):
        return np.full(len(boxes), UNKNOWN, dtype=object), np.zeros(len(boxes))
    height = np.maximum(boxes[:, 3] - boxes[:, 1], 1e-6)
    labels, confidence = classify(height / expected, (boxes[:, 2] - boxes[:, 0]) / height)
    seen = np.isfinite(boxes).all(axis=1)
    if image_size is not None:
        side, end = _edges(boxes, image_size)
        lying = seen & cut_postures(boxes, np.asarray(expected, float), labels, side, end)
        seen &= ~side & ~end
        labels = np.where(lying, LYING, labels)
        seen |= lying
    labels, confidence = np.where(seen, labels, UNKNOWN), np.where(seen, confidence, 0.0)
    if keypoints is not None:
        down = np.nan_to_num(head_down(boxes, keypoints), nan=-1.0)
        flipped = (labels == SITTING) & (down > HEAD_DOWN)
        labels = np.where(flipped, LYING, labels)
        confidence = np.where(
            flipped,
            np.round(0.5 + 0.5 * np.clip((down - HEAD_DOWN) / 0.15, 0.0, 1.0), 3),
            confidence,
        )
    return labels, confidence


def _edges(boxes: np.ndarray, image_size: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether each box [M, 4] is within ``BORDER_PX`` of the left or right border, and of the
    top or bottom one, of an image of ``image_size`` (width, height)."""
    w, h = float(image_size[0]), float(image_size[1])
    side = (boxes[:, 0] <= BORDER_PX) | (boxes[:, 2] >= w - BORDER_PX)
    return side, (boxes[:, 1] <= BORDER_PX) | (boxes[:, 3] >= h - BORDER_PX)


def cut_postures(
    boxes: np.ndarray, expected: np.ndarray, labels: np.ndarray, side: np.ndarray, end: np.ndarray
) -> np.ndarray:
    """Whether each box [M, 4] at the image border (``side``: the left or right one; ``end``:
    the top or bottom one) is still surely a body lying on the floor (module docstring):
    cut by the top or bottom, flat and at least ``WHOLE_BODY_WIDTH`` of a standing person's
    height ``expected`` wide (what is cut off only adds to its length); cut by a side only, its
    height (whole) and aspect (only cut narrower) read lying. In the simulated rooms such boxes
    of lying bodies are 0.3-0.35 of the height and 3 times as wide as tall; those of squats are
    0.45-0.7 and 0.5-0.7 of the height wide, of walkers 0.8-1.2 and 0.2-0.6."""
    width = boxes[:, 2] - boxes[:, 0]
    height = np.maximum(boxes[:, 3] - boxes[:, 1], 1e-6)
    flat = (width / height >= LYING_FLAT_ASPECT) & (width >= WHOLE_BODY_WIDTH * expected)
    return np.where(end, flat, side & (labels == LYING))


def at_border(boxes: np.ndarray, image_size: np.ndarray, margin: float = CUT_MARGIN) -> np.ndarray:
    """Whether each box [M, 4] ends within ``margin`` of the image's width or height of an edge
    of an image of ``image_size`` (width, height): the person may be cut off by the frame.

    Why a fraction of the image and not pixels: the real CMC room's Faster R-CNN boxes of people
    whose legs are below the frame end 2-40 px above the bottom of a 1024 px image, and no
    fixed pixel count holds from a 640 px webcam to a 1920 px one."""
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    w, h = float(image_size[0]), float(image_size[1])
    near = (boxes[:, 0] < margin * w) | (boxes[:, 2] > (1.0 - margin) * w)
    return near | (boxes[:, 1] < margin * h) | (boxes[:, 3] > (1.0 - margin) * h)


def cut_off(
    boxes: np.ndarray, area: SetupArea | None, camera: int, image_size: np.ndarray
) -> np.ndarray:
    """Whether each box [M, 4] of camera ``camera`` may be a person cut off by the frame, so
    that its centre is not their body's: at the border (:func:`at_border`) and narrower than
    ``WHOLE_BODY_WIDTH`` of a standing person's height at its bottom centre.

    Why the width: a walker near the camera whose legs are below the frame leaves a short box
    of head and torso, about half a standing height wide (the real CMC room's lying boxes at the
    border: median 0.42-0.48, 97-98 % below 0.8; ``bench/results/real_cmc_chain_tuning.md``),
    while a body lying across the view is a body's length wide. A body lying along the line of
    sight at the border is narrow and counts as cut: its box says nothing sure either."""
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    cut = at_border(boxes, image_size)
    expected = standing_height_at(boxes, area, camera)
    if expected is None:
        return cut
    return cut & (boxes[:, 2] - boxes[:, 0] < WHOLE_BODY_WIDTH * np.asarray(expected, float))


def camera_postures(
    boxes: np.ndarray,
    area: SetupArea | None,
    camera: int,
    image_size: np.ndarray | None = None,
    keypoints: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`box_postures` and the standing boxes [M, 4] that replace seated and lying ones."""
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    labels, confidence = box_postures(boxes, area, camera, image_size, keypoints)
    if area is None:
        return labels, confidence, boxes
    return labels, confidence, standing_boxes(boxes, labels, area, camera)


def normalise(
    detections: Sequence[Detections],
    area: SetupArea | None,
    image_sizes: np.ndarray | None = None,
    doubt_lying: Callable[[int, np.ndarray], np.ndarray] | None = None,
) -> tuple[list[Detections], BoxPostures]:
    """Each camera's detections with seated and lying boxes replaced by standing ones, and the
    posture of every box (``unknown`` everywhere without a height model; read from the
    keypoints too where the detections carry them). ``doubt_lying(camera, boxes)``: which of a
    camera's lying boxes [M, 4] ([M] bool) are no evidence of a body on the floor (a place
    where the camera keeps reading lying, :mod:`service.tracking.recurring_boxes`); those are
    read ``unknown`` and kept as detected."""
    labels: list[np.ndarray] = []
    confidence: list[np.ndarray] = []
    out: list[Detections] = []
    for k, det in enumerate(detections):
        size = None if image_sizes is None else image_sizes[k]
        names, conf, fixed = camera_postures(det.boxes, area, k, size, det.keypoints)
        lying = names == LYING
        if doubt_lying is not None and lying.any():
            as_detected = np.asarray(det.boxes, np.float64).reshape(-1, 4)
            doubt = np.zeros(len(names), bool)
            doubt[lying] = doubt_lying(k, as_detected[lying])
            if doubt.any():
                names, conf, fixed = names.copy(), conf.copy(), fixed.copy()
                names[doubt], conf[doubt] = UNKNOWN, 0.0
                fixed[doubt] = as_detected[doubt]
        labels.append(names)
        confidence.append(conf)
        changed = (names != STANDING) & (names != UNKNOWN)
        out.append(
            dataclasses.replace(det, boxes=fixed.astype(np.float32)) if changed.any() else det
        )
    return out, BoxPostures(labels, confidence)


class PostureSmoother:
    """A track's posture over time: per label, an exponential average of the confidence its
    associations gave it over ``SMOOTHING_S``, so one odd box does not flip it."""

    def __init__(self, smoothing_s: float = SMOOTHING_S) -> None:
        self.smoothing_s = smoothing_s
        self._evidence: dict[int, dict[str, float]] = {}
        self._time: dict[int, float] = {}

    def update(self, track_id: int, t: float, label: str, confidence: float) -> tuple[str, float]:
        """Fold one observation in; the track's posture and its confidence (0..1)."""
        evidence = self._evidence.setdefault(track_id, {})
        dt = max(t - self._time.get(track_id, t), 0.0)
        self._time[track_id] = t
        keep = float(np.exp(-dt / self.smoothing_s)) if evidence else 0.0
        for name in evidence:
            evidence[name] *= keep
        evidence[label] = evidence.get(label, 0.0) + (1.0 - keep if keep else 1.0) * confidence
        return self.current(track_id)

    def current(self, track_id: int) -> tuple[str, float]:
        evidence = self._evidence.get(track_id)
        if not evidence or sum(evidence.values()) <= 0:
            return UNKNOWN, 0.0
        label = max(evidence, key=lambda name: evidence[name])
        return label, round(evidence[label] / sum(evidence.values()), 3)

    def forget(self, alive: set[int]) -> None:
        for gone in set(self._evidence) - alive:
            self._evidence.pop(gone, None)
            self._time.pop(gone, None)

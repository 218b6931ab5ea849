"""Posture from the box shape (service.tracking.posture): labels, the standing box that replaces
a seated or lying one, one posture per associated person (service.tracking.posture_agreement),
the track's smoothed posture, and the snapshot's optional field."""

from __future__ import annotations

import json
from collections.abc import Sequence

import numpy as np
import pytest

from models.detector.base import Detections
from models.mom.setup_area import CameraRegion, SetupArea
from service.pipeline.live import served_person
from service.stages import Association, Track, TrackAnchor
from service.tracking import posture
from service.tracking.posture import LYING, SITTING, STANDING, UNKNOWN, PostureSmoother
from service.tracking.posture_agreement import agree, agreed_rows

STANDING_PX = 200.0  # a person standing anywhere looks 200 px tall to this camera


def _area() -> SetupArea:
    flat = np.array([np.log(STANDING_PX), 0, 0, 0, 0, 0], float)
    hull = np.array([[0.0, 0.0], [640.0, 0.0], [640.0, 480.0], [0.0, 480.0]])
    region = CameraRegion(hull, (50.0, 400.0), flat, 0.05)
    return SetupArea(np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 4.0]]), 0.5, (region,))


def test_box_shape_gives_the_posture() -> None:
    ratio = np.array([1.0, 0.65, 0.65, 0.3, 0.6, 0.6, 0.66, 0.52])
    aspect = np.array([0.4, 0.7, 0.3, 0.9, 1.6, 0.8, 1.1, 1.1])
    labels, confidence = posture.classify(ratio, aspect)
    # an upright box; a short wide one (seated); short but narrow (an occluded walker's upper
    # half): left standing; very short; low and flat; short and fairly wide; a seated person
    # seen from the side (as wide as tall, not that short); the armchair sitter seen side-on
    # (as wide as tall and shorter: until 2026-12-04 read lying, and a false fall)
    assert labels.tolist() == [STANDING, SITTING, STANDING, LYING, LYING, SITTING, SITTING, SITTING]
    assert ((confidence >= 0.5) & (confidence <= 1.0)).all()


def test_a_crouch_is_not_lying_and_a_body_across_the_view_is() -> None:
    # height / a standing person's there and width / height: a squat's compact box (0.43 of
    # the height, as wide as tall: until 2026-12-04 lying by its height alone, every false
    # fall the bench had), a squat reaching forward (0.38 tall, 1.4 wide per unit height); a
    # body lying obliquely (0.5 tall, 1.7 wide: flat), one flat across the view, one lying
    # very low (0.3), and the armchair sitter side-on (0.58 tall, as wide as tall)
    ratio = np.array([0.43, 0.38, 0.5, 0.36, 0.3, 0.58])
    aspect = np.array([1.0, 1.4, 1.7, 2.6, 1.2, 1.3])
    labels, confidence = posture.classify(ratio, aspect)
    assert labels.tolist() == [SITTING, SITTING, LYING, LYING, LYING, SITTING]
    assert ((confidence >= 0.5) & (confidence <= 1.0)).all()


def test_a_short_box_narrower_than_a_body_on_the_floor_is_no_lying_read() -> None:
    # 0.25 of a standing height: 0.4 as wide as tall (0.1 of the height: a detector's
    # person-shaped false box, short), as wide as tall (0.25: a body seen end-on), flat, and
    # 0.3 tall and half as wide (0.15 of the height: as narrow as a lying child seen end-on)
    ratio = np.array([0.25, 0.25, 0.25, 0.3])
    aspect = np.array([0.4, 1.0, 2.0, 0.5])
    labels, confidence = posture.classify(ratio, aspect)
    assert labels.tolist() == [UNKNOWN, LYING, LYING, LYING]
    assert confidence[0] == 0.0 and (confidence[1:] >= 0.5).all()


def test_a_body_flat_on_the_floor_cut_by_the_image_edge_is_lying() -> None:
    size = np.array([640, 480])
    across = [300.0, 420.0, 500.0, 480.0]  # cut by the bottom edge: 60 px tall, 200 wide
    torso = [300.0, 380.0, 400.0, 480.0]  # a walker's upper body cut there: 100 x 100
    side = [0.0, 300.0, 150.0, 360.0]  # cut by the left edge, 0.3 of the height: on the floor
    crouch = [0.0, 200.0, 90.0, 300.0]  # cut by the left edge, half the height: not judged
    labels, _ = posture.box_postures(np.array([across, torso, side, crouch]), _area(), 0, size)
    assert labels.tolist() == [LYING, UNKNOWN, LYING, UNKNOWN]


def test_one_view_of_a_body_across_it_outvotes_a_lengthwise_view() -> None:
    # a lying body seen lengthwise is short and narrow (sitting) in one view and a body's
    # flat (lying) in the other: no crouch or sitter gives a flat box, so that view wins
    labels = [np.array([SITTING], object), np.array([LYING], object)]
    postures = posture.BoxPostures(labels, [np.array([0.95]), np.array([0.7])])
    assert postures.of([0, 0])[0] == LYING
    assert postures.of([0, None])[0] == SITTING


def _pose(shoulder_y: float, hip_y: float, knee_y: float, ankle_y: float) -> np.ndarray:
    """COCO-17 keypoints [17, 3] with the shoulders, hips, knees and ankles at these heights
    (pixels), all found (confidence 0.9); the face and arms missing."""
    points = np.full((17, 3), np.nan)
    for joints, y in (((5, 6), shoulder_y), ((11, 12), hip_y), ((13, 14), knee_y),
                      ((15, 16), ankle_y)):  # fmt: skip
        for j in joints:
            points[j] = (340.0 + (j % 2) * 10.0, y, 0.9)
    return points


def test_a_body_lying_head_towards_the_camera_reads_lying_by_its_keypoints() -> None:
    # 0.45 of a standing height and about as wide as tall: a squat's box, or a body lying along
    # the line of sight. Lying head towards the camera, the shoulders are below the hips in the
    # image (nearer points of the floor are lower); a squat, a seated person and a body lying
    # feet towards the camera keep the shoulders above the hips
    box = [300.0, 200.0, 390.0, 290.0]
    head_down = _pose(280.0, 240.0, 220.0, 205.0)
    squat = _pose(215.0, 255.0, 245.0, 285.0)
    seated = _pose(210.0, 250.0, 255.0, 285.0)
    feet_down = _pose(210.0, 230.0, 255.0, 285.0)
    shoulders_missing = head_down.copy()
    shoulders_missing[5:7] = np.nan
    occluded = head_down.copy()
    occluded[[5, 6, 11, 12], 2] = 0.2  # a pose estimator's guess at hidden joints
    points = np.stack([head_down, squat, seated, feet_down, shoulders_missing, occluded])
    boxes = np.array([box] * len(points))
    size = np.array([640, 480])
    labels, confidence = posture.box_postures(boxes, _area(), 0, size, points)
    assert labels.tolist() == [LYING, SITTING, SITTING, SITTING, SITTING, SITTING]
    assert 0.5 <= confidence[0] <= 1.0
    assert posture.box_postures(boxes, _area(), 0, size)[0].tolist() == [SITTING] * len(points)
    # a standing or cut box is not read from its keypoints (a walker's shoulders never drop
    # below the hips; a cut box is judged by the border rules)
    tall = np.array([[300.0, 100.0, 380.0, 300.0], [0.0, 200.0, 90.0, 290.0]])
    labels, _ = posture.box_postures(tall, _area(), 0, size, np.stack([head_down, head_down]))
    assert labels.tolist() == [STANDING, UNKNOWN]


def test_normalise_reads_the_keypoints_of_the_detections() -> None:
    box = np.array([[300.0, 200.0, 390.0, 290.0]], np.float32)
    points = _pose(280.0, 240.0, 220.0, 205.0)[None].astype(np.float32)
    det = Detections(box, np.ones(1, np.float32), points)
    fixed, postures = posture.normalise([det], _area(), np.array([[640, 480]]))
    # lying, and converted as lying (LYING_FOOT down the box), not as its shape says (seated,
    # from its top), which put a lone view of such a body 1.5 m off (module docstring)
    assert postures.of([0])[0] == LYING
    assert fixed[0].boxes[0, 3] == pytest.approx(200.0 + posture.LYING_FOOT * 90.0)


def test_seated_and_lying_boxes_become_standing_ones() -> None:
    seated = [300.0, 100.0, 380.0, 230.0]  # 130 px tall, 80 wide
    lying = [200.0, 300.0, 360.0, 380.0]  # 80 px tall, 160 wide
    upright = [100.0, 100.0, 180.0, 300.0]
    cut = [0.0, 250.0, 60.0, 330.0]  # short, but at the image border
    labels, _, boxes = posture.camera_postures(
        np.array([seated, lying, upright, cut]), _area(), 0, np.array([640, 480])
    )
    assert labels.tolist() == [SITTING, LYING, STANDING, UNKNOWN]
    # seated: the head stays, the feet go SEATED_TOP standing heights below it
    foot = 100.0 + posture.SEATED_TOP * STANDING_PX
    assert boxes[0] == pytest.approx([340 - 40, foot - 200, 340 + 40, foot])
    # lying: the floor under the body's middle is 0.7 down the box (300 + 0.7 * 80), not its
    # centre (340), which put the simulated lounge's lying bodies twice as far off
    assert boxes[1, 3] == pytest.approx(356.0) and boxes[1, 3] - boxes[1, 1] == pytest.approx(200)
    assert boxes[2] == pytest.approx(upright) and boxes[3] == pytest.approx(cut)


def test_normalise_keeps_detections_of_models_without_a_height_model() -> None:
    det = Detections(np.array([[300, 100, 380, 230]], np.float32), np.ones(1, np.float32))
    same, postures = posture.normalise([det], None)
    assert same[0] is det and postures.of([0]) == (UNKNOWN, 0.0)
    fixed, postures = posture.normalise([det], _area(), np.array([[640, 480]]))
    assert fixed[0].boxes[0, 3] == pytest.approx(228.0) and postures.of([0])[0] == SITTING


def test_one_odd_box_does_not_flip_a_track_posture() -> None:
    smoother = PostureSmoother(smoothing_s=1.0)
    for i in range(30):
        label, _ = smoother.update(7, i / 15, SITTING, 0.9)
    assert label == SITTING
    assert smoother.update(7, 2.0, STANDING, 1.0)[0] == SITTING
    for i in range(31, 60):
        label, confidence = smoother.update(7, i / 15, LYING, 0.8)
    assert label == LYING and confidence > 0.8
    smoother.forget(set())
    assert smoother.current(7) == (UNKNOWN, 0.0)


def test_snapshot_person_carries_the_posture_only_when_known() -> None:
    track = Track(3, 1.0, 2.0, 0.0, 0.0, 0.9, [0, 1], posture=(SITTING, 0.83))
    person = served_person(track)
    assert person["posture"] == "sitting" and person["posture_confidence"] == 0.83
    assert "posture" not in served_person(Track(4, 1.0, 2.0, 0.0, 0.0, 0.9))
    json.dumps(person)  # plain JSON


class _BoxBottoms:
    """A localizer double: a row's position is the mean of its boxes' bottom edges (pixels),
    enough to see which boxes it was given."""

    observation = "bbox"

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        bottom = np.nanmean(np.asarray(boxes)[..., 3], axis=1)
        return np.stack([bottom, bottom], axis=1)

    def covariance(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        return np.tile(np.eye(2), (len(boxes), 1, 1))


def test_a_seated_person_short_in_one_view_is_read_seated_in_both() -> None:
    """Per box, the view of a seated person that looks 0.8 of a standing height reads as
    standing; once associated with a clearly seated view, it is converted as seated too and
    the person localized again. A seated box paired with a standing person's box is no person:
    the pair is split into two single views."""
    area = SetupArea(_area().floor, 0.5, (_area().cameras[0], _area().cameras[0]))
    seated = [300.0, 100.0, 380.0, 230.0]  # 0.65 of a standing height, wide: sitting
    short = [100.0, 100.0, 190.0, 260.0]  # 0.8, as wide as a walker in stride: "standing"
    tall = [100.0, 100.0, 180.0, 300.0]  # a standing person's height
    runtime = _BoxBottoms()
    results = []
    for other in (short, tall):
        detected = [
            Detections(np.array([seated], np.float32), np.ones(1, np.float32)),
            Detections(np.array([other], np.float32), np.ones(1, np.float32)),
        ]
        normalised, postures = posture.normalise(detected, area, np.array([[640, 480]] * 2))
        assert postures.labels[1].tolist() == [STANDING]
        boxes = np.stack([normalised[0].boxes[0], normalised[1].boxes[0]]).astype(float)
        found = Association(boxes, [0, 1], runtime.localize(boxes[None])[0], 0.1, [0, 0])
        results.append(agree([found], detected, postures, area, runtime))
    (agreed,) = results[0]  # the head stays: the feet go SEATED_TOP standing heights below it
    assert agreed.boxes[1, 3] == pytest.approx(100.0 + posture.SEATED_TOP * STANDING_PX)
    assert agreed.world[0] == pytest.approx(agreed.boxes[:, 3].mean())
    low, high = results[1]
    assert (low.cameras, low.detection_index) == ([0], [0, None])
    assert (high.cameras, high.detection_index) == ([1], [None, 0])
    assert low.world[0] == pytest.approx(boxes[0, 3]) and high.world[0] == pytest.approx(300.0)
    rows = agreed_rows(np.array([[seated, short]]), area, np.array([[640, 480]] * 2))
    assert rows[0, 1, 3] == pytest.approx(100.0 + posture.SEATED_TOP * STANDING_PX)


def test_a_box_cut_by_the_border_is_left_out_of_a_lying_person_s_position() -> None:
    """A body on the floor whole in one view and cut by the frame's edge in the other (its box
    ``unknown``): the cut box, read as a standing person's, put the body a metre from where it
    lay; it is left out, and the body localized from its whole view. A seated vote keeps it."""
    area = SetupArea(_area().floor, 0.5, (_area().cameras[0], _area().cameras[0]))
    lying = [200.0, 380.0, 400.0, 440.0]  # 0.3 of a standing height, flat
    cut = [0.0, 150.0, 60.0, 330.0]  # against the left edge: not judged
    detected = [
        Detections(np.array([lying], np.float32), np.ones(1, np.float32)),
        Detections(np.array([cut], np.float32), np.ones(1, np.float32)),
    ]
    normalised, postures = posture.normalise(detected, area, np.array([[640, 480]] * 2))
    assert [postures.labels[0][0], postures.labels[1][0]] == [LYING, UNKNOWN]
    boxes = np.stack([normalised[0].boxes[0], normalised[1].boxes[0]]).astype(float)
    runtime = _BoxBottoms()
    found = Association(boxes, [0, 1], runtime.localize(boxes[None])[0], 0.1, [0, 0])
    (agreed,) = agree([found], detected, postures, area, runtime)
    assert (agreed.cameras, agreed.detection_index) == ([0], [0, None])
    assert agreed.world[0] == pytest.approx(boxes[0, 3])
    rows = agreed_rows(np.array([[lying, cut]]), area, np.array([[640, 480]] * 2))
    assert rows[0, 0, 3] == pytest.approx(boxes[0, 3]) and np.isnan(rows[0, 1]).all()
    seated = [300.0, 100.0, 380.0, 230.0]
    detected[0] = Detections(np.array([seated], np.float32), np.ones(1, np.float32))
    normalised, postures = posture.normalise(detected, area, np.array([[640, 480]] * 2))
    boxes = np.stack([normalised[0].boxes[0], normalised[1].boxes[0]]).astype(float)
    found = Association(boxes, [0, 1], runtime.localize(boxes[None])[0], 0.1, [0, 0])
    (agreed,) = agree([found], detected, postures, area, runtime)
    assert agreed.cameras == [0, 1]


class _FloorArea:
    """A set-up area of x < 3 m on the floor."""

    def contains(self, world: np.ndarray) -> np.ndarray:
        return np.asarray(world)[:, 0] < 3.0


class _RowMap:
    """A model whose floor x is a box's bottom / 100, whose set-up area is x < 3 m, and whose
    image check (like :meth:`models.mom.setup_area.SetupArea.boxes_in_region`) wants a standing
    person's height: 160 px or more."""

    setup_area = _FloorArea()

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        bottom = np.nanmax(np.asarray(boxes, float)[:, :, 3], axis=1)
        return np.stack([bottom / 100.0, np.zeros(len(bottom))], 1)

    def inside(self, boxes: np.ndarray, world: np.ndarray) -> np.ndarray:
        boxes = np.asarray(boxes, float)
        seen = np.isfinite(boxes).all(axis=2).any(axis=1)  # none seen: in the region, as
        # MomRuntime.inside says (SetupArea.boxes_in_region)
        tall = np.nanmax(np.where(seen[:, None], boxes[:, :, 3] - boxes[:, :, 1], 0.0), 1)
        return self.setup_area.contains(world) & ((tall >= 160.0) | ~seen)


def test_a_replaced_box_is_not_carried_into_the_set_up_area() -> None:
    """A short box beyond the area (a fragment, or a person cut by someone in front) reads as
    seated; its standing replacement reaches nearer the camera, into the area. The chain judges
    such a person by the boxes as detected (real CMC room: bench/results/real_cmc_chain_tuning.md);
    a seated person inside the area (whose box as detected is never a standing person's height),
    and boxes left as detected, keep their mark."""
    from service.pipeline.chain import _outside_as_detected, gate_to_area

    detected = [Detections(np.array([[0, 200, 80, 350], [0, 100, 80, 250]], np.float32),
                           np.ones(2, np.float32))]  # fmt: skip

    def person(box: list[float], index: int) -> Association:
        boxes = np.array([box], np.float32)
        return Association(boxes, [0], _RowMap().localize(boxes[None])[0], 0.0, [index])

    fragment = person([0, 120, 80, 280], 0)  # replaced: 2.8 m, inside; as detected 3.5 m
    seated = person([0, 40, 80, 200], 1)  # replaced: 2.0 m; as detected 2.5 m, inside too
    walker = person([0, 200, 80, 350], 0)  # as detected, beyond the area
    found = [fragment, seated, walker]
    model = _RowMap()
    _outside_as_detected(found, detected, model, model.setup_area)  # type: ignore[arg-type]
    assert [a.inside for a in found] == [False, True, True]  # the walker is the gate's job
    assert gate_to_area(found, _RowMap(), "drop") == [seated]


class _RowMapCamera(_RowMap):
    """The row map as one 640 × 480 camera with :func:`_area`'s height model (a standing person
    is 200 px tall everywhere), set-up area x < 4.5 m, and y the box centre's column / 100 (the
    people apart): what the chain's posture step needs."""

    observation = "bbox"
    num_cameras = 1
    image_sizes = np.array([[640.0, 480.0]])
    setup_area = SetupArea(  # type: ignore[assignment]
        np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 5.0], [0.0, 5.0]]), 0.5, _area().cameras
    )

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        boxes = np.asarray(boxes, float)
        centre = np.nanmean(0.5 * (boxes[:, :, 0] + boxes[:, :, 2]), axis=1)
        return np.stack([super().localize(boxes)[:, 0], centre / 100.0], 1)

    def covariance(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        return np.tile(0.01 * np.eye(2), (len(boxes), 1, 1))

    def reproject(self, world: np.ndarray) -> np.ndarray:
        return np.full((len(world), 1, 2), [320.0, 240.0])


def _each_box(
    detections: Sequence[Detections],
    runtime: _RowMapCamera,
    /,
    *,
    max_error_px: float,
    anchors: Sequence[TrackAnchor] = (),
) -> list[Association]:
    """An association stage double: every box of the one camera is a person."""
    boxes = np.asarray(detections[0].boxes, float).reshape(-1, 1, 4)
    world = runtime.localize(boxes) if len(boxes) else np.zeros((0, 2))
    return [Association(boxes[i], [0], world[i], 0.0, [i]) for i in range(len(boxes))]


def test_a_lying_body_is_kept_and_a_torso_cut_by_the_border_is_judged_as_detected() -> None:
    """Three boxes read as lying (0.4-0.57 of a standing height); their standing replacements
    land inside the area (rows 0.7 down them, 440-441 px: 4.40-4.41 m), as detected they lie
    beyond it (4.65-4.74 m). A narrow one ending 6 px above the image bottom (within
    ``CUT_MARGIN``) may be a walker whose legs are below the frame (the real CMC room's fragments,
    ``bench/results/real_cmc_chain_tuning.md``): judged as detected, dropped. One ending 15 px
    above it holds the whole body, and one as near the bottom but a body's length wide (a
    fallen person near the camera): both kept and served lying."""
    from service.pipeline.chain import Chain
    from service.tracking.tracker import RECOMMENDED, Tracker

    fallen = [200.0, 385.0, 360.0, 465.0]
    cut = [400.0, 396.0, 520.0, 474.0]  # 120 px wide: 0.6 of a standing height
    near = [40.0, 360.0, 260.0, 474.0]  # 220 px wide: a body across the view
    boxes = np.array([fallen, cut, near])
    assert posture.at_border(boxes, np.array([640, 480])).tolist() == [False, True, True]
    assert posture.cut_off(boxes, _area(), 0, np.array([640, 480])).tolist() == [
        False,
        True,
        False,
    ]
    runtime = _RowMapCamera()
    chain = Chain(
        Tracker(fps_hint=10, **RECOMMENDED),
        associate=_each_box,  # type: ignore[arg-type]
        view_bias=None,
    )
    detected = [Detections(boxes.astype(np.float32), np.ones(3, np.float32))]
    for i in range(20):
        served, tracks = chain(i / 10, detected, runtime, [True], i)  # type: ignore[arg-type]
    assert [a.detection_index for a in served] == [[0], [2]]
    assert [a.world[0] for a in served] == pytest.approx([4.41, 4.398])
    assert [a.detection_index for a in chain.outside] == [[1]]
    assert sorted(t.x for t in tracks) == pytest.approx([4.398, 4.41], abs=0.05)
    assert all(t.posture is not None and t.posture[0] == LYING for t in tracks)


def test_the_tracker_is_told_which_positions_are_of_lying_bodies() -> None:
    """``Origin.standing`` is false for a box read lying, true for an upright one: the tracker
    keeps its starting measurement scale for the first (``service.tracking.noise_scale``)."""
    from service.pipeline.chain import Chain
    from service.stages import Origin
    from service.tracking.tracker import RECOMMENDED, Tracker

    fallen = [200.0, 385.0, 360.0, 465.0]  # as in the test above: read lying
    upright = [450.0, 225.0, 490.0, 425.0]  # 200 px tall, 40 wide
    tracker = Tracker(fps_hint=10, **RECOMMENDED)
    seen: list[list[Origin]] = []
    update = tracker.update

    def spy(t, positions, origins=None, **kwargs):
        seen.append(list(origins or []))
        return update(t, positions, origins, **kwargs)

    tracker.update = spy  # type: ignore[method-assign,assignment]
    chain = Chain(tracker, associate=_each_box, view_bias=None)  # type: ignore[arg-type]
    boxes = np.array([fallen, upright], np.float32)
    chain(0.0, [Detections(boxes, np.ones(2, np.float32))], _RowMapCamera(), [True], 0)  # type: ignore[arg-type]
    assert sorted(o.standing for o in seen[-1]) == [False, True]

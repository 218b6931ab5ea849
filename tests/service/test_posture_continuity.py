"""A compact box is read as a body on the floor when only that reading keeps a tracked person in
place (service.tracking.posture_continuity)."""

from __future__ import annotations

import numpy as np
import pytest

from models.detector.base import Detections
from models.mom.setup_area import CameraRegion, SetupArea
from service.stages import Association, TrackAnchor
from service.tracking import posture
from service.tracking.posture import LYING, SITTING
from service.tracking.posture_continuity import reread_lying

STANDING_PX = 200.0  # a person standing anywhere looks 200 px tall to this camera
SIZES = np.array([[640.0, 480.0]])
COMPACT = [300.0, 200.0, 400.0, 290.0]  # 0.45 of a standing height, as wide as tall: sitting


def _area() -> SetupArea:
    flat = np.array([np.log(STANDING_PX), 0, 0, 0, 0, 0], float)
    hull = np.array([[0.0, 0.0], [640.0, 0.0], [640.0, 480.0], [0.0, 480.0]])
    region = CameraRegion(hull, (50.0, 400.0), flat, 0.05)
    return SetupArea(np.array([[0.0, 0.0], [9.0, 0.0], [9.0, 9.0]]), 0.5, (region,))


class _OneCamera:
    """A localizer double for one camera looking along x: a box's bottom edge at row v stands
    at x = v / 50 m (a row is 2 cm of floor), its centre column at y = u / 100 m."""

    observation = "bbox"

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        boxes = np.asarray(boxes, float)
        return np.stack(
            [boxes[:, 0, 3] / 50.0, 0.5 * (boxes[:, 0, 0] + boxes[:, 0, 2]) / 100.0], axis=1
        )

    def covariance(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        return np.tile(0.01 * np.eye(2), (len(boxes), 1, 1))


Seen = tuple[list[Detections], list[Association], posture.BoxPostures]


def _seen(boxes: list[list[float]]) -> Seen:
    """Each box detected by the one camera, converted as its shape says and associated alone."""
    detected = [Detections(np.array(boxes, np.float32), np.ones(len(boxes), np.float32))]
    normalised, postures = posture.normalise(detected, _area(), SIZES)
    runtime = _OneCamera()
    found = []
    for i, box in enumerate(normalised[0].boxes):
        rows = np.asarray(box, np.float64).reshape(1, 4)
        found.append(Association(rows, [0], runtime.localize(rows[None])[0], 0.0, [i]))
    return detected, found, postures


def _anchor(x: float, y: float, unseen_s: float = 0.0, track_id: int | None = None) -> TrackAnchor:
    return TrackAnchor(np.array([x, y]), 0.04 * np.eye(2), unseen_s=unseen_s, track_id=track_id)


def test_a_compact_box_where_a_person_stood_is_a_body_on_the_floor() -> None:
    """Read seated, the box's top is a head 0.64 of a standing height up, so its feet are at
    row 200 + 128 = 328 (x 6.56 m); read as a body on the floor, its centre row 245 (x 4.9 m)
    is on the floor. The person was tracked at 5 m: nobody moves 1.5 m while going down."""
    detected, found, postures = _seen([COMPACT])
    assert postures.labels[0].tolist() == [SITTING]
    assert found[0].world[0] == pytest.approx(6.56)
    anchors = [_anchor(5.0, 3.5, unseen_s=1.0)]  # unseen for a second while going down
    (read,) = reread_lying(found, detected, postures, _area(), _OneCamera(), anchors)
    assert read.world == pytest.approx([4.9, 3.5])
    assert postures.of(read.detection_index)[0] == LYING
    assert postures.confidence[0][0] >= 0.9  # 1.56 m against 0.1: far beyond the margin


@pytest.mark.parametrize(
    "anchors, others",
    [
        ([_anchor(6.5, 3.5)], []),  # sat down where they stood: the seated reading holds
        ([_anchor(5.6, 3.5)], []),  # both readings within a metre of the track: a squat's
        ([], []),  # nobody tracked near: a new person, judged by the box alone
        ([_anchor(5.0, 3.5)], [[300.0, 50.0, 380.0, 250.0]]),  # a standing person is there
        ([_anchor(5.0, 3.5, unseen_s=2.0)], []),  # a track only the still hold keeps: stale
        # someone else is tracked where it reads seated: their box, not a body beside another
        ([_anchor(5.0, 3.5, track_id=1), _anchor(6.4, 3.5, track_id=2)], []),
        ([_anchor(5.0, 3.5), _anchor(6.4, 3.5)], []),  # tracks unknown: another's, to be safe
    ],
)
def test_the_seated_reading_stays_unless_only_lying_keeps_the_track(
    anchors: list[TrackAnchor], others: list[list[float]]
) -> None:
    detected, found, postures = _seen([COMPACT, *others])
    read = reread_lying(found, detected, postures, _area(), _OneCamera(), anchors)
    assert read[0].world[0] == pytest.approx(6.56)
    assert postures.labels[0][0] == SITTING


def test_a_body_is_read_lying_where_its_own_track_was_dragged_to_the_seated_reading() -> None:
    """The same person's track, dragged by the first seated reads to where the box reads
    seated, is no one else: the place it stood anchors the lying reading."""
    detected, found, postures = _seen([COMPACT])
    anchors = [_anchor(6.4, 3.5, track_id=7), _anchor(5.0, 3.5, track_id=7)]
    (read,) = reread_lying(found, detected, postures, _area(), _OneCamera(), anchors)
    assert read.world == pytest.approx([4.9, 3.5])
    assert postures.of(read.detection_index)[0] == LYING


@pytest.mark.parametrize("width_px, lying", [(42.0, True), (38.0, False)])
def test_a_box_narrower_than_a_body_seen_end_on_is_not_read_lying(
    width_px: float, lying: bool
) -> None:
    """A short box (0.35 of a standing height) reads sitting at 0.21 or 0.19 of a standing
    height wide; its seated reading is 1.96 m beyond the track, its lying one 0.1 m. A body on
    the floor is at least as wide as its shoulders seen end-on: 0.19 is something else (the
    held-out daily life's false box), and the seated reading stays."""
    detected, found, postures = _seen([[349.0 - width_px / 2, 220.0, 349.0 + width_px / 2, 290.0]])
    assert postures.labels[0].tolist() == [SITTING]
    (read,) = reread_lying(found, detected, postures, _area(), _OneCamera(), [_anchor(5.0, 3.5)])
    assert read.world[0] == pytest.approx(5.1 if lying else 6.96)
    assert postures.labels[0][0] == (LYING if lying else SITTING)


class _OneCameraRoom(_OneCamera):
    """:class:`_OneCamera` as the chain's model: its set-up area (a 9 m floor) and image."""

    num_cameras = 1
    image_sizes = SIZES
    setup_area = _area()

    def reproject(self, world: np.ndarray) -> np.ndarray:
        return np.full((len(world), 1, 2), [320.0, 240.0])

    def inside(self, boxes: np.ndarray, world: np.ndarray) -> np.ndarray:
        return np.ones(len(world), dtype=bool)


def test_a_track_dragged_by_seated_reads_is_read_lying_from_where_it_stood() -> None:
    """A person stands at x 5 m, then goes down seen lengthwise by the one camera: the first
    compact boxes read seated 0.8 m beyond them (under the rule's 1.2 m jump) and drag the
    track there; the later ones read seated 1.56 m beyond where they stood (0.8-1 m from the
    dragged track) and lying 0.1 m from that place. Measured from where the track last stood
    for sure, they are read lying and the track comes back (most of the way in 2 s: a body on
    the floor stops the track's filter, which then averages the lying positions from where the
    drag left it); without that place the drag holds."""
    from service.pipeline.chain import Chain
    from service.tracking.tracker import RECOMMENDED, Tracker
    from tests.service.test_posture import _each_box

    standing = [300.0, 50.0, 380.0, 250.0]  # x 5 m
    dragging = [300.0, 162.0, 400.0, 268.0]  # seated 5.8 m, lying 4.3 m: neither re-read
    runtime = _OneCameraRoom()
    ends = []
    for remember in (True, False):
        chain = Chain(
            Tracker(fps_hint=10, **RECOMMENDED),
            associate=_each_box,  # type: ignore[arg-type]
            view_bias=None,
        )
        if not remember:
            chain._stood_at = lambda t: []  # type: ignore[method-assign]
        frames = [standing] * 30 + [dragging] * 5 + [COMPACT] * 20
        for i, box in enumerate(frames):
            detected = [Detections(np.array([box], np.float32), np.ones(1, np.float32))]
            _, tracks = chain(i / 10, detected, runtime, [True], i)  # type: ignore[arg-type]
            if i == 34:
                assert len(tracks) == 1 and tracks[0].x > 5.5  # dragged
        assert len(tracks) == 1 and tracks[0].posture is not None
        ends.append((tracks[0].x, tracks[0].posture[0]))
    assert 4.7 < ends[0][0] < 5.3 and ends[0][1] == LYING
    assert ends[1][0] > 5.5 and ends[1][1] == SITTING


def test_where_a_track_stood_is_anchored_with_how_long_the_track_is_unseen() -> None:
    """A person stands at x 5 m for 3 s, sits down there for 1 s, then no camera sees them in
    four frame sets: at the next, the place they stood (1.5 s before) is kept, unseen for 0.5 s,
    so the re-read drops it with the track once the track is unseen longer than ``HELD_S`` (the
    held-out daily life's false fall: a track held where a sitter had stood up and walked off
    anchored a false box read lying 1.8 s later)."""
    from service.pipeline.chain import Chain
    from service.tracking.tracker import RECOMMENDED, Tracker
    from tests.service.test_posture import _each_box

    standing = [300.0, 50.0, 380.0, 250.0]  # x 5 m
    seated = [300.0, 122.0, 390.0, 212.0]  # its head 0.64 of a standing height above x 5 m
    runtime = _OneCameraRoom()
    chain = Chain(
        Tracker(fps_hint=10, **RECOMMENDED),
        associate=_each_box,  # type: ignore[arg-type]
        view_bias=None,
    )
    frames = [[standing]] * 30 + [[seated]] * 10 + [[]] * 4
    for i, boxes in enumerate(frames):
        detected = [Detections(np.array(boxes, np.float32).reshape(-1, 4), np.ones(len(boxes)))]
        _, tracks = chain(i / 10, detected, runtime, [True], i)  # type: ignore[arg-type]
    assert tracks[0].posture is not None and tracks[0].posture[0] == SITTING
    (stood,) = chain._stood_at(4.4)
    assert stood.xy == pytest.approx([5.0, 3.4], abs=0.05)
    assert stood.unseen_s == pytest.approx(0.5)
    (held,) = chain.tracker.anchors(4.4)  # type: ignore[attr-defined]
    assert stood.track_id == held.track_id == tracks[0].id  # one person's two anchors

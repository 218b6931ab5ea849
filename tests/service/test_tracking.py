"""Tracker behaviour on scripted floor trajectories (metres, seconds)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from service.stages import Origin
from service.tracking.image_continuity import MAX_AGE_S, ImageContinuity, ViewMemory
from service.tracking.tracker import RECOMMENDED, Tracker

FPS = 30.0


def run(tracker: Tracker, frames: list[np.ndarray], fps: float = FPS) -> list[list]:
    return [
        tracker.update(i / fps, p, [Origin(cameras=(0, 1))] * len(p)) for i, p in enumerate(frames)
    ]


def test_straight_walk_gives_velocity_and_smooths() -> None:
    rng = np.random.default_rng(0)
    velocity = np.array([1.2, -0.5])
    times = np.arange(90) / FPS
    truth = np.array([1.0, 4.0]) + times[:, None] * velocity
    noisy = truth + rng.normal(0, 0.05, truth.shape)
    out = run(Tracker(fps_hint=FPS), [p[None] for p in noisy])
    last = out[-1]
    assert len(last) == 1 and last[0].id == 1
    assert np.hypot(last[0].vx - velocity[0], last[0].vy - velocity[1]) < 0.15
    assert last[0].cameras == [0, 1] and not last[0].coasting
    assert last[0].confidence > 0.9
    # Smoothing: over the last second the filtered track is closer to the truth than the input.
    est = np.array([[o[0].x, o[0].y] for o in out[60:]])
    assert (
        np.linalg.norm(est - truth[60:], axis=1).mean()
        < np.linalg.norm(noisy[60:] - truth[60:], axis=1).mean()
    )


def test_crossing_people_keep_ids() -> None:
    rng = np.random.default_rng(1)
    times = np.arange(120) / FPS  # 4 s, crossing at t = 2 s
    a = np.stack([times * 1.2, times * 1.2], axis=1)  # (0,0) -> (4.8,4.8)
    b = np.stack([times * 1.2, 4.8 - times * 1.2], axis=1)  # (0,4.8) -> (4.8,0)
    frames = []
    for i in range(len(times)):
        pts = np.stack([a[i], b[i]]) + rng.normal(0, 0.04, (2, 2))
        frames.append(pts[rng.permutation(2)])  # detection order carries no identity
    out = run(Tracker(fps_hint=FPS), frames)
    first = {int(tr.y > 2.4): tr.id for tr in out[10]}
    assert len(first) == 2
    final = out[-1]
    assert len(final) == 2
    by_id = {tr.id: tr for tr in final}
    # The one that started at y=0 ends near y=4.8 and vice versa.
    assert by_id[first[0]].y > 4.0
    assert by_id[first[1]].y < 0.8


def test_one_second_occlusion_keeps_id_and_coasts() -> None:
    tracker = Tracker(fps_hint=FPS, max_missing_s=1.5)
    velocity = np.array([1.0, 0.0])
    ids = []
    coasting_conf = []
    for i in range(150):
        t = i / FPS
        hidden = 60 <= i < 90  # exactly 1 s without detections
        pos = np.zeros((0, 2)) if hidden else (np.array([0.5, 2.0]) + t * velocity)[None]
        tracks = tracker.update(t, pos, [Origin(cameras=(1,))] * len(pos))
        if t < tracker.confirm_single_s - 1e-9:  # one camera's word: tentative for longer
            assert tracks == []
            continue
        assert len(tracks) == 1
        ids.append(tracks[0].id)
        if hidden:
            assert tracks[0].coasting and tracks[0].cameras == []
            coasting_conf.append(tracks[0].confidence)
            # Coasting follows the predicted walk, not the last seen point.
            assert abs(tracks[0].x - (0.5 + t)) < 0.1
    assert set(ids) == {1}
    assert coasting_conf == sorted(coasting_conf, reverse=True)
    assert coasting_conf[-1] < 0.5


def test_a_track_fed_a_lying_body_coasts_where_the_body_lies() -> None:
    """A walker at 1 m/s falls: the first measurement of the body on the floor (its boxes read
    lying) stops the track there; unseen for the next half second, it is served where the body
    lies, not 0.5 m on along the walk (a fall of the simulated lounge came 6 s late that way)."""
    for motion, lying in itertools.product(("imm", "cv"), (False, True)):
        tracker = Tracker(fps_hint=FPS, motion=motion, serve_coast_s=0.5)
        for i in range(30):
            t = i / FPS
            walker = np.array([[0.5 + t, 2.0]])
            tracker.update(t, walker, [Origin(cameras=(0, 1))])
        down = np.array([[0.5 + 30 / FPS, 2.0]])
        (at_fall,) = tracker.update(30 / FPS, down, [Origin(cameras=(0, 1), standing=not lying)])
        assert abs(at_fall.x - down[0, 0]) < 0.1
        for i in range(31, 31 + int(0.5 * FPS)):
            (track,) = tracker.update(i / FPS, np.zeros((0, 2)), [])
            assert track.coasting
        moved = track.x - at_fall.x
        assert (abs(moved) < 0.02) if lying else (moved > 0.4), (motion, lying, moved)


def test_new_person_gets_new_id_and_ids_never_reused() -> None:
    tracker = Tracker(fps_hint=FPS, max_missing_s=0.5)
    for i in range(30):
        tracks = tracker.update(i / FPS, np.array([[1.0, 1.0]]), None)
    assert [tr.id for tr in tracks] == [1]
    for i in range(30, 60):
        tracks = tracker.update(i / FPS, np.array([[1.0, 1.0], [4.0, 3.0]]), None)
    assert sorted(tr.id for tr in tracks) == [1, 2]
    # Person 1 leaves; after max_missing_s their track is gone.
    for i in range(60, 90):
        tracks = tracker.update(i / FPS, np.array([[4.0, 3.0]]), None)
    assert [tr.id for tr in tracks] == [2]
    # Someone appears where person 1 was: a fresh id, not 1 again.
    for i in range(90, 100):
        tracks = tracker.update(i / FPS, np.array([[1.0, 1.0], [4.0, 3.0]]), None)
    assert sorted(tr.id for tr in tracks) == [2, 3]


def test_stale_tracks_dropped_after_max_missing() -> None:
    tracker = Tracker(fps_hint=10.0, max_missing_s=1.0)
    for i in range(10):
        tracker.update(i / 10, np.array([[2.0, 2.0]]), None)
    assert len(tracker.update(1.4, np.zeros((0, 2)), [])) == 1  # 0.5 s unseen: coasting
    assert len(tracker.update(1.85, np.zeros((0, 2)), [])) == 1  # 0.95 s
    assert tracker.update(2.0, np.zeros((0, 2)), []) == []  # 1.1 s: dropped


def test_single_spurious_detection_is_not_reported_and_gate_is_metres() -> None:
    tracker = Tracker(fps_hint=FPS, gate_m=0.5)
    for i in range(20):
        tracks = tracker.update(i / FPS, np.array([[1.0, 1.0]]), None)
    # A one-frame ghost 3 m away is neither reported nor allowed to steal the id.
    tracks = tracker.update(20 / FPS, np.array([[4.0, 1.0]]), None)
    assert [(tr.id, tr.coasting) for tr in tracks] == [(1, True)]
    tracks = tracker.update(21 / FPS, np.array([[1.0, 1.0]]), None)
    assert [(tr.id, tr.coasting) for tr in tracks] == [(1, False)]


def test_nan_positions_are_ignored_and_origins_checked() -> None:
    tracker = Tracker(fps_hint=FPS, confirm_s=0.0)
    tracks = tracker.update(
        0.0, np.array([[np.nan, 1.0], [2.0, 2.0]]), [Origin(), Origin(cameras=(2,))]
    )
    assert [(tr.x, tr.y, tr.cameras) for tr in tracks] == [(2.0, 2.0, [2])]
    with pytest.raises(ValueError, match="origins"):
        tracker.update(0.1, np.array([[1.0, 1.0]]), [])


def test_one_camera_needs_longer_to_be_believed() -> None:
    tracker = Tracker(fps_hint=FPS, confirm_single_s=1.0)
    one, two = [], []
    for i in range(40):
        tracks = tracker.update(
            i / FPS,
            np.array([[1.0, 1.0], [4.0, 4.0]]),
            [Origin(cameras=(0,)), Origin(cameras=(0, 1))],
        )
        one.append(any(abs(tr.x - 1.0) < 0.1 for tr in tracks))
        two.append(any(abs(tr.x - 4.0) < 0.1 for tr in tracks))
    assert two.index(True) == round(tracker.confirm_s * FPS)  # 0.3 s
    assert one.index(True) == round(tracker.confirm_single_s * FPS)  # 1 s


def test_single_view_ghost_where_another_camera_looks_is_dropped() -> None:
    """A box only camera 0 reports, at a place camera 1 covers too, is a detector ghost."""
    both = lambda xy, lying=None: np.ones((len(xy), 2), dtype=bool)  # noqa: E731
    only_zero = lambda xy, lying=None: np.c_[np.ones(len(xy), bool), np.zeros(len(xy), bool)]  # noqa: E731
    for coverage, reported in ((both, False), (only_zero, True), (None, True)):
        tracker = Tracker(fps_hint=FPS, ghost_s=0.5)
        for i in range(45):
            tracks = tracker.update(
                i / FPS, np.array([[2.0, 2.0]]), [Origin(cameras=(0,))], coverage=coverage
            )
        assert bool(tracks) == reported, coverage
    tracker = Tracker(fps_hint=FPS, ghost_s=0.5)  # seen by both cameras once: a person
    for i in range(45):
        origins = [Origin(cameras=(0, 1) if i == 20 else (0,))]
        tracks = tracker.update(i / FPS, np.array([[2.0, 2.0]]), origins, coverage=both)
    assert len(tracks) == 1


def test_a_lone_lying_view_where_the_other_camera_sees_no_floor_is_no_ghost() -> None:
    """Camera 1 covers a standing person at the spot but not the floor there: a body lying
    there that camera 0 alone reports stays served; a standing person there is a ghost."""
    over_the_body = lambda xy, lying=None: np.c_[  # noqa: E731
        np.ones(len(xy), bool), np.ones(len(xy), bool) if lying is None else ~lying
    ]
    for standing, reported in ((True, False), (False, True)):
        tracker = Tracker(fps_hint=FPS, ghost_s=0.5)
        origins = [Origin(cameras=(0,), standing=standing)]
        for i in range(45):
            tracks = tracker.update(
                i / FPS, np.array([[2.0, 2.0]]), origins, coverage=over_the_body
            )
        assert bool(tracks) == reported, standing


def test_measurement_covariance_is_used_and_checked() -> None:
    """Measurements precise across the line of sight (y) follow a sideways step at once."""
    sight = np.diag([0.5**2, 0.02**2])
    # the covariances as given (RECOMMENDED starts at 9 times them and learns the scale)
    options = {**RECOMMENDED, "robust_chi2": 0.0, "measurement_scale": 1.0, "adapt_scale_s": 0.0}
    plain = Tracker(fps_hint=FPS, **options)
    steered = Tracker(fps_hint=FPS, **options)
    for i in range(50):
        z = np.array([[3.0, 3.0 if i < 45 else 3.3]])
        a = plain.update(i / FPS, z, [Origin(cameras=(0,))])
        b = steered.update(i / FPS, z, [Origin(cameras=(0,))], covariances=[sight])
    assert b[0].y - 3.0 > 0.25 and a[0].y - 3.0 < b[0].y - 3.0
    with pytest.raises(ValueError, match="covariances"):
        steered.update(5.0, np.zeros((1, 2)), None, covariances=[])
    # None or NaN covariances fall back to the isotropic default.
    steered.update(5.1, np.array([[3.0, 3.0]]), None, covariances=[np.full((2, 2), np.nan)])


def test_coasting_is_served_for_serve_coast_s_then_held_with_its_id() -> None:
    """After ``serve_coast_s`` unseen the track is no longer reported (``hidden`` says
    "coasting"); it keeps its id when the person reappears before ``max_missing_s``."""
    tracker = Tracker(fps_hint=FPS, serve_coast_s=0.5, max_missing_s=1.5)
    served, why = [], []
    for i in range(90):
        hidden = 30 <= i < 60  # 1 s unseen
        pos = np.zeros((0, 2)) if hidden else np.array([[2.0, 2.0]])
        tracks = tracker.update(i / FPS, pos, [Origin(cameras=(0, 1))] * len(pos))
        if hidden:
            served.append(bool(tracks))
            why.append([w for _, w in tracker.hidden()])
    assert served == [True] * 15 + [False] * 15  # 0.5 s at 30 fps
    assert why[-1] == ["coasting"] and why[0] == []
    assert [t.id for t in tracks] == [1]
    assert [w for _, w in Tracker(fps_hint=FPS).hidden()] == []


def test_hidden_names_tentative_and_ghost_tracks() -> None:
    both = lambda xy, lying=None: np.ones((len(xy), 2), dtype=bool)  # noqa: E731
    tracker = Tracker(fps_hint=FPS, ghost_s=0.5, confirm_single_s=0.3)
    tracker.update(0.0, np.array([[2.0, 2.0]]), [Origin(cameras=(0,))], coverage=both)
    assert [w for _, w in tracker.hidden()] == ["tentative"]
    for i in range(1, 30):
        tracks = tracker.update(
            i / FPS, np.array([[2.0, 2.0]]), [Origin(cameras=(0,))], coverage=both
        )
    assert tracks == [] and [w for _, w in tracker.hidden()] == ["ghost"]


def test_box_its_own_camera_cannot_see_there_is_doubted() -> None:
    """``doubt_outside``: a single-view position the reporting camera does not cover (a false
    box localized out of its view) is a ghost; one it covers, alone, is not."""
    nobody = lambda xy, lying=None: np.zeros((len(xy), 2), dtype=bool)  # noqa: E731
    only_one = lambda xy, lying=None: np.c_[np.zeros(len(xy), bool), np.ones(len(xy), bool)]  # noqa: E731
    for doubt, reported in ((True, False), (False, True)):
        tracker = Tracker(fps_hint=FPS, ghost_s=0.5, doubt_outside=doubt)
        for i in range(45):
            origins = [Origin(cameras=(0,))]
            tracks = tracker.update(i / FPS, np.array([[2.0, 2.0]]), origins, coverage=nobody)
        assert bool(tracks) == reported
    tracker = Tracker(fps_hint=FPS, ghost_s=0.5, doubt_outside=True)
    for i in range(45):
        origins = [Origin(cameras=(1,))]
        tracks = tracker.update(i / FPS, np.array([[2.0, 2.0]]), origins, coverage=only_one)
    assert len(tracks) == 1


def test_likelihood_cost_pairs_a_lone_view_along_its_line_of_sight() -> None:
    """Two people 0.75 m apart; a lone view of the first, 0.6 m off along its line of sight (x)
    and so nearer the second in metres, goes to the first by likelihood, to the second by
    Euclidean distance."""
    sight = np.diag([0.6**2, 0.05**2])  # long along x
    a, b = np.array([2.0, 2.0]), np.array([2.6, 2.45])
    owner = {}
    for cost in ("euclidean", "likelihood"):
        tracker = Tracker(fps_hint=FPS, gate_m=1.5, assign_cost=cost, robust_chi2=0.0)
        precise = [np.eye(2) * 0.05**2] * 2
        for i in range(30):
            tracks = tracker.update(i / FPS, np.stack([a, b]), None, covariances=precise)
        first = min(tracks, key=lambda t: np.hypot(t.x - a[0], t.y - a[1])).id
        z = a + np.array([0.6, 0.0])
        tracks = tracker.update(30 / FPS, z[None], None, covariances=[sight])
        moved = [t for t in tracks if not t.coasting]
        owner[cost] = moved[0].id == first
    assert owner == {"euclidean": False, "likelihood": True}
    with pytest.raises(ValueError, match="assign_cost"):
        Tracker(assign_cost="cosine")


@pytest.mark.parametrize("fps", [4.0, 30.0])
def test_timing_rules_mean_the_same_at_4_and_30_frame_sets_a_second(fps: float) -> None:
    """Confirmation, confidence and coasting are in seconds: a person seen for 2 s, then
    unseen for 0.5 s, looks the same to clients whatever the camera rate (the real CMC room
    runs at 4 fps; webcams at 30)."""
    tracker = Tracker(fps_hint=30.0, **RECOMMENDED)  # the daemon's hint, whatever the rate
    seen = round(2.0 * fps)
    frames = [np.array([[1.0 + 0.5 * i / fps, 2.0]]) for i in range(seen)]
    frames += [np.zeros((0, 2))] * round(0.5 * fps)
    out = run(tracker, frames, fps)
    first_served = next(i for i, o in enumerate(out) if o) / fps
    assert first_served <= 0.3 + 1.0 / fps  # confirm_s, to within one frame
    assert out[seen - 1][0].confidence == pytest.approx(1.0 - np.exp(-2.0 / 0.32), abs=0.08)
    # 0.5 s unseen: the detection rate has fallen by the same factor at either rate
    assert out[-1] == [] or out[-1][0].confidence < 0.3
    missed = [o for o in out[seen:] if o]
    rates = [o[0].confidence for o in missed]
    assert all(b < a for a, b in itertools.pairwise(rates))


@pytest.mark.parametrize("image_std_h", [0.0, RECOMMENDED["image_std_h"]])
def test_boxes_of_each_camera_keep_neighbours_apart_where_the_floor_cannot(
    image_std_h: float,
) -> None:
    """Two people walking side by side 0.5 m apart at 4 fps; in one frame set their floor
    positions come out crossed (each 0.3 m off towards the other, as a cut box does in a
    crowd), while each camera's boxes stay where they were. On the floor alone each track takes
    the other's measurement; with image continuity each keeps its own."""
    fps = 4.0
    tracker = Tracker(fps_hint=fps, assign_cost="likelihood", image_std_h=image_std_h)
    boxes = {  # camera 0 and 1: box centres 300 px apart, 400 px tall
        "A": np.array([[280.0, 100.0, 320.0, 500.0], [880.0, 100.0, 920.0, 500.0]]),
        "B": np.array([[580.0, 100.0, 620.0, 500.0], [1180.0, 100.0, 1220.0, 500.0]]),
    }
    fed: dict[int, int | None] = {}
    for i in range(12):
        t = i / fps
        a, b = np.array([1.0 + t, 1.0]), np.array([1.0 + t, 1.5])
        if i == 10:
            shift = np.array([0.0, 0.3])
            a, b = a + shift, b - shift
        fed_by = [Origin(cameras=(0, 1), association=i, boxes=boxes[w]) for i, w in enumerate("AB")]
        tracks = tracker.update(t, np.stack([a, b]), fed_by)
        if i == 9:
            on_a = min(tracks, key=lambda tr: abs(tr.y - 1.0)).id
        if i == 10:
            fed = {tr.id: tr.association for tr in tracks}
    assert fed[on_a] == (0 if image_std_h > 0 else 1)  # association 0 is A's


def test_image_continuity_forgets_old_boxes_and_ignores_missing_views() -> None:
    memory = ViewMemory()
    memory.remember(np.array([[100.0, 0.0, 140.0, 200.0], [np.nan] * 4]), 0.0)
    memory.remember(np.array([[110.0, 0.0, 150.0, 200.0], [np.nan] * 4]), 0.25)
    assert memory.velocity[0] > 0 and 1 not in memory.seen
    term = ImageContinuity(std_h=0.1, growth_hps=0.3, cap=4.0)
    here = np.array([[120.0, 0.0, 160.0, 200.0], [10.0, 0.0, 50.0, 100.0]])
    far = np.array([[900.0, 0.0, 940.0, 200.0], [np.nan] * 4])
    cost = term.cost([memory], [here, far, None], 0.5)
    assert cost[0, 0] < 0 < cost[0, 1] <= 3.0  # capped: one camera never vetoes alone
    assert cost[0, 2] == 0.0  # no box in common: no opinion
    assert term.cost([memory], [far], 0.25 + MAX_AGE_S + 0.01)[0, 0] == 0.0  # forgotten


def test_anchors_carry_each_cameras_predicted_box_centre() -> None:
    """``Tracker.anchors``: per camera, the last box centre moved on by its image velocity,
    with the measured label std (``LABEL_STD_H`` + ``LABEL_GROWTH_HPS`` per second, in box
    heights); NaN for a camera that has not seen the track (the association's box continuity)."""
    from service.tracking.image_continuity import LABEL_GROWTH_HPS, LABEL_STD_H

    tracker = Tracker(**{**RECOMMENDED, "fps_hint": 4.0})
    for i in range(8):
        t = i * 0.25
        box = np.array([[100.0 + 40 * i, 0.0, 140.0 + 40 * i, 200.0], [np.nan] * 4])
        tracker.update(t, np.array([[1.0 + 0.1 * i, 2.0]]), [Origin(cameras=(0,), boxes=box)])
    (anchor,) = tracker.anchors(2.0)
    assert anchor.image_x is not None and anchor.image_std is not None
    assert anchor.image_x[0] == pytest.approx(120.0 + 40 * 8, abs=10.0)  # 160 px/s on
    assert anchor.image_std[0] == pytest.approx(200.0 * (LABEL_STD_H + LABEL_GROWTH_HPS * 0.25))
    assert len(anchor.image_x) == 1 or np.isnan(anchor.image_x[1])


def test_an_anchor_says_how_long_no_camera_has_seen_its_track() -> None:
    """The lone-view continuity reading leaves out tracks unseen for long (held still places)."""
    tracker = Tracker(fps_hint=FPS, **RECOMMENDED)
    for i in range(30):
        tracker.update(i / FPS, np.array([[2.0, 2.0]]), [Origin(cameras=(0, 1))])
    assert [a.unseen_s for a in tracker.anchors(30 / FPS)] == pytest.approx([1 / FPS])
    for i in range(30, 39):
        tracker.update(i / FPS, np.empty((0, 2)), [])
    assert [a.unseen_s for a in tracker.anchors(39 / FPS)] == pytest.approx([10 / FPS])

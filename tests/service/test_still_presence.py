"""Presence that holds (issue 27): a person who sits still keeps their id and their zone through
detector dropouts of several seconds; a walker lost for as long is not held. Frame timestamps
drive everything (no clock)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.serving.still_presence import blackouts, sitter_scene, still_presence
from service.stages import Origin
from service.tracking.stillness import StillMemory, StillRule
from service.tracking.tracker import RECOMMENDED, Tracker

FPS = 5.0  # the tracker's rules are in seconds; 5 frame sets a second keep the hour short


def test_a_seated_person_holds_id_and_zone_for_an_hour_of_dropouts() -> None:
    minutes = 60
    holes = blackouts(minutes * 60, per_hour=60, longest_s=8.0, seed=3)
    assert (holes[:, 1] - holes[:, 0]).max() > 6.0  # several seconds with no camera at all
    r = still_presence(sitter_scene(minutes, FPS, 3), int(minutes * 60 * FPS), RECOMMENDED, holes)
    assert r["occupied_pct"] >= 99.5 and r["ids"] == 1 and r["events"] == 0, r


def test_without_the_hold_the_same_dropouts_break_presence() -> None:
    minutes = 10
    holes = blackouts(minutes * 60, per_hour=60, longest_s=8.0, seed=3)
    plain = {**RECOMMENDED, "hold_still_s": 0.0}
    r = still_presence(sitter_scene(minutes, FPS, 3), int(minutes * 60 * FPS), plain, holes)
    assert r["occupied_pct"] < 99.0 and r["ids"] > 1, r


def _feed(tracker: Tracker, points: np.ndarray, fps: float, start: float = 0.0) -> list:
    tracks: list = []
    for i, p in enumerate(points):
        tracks = tracker.update(start + i / fps, p.reshape(1, 2), [Origin(cameras=(0, 1))])
    return tracks


def test_only_a_still_track_is_held_unseen() -> None:
    fps = 10.0
    still = Tracker(fps_hint=fps, **RECOMMENDED)
    tracks = _feed(still, np.tile([2.0, 2.0], (100, 1)), fps)  # 10 s in one spot
    assert [t.id for t in tracks] == [1]
    for i in range(1, 120):  # 12 s unseen: served, coasting, same id
        tracks = still.update(10.0 + i / fps, np.zeros((0, 2)))
    assert [t.id for t in tracks] == [1] and tracks[0].coasting
    assert still.update(10.0 + 16.0, np.zeros((0, 2))) == []  # past hold_still_s: gone
    walker = Tracker(fps_hint=fps, **RECOMMENDED)
    path = np.stack([np.linspace(1.0, 8.0, 100), np.full(100, 2.0)], 1)  # 0.7 m/s
    assert [t.id for t in _feed(walker, path, fps)] == [1]
    assert walker.update(10.0 + 1.0, np.zeros((0, 2))) == []  # coasting beyond 0.5 s: not served


def _still_for(tracker: Tracker, seconds: float, fps: float, at=(2.0, 2.0)) -> list:
    return _feed(tracker, np.tile(at, (int(seconds * fps), 1)), fps)


def test_lone_views_off_by_half_a_metre_do_not_end_stillness() -> None:
    """The chain's failure (bench/results/still_presence_chain.md): when one camera misses a
    seated person the other's lone view, or a fragment of their body, is put 0.4-0.5 m off;
    two seconds of those, then an 8 s dropout, must not cost the id. Under the former rule (the
    filtered track within 0.3 m for 5 s) the off measurements restarted the still clock and the
    dropout ended the track."""
    fps = 5.0
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    _still_for(tracker, 10.0, fps)
    for i in range(10):  # 2 s of one camera's view, 0.45 m off
        tracks = tracker.update(10.0 + i / fps, np.array([[2.45, 2.0]]), [Origin(cameras=(0,))])
    start = 12.0
    for i in range(40):  # 8 s unseen
        tracks = tracker.update(start + i / fps, np.zeros((0, 2)))
        assert [t.id for t in tracks] == [1], start + i / fps
        # held at the median of what was measured, not where the odd views pulled the filter
        assert abs(tracks[0].x - 2.0) < 0.05 and tracks[0].vx == 0.0
    tracks = tracker.update(start + 8.0, np.array([[2.05, 2.0]]), [Origin(cameras=(0, 1))])
    assert [t.id for t in tracks] == [1] and not tracks[0].coasting


def test_a_held_still_track_is_taken_back_only_near_its_place() -> None:
    """While a still person is unseen, a false box 1.4 m off does not take (and drag) their
    track: it starts a track of its own; the person reappearing at their place gets their id
    back."""
    fps = 5.0
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    _still_for(tracker, 10.0, fps)
    tracker.update(10.0, np.zeros((0, 2)))
    tracks = tracker.update(10.2, np.array([[3.4, 2.0]]), [Origin(cameras=(1,))])
    assert [t.id for t in tracks] == [1] and tracks[0].x == 2.0 and tracks[0].coasting
    tracks = tracker.update(14.0, np.array([[2.1, 2.1]]), [Origin(cameras=(0, 1))])
    assert 1 in [t.id for t in tracks]


def test_a_still_person_who_walks_off_in_view_is_followed() -> None:
    """Stillness holds the track at its place only while unseen: a still person who gets up
    and walks away in view keeps the id and the served position follows them."""
    fps = 10.0
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    _still_for(tracker, 10.0, fps)
    path = np.stack([2.0 + 0.1 * np.arange(1, 41), np.full(40, 2.0)], 1)  # 1 m/s for 4 s
    tracks = _feed(tracker, path, fps, start=10.0)
    assert [t.id for t in tracks] == [1] and tracks[0].x > 5.5


def test_a_still_person_who_walks_off_and_is_missed_is_not_pulled_back() -> None:
    """The set-up check's failure (a fresh-clone CI run): the person stood 8 s on a mark, walked
    3.5 m at 3 m/s, and a one-second stall of the pipeline left their track unseen. The window's
    median was still the mark they had left, so the track was held there (served 3.5 m from the
    person for 15 s) and the person, beyond the still gate, was a new track. Once the recent
    measurements are beyond the still gate from the place, the person has left it."""
    fps = 30.0
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    _still_for(tracker, 8.0, fps, at=(7.5, 2.5))
    direction = np.array([-1.0, 1.0]) / np.sqrt(2.0)
    path = np.array([7.5, 2.5]) + np.outer(0.1 * np.arange(1, 31), direction)  # 3 m in 1 s
    _feed(tracker, path, fps, start=8.0)
    for i in range(1, 31):  # a 1 s stall: no measurement reaches the tracker
        tracks = tracker.update(9.0 + i / fps, np.zeros((0, 2)))
        assert all(np.hypot(t.x - 7.5, t.y - 2.5) > 1.0 for t in tracks), tracks
    tracks = _feed(tracker, np.tile([5.0, 5.0], (15, 1)), fps, start=10.1)  # arrived, seen
    assert len(tracks) == 1 and np.hypot(tracks[0].x - 5.0, tracks[0].y - 5.0) < 0.3, tracks


def test_a_still_person_who_walks_off_keeps_their_id_and_leaves_no_phantom() -> None:
    """A still person gets up and walks off seen by one camera (their track held at the place,
    its filter following the lone views), then is seen by two cameras 2 m on: a new track. The
    held track's filter coasts on over the new one; the shadow merge used to drop the new
    track (the younger) and keep the old one held at the place: the person was served nowhere
    and a phantom sat at the place for 15 s (a missed fall and false falls of the simulated
    lounge). Now the old id takes the new track's state: the person keeps their id, served
    where they are, and nothing is left at the place."""
    lone = 2.0 + 0.1 * np.arange(1, 9)  # up and off at 1 m/s
    served, tracks = _walk_off(lone, np.full(40, 4.0))  # 4 s standing 2 m from the place
    assert sum(1 for ids in served if ids) >= len(served) - 5, served
    assert [t.id for t in tracks] == [1] and tracks[0].x == pytest.approx(4.0, abs=0.05)


def _walk_off(lone: np.ndarray, seen: np.ndarray, fps: float = 10.0) -> tuple[list, list]:
    """10 s still at (2, 2), then the x positions ``lone`` seen by one camera and ``seen`` by
    both: per frame of ``seen``, the ids served (not coasting) within 0.2 m of the person, and
    the last frame's tracks."""
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    _still_for(tracker, 10.0, fps)
    t, served, tracks = 10.0, [], []
    for x in lone:
        t += 1.0 / fps
        tracker.update(t, np.array([[x, 2.0]]), [Origin(cameras=(0,))])
    for x in seen:
        t += 1.0 / fps
        tracks = tracker.update(t, np.array([[x, 2.0]]), [Origin(cameras=(0, 1))])
        served.append([tr.id for tr in tracks if not tr.coasting and abs(tr.x - x) < 0.2])
    return served, tracks


def test_a_still_person_who_walks_off_is_served_where_their_held_filter_creeps_behind() -> None:
    """A still person gets up and walks off slowly, their first steps one camera's views within
    ``still_gate_m`` (1 m) of the place (the track held there, its filter following them);
    then both cameras see them 1.1 m from the place, walking slowly on, then standing. The
    assignment expects the held track at its place (nothing beyond ``still_gate_m`` of it), and
    births used to be kept clear of its filter, which crept along behind the walker: they were
    served nowhere for seconds (a missed fall of the simulated lounge). They must be served
    within the confirmation time, and keep their id."""
    lone = 2.0 + 0.05 * np.arange(1, 17)  # up and off at 0.5 m/s
    seen = np.minimum(3.07 + 0.03 * np.arange(1, 41), 3.3)  # 1.1 m off at 0.3 m/s, then still
    served, tracks = _walk_off(lone, seen)
    assert all(served[12:]), served  # within 1.2 s, and from then on
    assert [t.id for t in tracks] == [1], tracks


def test_leaving_the_place_ends_stillness() -> None:
    rule = StillRule(after_s=5.0, window_s=10.0, radius_m=0.5, share=0.6, leave_m=1.0)
    memory = StillMemory()
    for i in range(40):  # 8 s in one spot
        memory.remember(i * 0.2, np.array([1.0, 1.0]), rule)
    assert memory.place is not None
    for i in range(1, 6):  # walks off at 1.5 m/s: still while within the gate, then not
        memory.remember(8.0 + i * 0.2, np.array([1.0 + 0.3 * i, 1.0]), rule)
        recent = np.median([1.0 + 0.3 * j for j in range(max(1, i - 2), i + 1)])
        assert (memory.place is None) == (recent - 1.0 > 1.0), (i, memory.place)
    assert memory.place is None


def test_two_cameras_placing_the_person_beyond_the_radius_end_stillness() -> None:
    """Two cameras' fixes are where the person is: 0.9 m from the place, within the still gate,
    they have left it, and a lone view after them does not undo that (a faller of the lounge
    was held back at the place they had left, a metre behind them, when one camera lost them).
    One camera's views as far off leave it still (a lone view's range is poorly known; its
    neighbour may be a false box)."""
    rule = StillRule(after_s=5.0, window_s=10.0, radius_m=0.5, share=0.6, leave_m=1.0,
                     leave_seen_m=0.5)  # fmt: skip
    for views, left in (((2, 2, 2), True), ((2, 2, 1), True), ((1, 1, 2), False)):
        memory = StillMemory()
        for i in range(40):  # 8 s in one spot, two cameras
            memory.remember(i * 0.2, np.array([1.0, 1.0]), rule, 2)
        for i, count in enumerate(views, 1):  # three fixes 0.9 m off (a lone view last)
            memory.remember(8.0 + i * 0.2, np.array([1.9, 1.0]), rule, count)
        assert (memory.place is None) == left, (views, memory.place)


def test_a_person_who_left_the_place_is_not_made_still_there_again_by_a_fix_after_a_gap() -> None:
    """1501's false fall in the lounge's daily life (``bench/results/falls.md``): a person who
    had stood still walked 1.15 m off, seen by both cameras, and squatted; after a second
    unseen, one two-camera fix 0.83 m from the place (within the gate, ``leave_m``) made the
    old place theirs again, the track was held back there and a pair read lying beside it
    fired a fall. Two two-camera fixes beyond the radius are needed to leave, one keeps them
    away once left; still elsewhere, the new spot is their place."""
    rule = StillRule(after_s=5.0, window_s=10.0, radius_m=0.5, share=0.6, leave_m=1.0,
                     leave_seen_m=0.5)  # fmt: skip
    memory = StillMemory()
    for i in range(40):  # 8 s in one spot, two cameras
        memory.remember(i * 0.2, np.array([1.0, 1.0]), rule, 2)
    for i in range(1, 8):  # walks 1.15 m off in 1.4 s, two cameras
        memory.remember(8.0 + i * 0.2, np.array([1.0 + 1.15 * i / 7, 1.0]), rule, 2)
    assert memory.place is None
    memory.remember(10.4, np.array([1.83, 1.0]), rule, 2)  # after a 1 s dropout, 0.83 m off
    assert memory.place is None
    for i in range(1, 30):  # still at the new spot for 5.8 s: still there, not at the old place
        memory.remember(10.4 + i * 0.2, np.array([1.83, 1.0]), rule, 2)
    assert memory.place is not None and np.allclose(memory.place, [1.83, 1.0])


def test_a_still_person_whose_fixes_swing_off_for_a_moment_is_still_again_once_back() -> None:
    """A body on the floor: its two-camera fixes swing 0.6 m off for a few frames and come
    back. That reads as leaving, and the person is still at the place again as soon as their
    recent fixes are back within the radius, not only after a fresh ``after_s`` (forgetting
    the time at the place, rejected on 2026-12-07, made the lounge's lying person's posture
    right 80 % of the time instead of 94 %: ``bench/results/falls.md``)."""
    rule = StillRule(after_s=5.0, window_s=10.0, radius_m=0.5, share=0.6, leave_m=1.0,
                     leave_seen_m=0.5)  # fmt: skip
    memory = StillMemory()
    for i in range(40):  # 8 s in one spot, two cameras
        memory.remember(i * 0.2, np.array([1.0, 1.0]), rule, 2)
    for i in range(1, 4):  # 0.6 s of fixes 0.6 m off
        memory.remember(8.0 + i * 0.2, np.array([1.6, 1.0]), rule, 2)
    assert memory.place is None
    for i in range(1, 5):  # back at the place: still there within the recent span
        memory.remember(8.6 + i * 0.2, np.array([1.0, 1.0]), rule, 2)
    assert memory.place is not None and np.allclose(memory.place, [1.0, 1.0])


def test_the_place_is_where_two_cameras_put_the_person_in_the_last_seconds() -> None:
    """A person still for 8 s who shifts 0.4 m (within the radius: still) is held where two
    cameras put them in the last 2 s, not at the window's median behind them: held at the
    median, 0.5 m off, their fall's lone views were read 0.6 m from the track and the fall was
    missed (1408 of the lounge's falls, ``bench/results/falls.md``). With too few such fixes,
    or with them beyond the radius, the window's median stays the place."""
    rule = StillRule(after_s=5.0, window_s=10.0, radius_m=0.5, share=0.6, leave_m=1.0,
                     leave_seen_m=0.5)  # fmt: skip
    memory = StillMemory()
    for i in range(40):  # 8 s in one spot, two cameras
        memory.remember(i * 0.2, np.array([1.0, 1.0]), rule, 2)
    for i in range(1, 11):  # 2 s 0.4 m on, two cameras
        memory.remember(8.0 + i * 0.2, np.array([1.4, 1.0]), rule, 2)
    assert memory.place is not None and np.allclose(memory.place, [1.4, 1.0])
    lone = StillMemory()
    for i in range(40):
        lone.remember(i * 0.2, np.array([1.0, 1.0]), rule, 2)
    for i in range(1, 11):  # the same shift seen by one camera: its range is poorly known
        lone.remember(8.0 + i * 0.2, np.array([1.4, 1.0]), rule, 1)
    assert lone.place is not None and np.allclose(lone.place, [1.0, 1.0])
    swung = StillMemory()
    for i in range(40):
        swung.remember(i * 0.2, np.array([1.0, 1.0]), rule, 2)
    for i in range(1, 8):  # 1.4 s of two-camera fixes 0.6 m off, then back: still at the place
        swung.remember(8.0 + i * 0.2, np.array([1.6, 1.0]), rule, 2)
    for i in range(1, 4):  # the last 2 s's fixes lie mostly beyond the radius: not the place
        swung.remember(9.4 + i * 0.2, np.array([1.0, 1.0]), rule, 2)
    assert swung.place is not None and np.allclose(swung.place, [1.0, 1.0])


def test_a_still_track_one_camera_loses_is_held_where_two_last_put_it() -> None:
    fps = 10.0
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    _still_for(tracker, 8.0, fps, at=(2.0, 2.0))
    _feed(tracker, np.tile([2.4, 2.0], (20, 1)), fps, start=8.0)  # 2 s 0.4 m on, two cameras
    for i in range(10):  # one camera's lone views 0.2 m off: held, not moved
        tracks = tracker.update(10.0 + i / fps, np.array([[2.6, 2.0]]), [Origin(cameras=(0,))])
    assert [t.id for t in tracks] == [1]
    assert abs(tracks[0].x - 2.4) < 0.05, tracks


def test_after_leaving_lone_views_within_the_gate_make_the_place_theirs_again() -> None:
    """Only two-camera fixes keep a person who left away from the place; one camera's views
    within ``leave_m`` of it take them back, as before they left (a lone view's range is
    poorly known). Holding them away until those views too were within the radius lost two
    falls of the lounge (seed set 1401): the track held where a faller had lain, no longer
    taken back there, changed which track took the body of the next fall nearby
    (``bench/results/falls.md``)."""
    rule = StillRule(after_s=5.0, window_s=10.0, radius_m=0.5, share=0.6, leave_m=1.0,
                     leave_seen_m=0.5)  # fmt: skip
    memory = StillMemory()
    for i in range(40):  # 8 s in one spot, two cameras
        memory.remember(i * 0.2, np.array([1.0, 1.0]), rule, 2)
    for i in range(1, 3):  # two two-camera fixes 0.6 m off: left
        memory.remember(8.0 + i * 0.2, np.array([1.6, 1.0]), rule, 2)
    assert memory.place is None
    for i in range(1, 5):  # one camera's views 0.7 m off: at the place again
        memory.remember(8.4 + i * 0.2, np.array([1.7, 1.0]), rule, 1)
    assert memory.place is not None and np.allclose(memory.place, [1.0, 1.0])


def _taken_away_and_ended(fps: float) -> Tracker:
    """A still person's held track taken 0.95 m off by a false pair at 11 s, ended at 13.2 s."""
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    _still_for(tracker, 10.0, fps)
    for i in range(5):  # 1 s unseen: held
        tracker.update(10.0 + i / fps, np.zeros((0, 2)))
    tracks = _feed(tracker, np.tile([2.95, 2.0], (4, 1)), fps, start=11.0)  # the false pair
    assert [t.id for t in tracks] == [1] and tracks[0].x > 2.5  # took the track away
    for i in range(1, 16):  # 3 s of nobody: the dragged track ends
        tracks = tracker.update(11.6 + i / fps, np.zeros((0, 2)))
    assert tracks == []
    return tracker


@pytest.mark.parametrize(
    ("start", "at", "ident"),
    [(14.8, (2.05, 2.0), 1), (14.8, (3.0, 3.5), 2), (30.0, (2.05, 2.0), 2)],
    ids=["back at the place", "elsewhere", "after the hold"],
)
def test_a_sitter_whose_held_track_a_false_pair_took_away_gets_their_id_back(
    start: float, at: tuple[float, float], ident: int
) -> None:
    """The seated hour on the AMD machine (``bench/results/still_presence_chain.md``, 1665 s):
    during a dropout a false box of each camera, paired 1 m from the sitter, took their held
    track (two cameras release a hold) and it ended there; the sitter, seen again at their
    place 3 s later, became a new id. A new track where a still person's track ended, within
    ``hold_still_s``, is that person; elsewhere, or later, it is somebody new."""
    fps = 5.0
    tracker = _taken_away_and_ended(fps)
    tracks = _feed(tracker, np.tile(at, (5, 1)), fps, start=start)
    assert [t.id for t in tracks] == [ident], tracks


def test_a_still_person_two_cameras_see_walk_off_is_not_held_back_at_the_place() -> None:
    """Seed 101's false fall in the lounge's daily life (``bench/results/falls.md``): a person
    who had stood still walked 0.95 m, seen by both cameras, and crouched there; unseen for a
    moment, their track was held back at the place they had left (within the still gate), a
    new track was born for the crouch, and a false box's lone view read lying on the held
    phantom. Now the track is not held at the place: it stays with the person and keeps
    their id when they are seen again."""
    fps = 5.0
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    _still_for(tracker, 10.0, fps)
    path = np.stack([2.0 + 0.19 * np.arange(1, 6), np.full(5, 2.0)], 1)  # 0.95 m in 1 s
    tracks = _feed(tracker, path, fps, start=10.0)
    for i in range(1, 6):  # unseen for 1 s
        tracks = tracker.update(11.0 + i / fps, np.zeros((0, 2)))
        assert all(np.hypot(t.x - 2.0, t.y - 2.0) > 0.5 for t in tracks), tracks
    tracks = _feed(tracker, np.tile([2.95, 2.0], (10, 1)), fps, start=12.2)  # seen again
    assert [t.id for t in tracks] == [1], tracks


def test_a_held_still_track_claims_a_fix_at_its_place() -> None:
    """The hour's id change (bench/results/still_presence_chain.md, 1513 s): while a sitter was
    unseen, a track beside their place was fed; the sitter's fix at the place cost less on that
    fresh track than on their held one (whose covariance grew while held) and went there. A
    fix within a quarter metre of a held place is the held track's."""
    fps = 5.0
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    both = [Origin(cameras=(0, 1))] * 2
    for i in range(50):  # 10 s: two people side by side on a sofa, 0.4 m apart
        tracks = tracker.update(i / fps, np.array([[2.0, 2.0], [2.4, 2.0]]), both)
    ids = {round(tr.x, 1): tr.id for tr in tracks}
    for i in range(15):  # 3 s: the one at 2.0 unseen, held at their place
        tracks = tracker.update(10.0 + i / fps, np.array([[2.4, 2.0]]), both[:1])
    tracks = tracker.update(13.0, np.array([[2.02, 2.0]]), both[:1])  # back; the other missed
    seen = [tr for tr in tracks if not tr.coasting]
    assert [tr.id for tr in seen] == [ids[2.0]], tracks


def test_stillness_needs_the_window_and_the_share() -> None:
    rule = StillRule(after_s=5.0, window_s=10.0, radius_m=0.5, share=0.6)
    memory = StillMemory()
    rng = np.random.default_rng(0)
    for i in range(24):  # 4.8 s in one spot: not yet
        memory.remember(i * 0.2, np.array([1.0, 1.0]) + rng.normal(0, 0.05, 2), rule)
    assert memory.place is None
    memory.remember(5.0, np.array([1.0, 1.0]), rule)
    assert memory.place is not None and np.allclose(memory.place, [1.0, 1.0], atol=0.05)
    walker = StillMemory()
    for i in range(60):  # a slow walk, 0.5 m/s, for 12 s
        walker.remember(i * 0.2, np.array([0.1 * i, 0.0]), rule)
        assert walker.place is None
    shuffler = StillMemory()  # one measurement in three 2 m off (a mispair): still
    for i in range(60):
        shuffler.remember(i * 0.2, np.array([2.0 if i % 3 == 0 else 0.0, 0.0]), rule)
    assert shuffler.place is not None and abs(shuffler.place[0]) < 1e-9


def _everywhere(xy: np.ndarray, lying: np.ndarray | None = None) -> np.ndarray:
    """Coverage: both cameras should see a person anywhere (the ghost check's input)."""
    return np.ones((len(xy), 2), dtype=bool)


def test_a_lone_view_beside_a_still_person_does_not_move_them() -> None:
    """The chain's 434 s exit (bench/results/still_presence_chain.md): during a dropout one
    camera's persisting false box 0.8 m from a seated person took their track, and the filter,
    given the jump as a velocity, carried it out of the sofa's zone. A lone view within the
    still gate keeps the track alive at its still place; two cameras move it."""
    fps = 5.0
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    _still_for(tracker, 10.0, fps)
    for i in range(1, 8):  # 1.4 s of camera 1's box 0.8 m off
        tracks = tracker.update(10.0 + i / fps, np.array([[2.0, 2.8]]), [Origin(cameras=(1,))])
        assert [t.id for t in tracks] == [1] and not tracks[0].coasting
        assert abs(tracks[0].x - 2.0) < 0.05 and abs(tracks[0].y - 2.0) < 0.05, tracks[0]
    tracks = tracker.update(11.6, np.array([[2.0, 2.4]]), [Origin(cameras=(0, 1))])
    assert [t.id for t in tracks] == [1] and tracks[0].y > 2.1  # two views: the filter


def test_a_false_pair_beside_a_held_still_person_is_not_served() -> None:
    """The chain's commonest loss (bench/results/still_presence_chain.md): while a seated person
    is lost, a false box of each camera ~1 m from them is paired into a two-camera "person"
    for one frame. Beside a still track that needs ``still_multi_view_s`` of two views, not
    one frame, so the false track stays subject to the ghost check and is not served."""
    fps = 5.0
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    for i in range(55):  # still for 10 s, then unseen for 1 s
        seen = i < 50
        tracker.update(
            i / fps,
            np.array([[2.0, 2.0]] if seen else np.zeros((0, 2))),
            [Origin(cameras=(0, 1))] if seen else [],
            None,
            _everywhere,
        )
    script = [((1,), 3.1), ((1,), 3.1), ((0, 1), 3.0)] + [((0,), 3.0)] * 8
    for i, (cameras, x) in enumerate(script):  # the sitter unseen from 10 s
        tracks = tracker.update(
            11.0 + i / fps, np.array([[x, 2.0]]), [Origin(cameras=cameras)], None, _everywhere
        )
        assert [t.id for t in tracks] == [1], (11.0 + i / fps, tracks)


def test_a_real_person_beside_a_still_one_is_served_within_the_wait() -> None:
    """The price of that wait: a second person appearing in both cameras 1 m from a still one
    is served once seen by both for ``still_multi_view_s`` (1 s, its first frame counting one
    frame interval) instead of ``confirm_s`` (0.3 s)."""
    fps = 5.0
    tracker = Tracker(fps_hint=fps, **RECOMMENDED)
    _still_for(tracker, 10.0, fps)
    both = [Origin(cameras=(0, 1))] * 2
    served_at = None
    for i in range(15):
        t = 10.0 + i / fps
        tracks = tracker.update(t, np.array([[2.0, 2.0], [3.0, 2.0]]), both, None, _everywhere)
        if served_at is None and len(tracks) == 2:
            served_at = t - 10.0
    assert served_at is not None and 0.7 <= served_at <= 1.05, served_at

"""The fall bench's scripts: falls happen where and when the bench scores them, daily life never
lies down, the true-association runner hears a scripted fall, and a fall no camera sees is told
apart."""

from __future__ import annotations

import numpy as np

from bench.serving.falls import (
    IN_TIME_S,
    ROOMS,
    Cached,
    Fall,
    SetupOnly,
    daily_script,
    detected_down,
    fall_events,
    fall_script,
    identity_snapshots,
    match_falls,
    room_scene,
    truth_snapshots,
)
from models.simulate.postures import LYING
from models.simulate.script import Segment
from service.outputs.falls import FallRules

FPS = 10.0
CORNER = (0.1, 3.9)  # a corner of the lounge no camera sees the floor of


def test_scripted_falls_are_on_the_floor_at_floor_t_on_free_floor():
    room = ROOMS["lounge"]
    route, falls = fall_script(room, np.random.default_rng(4))
    scene = room_scene(room, (tuple(route),), FPS, seed=4)
    for fall in falls:
        assert any(x0 <= fall.where[0] <= x1 and y0 <= fall.where[1] <= y1
                   for x0, y0, x1, y1 in room.free)  # fmt: skip
        before = round((fall.floor_t - 0.3) * FPS)
        after = round((fall.floor_t + 0.1) * FPS)
        code, weight = scene.walkers.states(before, after + 1).postures()
        assert code[-1, 0] == LYING and weight[-1, 0] == 1.0  # down at floor_t
        assert weight[0, 0] < 1.0  # still falling just before


def test_daily_life_sits_only_on_its_own_seat_and_never_lies():
    room = ROOMS["office-desks"]
    route = daily_script(room, np.random.default_rng(2), 3600.0, seat=1)
    assert sum(s.seconds for s in route) >= 3600.0
    assert {s.posture for s in route} <= {"standing", "sitting", "crouching"}
    seats = {s.start for s in route if s.posture == "sitting"}
    assert seats <= {room.seats[1][0]} and seats
    never = daily_script(room, np.random.default_rng(2), 600.0, seat=None)
    assert "sitting" not in {s.posture for s in never}


def test_the_true_association_runners_report_a_scripted_fall_in_time(tmp_path):
    room = ROOMS["lounge"]
    setup = SetupOnly.simulated("living-room", frames=900)  # the lounge's cameras
    route, falls = fall_script(room, np.random.default_rng(1), count=1)
    scene = room_scene(room, (tuple(route),), FPS, seed=1)
    frames = int(sum(s.seconds for s in route) * FPS)
    for run in (truth_snapshots, identity_snapshots):
        cached = Cached(run, run.__name__, tmp_path)
        served = cached(setup, scene, frames)
        assert cached(setup, scene, frames) == served  # read back from the cache
        late, wrong = match_falls(fall_events(served, FallRules()), falls, FallRules())
        assert wrong == 0 and late[0] is not None and 0.0 <= late[0] <= IN_TIME_S
    assert len(list(tmp_path.glob("falls-*.pkl"))) == 2  # one per runner


def test_a_fall_event_after_the_person_got_up_is_not_that_falls():
    # twice at the same spot: down 20 s (LIE_S), up, 3 s standing, down again
    falls = [Fall((1.0, 1.0), 10.0), Fall((1.1, 1.0), 34.0)]
    second = {"t": 34.5, "x": 1.05, "y": 1.0}
    late, wrong = match_falls([second], falls, FallRules())
    assert late == [None, 0.5] and wrong == 0


def test_a_fall_is_seen_down_only_where_a_camera_finds_the_body():
    """A fall on the lounge's open floor is in the cameras' view; the same fall in a corner
    whose floor neither camera sees is detected by neither: counted, as a fall no camera saw."""
    room = ROOMS["lounge"]
    for spot, seen in (((2.5, 1.5), True), (CORNER, False)):
        route = (Segment(spot, spot, 3.0), Segment(spot, spot, 20.0, "lying", 0.3, ramp_s=0.8))
        scene = room_scene(room, (route,), FPS, seed=1)
        assert detected_down(scene, Fall(spot, 3.8)) is seen

"""The fall bench's scripts: falls happen where and when the bench scores them, daily life never
lies down, and the true-association runner hears a scripted fall."""

from __future__ import annotations

import numpy as np

from bench.serving.falls import (
    ROOMS,
    SetupOnly,
    daily_script,
    fall_script,
    room_scene,
    truth_events,
)
from models.simulate.postures import LYING
from service.outputs.falls import FALL

FPS = 10.0


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


def test_the_true_association_runner_reports_a_scripted_fall():
    room = ROOMS["lounge"]
    setup = SetupOnly.simulated("living-room", frames=900)  # the lounge's cameras
    route, falls = fall_script(room, np.random.default_rng(1), count=1)
    scene = room_scene(room, (tuple(route),), FPS, seed=1)
    frames = int(sum(s.seconds for s in route) * FPS)
    events = truth_events(setup, scene, frames)
    found = [e for e in events if e["type"] == FALL]
    assert len(found) == 1
    assert np.hypot(found[0]["x"] - falls[0].where[0], found[0]["y"] - falls[0].where[1]) < 1.0
    assert falls[0].floor_t + 10.0 - 1.0 <= found[0]["t"] <= falls[0].floor_t + 10.0 + 3.0

"""Presence that holds (issue 27): a person who sits still keeps their id and their zone through
detector dropouts of several seconds; a walker lost for as long is not held. Frame timestamps
drive everything (no clock)."""

from __future__ import annotations

import numpy as np

from bench.serving.still_presence import blackouts, sitter_scene, still_presence
from service.stages import Origin
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

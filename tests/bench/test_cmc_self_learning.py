"""The CMC self-learning bench's pure parts: the simulated bump, the mark subsets, the chained
replay (its run without the data: tests/bench/test_real_cmc.py)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.real import cmc_data
from bench.real.cmc_bump import bump_homography, bumped_replay, move_boxes
from bench.real.cmc_learning_run import GAP_FRAMES, chained
from bench.real.cmc_setup import mark_grid, near_marks
from models.data.detections_replay import DetectionsReplay

SIZE = (1920, 1024)


def test_bump_turns_about_the_centre_and_shifts() -> None:
    h = bump_homography(SIZE, roll_deg=3.0, dx=10.0)
    centre = np.array([960.0, 512.0, 1.0])
    assert np.allclose(h @ centre, [970.0, 512.0, 1.0])
    right = h @ np.array([1060.0, 512.0, 1.0])  # 100 px right of the centre
    a = np.radians(3.0)
    assert np.allclose(right[:2], [960 + 100 * np.cos(a) + 10, 512 + 100 * np.sin(a)])


def test_moved_boxes_are_the_bounds_of_the_turned_corners_clipped() -> None:
    boxes = np.array([[900.0, 300.0, 1000.0, 700.0], [1900.0, 0.0, 1920.0, 100.0], [np.nan] * 4])
    assert np.allclose(move_boxes(boxes[:2], np.eye(3), SIZE), boxes[:2])
    moved = move_boxes(boxes, bump_homography(SIZE), SIZE)
    w, h = moved[0, 2] - moved[0, 0], moved[0, 3] - moved[0, 1]
    a = np.radians(3.0)
    assert w == pytest.approx(100 * np.cos(a) + 400 * np.sin(a))  # a turned box is wider
    assert h == pytest.approx(400 * np.cos(a) + 100 * np.sin(a))
    assert moved[1, 2] == 1920.0 and moved[1, 0] <= 1920.0  # pushed out: clipped, kept
    assert np.isnan(moved[2]).all()


def test_bumped_replay_moves_one_camera_from_one_frame_in_place() -> None:
    frame = np.array([0, 0, 1, 1, 2])
    camera = np.array([0, 1, 0, 1, 1])
    boxes = np.tile([800.0, 300.0, 900.0, 600.0], (5, 1))
    replay = DetectionsReplay(frame, camera, boxes, np.ones(5), np.array([SIZE, SIZE]), 4.0)
    out = bumped_replay(replay, 1, 1, bump_homography(SIZE))
    changed = ~np.isclose(out.boxes, replay.boxes).all(axis=1)
    assert changed.tolist() == [False, False, False, True, True]
    assert (out.frame == replay.frame).all() and (out.camera == replay.camera).all()


def test_mark_subsets_keep_rows_near_the_marks() -> None:
    for side in (2, 3):
        marks = mark_grid(side)
        assert len(marks) == side * side and cmc_data.in_area(marks).all()
    marks = mark_grid(2)
    xy = marks[0] + np.array([[0.0, 0.0], [0.29, 0.0], [0.31, 0.0]])
    assert near_marks(xy, marks).tolist() == [True, True, False]


def test_chained_replays_follow_each_other_with_a_gap() -> None:
    def part(frames: list[int]) -> DetectionsReplay:
        n = len(frames)
        return DetectionsReplay(
            np.array(frames), np.zeros(n), np.tile([0.0, 0, 10, 10], (n, 1)), np.ones(n),
            np.array([SIZE]), 4.0,
        )  # fmt: skip

    joined, offsets = chained([part([1, 2, 5]), part([1, 3])])
    assert offsets == [-1, 4 + GAP_FRAMES - 1]
    assert joined.frame.tolist() == [0, 1, 4, 4 + GAP_FRAMES, 6 + GAP_FRAMES]

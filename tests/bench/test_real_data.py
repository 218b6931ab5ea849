"""The real-data benches' geometry, loaders and scores (bench.real.*), on
hand
cases and synthetic files: no real data needed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.real.chain import breakdown, foot_point, match_people
from bench.real.data import Calibration, FloorGrid, opencv_values, rodrigues
from bench.real.replay import ReplayWalkers, pack_slots
from bench.real.scoring import DetectionScore, match_floor
from bench.real.shelf_data import load_detections
from service.stages import Association


def camera(position=(0.0, -6.0, 3.0)) -> Calibration:
    """A 1920x1080 camera at ``position`` looking at the floor origin."""
    from models.simulate.camera import PinholeCamera

    cam = PinholeCamera.look_at(position, (0.0, 0.0, 0.5), 60.0, (1920, 1080))
    return Calibration("test", cam.K, cam.R, cam.t, (1920, 1080))


def test_rodrigues_matches_a_quarter_turn_and_stays_a_rotation() -> None:
    quarter = rodrigues(np.array([0, 0, np.pi / 2]))
    assert np.allclose(quarter, [[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    r = rodrigues(np.array([1.76, 0.47, -0.33]))
    assert np.allclose(r @ r.T, np.eye(3)) and np.isclose(np.linalg.det(r), 1.0)
    assert np.allclose(rodrigues(np.zeros(3)), np.eye(3))


def test_opencv_values_reads_matrices_and_plain_text(tmp_path: Path) -> None:
    path = tmp_path / "cal.xml"
    path.write_text(
        '<?xml version="1.0"?><opencv_storage><rvec type_id="opencv-matrix"><rows>3</rows>'
        "<cols>1</cols><dt>d</dt><data>1. 2.\n 3.</data></rvec><tvec>\n -5.5 4 1e2 </tvec>"
        "</opencv_storage>"
    )
    assert opencv_values(path, "rvec").tolist() == [1.0, 2.0, 3.0]
    assert opencv_values(path, "tvec").tolist() == [-5.5, 4.0, 100.0]
    with pytest.raises(ValueError, match="no <K>"):
        opencv_values(path, "K")


def test_floor_grid_follows_the_wildtrack_formula() -> None:
    grid = FloorGrid((-3.0, -9.0), 0.025, 480)
    ids = np.array([0, 479, 480, 456826])
    expected = [[-3.0, -9.0], [-3.0 + 0.025 * 479, -9.0], [-3.0, -8.975]]
    expected.append([-3.0 + 0.025 * (456826 % 480), -9.0 + 0.025 * (456826 // 480)])
    assert np.allclose(grid.position(ids), expected)


def test_projection_round_trip_through_the_foot_point() -> None:
    cal = camera()
    xy = np.array([[0.5, -1.0], [-1.2, 2.0]])
    pixels, depth = cal.project(np.c_[xy, np.zeros(2)])
    assert (depth > 0).all()
    boxes = np.c_[pixels[:, 0] - 20, pixels[:, 1] - 150, pixels[:, 0] + 20, pixels[:, 1]]
    tuples = np.stack([boxes, np.full((2, 4), np.nan)], axis=1)  # second camera unseen
    assert np.allclose(foot_point(tuples, [cal, cal]), xy, atol=1e-6)


def test_facing_flips_the_sign_without_moving_a_pixel() -> None:
    cal = camera()
    flipped = Calibration("f", cal.K, -cal.R, -cal.t, cal.image_size)
    floor = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    assert (flipped.project(floor)[1] < 0).all()
    fixed = flipped.facing(floor)
    assert (fixed.project(floor)[1] > 0).all()
    assert np.allclose(fixed.project(floor)[0], cal.project(floor)[0])
    assert cal.facing(floor) is cal


def test_match_people_pairs_boxes_with_their_projected_floor_point() -> None:
    cal = camera()
    xy = np.array([[0.0, 0.0], [1.5, 0.5]])
    feet, _ = cal.project(np.c_[xy, np.zeros(2)])
    boxes = np.array(
        [
            [feet[1, 0] - 15, feet[1, 1] - 200, feet[1, 0] + 15, feet[1, 1] + 5],  # person 1
            [10, 10, 40, 100],  # nobody
            [feet[0, 0] - 15, feet[0, 1] - 200, feet[0, 0] + 15, feet[0, 1] - 5],  # person 0
        ]
    )
    assert match_people(boxes, cal, xy).tolist() == [1, -1, 0]


def test_moda_on_a_hand_case() -> None:
    score = DetectionScore()
    truth = np.array([[0.0, 0.0], [2.0, 0.0], [5.0, 5.0]])
    served = np.array([[0.1, 0.0], [2.0, 0.3], [9.0, 9.0]])
    rows, matched = score.add(served, truth)
    assert sorted(rows.tolist()) == [0, 1] and sorted(matched.tolist()) == [0, 1]
    result = score.result()
    assert (result["tp"], result["fp"], result["fn"]) == (2, 1, 1)
    assert result["moda"] == pytest.approx(100 * (1 - 2 / 3))
    assert result["modp"] == pytest.approx(100 * np.mean([1 - 0.1 / 0.5, 1 - 0.3 / 0.5]))
    assert result["precision"] == pytest.approx(200 / 3)


def test_floor_matching_is_one_to_one_and_global() -> None:
    # greedy would give served 0 to truth 0 (0.1 m) and leave truth 1 unmatched
    served = np.array([[0.1, 0.0], [0.45, 0.0]])
    truth = np.array([[0.0, 0.0], [0.55, 0.0]])
    rows, cols, dist = match_floor(served, truth)
    assert cols.tolist() == [0, 1]
    assert rows.tolist() == [0, 1] and dist.max() <= 0.5
    assert match_floor(np.zeros((0, 2)), truth)[0].size == 0


def association(world: tuple[float, float], index: list[int | None]) -> Association:
    cameras = [k for k, j in enumerate(index) if j is not None]
    return Association(np.zeros((2, 4)), cameras, np.array(world), 0.0, index)


def test_breakdown_names_each_false_positive_and_miss() -> None:
    labels = [np.array([0, 1, -1]), np.array([0, 1])]  # camera 0: boxes of 0, 1, nobody
    found = [
        association((0, 0), [0, 0]),  # person 0: matched
        association((5, 5), [2, None]),  # a false box alone
        association((3, 3), [1, 0]),  # person 1 with person 0
        association((0.1, 0), [0, None]),  # a second position of person 0
    ]
    fp, fn, views = breakdown(found, labels, np.array([0]), np.array([0]), people=3)
    assert fp == {"no true person": 1, "mixed people": 1, "duplicate": 1}
    assert fn == {"boxed, not served within 0.5 m": 1, "no box in any camera": 1}
    assert views == {"1": 2, "2": 1}


def test_pack_slots_reuses_a_slot_only_after_a_gap() -> None:
    present = np.zeros((10, 4), bool)
    present[0:3, 0] = True  # ends at 2
    present[4:8, 1] = True  # starts at 4: may reuse slot 0 (free from 4)
    present[3:5, 2] = True  # starts at 3: slot 0 still in its gap
    present[0:10, 3] = True
    slot = pack_slots(present)
    assert slot[0] == slot[1] and len(set(slot.tolist())) == 3
    for s in set(slot.tolist()):  # no two people of a slot at once
        assert present[:, slot == s].sum(axis=1).max() <= 1


def test_replay_walkers_give_nan_where_nobody_is() -> None:
    xy = np.full((4, 2, 2), np.nan)
    xy[:2, 0] = [[0.0, 0.0], [0.5, 0.0]]
    xy[3, 1] = [2.0, 2.0]
    walkers = ReplayWalkers(xy, fps=2.0, rng=np.random.default_rng(0))
    states = walkers.states(0, 6)
    assert states.position.shape == (6, walkers.slots, 2)
    assert np.isfinite(states.position[0]).all(axis=1).sum() == 1
    assert np.isnan(states.position[4:]).all()  # past the annotation
    assert walkers.person[3].max() == 1 and walkers.person[2].max() == -1
    assert np.isclose(states.heading[1][walkers.person[1] == 0][0], 0.0)


def test_shelf_detections_skip_the_part_affinities(tmp_path: Path) -> None:
    counts = [0] * 25
    counts[1], counts[8] = 1, 2
    lines = ["4 2"]
    for _ in range(2):
        for n in counts:
            lines.append(str(n))
            lines += [" ".join(["0.5"] * n)] * 3 if n else []
        lines.append("0.9 0.8")  # the one PAF with data: limb (1, 8), 1 x 2 scores
    path = tmp_path / "0.txt"
    path.write_text("\n".join(lines))
    frames = load_detections(path, (1032, 776))
    assert len(frames) == 2 and len(frames[1][8]) == 2
    assert np.allclose(frames[0][1][0], [0.5 * 1031, 0.5 * 775, 0.5])


@pytest.mark.parametrize("name", ["multiviewx", "wildtrack", "shelf", "shelf_stream"])
def test_each_bench_skips_with_one_line_without_its_data(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import importlib

    module = importlib.import_module(f"bench.real.{name}")
    out = tmp_path / "result.md"
    assert module.main(["--data", str(tmp_path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out.strip().splitlines()
    assert len(printed) == 1 and "not found" in printed[0]
    assert not out.exists()


def test_report_stage_answers_by_frame_and_can_be_closed() -> None:
    """The offline pipeline stops its detect stage (``close``) and reads its counters
    (``stats``); the real-data streams crashed at their end when the stage had neither."""
    from bench.real.stream import ReportStage
    from capture.rig import FrameSet
    from capture.worker import Frame
    from models.detector.base import Detections

    asked: list[int] = []

    def report(frame: int) -> list[Detections]:
        asked.append(frame)
        return [Detections.empty()]

    stage = ReportStage(report)
    frame = Frame(camera=0, image=None, timestamp=3.5, seq=7)
    found = stage(FrameSet(frames=[frame], skew=0.0, stale=[False]))
    assert asked == [7] and len(found) == 1
    stage.close()
    assert callable(stage.stats)

"""The simulated-vs-real CMC benchmark's pieces: pairing, grid rows, the table, the skip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.real import cmc_detector, sim_vs_real
from bench.real.cmc_pairing import (
    Frames,
    crowd_size,
    floor_point,
    iou,
    pair,
    project,
    simulated_frames,
)
from models.data.dataset import MomDataset
from models.simulate import PRESETS, DetectorProfile, Scene


def test_projection_and_floor_point_invert_each_other() -> None:
    matrix = Scene(PRESETS["cmc-room"], seed=0).projection_matrices()[1]
    floor = np.array([[3.0, 1.0], [5.5, 2.5]])
    pixels, depth = project(matrix, np.column_stack([floor, np.zeros(2)]))
    assert (depth > 0).all()
    np.testing.assert_allclose(floor_point(matrix, pixels), floor, atol=1e-9)
    boxes = np.array([[0.0, 0.0, 2.0, 2.0]])
    np.testing.assert_allclose(iou(boxes, np.array([[1.0, 0.0, 3.0, 2.0]])), [[1 / 3]])


def test_exact_detector_pairs_everyone_and_finds_nobody_outside() -> None:
    import dataclasses

    config = dataclasses.replace(
        PRESETS["cmc-room"], people=2, outside_people=0, detector_profile=DetectorProfile.exact()
    )
    frames = simulated_frames(Scene(config, seed=1), 20, "exact")
    pairs = pair(frames)
    free = pairs.visible & (pairs.occluded < 0.1)
    assert free.sum() > 100 and np.isfinite(pairs.box[free]).all()
    result = cmc_detector.measure([frames])
    assert result["unmatched"]["outside_per_frame"] == 0
    assert sum(result["cameras_per_person"]) == pytest.approx(1.0)


def test_crowd_is_what_the_people_stand_in_not_the_mean_over_frames() -> None:
    # two frames of 1 person and two of 10: the mean over frames is 5.5, but 20 of the 22
    # person-frames stand among 10 (Σ n² / Σ n = 202 / 22 = 9.2)
    people = [np.zeros((n, 4)) for n in (1, 1, 10, 10)]
    frames = Frames("crowd", people, [[] for _ in people], np.zeros((4, 3, 4)))
    assert crowd_size(frames) == 9
    assert crowd_size(Frames("empty", [], [], np.zeros((4, 3, 4)))) == 0


def test_grid_rows_keep_the_rows_near_the_nine_marks() -> None:
    world = np.array([[2.03 + 4.27 / 6, 3.41 / 6], [4.165, 1.705], [2.2, 0.1], [6.0, 3.3]])
    data = MomDataset(
        world=world.astype(np.float32),
        boxes=np.tile(np.array([10.0, 10.0, 30.0, 50.0], np.float32), (4, 1, 1)),
        frame=np.arange(4),
        track=np.zeros(4, np.int64),
        image_size=np.array([[1920, 1024]], np.int32),
    )
    assert sim_vs_real.grid_rows(data).tolist() == [0, 1]


def test_table_flags_ratios_beyond_twenty_percent() -> None:
    real = {
        "variants": {"dense": {"moda": 50.0, "mota": None}, "marks9": {}},
        "cameras": [0.0, 0.1, 0.2, 0.3, 0.4],
        "outside": 5.0,
    }
    sim = {
        "dense.moda": 55.0, "dense.mota": 1.0, "marks9.moda": 70.0, "marks9.mota": 60.0,
        "dense.precision": 1.0, "dense.recall": 1.0, "marks9.precision": 1.0, "marks9.recall": 1.0,
        "cameras": [0.0, 0.1, 0.3, 0.3, 0.3], "outside": 7.0,
    }  # fmt: skip
    rows = {r[0]: r for r in sim_vs_real.table(real, sim)}
    assert rows["dense: per-frame MODA %"][3:] == ["1.10", "yes"]
    assert rows["dense: streamed MOTA %"][1].startswith("pending")
    assert rows["people boxed by 2 camera(s), %"][3:] == ["1.50", "**no**"]
    assert rows["boxes of people outside the area / frame"][3:] == ["1.40", "**no**"]
    assert "people boxed by 0 camera(s), %" not in rows


def test_benches_skip_with_one_line_without_data(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    assert sim_vs_real.main(["--data", str(tmp_path), "--out", str(tmp_path / "x.md")]) == 0
    assert cmc_detector.main(["--data", str(tmp_path), "--out", str(tmp_path / "x.json")]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 2 and all("skipped" in line for line in lines)
    assert not (tmp_path / "x.md").exists() and not (tmp_path / "x.json").exists()


def test_real_shares_carry_their_sampling_interval() -> None:
    """The block bootstrap's interval holds the share it resamples, and the table says when a
    simulated share outside the ±20 % band lies inside the real one's interval."""
    import dataclasses

    config = dataclasses.replace(PRESETS["cmc-room"], people=6, outside_people=0)
    frames = simulated_frames(Scene(config, seed=2), 80, "crowd")
    shares = cmc_detector.measure([frames])["cameras_per_person"]
    bands = sim_vs_real.share_intervals(frames, draws=300)
    assert len(bands) == 6
    for share, (low, high) in zip([*shares, sum(shares[:3])], bands, strict=True):
        assert low - 1e-9 <= share <= high + 1e-9 and low <= high
    real = {"variants": {}, "cameras": [0.0, 0.04, 0.2, 0.4, 0.36], "outside": 5.0,
            "cameras_interval": [(0, 0), (0.028, 0.046), (0.17, 0.25), (0.3, 0.5), (0.3, 0.4),
                                 (0.2, 0.3)]}  # fmt: skip
    sim = {"cameras": [0.0, 0.03, 0.15, 0.4, 0.42], "outside": 5.0}
    sim.update({f"{v}.{k}": 1.0 for v in sim_vs_real.VARIANTS for k in sim_vs_real.FIGURES})
    rows = {r[0]: r for r in sim_vs_real.table(real, sim)}
    one = rows["people boxed by 1 camera(s), %"]
    assert one[1] == "4.0 (95 %: 2.8 to 4.6)"
    assert one[4] == "**no**, within the real interval"
    assert rows["people boxed by 2 camera(s), %"][4] == "**no**"  # 15 % of 20 %: outside both

"""The simulated-vs-real CMC benchmark's pieces: pairing, grid rows, the table, the skip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.real import cmc_detector, sim_vs_real
from bench.real.cmc_pairing import floor_point, iou, pair, project, simulated_frames
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

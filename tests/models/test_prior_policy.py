"""The localizer policy: floor-mark data uses the geometry prior, dense walks use MoM."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from models.prior_policy import attach_floor_prior, choose_policy, label_coverage
from models.simulate import simulate
from service.setup.collector import DatasetAppender, collect, plan_steps
from service.setup.feeds import SyntheticFeed
from service.setup.marks import grid_marks


def _marks(tmp_path: Path, grid: str = "3x3", seconds: float = 4.0):
    feed = SyntheticFeed("indoor-2cam", 3)
    steps = plan_steps(grid_marks(grid, "10x10"), seconds, start=(5.0, 5.0))
    feed.prepare(steps)
    return collect(feed, steps, DatasetAppender(tmp_path / "m.npz", feed.image_sizes)).path


def test_coverage_of_marks_and_of_dense_walks() -> None:
    marks = np.array([[x, y] for x in (1.0, 5.0, 9.0) for y in (1.0, 5.0, 9.0)])
    assert label_coverage(np.repeat(marks, 50, axis=0)) < 0.05
    dense = np.random.default_rng(0).uniform(0, 10, size=(20000, 2))
    assert label_coverage(dense) > 0.95


def test_marks_choose_the_prior_and_dense_data_chooses_mom(tmp_path: Path) -> None:
    from models.dataset import MomDataset

    entry, prior = choose_policy(MomDataset.load(_marks(tmp_path)), "bbox")
    assert entry["policy"] == "prior" and prior is not None and entry["prior"] is not None
    dense = simulate("indoor-2cam", frames=1500, seed=4).dataset
    entry, _ = choose_policy(dense, "bbox")
    assert entry["policy"] == "mom", entry["reason"]


def test_attach_writes_the_entry_into_model_json(tmp_path: Path) -> None:
    from models.dataset import MomDataset

    data = MomDataset.load(_marks(tmp_path, "2x2"))
    (tmp_path / "model.json").write_text(json.dumps({"format": "mom-model-v1"}))
    summary = attach_floor_prior(data, tmp_path, "bbox")
    meta = json.loads((tmp_path / "model.json").read_text())
    assert meta["format"] == "mom-model-v1"
    assert meta["floor_prior"]["policy"] == summary["policy"] == "prior"
    assert "prior" not in summary and meta["floor_prior"]["prior"]["cameras"]


def test_degenerate_marks_fall_back_to_mom(tmp_path: Path) -> None:
    from models.dataset import MomDataset

    data = MomDataset.load(_marks(tmp_path, "1x3"))  # three marks on a line: no homography
    entry, prior = choose_policy(data, "bbox")
    assert prior is None and entry["policy"] == "mom" and "no floor prior" in entry["reason"]


def test_model_trained_on_marks_localizes_the_whole_room_with_the_prior(tmp_path: Path) -> None:
    """Train on 9 marks, test on people walking everywhere: the geometry carries the room."""
    from models.dataset import MomDataset
    from models.evaluate import score
    from models.mom_runtime import MomRuntime
    from models.train import train_model

    data = MomDataset.load(_marks(tmp_path, "3x3", 6.0))
    metrics = train_model(data, tmp_path / "model", epochs=5, progress=False)
    assert metrics["floor_prior"]["policy"] == "prior"
    runtime = MomRuntime.load(tmp_path / "model")
    assert runtime.policy == "prior"
    test = simulate("indoor-2cam", frames=400, seed=3).dataset
    with_prior = score(runtime.localize(test.boxes), test).metrics
    encoder_only = score(runtime._encode(test.boxes), test).metrics
    assert with_prior["mean"] < 0.3, with_prior
    assert with_prior["mean"] < 0.6 * encoder_only["mean"], (with_prior, encoder_only)

"""The never-worse gate: a candidate model worse on either check is never served."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import service.learning.improve as improve
from models.data.dataset import MomDataset
from service.learning.gate import (
    HELD_OUT_BLOCK_S,
    Score,
    held_out,
    judge,
    labels_error,
    marks_error,
    score,
)
from service.learning.labels import LabelBatch
from service.learning.listener import SelfLabeler
from tests.service.learning.frames import SIZES
from tests.service.mom_doubles import ModelDouble


class Line(ModelDouble):
    """A model double: camera k's box left edge / 100 is x, top edge / 100 is y, plus a bias
    per camera; fused = the mean of the seen cameras."""

    num_cameras = 2
    image_sizes = SIZES

    def __init__(self, bias: tuple[float, float] = (0.0, 0.0), name: str = "m") -> None:
        self.bias = np.array(bias)
        self.model_dir = Path(name)
        self.meta = {"name": name}

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        per_camera = boxes[..., :2] / 100.0 + self.bias[None, :, None]
        return np.nanmean(per_camera, axis=1)

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray:
        return np.zeros(len(boxes))


def boxes_at(world: np.ndarray) -> np.ndarray:
    """Boxes whose left/top edge encode ``world`` in both cameras (``Line`` reads them)."""
    corner = world * 100.0
    box = np.concatenate([corner, corner + np.array([40.0, 150.0])], axis=-1)
    return np.stack([box, box], axis=1).astype(np.float32)


def marks_dataset() -> MomDataset:
    world = np.repeat(np.array([[1.0, 1.0], [4.0, 1.0], [1.0, 3.0], [4.0, 3.0]]), 20, axis=0)
    n = len(world)
    return MomDataset(
        world=world.astype(np.float32),
        boxes=boxes_at(world),
        frame=np.arange(n),
        track=np.repeat(np.arange(4), 20),
        image_size=SIZES,
    )


def labels_batch(n: int = 400, seconds: float = 600.0) -> LabelBatch:
    rng = np.random.default_rng(3)
    world = rng.uniform(0.5, 4.5, (n, 2))
    return LabelBatch(
        t=np.linspace(0, seconds, n),
        track=np.arange(n) % 3,
        world=world.astype(np.float32),
        covariance=np.tile(np.eye(2, dtype=np.float32) * 0.0025, (n, 1, 1)),
        boxes=boxes_at(world),
        keypoints=np.full((n, 2, 17, 3), np.nan, np.float32),
        cost=np.full(n, 5.0, np.float32),
    )


def test_the_checks_measure_what_they_say() -> None:
    marks, labels = marks_dataset(), labels_batch()
    assert marks_error(Line(), marks) == (0.0, 0.0)
    biased = marks_error(Line((0.3, 0.3)), marks)
    assert biased is not None and biased[0] == pytest.approx(0.3 * np.sqrt(2), abs=1e-3)
    assert labels_error(Line(), labels) == 0.0
    assert labels_error(Line((0.2, 0.0)), labels) == pytest.approx(0.1 * np.sqrt(2), abs=1e-3)
    hold = held_out(labels)
    assert 0.15 < hold.mean() < 0.25
    blocks = np.floor(labels.t / HELD_OUT_BLOCK_S)
    assert all(len(set(hold[blocks == b])) == 1 for b in np.unique(blocks))  # whole blocks


def test_a_worse_candidate_is_never_served() -> None:
    marks, labels = marks_dataset(), labels_batch()
    current = score(Line((0.05, 0.05)), marks, labels)
    worse_on_marks = score(Line((0.2, 0.2)), marks, labels)
    verdict = judge(current, worse_on_marks)
    assert not verdict.serve and "worse on the floor marks" in verdict.reason
    # better on the marks, worse on the held-out labels: kept as well
    better_marks_worse_labels = Score(0.0, (current.labels_m or 0) + 0.01, 4, labels.n)
    verdict = judge(current, better_marks_worse_labels)
    assert not verdict.serve and "worse on 400 held-out self-labels" in verdict.reason
    # equal: not served either (nothing gained, and a swap resets the camera checks)
    assert not judge(current, current).serve
    better = score(Line((0.0, 0.01)), marks, labels)
    verdict = judge(current, better)
    assert verdict.serve and "serving the new model" in verdict.reason


def test_no_marks_no_verdict_in_favour() -> None:
    assert not judge(Score(None, 0.3, 0, 10), Score(None, 0.1, 0, 10)).serve


class Serving:
    def __init__(self, runtime: Line) -> None:
        self.runtime = runtime
        self.reloaded: list[Path] = []

    def reload_model(self, model_dir: Any = None) -> dict[str, Any]:
        self.reloaded.append(Path(model_dir))
        return {}


def fake_train(recording: Path, staging: Path, options: list[str], nice_by: int = 19):
    """A child that writes a model directory as ``momloc train`` would (no torch needed)."""
    script = (
        f"import pathlib; p = pathlib.Path({str(staging)!r}); p.mkdir(); "
        "(p / 'encoder.onnx').write_text('x'); (p / 'model.json').write_text('{}')"
    )
    return subprocess.Popen(
        [sys.executable, "-c", script],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.parametrize("candidate_bias, served", [((0.4, 0.0), False), ((0.0, 0.0), True)])
def test_a_run_serves_only_a_better_model_and_keeps_the_current_one_otherwise(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, candidate_bias: tuple, served: bool
) -> None:
    monkeypatch.setattr(improve, "spawn_train", fake_train)
    marks = marks_dataset()
    marks.save(tmp_path / "marks.npz")
    labeler = SelfLabeler(tmp_path, threaded=False)
    current = Line((0.1, 0.1), "current")
    labeler._store_for(current)  # the room of the model in service
    assert labeler.store is not None
    labeler.store.add(labels_batch())
    serving = Serving(current)
    job = improve.Improver(
        tmp_path, labeler, serving, load=lambda path: Line(candidate_bias, "candidate")
    )
    verdict = job.run()
    assert verdict is not None and verdict.serve is served
    final = tmp_path / "model"
    if served:
        assert serving.reloaded == [final]
        learned = json.loads((final / "model.json").read_text())["learning"]
        assert learned["room"] == labeler.room and learned["parent"] == "current"
    else:
        assert serving.reloaded == [] and not final.exists()
        assert "kept the model in service" in job.status()["last"]["reason"]
    assert not (tmp_path / "learning" / str(labeler.room) / "candidate").exists()
    assert job.status()["state"] == "done"


def test_no_improvement_on_marks_that_no_longer_match_a_repaired_camera(tmp_path: Path) -> None:
    marks_dataset().save(tmp_path / "marks.npz")
    repaired = Line((0.0, 0.0), "repaired")
    repaired.meta = {"learning": {"repaired": {"camera": 1}}}
    labeler = SelfLabeler(tmp_path, threaded=False)
    job = improve.Improver(tmp_path, labeler, Serving(repaired))
    assert job.run() is None
    assert job.status()["state"] == "failed" and "record the marks again" in job.status()["error"]


def test_the_marks_check_tolerates_no_more_than_its_own_standard_error() -> None:
    current = Score(0.070, 0.30, 4, 100, marks_se_m=0.004)
    assert judge(current, Score(0.073, 0.25, 4, 100)).serve  # within the check's noise
    refused = judge(current, Score(0.075, 0.25, 4, 100))
    assert not refused.serve and "worse on the floor marks" in refused.reason

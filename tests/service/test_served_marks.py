"""`momloc eval --served`: a floor-mark recording scored as the set-up check scores the live
stream, through the daemon's association and tracking, with a real trained model."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from models.data.dataset import MomDataset
from models.geometry import calibrated_baseline as baseline
from service.offline.served_marks import served_at_marks
from service.setup.collector import progress_path
from tests.models.test_evaluate import CAMERAS, _dataset

ROOT = Path(__file__).resolve().parents[2]
MARKS = [(x, y) for y in (1.0, 2.0, 3.0) for x in (1.0, 2.0, 3.0)]
ROWS_PER_MARK = 20
HEIGHT_M = 1.7


def _boxes(world: np.ndarray) -> np.ndarray:
    """[N, K, 4] exact boxes of a 1.7 m person standing at ``world`` [N, 2] (width 0.4 h)."""
    out = []
    for p in CAMERAS:
        foot = baseline.project(p, np.c_[world, np.zeros(len(world))])
        head = baseline.project(p, np.c_[world, np.full(len(world), HEIGHT_M)])
        half = 0.2 * (foot[:, 1] - head[:, 1])
        out.append(np.c_[foot[:, 0] - half, head[:, 1], foot[:, 0] + half, foot[:, 1]])
    return np.stack(out, axis=1)


def _mark_recording(walk_rows: int = 0) -> MomDataset:
    """One person on each mark for ROWS_PER_MARK frames, optionally walking between marks."""
    world = []
    for i, mark in enumerate(MARKS):
        world += [mark] * ROWS_PER_MARK
        if walk_rows and i + 1 < len(MARKS):
            world += list(np.linspace(mark, MARKS[i + 1], walk_rows + 2)[1:-1])
    world_array = np.array(world, dtype=np.float64)
    n = len(world_array)
    return MomDataset(
        world=world_array,
        boxes=_boxes(world_array),
        frame=np.arange(n),
        track=np.zeros(n, dtype=np.int64),
        image_size=np.array([[640, 480], [640, 480]]),
    )


@pytest.fixture(scope="module")
def marks_model(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    from models.mom.training.train import train_model

    folder = tmp_path_factory.mktemp("served")
    recording = _mark_recording()
    assert np.isfinite(recording.boxes).all()
    assert (recording.boxes[..., 2:] < 640).all() and (recording.boxes[..., :2] > 0).all()
    train_model(recording, folder / "model", epochs=3, seed=0, progress=False)
    meta = json.loads((folder / "model" / "model.json").read_text())
    assert meta["floor_prior"]["policy"] == "prior"  # marks: floor-mark geometry
    return folder / "model", folder


def test_exact_boxes_are_served_at_their_marks(marks_model: tuple[Path, Path]) -> None:
    model, folder = marks_model
    data = _mark_recording(walk_rows=6).save(folder / "walked.npz")
    summary = served_at_marks(model, data)
    per_mark = summary["per_mark"]
    # the walk's interpolated labels are not marks; every mark is, in recording order
    assert [(m["x"], m["y"]) for m in per_mark] == MARKS
    assert [m["name"] for m in per_mark] == [f"{x:.2f},{y:.2f}" for x, y in MARKS]
    assert all(m["rows"] == ROWS_PER_MARK for m in per_mark)
    # a track is served within a few frames of arriving and on every frame after
    assert all(ROWS_PER_MARK // 2 < m["samples"] <= ROWS_PER_MARK for m in per_mark), per_mark
    # exact boxes, a homography from exact marks: centimetres
    assert summary["marks"] == 9 and summary["unmeasured"] == 0
    assert all(m["error_m"] < 0.05 for m in per_mark), per_mark
    assert summary["median_m"] == pytest.approx(np.median([m["error_m"] for m in per_mark]))


def test_marks_seen_elsewhere_or_by_nobody(marks_model: tuple[Path, Path]) -> None:
    model, folder = marks_model
    arrays = _mark_recording().arrays()
    # no camera sees anybody at the first mark: nothing is served, the mark is not measured; at
    # the one before the last nobody either, and the stream holds the person where they were
    # last seen (the previous mark, 1 m away); at the last mark the boxes are of a person at the
    # first mark: 2.8 m from the label
    arrays["boxes"][:ROWS_PER_MARK] = np.nan
    last = slice(len(MARKS) * ROWS_PER_MARK - ROWS_PER_MARK, None)
    arrays["boxes"][last] = _boxes(np.array([MARKS[0]] * ROWS_PER_MARK))
    arrays["boxes"][last.start - ROWS_PER_MARK : last.start] = np.nan
    data = MomDataset(**arrays).save(folder / "moved.npz")
    progress_path(data).write_text(
        json.dumps(
            {
                "format": "momloc-collect-progress-v1",
                "done": [{"name": f"M{i}", "x": x, "y": y} for i, (x, y) in enumerate(MARKS)],
                "legacy_rows": 0,
            }
        )
    )
    done = subprocess.run(
        [sys.executable, "-m", "service.cli", "eval", str(model), str(data), "--served", "--json"],
        capture_output=True, text=True, cwd=ROOT, timeout=300, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert [m["name"] for m in summary["per_mark"]] == [f"M{i}" for i in range(len(MARKS))]
    unseen, *_, held, elsewhere = summary["per_mark"]
    assert unseen["error_m"] is None and unseen["samples"] == 0 and unseen["rows"] == 20
    assert held["error_m"] == pytest.approx(1.0, abs=0.05), held
    assert elsewhere["error_m"] == pytest.approx(np.hypot(2.0, 2.0), abs=0.05), elsewhere
    assert summary["marks"] == 8 and summary["unmeasured"] == 1 and summary["median_m"] < 0.05
    assert summary["text"].endswith("over 8 marks (1 not measured: nobody seen)")


def test_a_walk_has_no_marks_and_is_refused_in_one_line(tmp_path: Path) -> None:
    data = _dataset(60).save(tmp_path / "walk.npz")
    model = tmp_path / "model"
    model.mkdir()
    done = subprocess.run(
        [sys.executable, "-m", "service.cli", "eval", str(model), str(data), "--served"],
        capture_output=True, text=True, cwd=ROOT, timeout=300, check=False,
    )  # fmt: skip
    assert done.returncode == 2 and done.stdout == ""
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "no floor mark" in lines[0], done.stderr

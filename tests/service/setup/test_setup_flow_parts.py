"""Pieces of the web set-up flow: per-mark quality, forgetting a mark, the following person,
training failure lines, the check summary."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from models.data.dataset import MomDataset
from models.simulate import get_config
from models.simulate.following import SPEED_MPS, install_follower
from service.setup.check_score import summarise
from service.setup.collector import (
    DatasetAppender,
    FeedFrame,
    Step,
    collect,
    forget_mark,
    plan_steps,
    progress_path,
)
from service.setup.marks import FloorMark
from service.setup.quality import MarkQuality
from service.setup.training import failure_reason

SIZES = np.array([[640, 480], [640, 480]], np.int32)
BOX = np.array([[100.0, 50.0, 160.0, 250.0]], np.float32)
NONE = np.zeros((0, 4), np.float32)


class ScriptFeed:
    """10 frame sets per second; camera 1 sees the person only at mark ``blind_except``."""

    image_sizes = SIZES

    def __init__(self, seen_by_1: str) -> None:
        self.seen_by_1 = seen_by_1

    def prepare(self, steps: list[Step]) -> None:
        pass

    def frames(self, step: Step) -> Iterator[FeedFrame]:
        second = BOX if step.mark is not None and step.mark.name == self.seen_by_1 else NONE
        for i in range(round(step.seconds * 10)):
            yield FeedFrame(i / 10, [BOX, second], None)

    def close(self) -> None:
        """No cameras to release."""


def record(tmp_path: Path, marks: list[FloorMark]) -> tuple[MarkQuality, Path]:
    out = tmp_path / "room.npz"
    quality = MarkQuality(marks, 2)
    steps = plan_steps(marks, 2.0, start=(0, 0), move_s=0.5, countdown_s=0.2)
    writer = quality.counting(DatasetAppender(out, SIZES))

    def progress(p) -> None:
        quality.frame(p.step, p.cameras_seeing)

    collect(ScriptFeed("b"), steps, writer, on_progress=progress)
    quality.finish()
    return quality, out


def test_quality_counts_frames_per_camera_and_names_the_weak_camera(tmp_path: Path) -> None:
    marks = [FloorMark("a", 1, 1), FloorMark("b", 2, 1)]
    quality, _ = record(tmp_path, marks)
    report = {q["mark"]: q for q in quality.report()}
    assert report["a"]["frames"] == 20 and report["a"]["kept"] == 20
    assert report["a"]["per_camera"] == [20, 0]
    assert report["b"]["per_camera"] == [20, 20] and report["b"]["warnings"] == []
    (warning,) = report["a"]["warnings"]
    assert warning.startswith("camera 1 saw you in 0 of 20 frames at a") and "again" in warning


def test_forget_mark_removes_its_rows_and_completion(tmp_path: Path) -> None:
    marks = [FloorMark("a", 1, 1), FloorMark("b", 2, 1)]
    _, out = record(tmp_path, marks)
    assert forget_mark(out, marks[0]) == 20
    data = MomDataset.load(out)
    assert data.n == 20 and np.allclose(data.world[:, :2], [2, 1])
    again = DatasetAppender(out, SIZES)
    assert not again.has_mark(marks[0]) and again.has_mark(marks[1])
    assert forget_mark(out, marks[1]) == 20
    assert not out.exists() and not progress_path(out).exists()


def test_following_person_walks_to_the_target_then_stands_there() -> None:
    from models.simulate import Scene

    scene = Scene(get_config("indoor-2cam", people=1), seed=3)
    walker = install_follower(scene)
    target = (2.0, 8.0)
    walker.target = lambda: target
    start = np.array([5.0, 5.0])
    frames = int(np.linalg.norm(np.subtract(target, start)) / SPEED_MPS * scene.fps) + 30
    states = walker.states(0, frames + 60)
    assert np.linalg.norm(states.position[0, 0] - start) <= SPEED_MPS / scene.fps + 1e-9
    assert np.linalg.norm(states.position[-1, 0] - target) < 0.1  # standing, swaying a little
    # the same frames asked again (renderer and observation blocks) give the same person
    assert np.array_equal(walker.states(10, 20).position, states.position[10:20])
    observation = scene.observe(frames + 30)
    assert np.linalg.norm(observation.world[0, :2] - target) < 0.1


def test_training_failure_is_one_line() -> None:
    lines = ["Traceback (most recent call last):", "ModuleNotFoundError: No module named 'torch'"]
    assert "pip install" in failure_reason(lines, 1)
    cli = ["momloc train: error: x.npz: not a readable .npz file (not a zip archive)"]
    assert failure_reason(cli, 2) == "x.npz: not a readable .npz file (not a zip archive)"
    assert failure_reason([], -15) == "momloc train exited with code -15"


@pytest.mark.parametrize(
    ("errors", "text"),
    [
        ([0.1, 0.3, 0.2], "median 0.20 m over 3 marks"),
        ([0.05, None], "median 0.05 m over 1 mark (1 not measured: nobody seen)"),
        ([None], "nobody was seen on any of the 1 marks"),
    ],
)
def test_check_summary(errors: list[float | None], text: str) -> None:
    marks = [{"name": f"m{i}", "error_m": e} for i, e in enumerate(errors)]
    assert summarise(marks)["text"] == text


def test_check_summary_text_shows_the_stored_figure() -> None:
    """The page's line and the stored median are one number (CI saw 'median 0.06 m' beside
    median_m 0.065: the line was formatted from 0.0645, the figure rounded from it)."""
    summary = summarise([{"name": "a", "error_m": 0.064}, {"name": "b", "error_m": 0.065}])
    assert summary["median_m"] == 0.065
    assert summary["text"] == f"median {summary['median_m']:.2f} m over 2 marks"


def test_training_reports_the_kept_models_error_not_the_last_epochs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Early stopping keeps the best epoch, ``patience`` epochs before the last: the page's
    figure for the first and the final model is the kept one's (the closing summary)."""
    import json
    import subprocess
    import sys
    import time

    from service.setup import training

    def fake_train(
        recording: Path, staging: Path, options: list[str], nice_by: int = training.NICE
    ) -> subprocess.Popen[str]:
        lines = [
            {"epoch": e, "max_epochs": 3, "val_error_m": 0.5, "val_median_m": m}
            for e, m in ((1, 0.4), (2, 0.2), (3, 0.3))
        ] + [{"val_mean_m": 0.25, "val_median_m": 0.2, "epochs_run": 3, "stopped_by": "patience"}]
        script = (
            f"import pathlib; p = pathlib.Path({str(staging)!r}); p.mkdir(); "
            "(p / 'encoder.onnx').write_text(''); (p / 'model.json').write_text('{}'); "
            f"print({chr(10).join(json.dumps(line) for line in lines)!r})"
        )
        return subprocess.Popen(
            [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            text=True,
        )  # fmt: skip

    monkeypatch.setattr(training, "spawn_train", fake_train)
    (tmp_path / "rec.npz").write_bytes(b"")
    job = training.TrainingJob(lambda: tmp_path, lambda path: {"loaded": True})
    job.start(tmp_path / "rec.npz", first_model=True)
    deadline = time.monotonic() + 30
    while job.status()["state"] == "running" and time.monotonic() < deadline:
        time.sleep(0.02)
    done = job.status()
    assert done["state"] == "done", done
    assert done["epoch"] == 3  # the last epoch run
    assert done["val_median_m"] == done["first_model"]["val_median_m"] == 0.2  # the kept one
    assert done["val_error_m"] == 0.25

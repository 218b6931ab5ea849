"""Guided collection: plan, frame filter, nothing lost on interruption, resume, synthetic CLI."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from common.errors import MomlocError
from models.data.dataset import MomDataset
from service.setup.collector import (
    DatasetAppender,
    FeedFrame,
    Step,
    collect,
    frame_row,
    plan_steps,
    progress_path,
)
from service.setup.marks import FloorMark, grid_marks

SIZES = np.array([[640, 480], [640, 480]], np.int32)
BOX = np.array([[100.0, 50.0, 160.0, 250.0]], np.float32)
NONE = np.zeros((0, 4), np.float32)


class ListFeed:
    """A feed replaying fixed frames at 10 Hz; can fail after ``fail_after`` frames."""

    image_sizes = SIZES

    def __init__(self, frame: FeedFrame, fail_after: int | None = None) -> None:
        self.frame, self.fail_after, self.sent = frame, fail_after, 0

    def prepare(self, steps: list[Step]) -> None:
        pass

    def frames(self, step: Step) -> Iterator[FeedFrame]:
        for _ in range(round(step.seconds * 10)):
            if self.fail_after is not None and self.sent >= self.fail_after:
                raise KeyboardInterrupt
            self.sent += 1
            yield FeedFrame(self.sent / 10, self.frame.boxes, None)

    def close(self) -> None:
        """No cameras to release."""


def test_plan_has_move_countdown_record_and_walks() -> None:
    marks = [FloorMark("a", 0, 0), FloorMark("b", 3, 0)]
    steps = plan_steps(marks, 10, start=(0, 0), walk=True, move_s=5, countdown_s=2)
    assert [s.kind for s in steps] == ["move", "countdown", "record", "walk", "record"]
    walk = steps[3]
    assert walk.seconds == pytest.approx(3 / 0.6)
    assert walk.position(0.5) == (1.5, 0.0)
    with pytest.raises(MomlocError, match="--seconds"):
        plan_steps(marks, 0, start=(0, 0))


def test_frame_filter_keeps_one_person_frames_only() -> None:
    assert frame_row(FeedFrame(0, [BOX, BOX]), False) is not None
    row = frame_row(FeedFrame(0, [BOX, NONE]), False)
    assert row is not None
    boxes, _ = row
    assert np.isnan(boxes[1]).all() and np.isfinite(boxes[0]).all()
    assert frame_row(FeedFrame(0, [BOX, NONE]), True) is None
    assert frame_row(FeedFrame(0, [np.concatenate([BOX, BOX]), BOX]), False) is None
    assert frame_row(FeedFrame(0, [NONE, NONE]), False) is None


def test_interrupted_collection_keeps_recorded_rows(tmp_path: Path) -> None:
    out = tmp_path / "marks.npz"
    steps = plan_steps([FloorMark("a", 1, 2)], 10, start=(1, 2), move_s=1, countdown_s=1)
    feed = ListFeed(FeedFrame(0, [BOX, BOX]), fail_after=20 + 45)  # move+countdown, then 4.5 s
    with pytest.raises(KeyboardInterrupt):
        collect(feed, steps, DatasetAppender(out, SIZES))
    data = MomDataset.load(out)
    assert data.n == 45
    np.testing.assert_allclose(data.world, [[1, 2]] * 45)


def test_resume_appends_and_detects_recorded_marks(tmp_path: Path) -> None:
    out = tmp_path / "marks.npz"
    a, b = FloorMark("a", 1, 2), FloorMark("b", 3, 2)
    feed = ListFeed(FeedFrame(0, [BOX, BOX]))
    collect(feed, plan_steps([a], 2, start=(1, 2)), DatasetAppender(out, SIZES))
    writer = DatasetAppender(out, SIZES)
    assert writer.has_mark(a) and not writer.has_mark(b)
    collect(feed, plan_steps([b], 2, start=(1, 2)), writer)
    data = MomDataset.load(out)
    assert data.n == 40 and len(np.unique(data.track)) == 2
    assert (np.diff(data.frame) > 0).all()
    with pytest.raises(MomlocError, match="recorded with cameras"):
        DatasetAppender(out, np.array([[1280, 720]], np.int32))


def test_resume_records_a_partly_recorded_mark_again(tmp_path: Path) -> None:
    """Defect 5: a crash during a mark left rows there; that mark is not done, the rest are."""
    out = tmp_path / "marks.npz"
    a, b = FloorMark("A1", 1, 2), FloorMark("A2", 3, 2)
    steps = plan_steps([a, b], 2, start=(1, 2), move_s=1, countdown_s=1)
    # a: move 1 s + countdown 1 s + record 2 s = 40 frames; b: move 2 m (2 s) + countdown 1 s,
    # then the crash after 1 frame of b's recording
    crash = ListFeed(FeedFrame(0, [BOX, BOX]), fail_after=40 + 30 + 1)
    with pytest.raises(KeyboardInterrupt):
        collect(crash, steps, DatasetAppender(out, SIZES))
    assert MomDataset.load(out).n == 20 + 1
    writer = DatasetAppender(out, SIZES)
    assert writer.has_mark(a)
    assert not writer.has_mark(b) and writer.has_rows_at(b)
    collect(ListFeed(FeedFrame(0, [BOX, BOX])), plan_steps([b], 2, start=(3, 2)), writer)
    assert DatasetAppender(out, SIZES).has_mark(b)
    data = MomDataset.load(out)
    assert (np.abs(data.world - [3, 2]).max(axis=1) < 0.01).sum() == 1 + 20


def test_a_mark_stopped_part_way_is_not_done(tmp_path: Path) -> None:
    out = tmp_path / "marks.npz"
    a = FloorMark("A1", 1, 2)
    feed = ListFeed(FeedFrame(0, [BOX, BOX]), fail_after=20 + 5)
    with pytest.raises(KeyboardInterrupt):
        collect(
            feed,
            plan_steps([a], 2, start=(1, 2), move_s=1, countdown_s=1),
            DatasetAppender(out, SIZES),
        )
    assert not DatasetAppender(out, SIZES).has_mark(a)


def test_data_file_without_progress_file_keeps_the_old_rule(tmp_path: Path) -> None:
    out = tmp_path / "marks.npz"
    a, b = FloorMark("A1", 1, 2), FloorMark("A2", 3, 2)
    collect(
        ListFeed(FeedFrame(0, [BOX, BOX])),
        plan_steps([a], 2, start=(1, 2)),
        DatasetAppender(out, SIZES),
    )
    progress_path(out).unlink()  # as written before progress files existed
    writer = DatasetAppender(out, SIZES)
    assert writer.has_mark(a) and not writer.has_mark(b)
    collect(ListFeed(FeedFrame(0, [BOX, BOX])), plan_steps([b], 2, start=(3, 2)), writer)
    again = DatasetAppender(out, SIZES)
    assert again.has_mark(a) and again.has_mark(b)


def _momloc(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "service.cli", *args], capture_output=True, text=True, check=False
    )


def test_synthetic_collect_cli_records_every_mark(tmp_path: Path) -> None:
    out = tmp_path / "room.npz"
    args = ["collect", "--source", "synthetic", "--preset", "indoor-2cam", "--seed", "3"]
    result = _momloc(*args, "--grid", "2x2", "--seconds", "4", "--out", str(out))
    assert result.returncode == 0, result.stderr
    data = MomDataset.load(out)
    marks = {(m.x, m.y) for m in grid_marks("2x2", "10x10")}
    assert {tuple(p) for p in np.round(data.world.astype(float), 4)} == marks
    # 4 marks x 4 s x 15 fps; with the measured default detector profile (nanodet) 172 of 240
    # frames kept on 2026-12-01 (> 80 % under the former kind noise): a frame where a camera
    # misses the person and shows a false box, or shows two boxes, is not kept.
    assert data.n > 0.6 * 4 * 4 * 15
    again = _momloc(*args, "--grid", "2x2", "--seconds", "4", "--out", str(out))
    assert again.returncode == 0 and "already in" in again.stdout


def test_collect_cli_errors_are_one_line(tmp_path: Path) -> None:
    result = _momloc("collect", "--grid", "3x3", "--seconds", "5", "--out", str(tmp_path / "x"))
    assert result.returncode == 2
    assert result.stderr.strip().count("\n") == 0 and "--room" in result.stderr


@pytest.mark.parametrize(("grid", "room"), [("3x3", "...x4"), ("1x20000", "4x4")])
def test_collect_cli_bad_grid_or_room_is_one_line_exit_2(
    tmp_path: Path, grid: str, room: str
) -> None:
    """Defect 4: `--room ...x4` was a traceback and exit 1."""
    args = ["collect", "--source", "synthetic", "--grid", grid, "--room", room]
    result = _momloc(*args, "--seconds", "1", "--out", str(tmp_path / "x.npz"))
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().count("\n") == 0 and "Traceback" not in result.stderr


def test_live_feed_records_through_the_daemon_rig_and_detector_stage(tmp_path: Path) -> None:
    """The live path (settings -> rig -> detector stage) on the synthetic rig in real time."""
    from service.setup.feeds import LiveFeed

    config = tmp_path / "cams.yaml"
    config.write_text(
        "cameras: [{type: synthetic, index: 0}, {type: synthetic, index: 1}]\n"
        # the kind `ideal` profile on purpose: this checks the plumbing, and a measured
        # detector's misses and lasting false boxes can empty a 1 s recording (collect keeps
        # frames with exactly one box per camera)
        "synthetic: {preset: indoor-2cam, people: 1, fps: 20, detections: simulated,\n"
        "            detector_profile: ideal}\n"
    )
    feed = LiveFeed.from_config(str(config))
    try:
        assert feed.image_sizes.tolist() == [[640, 480], [640, 480]]
        steps = plan_steps([FloorMark("a", 5, 5)], 1.0, start=(5, 5), move_s=0.2, countdown_s=0.2)
        writer = collect(feed, steps, DatasetAppender(tmp_path / "live.npz", feed.image_sizes))
    finally:
        feed.close()
    assert 5 <= writer.new_rows <= 25  # about 1 s at 20 fps, frames with one person kept

"""The web-driven session: what a resumed collection reports, and that it plans the right marks."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.errors import MomlocError
from service.setup.collector import DatasetAppender, collect, plan_steps
from service.setup.marks import FloorMark, MarkIn, marks_from_entries
from service.setup.session import SetupSession
from tests.service.setup.test_collector import BOX, SIZES, FeedFrame, ListFeed


def _session(data_dir: Path) -> SetupSession:
    return SetupSession(data_dir, lambda: SIZES.tolist(), lambda tap: None, lambda tap: None)


def test_resume_reports_done_and_interrupted_marks(tmp_path: Path) -> None:
    """Issue 12, defect 5, through the web path: A2 was cut short, so it is recorded again."""
    a, b, c = FloorMark("A1", 1, 2), FloorMark("A2", 3, 2), FloorMark("A3", 5, 2)
    steps = plan_steps([a, b], 2, start=(1, 2), move_s=1, countdown_s=1)
    crash = ListFeed(FeedFrame(0, [BOX, BOX]), fail_after=40 + 30 + 1)  # 1 frame into A2
    with pytest.raises(KeyboardInterrupt):
        collect(crash, steps, DatasetAppender(tmp_path / "web.npz", SIZES))
    session = _session(tmp_path)
    status = session.start([a, b, c], 1.0, "web.npz", countdown_s=0, move_s=0)
    try:
        assert status["skipped_marks"] == ["A1"]
        assert status["incomplete_marks"] == ["A2"]
        assert status["steps"] == 2 * 3  # move, countdown, record for A2 and A3
    finally:
        session.stop()


def test_too_many_web_marks_are_refused(tmp_path: Path) -> None:
    entries = [MarkIn(name=f"m{i}", x=0.0, y=float(i)) for i in range(401)]
    with pytest.raises(MomlocError, match="401 marks, at most 400"):
        marks_from_entries(entries, "marks")

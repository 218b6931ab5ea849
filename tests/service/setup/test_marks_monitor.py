"""Floor marks parsing/grid and the camera-moved monitor's decision rule."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from common.errors import MomlocError
from service.camera_health.reprojection import CameraMotionMonitor
from service.setup.marks import FloorMark, grid_marks, load_marks, save_marks


def test_grid_marks_are_cell_centres_in_snake_order() -> None:
    marks = grid_marks("2x3", "6x4")
    assert [m.name for m in marks] == ["A1", "A2", "A3", "B3", "B2", "B1"]
    assert (marks[0].x, marks[0].y) == (1.0, 1.0)
    assert (marks[3].x, marks[3].y) == (5.0, 3.0)


@pytest.mark.parametrize(("grid", "room"), [("3", "4x5"), ("0x3", "4x5"), ("2.5x3", "4x5")])
def test_grid_rejects_bad_specs(grid: str, room: str) -> None:
    with pytest.raises(MomlocError, match="grid"):
        grid_marks(grid, room)


@pytest.mark.parametrize(
    ("grid", "room", "message"),
    [
        ("3x3", "...x4", "room '...x4': expected AxB"),
        ("3x3", "4x.", "room '4x.': expected AxB"),
        ("3x3", "1e9x4", "room '1e9x4': expected AxB"),
        ("3x3", "4000x4", "at most 1000 m"),
        ("...x3", "4x4", "grid '...x3': expected AxB"),
        ("1x20000", "4x4", "20000 marks, at most 400"),
        ("1x200000", "4x4", "at most 400"),
        ("26x9" + "9" * 5000, "4x4", "expected AxB"),
    ],
)
def test_grid_and_room_are_parsed_strictly_and_bounded(grid: str, room: str, message: str) -> None:
    """Defects 1 and 4: `...x4` used to crash float(); 1x20000 used to plan 20000 marks."""
    with pytest.raises(MomlocError, match=re.escape(message)):
        grid_marks(grid, room)


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ("{name: a, x: .nan, y: 2}", "entry 0 (a): x: must be a finite number"),
        ("{name: a, x: 1, y: .inf}", "entry 0 (a): y: must be a finite number"),
        ("{name: a, x: 1.0e+308, y: 2}", "entry 0 (a): x: Input should be less than or equal"),
        ("{name: a, x: false, y: 2}", "entry 0 (a): x: must be a number"),
        ("{name: a, x: '1.5', y: 2}", "entry 0 (a): x: must be a number"),
    ],
)
def test_marks_file_refuses_non_numbers_and_non_finite(
    tmp_path: Path, entry: str, message: str
) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(f"marks:\n  - {entry}\n")
    with pytest.raises(MomlocError, match=re.escape(message)):
        load_marks(path)


def test_marks_file_bounds_the_number_of_marks(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    entries = "".join(f"  - {{name: m{i}, x: {i % 10}, y: 1}}\n" for i in range(401))
    path.write_text("marks:\n" + entries)
    with pytest.raises(MomlocError, match="401 marks, at most 400"):
        load_marks(path)


def test_marks_round_trip(tmp_path: Path) -> None:
    marks = [FloorMark("door", 0.5, 1.0), FloorMark("sofa", 3.0, 2.25)]
    save_marks(marks, tmp_path / "m.yaml")
    assert load_marks(tmp_path / "m.yaml") == marks


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("marks: []", "non-empty list"),
        ("marks:\n  - {name: a, x: 1}", "entry 0 needs x and y"),
        ("marks:\n  - {name: a, x: one, y: 2}", "entry 0 \\(a\\): x: must be a number"),
        ("marks:\n  - {name: a, x: 1, y: 2}\n  - {name: a, x: 2, y: 2}", "duplicate mark name 'a'"),
        ("marks: [", "not valid YAML"),
    ],
)
def test_marks_file_errors_name_the_problem(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    with pytest.raises(MomlocError, match=message):
        load_marks(path)


def _feed(monitor: CameraMotionMonitor, t0: float, seconds: float, errors: list[float]) -> float:
    rng = np.random.default_rng(0)
    t = t0
    while t < t0 + seconds:
        frame = np.array([errors]) * rng.uniform(0.7, 1.3, size=(1, len(errors)))
        monitor.update(t, frame)
        t += 1 / 30
    return t


def test_monitor_flags_only_the_bumped_camera_after_hold_time() -> None:
    monitor = CameraMotionMonitor(2, warmup_s=5.0, hold_s=2.0, window_s=2.0)
    t = _feed(monitor, 0.0, 8.0, [3.0, 4.0])
    assert not any(s.moved for s in monitor.status())
    assert monitor.status()[0].baseline_px == pytest.approx(3.0, rel=0.15)
    t = _feed(monitor, t, 1.5, [3.0, 30.0])  # not long enough yet
    assert not monitor.status()[1].moved
    t = _feed(monitor, t, 4.0, [3.0, 30.0])
    status = monitor.status()
    assert status[1].moved and "camera 1" in (status[1].message or "")
    assert not status[0].moved
    _feed(monitor, t, 8.0, [3.0, 4.0])  # put back: the alert clears
    assert not monitor.status()[1].moved


def test_monitor_ignores_a_short_spike_and_unseen_frames() -> None:
    monitor = CameraMotionMonitor(1, baseline_px=[3.0], hold_s=2.0, window_s=1.0)
    t = _feed(monitor, 0.0, 3.0, [3.0])
    t = _feed(monitor, t, 0.5, [50.0])
    monitor.update(t, np.array([[np.nan]]))
    t = _feed(monitor, t, 3.0, [3.0])
    assert not monitor.status()[0].moved


def test_monitor_status_is_safe_while_the_pipeline_updates() -> None:
    """/v1/health reads status() while the pipeline thread updates (once a 500 in the suite)."""
    import sys
    import threading
    import time

    monitor = CameraMotionMonitor(2, window_s=0.5)  # ~500 samples: reads take a while
    stop = threading.Event()

    def pipeline() -> None:
        t = 0.0
        while not stop.is_set():
            t += 0.001
            monitor.update(t, np.full((1, 2), 5.0))

    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)  # switch threads often, as a loaded machine does
    thread = threading.Thread(target=pipeline)
    thread.start()
    try:
        deadline = time.monotonic() + 1.5
        while time.monotonic() < deadline:
            assert len(monitor.status()) == 2
    finally:
        stop.set()
        thread.join()
        sys.setswitchinterval(interval)

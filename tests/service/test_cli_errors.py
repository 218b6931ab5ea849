"""Issue 12: a path the OS refuses is one readable line and exit 2 for every command."""

from __future__ import annotations

import subprocess
import sys

import pytest

LONG = "x" * 300  # longer than any file-system name may be


@pytest.mark.parametrize(
    "args",
    [
        ["eval", LONG, f"{LONG}.npz"],
        ["detect", f"{LONG}.png"],
        ["simulate", "--preset", "indoor-2cam", "--frames", "2", "--seed", "1", "--out", LONG],
        ["collect", "--source", "synthetic", "--grid", "2x2", "--seconds", "1", "--out", LONG],
    ],
    ids=["eval", "detect", "simulate", "collect"],
)
def test_overlong_paths_are_one_line_and_exit_2(tmp_path, args):
    result = subprocess.run(
        [sys.executable, "-m", "service.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"momloc {args[0]}: error: "), lines
    assert len(lines[0]) < 400  # the path is shortened, not echoed whole

"""Serving never imports torch: `make demo` installs only the base package."""

from __future__ import annotations

import subprocess
import sys

SCRIPT = """
import sys
from service.api.app import create_app
from service.daemon import build_daemon
from service.demo import demo_settings
for mode in ("simulated", "rendered"):
    create_app(build_daemon(demo_settings(detections=mode)))
heavy = sorted(m for m in sys.modules if m.split(".")[0] in {"torch", "onnx", "matplotlib"})
print("HEAVY", heavy)
"""


def test_demo_daemon_builds_without_torch():
    result = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    assert "HEAVY []" in result.stdout

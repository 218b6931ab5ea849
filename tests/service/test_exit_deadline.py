"""After serving, the process ends even if a request is still running in a non-daemon thread."""

from __future__ import annotations

import subprocess
import sys
import time

SCRIPT = """
import threading, time
from service.api.server import _exit_soon_if_stuck
threading.Thread(target=time.sleep, args=(120,)).start()  # a request that does not end
_exit_soon_if_stuck(1.0)
"""


def test_a_stuck_worker_thread_does_not_keep_the_process_alive():
    started = time.monotonic()
    result = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert time.monotonic() - started < 30  # generous; without the deadline: 120 s
    assert "still running" in result.stderr

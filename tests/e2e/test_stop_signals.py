"""Issue 25, item 1: Ctrl-C (SIGINT) and SIGTERM stop every long-running command cleanly, keeping
what it wrote, however it was started (``service.stop_signals``).

Each command runs as a user's shell script or a supervisor starts it: the real CLI in a child
process that inherits SIGINT *ignored*, as a job started with ``&`` from a non-interactive shell
does (``trap '' INT`` then ``exec``: the shell sets the disposition, the command inherits it).
Python then installs no ``KeyboardInterrupt`` handler of its own, so only explicit handlers can
make the signal stop the command. Timeouts are generous: they bound a hang, they time nothing.
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from capture.recording import Recording
from models.data.dataset import MomDataset
from models.simulate import simulate
from service.demo import DEMO_PRESET, DEMO_SEED
from service.settings import DEMO_MODEL_DIR

pytestmark = pytest.mark.timeout(240)
ROOT = Path(__file__).resolve().parents[2]
STOP_WITHIN_S = 60.0  # a hang, not a speed: the commands stop in a second or two
SIGNALS = [signal.SIGINT, signal.SIGTERM]


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MOMLOC_")}
    return {**env, "PYTHONPATH": str(ROOT), **extra}


def start_ignoring_sigint(*args: object, **env: str) -> subprocess.Popen:
    """``momloc ARGS`` started the way ``momloc ARGS &`` in a script starts it: SIGINT ignored."""
    command = [sys.executable, "-m", "service.cli", *map(str, args)]
    return subprocess.Popen(
        ["sh", "-c", 'trap "" INT; exec "$0" "$@"', *command],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(**env),
        cwd=ROOT,
    )


def read_until(stream, pattern: str, proc: subprocess.Popen) -> re.Match:
    """Read ``stream`` until ``pattern`` matches (progress lines end in \\r, not newlines)."""
    seen = ""
    while (found := re.search(pattern, seen)) is None:
        char = stream.read(1)
        if not char:
            raise AssertionError(f"ended before {pattern!r} (exit {proc.poll()}): {seen[-2000:]}")
        seen += char
    return found


def stop(proc: subprocess.Popen, signum: int) -> tuple[str, str]:
    """Send ``signum``; the command must end (its outputs returned) instead of running on."""
    proc.send_signal(signum)
    try:
        return proc.communicate(timeout=STOP_WITHIN_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise AssertionError(f"still running {STOP_WITHIN_S:g} s after {signum!r}") from None


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_record_stops_with_its_manifest_and_track_accepts_the_folder(tmp_path, signum):
    config = tmp_path / "synthetic.yaml"
    config.write_text(
        "cameras:\n  - {type: synthetic, index: 0}\n  - {type: synthetic, index: 1}\n"
        f"synthetic: {{preset: {DEMO_PRESET}, seed: {DEMO_SEED}, people: 1, fps: 15}}\n"
    )
    rec = tmp_path / "rec"
    proc = start_ignoring_sigint("record", "--config", config, "--out", rec)
    try:
        read_until(proc.stderr, r"\b([5-9]|\d\d+) frame sets", proc)
        stdout, stderr = stop(proc, signum)
    finally:
        proc.kill()
    # an open-ended recording ends by a signal: that is its normal end
    assert proc.returncode == 0, stderr[-2000:]
    assert "frame sets in" in stdout
    assert (rec / "manifest.json").is_file()
    assert len(Recording.open(rec)) >= 5

    out = tmp_path / "positions.jsonl"
    tracked = subprocess.run(
        [sys.executable, "-m", "service.cli", "track", str(rec), "--model", str(DEMO_MODEL_DIR),
         "--out", str(out)],
        capture_output=True, text=True, env=_env(), cwd=ROOT, timeout=180,
    )  # fmt: skip
    assert tracked.returncode == 0, tracked.stderr[-2000:]
    assert len(out.read_text().splitlines()) == len(Recording.open(rec))


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_demo_daemon_stops(tmp_path, signum):
    port = _free_port()
    proc = start_ignoring_sigint(
        "demo", "--port", port, "--people", "1", "--detections", "simulated",
        MOMLOC_DATA_DIR=str(tmp_path),
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                health = httpx.get(f"http://127.0.0.1:{port}/v1/health", timeout=10).json()
                if health["pipeline"]["frames_processed"] > 5:
                    break
            except httpx.HTTPError:
                pass
            assert time.monotonic() < deadline and proc.poll() is None, "demo did not start"
            time.sleep(0.2)
        _, stderr = stop(proc, signum)
    finally:
        proc.kill()
    # a daemon told to stop has done its job: exit 0, no traceback, the port is free again
    assert proc.returncode == 0, stderr[-2000:]
    assert "Traceback" not in stderr
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", port))


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_collect_stops_keeping_the_rows_it_recorded(tmp_path, signum):
    out = tmp_path / "marks.npz"
    proc = start_ignoring_sigint(
        "collect", "--source", "synthetic", "--grid", "2x2", "--seconds", "3000",
        "--countdown", "0.5", "--move-seconds", "1", "--out", out,
    )  # fmt: skip
    try:
        # rows are flushed to the file every few seconds of (simulated) time
        deadline = time.monotonic() + 120
        while not out.is_file():
            assert time.monotonic() < deadline and proc.poll() is None, "nothing was written"
            time.sleep(0.2)
        stdout, stderr = stop(proc, signum)
    finally:
        proc.kill()
    assert proc.returncode == 128 + signum, stderr[-2000:]
    assert f"interrupted ({signal.Signals(signum).name})" in stderr
    assert "Traceback" not in stderr
    kept = MomDataset.load(out)
    assert kept.n > 0
    assert f"{kept.n} in total" in stdout


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_train_stops_and_leaves_no_partial_model(tmp_path, signum):
    data = tmp_path / "data.npz"
    simulate(DEMO_PRESET, frames=300, seed=0).dataset.save(data)
    out = tmp_path / "model"
    proc = start_ignoring_sigint(
        "train", data, "--out", out, "--epochs", "100000", "--quiet", "--progress-json"
    )
    try:
        read_until(proc.stdout, r'"epoch": 2,', proc)  # training is under way
        _, stderr = stop(proc, signum)
    finally:
        proc.kill()
    assert proc.returncode == 128 + signum, stderr[-2000:]
    assert "Traceback" not in stderr
    # the model is written atomically at the end: a stopped training leaves none, not half of one
    assert not (out / "model.json").exists()
    assert not list(tmp_path.rglob(".*.tmp"))  # common.atomic's temporary files


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_track_stops_and_keeps_the_former_output(tmp_path, signum):
    data = tmp_path / "scene.npz"
    simulate(DEMO_PRESET, frames=1500, seed=0).dataset.save(data)
    out = tmp_path / "positions.jsonl"
    out.write_text("the former run's positions\n")
    proc = start_ignoring_sigint(
        "track", "--detections", data, "--model", DEMO_MODEL_DIR, "--out", out
    )
    try:
        read_until(proc.stderr, r"tracking:.*\b[1-9]\d*/1500", proc)  # the progress bar moves
        _, stderr = stop(proc, signum)
    finally:
        proc.kill()
    assert proc.returncode == 128 + signum, stderr[-2000:]
    assert "Traceback" not in stderr
    # positions are written atomically: a stopped run leaves the former file, no temporary one
    assert out.read_text() == "the former run's positions\n"
    assert not list(tmp_path.glob(".*.tmp"))

"""Client toolchains for e2e tests, installed from Debian on first use (like chromium, mosquitto).

Toolchains come from Debian on first use (``tests.e2e.debian.ensure_debian``). The Unity
client is compiled with Mono's ``mcs`` against ``tests/unity/UnityEngineStub.cs`` (compiled first
into its own ``UnityEngine.dll``, as in Unity, so the client sees only the public stand-in API).
The Godot client runs in Debian's ``godot3-server`` (Godot 3.2.3 built without a renderer or a
window: it runs scripts with no display, no X server and no xvfb).
"""

from __future__ import annotations

import subprocess
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.e2e.debian import ensure_debian

ROOT = Path(__file__).resolve().parents[2]
UNITY_CLIENT = ROOT / "examples" / "unity" / "MoMLocalizerClient.cs"
UNITY_STUB = ROOT / "tests" / "unity" / "UnityEngineStub.cs"
UNITY_HARNESS = ROOT / "tests" / "unity" / "Harness.cs"
MONO_PACKAGES = ("mono-mcs", "mono-runtime", "libmono-system4.0-cil")
GODOT_CLIENT = ROOT / "examples" / "godot" / "momloc_client.gd"
GODOT_HARNESS = ROOT / "tests" / "godot" / "harness.gd"
GODOT = "godot3-server"


def compile_unity_harness(out_dir: Path) -> Path:
    """Compile the stub, then client + harness against it; returns the harness .exe."""
    ensure_debian(("mcs", "mono"), MONO_PACKAGES)
    stub = out_dir / "UnityEngine.dll"
    exe = out_dir / "Harness.exe"
    commands = (
        ["mcs", "-target:library", f"-out:{stub}", str(UNITY_STUB)],
        # -warnaserror: the client must compile cleanly, as Unity's console would show warnings
        [
            "mcs",
            "-warnaserror",
            f"-r:{stub}",
            "-r:System.Core.dll",
            f"-out:{exe}",
            str(UNITY_CLIENT),
            str(UNITY_HARNESS),
        ],
    )
    for command in commands:
        result = subprocess.run(command, capture_output=True, text=True, timeout=300)
        assert result.returncode == 0, f"{' '.join(command)}\n{result.stdout}\n{result.stderr}"
    return exe


def godot_command(work_dir: Path) -> list[str]:
    """The command that runs the Godot harness (arguments follow); Godot installed on first use.

    Godot without a project writes its log files to ``logs/`` under the working directory, so it
    runs in ``work_dir`` (``env -C``) rather than in the checkout.
    """
    ensure_debian((GODOT,), (GODOT,))
    # LANG: Godot takes its locale from LANG up to the '.', and "C" (C.UTF-8) makes it print two
    # ERROR lines at start. --no-window: no display anyway; -s: run a SceneTree script, no project.
    harness = [GODOT, "--no-window", "-s", str(GODOT_HARNESS), "--", str(GODOT_CLIENT)]
    return ["env", "-C", str(work_dir), "LANG=en_US.UTF-8", *harness]


class LineProcess:
    """A child process whose stdout lines are collected by a thread (nothing blocks on a pipe)."""

    def __init__(self, command: list[str], quit_line: str | None = "quit\n") -> None:
        """``quit_line``: what ends the child on stdin; None: it cannot read stdin, SIGTERM it."""
        self.quit_line = quit_line
        self.proc = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            bufsize=1,
        )
        self.lines: list[str] = []
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self._lock:
                self.lines.append(line.rstrip("\n"))

    def snapshot(self) -> list[str]:
        with self._lock:
            return list(self.lines)

    def wait_for(
        self, predicate: Callable[[list[str]], Any], timeout: float = 60.0, what: str = "output"
    ) -> Any:
        deadline = time.time() + timeout
        while time.time() < deadline:
            value = predicate(self.snapshot())
            if value:
                return value
            if self.proc.poll() is not None:
                break
            time.sleep(0.05)
        tail = "\n".join(self.snapshot()[-15:])
        raise AssertionError(
            f"timed out waiting for {what}; exit={self.proc.poll()}; last:\n{tail}"
        )

    def close(self) -> None:
        """Ask the child to quit ("quit" on stdin, or SIGTERM), kill it if it does not."""
        if self.proc.poll() is None:
            try:
                if self.quit_line is None:
                    self.proc.terminate()
                else:
                    assert self.proc.stdin is not None
                    self.proc.stdin.write(self.quit_line)
                    self.proc.stdin.close()
                self.proc.wait(timeout=15)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait(timeout=15)
        self._reader.join(timeout=5)


@pytest.fixture(scope="session")
def unity_harness(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The compiled Unity client console harness (Mono installed on first use)."""
    return compile_unity_harness(tmp_path_factory.mktemp("unity"))


@pytest.fixture(scope="session")
def godot_harness(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    """The command running tests/godot/harness.gd headless (godot3-server installed if missing)."""
    return godot_command(tmp_path_factory.mktemp("godot"))

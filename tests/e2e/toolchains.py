"""Client toolchains for e2e tests, installed from Debian on first use (like chromium, mosquitto).

Toolchains come from Debian on first use (``tests.e2e.debian.ensure_debian``). The Unity
client is compiled with Mono's ``mcs`` against ``tests/unity/UnityEngineStub.cs`` (compiled first
into its own ``UnityEngine.dll``, as in Unity, so the client sees only the public stand-in API).
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


class LineProcess:
    """A child process whose stdout lines are collected by a thread (nothing blocks on a pipe)."""

    def __init__(self, command: list[str]) -> None:
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
        if self.proc.poll() is None:
            try:
                assert self.proc.stdin is not None
                self.proc.stdin.write("quit\n")
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

"""Training from the web set-up: ``momloc train`` in a child process, followed live, hot-swapped.

Why a child process: training needs torch (the ``train`` extra) and a CPU core for minutes; in
the daemon's own process it would pull torch into serving (the architecture rule: serving
imports no torch) and fight the pipeline for the interpreter. The child runs at ``nice`` +10 so
the live pipeline keeps its frame rate on a 2-core machine (the ``nice`` program, not
``preexec_fn``: the daemon has threads, and code run between fork and exec can deadlock then),
and prints one JSON line per epoch (``momloc train --progress-json``), parsed here into
``epoch`` and ``val_error_m``.

Where the model goes: into ``data_dir/model.training`` first, then renamed to ``data_dir/model``
(the previous one kept as ``model.previous``), so a failed or cancelled run never touches the
model being served, and the watcher never sees a half-written directory. ``momloc serve`` without
``model_dir`` loads ``data_dir/model`` at the next start. Once in place, ``on_model(path)`` swaps
it into the running pipeline (``Pipeline.reload_model``).

A failure's reason is the child's last ``momloc train: error: ...`` line (the CLI's one-line
errors), or a line that says what is missing (torch not installed).
"""

from __future__ import annotations

import json
import logging
import shutil
import subprocess
import sys
import threading
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from models.atomic import replace_folder
from models.errors import MomlocError, shorten

log = logging.getLogger("momloc.setup.training")
NICE = 10
STOP_GRACE_S = 5.0


def model_path(data_dir: Path) -> Path:
    """Where the set-up flow's trained model lives (``momloc serve`` loads it when no
    ``model_dir`` is configured)."""
    return Path(data_dir) / "model"


class TrainingJob:
    """At most one training run; ``status()`` is the ``training`` object of /v1/setup/status."""

    def __init__(self, data_dir: Callable[[], Path], on_model: Callable[[Path], Any]) -> None:
        self._data_dir = data_dir
        self._on_model = on_model
        self._lock = threading.Lock()
        self._process: subprocess.Popen[str] | None = None
        self._cancelled = False
        self._state: dict[str, Any] = _idle()

    def start(self, recording: Path, epochs: int | None = None) -> dict[str, Any]:
        """Start ``momloc train recording``; MomlocError when one runs or the file is missing."""
        with self._lock:
            if self._process is not None and self._process.poll() is None:
                raise MomlocError("training is already running; cancel it first")
            if not recording.is_file():
                raise MomlocError(f"recording: {recording.name} does not exist; record marks first")
            final = model_path(self._data_dir())
            staging = final.with_name(final.name + ".training")
            shutil.rmtree(staging, ignore_errors=True)
            command = [
                sys.executable, "-m", "service.cli", "train", str(recording),
                "--out", str(staging), "--quiet", "--progress-json",
            ]  # fmt: skip
            if epochs is not None:
                command += ["--epochs", str(epochs)]
            nice = shutil.which("nice")  # exec's the command: same pid, so cancel still works
            if nice is not None:
                command = [nice, "-n", str(NICE), *command]
            self._process = subprocess.Popen(
                command,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                stdin=subprocess.DEVNULL,
                text=True,
            )
            self._cancelled = False
            self._state = {
                **_idle(),
                "state": "running",
                "recording": str(recording),
                "max_epochs": epochs,
                "model_dir": str(final.resolve()),
            }
            threading.Thread(
                target=self._follow,
                args=(self._process, staging, final),
                name="momloc-train-follow",
                daemon=True,
            ).start()
        return self.status()

    def _follow(self, process: subprocess.Popen[str], staging: Path, final: Path) -> None:
        errors: deque[str] = deque(maxlen=40)
        reader = threading.Thread(target=_drain, args=(process.stderr, errors), daemon=True)
        reader.start()
        assert process.stdout is not None
        for line in process.stdout:
            self._progress(line)
        code = process.wait()
        reader.join(timeout=5)
        if self._cancelled:
            self._finish("failed", error="training cancelled")
        elif code != 0:
            self._finish("failed", error=failure_reason(list(errors), code))
        else:
            try:
                _install(staging, final)
                info = self._on_model(final)
            except (MomlocError, OSError) as error:
                self._finish("failed", error=shorten(f"new model not loaded: {error}", 300))
                return
            self._finish("done", model=info)
        shutil.rmtree(staging, ignore_errors=True)

    def _progress(self, line: str) -> None:
        try:
            update = json.loads(line)
        except ValueError:
            return
        if not isinstance(update, dict):
            return
        if "epoch" in update:
            self._state.update(
                epoch=int(update["epoch"]),
                max_epochs=int(update["max_epochs"]),
                val_error_m=float(update["val_error_m"]),
            )
        elif "val_mean_m" in update:  # the closing summary
            self._state["metrics"] = {
                k: update[k]
                for k in ("val_mean_m", "val_median_m", "epochs_run", "stopped_by", "seconds")
                if k in update
            }

    def _finish(self, state: str, **fields: Any) -> None:
        self._state.update(state=state, **fields)
        if state == "failed":
            log.warning("training failed: %s", fields.get("error"))
        else:
            log.info("training done: model in %s", self._state["model_dir"])

    def cancel(self) -> dict[str, Any]:
        """Stop the running training (SIGTERM, SIGKILL after a grace period); no-op otherwise."""
        process = self._process
        if process is not None and process.poll() is None:
            self._cancelled = True
            process.terminate()
            try:
                process.wait(STOP_GRACE_S)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        return self.status()

    def status(self) -> dict[str, Any]:
        return dict(self._state)


def _idle() -> dict[str, Any]:
    return {"state": "idle", "epoch": None, "val_error_m": None, "model_dir": None, "error": None}


def _drain(stream: IO[str] | None, into: deque[str]) -> None:
    if stream is None:
        return
    for line in stream:
        if line.strip():
            into.append(line.strip())


def failure_reason(stderr: list[str], code: int) -> str:
    """One line saying why ``momloc train`` failed, from its standard error."""
    for line in reversed(stderr):
        if "momloc train: error:" in line:
            return shorten(line.split("error:", 1)[1].strip(), 300)
    if any("No module named 'torch'" in line for line in stderr):
        return "training needs PyTorch: pip install 'momloc[train]' (the train extra)"
    if stderr:
        return shorten(stderr[-1], 300)
    return f"momloc train exited with code {code}"


def _install(staging: Path, final: Path) -> None:
    """Put the new model in place: two directory renames, the old model kept as .previous."""
    if not (staging / "encoder.onnx").is_file() or not (staging / "model.json").is_file():
        raise MomlocError(f"{staging}: momloc train wrote no model")
    replace_folder(staging, final)

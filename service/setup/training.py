"""Training from the web set-up: ``momloc train`` in a child process, followed live, hot-swapped.

Why a child process: training needs torch (the ``train`` extra) and a CPU core for minutes; in
the daemon's own process it would pull torch into serving (the architecture rule: serving
imports no torch) and fight the pipeline for the interpreter. The child runs at ``nice`` +10 so
the live pipeline keeps its frame rate on a 2-core machine (the ``nice`` program, not
``preexec_fn``: the daemon has threads, and code run between fork and exec can deadlock then),
and prints one JSON line per epoch (``momloc train --progress-json``), parsed here into
``epoch``, ``val_error_m`` (the validation mean) and ``val_median_m`` (the median, which the
page shows: a nanodet recording's rows whose only box is a false box are metres off and set the
mean at 2.1-2.2 m while the served model's check measured 0.12 m, 2026-12-02).

Where the model goes: into ``data_dir/model.training`` first, then renamed to ``data_dir/model``
(the previous one kept as ``model.previous``), so a failed or cancelled run never touches the
model being served, and the watcher never sees a half-written directory. ``momloc serve`` without
``model_dir`` loads ``data_dir/model`` at the next start. Once in place, ``on_model(path)`` swaps
it into the running pipeline (``Pipeline.reload_model``).

Two stages (:class:`TrainingJob`): the adaptive schedule takes minutes (200-400 epochs, 2.5-6 min
measured on 2 loaded cores), which kept "Start to live positions" over the issue's 5 minutes on
its own. So the first stage trains for ``FIRST_MODEL_S`` seconds and is hot-loaded at once, and
the final model follows in the same job. Rejected: serving the floor prior alone as the first
model (the model directory and the runtime need an encoder; a second model format for seconds of
service is not worth it), and one child that writes an intermediate model (a model directory
written by a process that is still training is what the staging rename exists to avoid).

What it trains on: a snapshot of the recording, copied when the run starts
(``data_dir/model.recording/<name>.npz``), which every stage reads. Both stages then learn from the
same rows whatever happens to the recording meanwhile (``momloc collect`` into the same file from
a terminal; in the daemon the set-up's state machine, :mod:`service.setup.steps`, refuses
recording while training runs). Before it, each stage re-read the file: a first model on 185 rows,
the final on 258.

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
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from common.atomic import atomic_write, replace_folder
from common.errors import MomlocError, shorten
from service.setup.steps import SetupSteps

log = logging.getLogger("momloc.setup.training")
NICE = 10
STOP_GRACE_S = 5.0
# The first model's training time. Measured 2026-12-02 on a 3 x 3 x 20 s nanodet recording
# (2 cores, loaded): 10 s of epochs took 16 s wall with start-up and export, validation 0.12 m
# (91 epochs; 3 s / 10 epochs: 0.44 m). Marks recordings serve the floor-mark geometry
# (models.mom.prior_policy), which the first model fits in full, so its positions there are the
# final model's; the final training improves the encoder (the dense-data and fallback localizer).
FIRST_MODEL_S = 10.0


def model_path(data_dir: Path) -> Path:
    """Where the set-up flow's trained model lives (``momloc serve`` loads it when no
    ``model_dir`` is configured)."""
    return Path(data_dir) / "model"


class TrainingJob:
    """At most one training run; ``status()`` is the ``training`` object of /v1/setup/status.

    A run has one or two stages, each a ``momloc train`` child run in turn by one follower
    thread: with the adaptive schedule (no ``epochs``), first a quick model (``first_model``:
    ``FIRST_MODEL_S`` seconds of training) that is installed and hot-loaded at once, so
    positions are live while the final model trains; then the final model, installed over it
    (the first kept as ``model.first``, ``model.previous`` stays the model from before the run).
    ``state`` is ``running`` until the final stage ends; ``stage`` says which one runs and
    ``first_model`` what the first one gave.
    """

    def __init__(
        self,
        data_dir: Callable[[], Path],
        on_model: Callable[[Path], dict[str, Any]],
        steps: SetupSteps | None = None,
    ) -> None:
        self._data_dir = data_dir
        self._on_model = on_model
        self.steps = SetupSteps() if steps is None else steps
        # the child's priority below the daemon's (module docstring); a test of the flow on a
        # busy machine sets 0, so that the machine's other work does not starve the child
        self.nice_by = NICE
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._process: subprocess.Popen[str] | None = None
        self._cancelled = False
        self._state: dict[str, Any] = _idle()

    def start(
        self, recording: Path, epochs: int | None = None, first_model: bool | None = None
    ) -> dict[str, Any]:
        """Start training on ``recording``; MomlocError when one runs or the file is missing.
        ``first_model`` (default: only with the adaptive schedule) adds the quick first stage.
        Holds the set-up's ``train`` step until the run has ended."""
        self.steps.begin("train")
        try:
            return self._launch(recording, epochs, first_model)
        except BaseException:
            self.steps.end("train")
            raise

    def _launch(
        self, recording: Path, epochs: int | None, first_model: bool | None
    ) -> dict[str, Any]:
        with self._lock:
            if not recording.is_file():
                raise MomlocError(f"recording: {recording.name} does not exist; record marks first")
            final = model_path(self._data_dir())
            # its own name, so that the child's messages name the file the user chose
            snapshot = final.with_name(final.name + ".recording") / recording.name
            try:
                atomic_write(snapshot, lambda tmp: shutil.copyfile(recording, tmp))
            except OSError as error:
                raise MomlocError(f"recording: cannot take a copy to train on: {error}") from None
            stages: list[tuple[str, list[str]]] = []
            if epochs is None if first_model is None else first_model:
                stages.append(("first", ["--time-budget", f"{FIRST_MODEL_S:g}"]))
            stages.append(("final", [] if epochs is None else ["--epochs", str(epochs)]))
            self._cancelled = False
            self._state = {
                **_idle(),
                "state": "running",
                "stage": stages[0][0],
                "stages": [name for name, _ in stages],
                "first_model": None,
                "recording": str(recording),
                "max_epochs": epochs,
                "model_dir": str(final.resolve()),
            }
            self._thread = threading.Thread(
                target=self._run,
                args=(snapshot, stages, final),
                name="momloc-train-follow",
                daemon=True,
            )
            self._thread.start()
        return self.status()

    def _run(self, snapshot: Path, stages: list[tuple[str, list[str]]], final: Path) -> None:
        try:
            self._stages(snapshot, stages, final)
        except Exception as error:  # e.g. the child cannot be spawned: say so, never hang
            self._finish("failed", error=shorten(f"training could not run: {error}", 300))
        finally:
            shutil.rmtree(snapshot.parent, ignore_errors=True)
            self.steps.end("train")  # the status is final: the next step may start

    def _stages(self, recording: Path, stages: list[tuple[str, list[str]]], final: Path) -> None:
        first_loaded = False
        for name, options in stages:
            with self._lock:
                if self._cancelled:
                    break
                self._state.update(
                    stage=name, epoch=None, val_error_m=None, val_median_m=None, metrics=None
                )
                staging = final.with_name(final.name + ".training")
                shutil.rmtree(staging, ignore_errors=True)
                process = spawn_train(recording, staging, options, nice_by=self.nice_by)
                self._process = process
                started = time.monotonic()
            outcome = self._follow(process, staging, final, ".first" if first_loaded else None)
            if outcome is None:
                return  # failed or cancelled; the state says why
            if name == "first" and len(stages) > 1:
                first_loaded = True
                self._state["first_model"] = {
                    **self._kept_figures(),
                    "epochs": self._state.get("epoch"),
                    "seconds": round(time.monotonic() - started, 1),
                    "model": outcome,
                }
                log.info("first model loaded; final training continues")
                continue
            self._finish("done", model=outcome, **self._kept_figures())
            return
        self._finish("failed", error="training cancelled")

    def _follow(
        self, process: subprocess.Popen[str], staging: Path, final: Path, keep_as: str | None
    ) -> dict[str, Any] | None:
        """Follow one stage to its end; the loaded model's info, or None after a failure."""
        errors: deque[str] = deque(maxlen=40)
        reader = threading.Thread(target=drain, args=(process.stderr, errors), daemon=True)
        reader.start()
        assert process.stdout is not None
        for line in process.stdout:
            self._progress(line)
        code = process.wait()
        reader.join(timeout=5)
        try:
            if self._cancelled:
                self._finish("failed", error="training cancelled")
                return None
            if code != 0:
                self._finish("failed", error=failure_reason(list(errors), code))
                return None
            try:
                _install(staging, final, keep_as or ".previous")
                return self._on_model(final)
            except (MomlocError, OSError) as error:
                self._finish("failed", error=shorten(f"new model not loaded: {error}", 300))
                return None
        finally:
            shutil.rmtree(staging, ignore_errors=True)

    def _progress(self, line: str) -> None:
        update = progress_line(line)
        if update is None:
            return
        if "epoch" in update:
            self._state.update(
                epoch=int(update["epoch"]),
                max_epochs=int(update["max_epochs"]),
                val_error_m=float(update["val_error_m"]),
                val_median_m=float(update["val_median_m"]),
            )
        elif "val_mean_m" in update:  # the closing summary
            self._state["metrics"] = {
                k: update[k]
                for k in ("val_mean_m", "val_median_m", "epochs_run", "stopped_by", "seconds")
                if k in update
            }

    def _kept_figures(self) -> dict[str, Any]:
        """The installed model's validation errors: the stage's closing summary (early stopping
        keeps the best epoch, up to ``patience`` epochs before the last one), else the last
        epoch's."""
        summary = self._state.get("metrics") or {}
        return {
            "val_error_m": summary.get("val_mean_m", self._state.get("val_error_m")),
            "val_median_m": summary.get("val_median_m", self._state.get("val_median_m")),
        }

    def _finish(self, state: str, **fields: Any) -> None:
        self._state.update(state=state, **fields)
        if state == "failed":
            if self._state.get("first_model") is not None:
                self._state["error"] = f"{self._state['error']} (the first model stays loaded)"
            log.warning("training failed: %s", self._state.get("error"))
        else:
            log.info("training done: model in %s", self._state["model_dir"])

    def cancel(self) -> dict[str, Any]:
        """Stop the running training (SIGTERM, SIGKILL after a grace period); no-op otherwise."""
        with self._lock:
            thread = self._thread
            if thread is None or not thread.is_alive():
                return self.status()
            self._cancelled = True  # no further stage starts
            process = self._process
        if process is not None and process.poll() is None:
            process.terminate()
            try:
                process.wait(STOP_GRACE_S)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        thread.join(timeout=STOP_GRACE_S)
        return self.status()

    def status(self) -> dict[str, Any]:
        return dict(self._state)


def spawn_train(
    recording: Path, staging: Path, options: list[str], nice_by: int = NICE
) -> subprocess.Popen[str]:
    """``momloc train recording --out staging`` at low priority (``nice_by``), progress as JSON
    lines (also used by the room's self-improvement, ``service.learning.improve``)."""
    command = [
        sys.executable, "-m", "service.cli", "train", str(recording),
        "--out", str(staging), "--quiet", "--progress-json", *options,
    ]  # fmt: skip
    nice = shutil.which("nice")  # exec's the command: same pid, so cancel still works
    if nice is not None:
        command = [nice, "-n", str(nice_by), *command]
    return subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
    )


def progress_line(line: str) -> dict[str, Any] | None:
    """One line of the child's standard output as JSON (an epoch's progress or the closing
    summary), None for any other line."""
    try:
        update = json.loads(line)
    except ValueError:
        return None
    return update if isinstance(update, dict) else None


def _idle() -> dict[str, Any]:
    return {
        "state": "idle",
        "epoch": None,
        "val_error_m": None,
        "val_median_m": None,
        "model_dir": None,
        "error": None,
    }


def drain(stream: IO[str] | None, into: deque[str]) -> None:
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


def _install(staging: Path, final: Path, keep_as: str) -> None:
    """Put the new model in place: two directory renames, the old model kept as
    ``final + keep_as``."""
    if not (staging / "encoder.onnx").is_file() or not (staging / "model.json").is_file():
        raise MomlocError(f"{staging}: momloc train wrote no model")
    replace_folder(staging, final, keep_as)

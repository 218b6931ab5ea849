"""Self-improvement: retrain on floor marks + self-labels in the background, serve only a better
model.

When the room has gathered ``every_labels`` new self-labels since the last run, one run:

1. splits the labels into training and held-out rows (whole blocks, :func:`service.learning.
   gate.held_out`), refits the training labels' positions with every camera's floor map jointly
   (:func:`service.learning.training_set.aligned`) and writes the training set (the floor marks
   plus the weighted labels, :mod:`service.learning.training_set`) into the room's folder;
2. runs ``momloc train`` on it in a child process at ``nice`` + ``nice_by`` with a time budget
   (or a fixed number of epochs: the same work whatever the machine's load), exactly as the
   set-up page's Train button does (:mod:`service.setup.training`: a child process keeps torch
   out of the daemon and the CPU cap out of the pipeline's way), serving
   the floor geometry refitted on all rows (``--policy prior``): the labels' positions are the
   serving model's own, so no validation row can show its encoder beating that geometry
   (:mod:`models.mom.prior_policy`); its epochs show in the status (``epoch`` of
   ``max_epochs``), so a slow run on a busy machine is seen to move;
3. scores the candidate and the model in service on the same floor marks and held-out labels,
   row by row, and lets :func:`service.learning.gate.judge` decide (paired: only a candidate
   shown better beyond the checks' noise is served);
4. serves a winner like any trained model: installed as ``data_dir/model`` (the former one kept
   as ``model.previous``), hot-loaded through ``Pipeline.reload_model``, its ``model.json``
   saying it was learned by the room (``learning``: room, parent, verdict), so its labels keep
   going to the same room. A loser is deleted and the verdict says why it was not served.

The floor marks: ``learning.marks`` in the settings, else the newest ``.npz`` recording in
``data_dir`` (where the set-up page records). Without marks nothing is trained: the marks are
the room's only ground truth, and the gate would have nothing but the model's own labels to
judge by.
"""

from __future__ import annotations

import json
import logging
import shutil
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from common.atomic import atomic_write_json, replace_folder
from common.errors import MomlocError, shorten
from models.data.dataset import DatasetError, MomDataset
from service.learning.gate import Verdict, compare, held_out
from service.learning.listener import SelfLabeler
from service.learning.store import room_folder
from service.learning.training_set import aligned, training_set
from service.setup.training import drain, failure_reason, model_path, progress_line, spawn_train
from service.stages import LocalizationModel

log = logging.getLogger("momloc.learning")


class Serving(Protocol):
    """What the improver needs from the pipeline."""

    @property
    def runtime(self) -> LocalizationModel | None: ...

    def reload_model(self, model_dir: str | Path | None = None) -> dict[str, Any]: ...


@dataclass(frozen=True)
class ImproveOptions:
    """``learning`` settings of the background runs (``service.settings``); ``epochs`` (None:
    the adaptive schedule, stopped after ``time_budget_s``) caps the epochs instead."""

    every_labels: int = 2000
    nice_by: int = 19
    time_budget_s: float = 120.0
    epochs: int | None = None
    poll_s: float = 30.0


def newest_recording(data_dir: Path) -> Path | None:
    """The newest ``.npz`` directly in ``data_dir`` (the set-up page's recordings)."""
    found = sorted(Path(data_dir).glob("*.npz"), key=lambda p: p.stat().st_mtime)
    return found[-1] if found else None


class Improver:
    """At most one background run at a time (module docstring); ``status()`` for health."""

    def __init__(
        self,
        data_dir: Path,
        labeler: SelfLabeler,
        serving: Serving,
        *,
        marks: Path | None = None,
        options: ImproveOptions | None = None,
        load: Callable[[Path], LocalizationModel] | None = None,
        paused: Callable[[], bool] = lambda: False,
    ) -> None:
        self.data_dir = Path(data_dir)
        self.labeler = labeler
        self.serving = serving
        self.marks = marks
        self.options = options or ImproveOptions()
        self._load = load or _load_runtime
        # no run while a camera is flagged as moved (its labels are refused, its repair comes
        # first) or the set-up page trains (both would install data_dir/model)
        self._paused = paused
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._run_lock = threading.Lock()
        self._last_count = 0
        self.candidate: LocalizationModel | None = None  # the last run's, served or not
        self.state: dict[str, Any] = {"state": "waiting", "runs": 0, "served": 0, "last": None}

    # -- background ------------------------------------------------------------------------------

    def start(self) -> None:
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, name="momloc-improve", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)

    def _loop(self) -> None:
        while not self._stop.wait(self.options.poll_s):
            if self._paused():
                continue
            if self._count() - self._last_count >= self.options.every_labels:  # new labels
                try:
                    self.run()
                except Exception as error:  # never take the daemon down
                    log.exception("self-improvement run failed")
                    self.state.update(state="failed", error=shorten(str(error), 300))

    def _count(self) -> int:
        store = self.labeler.store
        return 0 if store is None else store.count

    # -- one run ---------------------------------------------------------------------------------

    def run(self) -> Verdict | None:
        """One run now (the loop calls it when enough labels are new; tests call it directly)."""
        with self._run_lock:
            self._last_count = self._count()
            self.state.update(
                state="training", started=time.time(), error=None, epoch=None, max_epochs=None
            )
            self.state["runs"] += 1
            try:
                verdict = self._run()
            except MomlocError as error:
                self.state.update(state="failed", error=str(error))
                log.warning("self-improvement: %s", error)
                return None
            self.state.update(state="done", last=verdict.as_dict(), finished=time.time())
            log.info("self-improvement: %s", verdict.reason)
            return verdict

    def _run(self) -> Verdict:
        current = self.serving.runtime
        if current is None:
            raise MomlocError("no model in service to improve")
        learned = current.meta.get("learning") or {}
        if learned.get("repaired"):
            raise MomlocError(
                f"camera {learned['repaired'].get('camera')} was repaired: the floor-mark "
                "recording shows it where it was before the bump; record the marks again to "
                "improve further"
            )
        room, store = self.labeler.room, self.labeler.store
        labels = None if store is None else store.load()
        if room is None or labels is None:
            raise MomlocError("no self-labels yet")
        marks = self._marks()
        hold = held_out(labels)
        if not hold.any() or hold.all():
            raise MomlocError(f"{labels.n} self-labels span too short a time to hold some out")
        folder = room_folder(self.data_dir, room)
        taught, placed, joint_fit = aligned(
            marks, labels.subset(~hold), seed=int(self.state["runs"])
        )
        self.state["joint_fit"] = joint_fit
        rows = training_set(marks, taught, seed=int(self.state["runs"]), placed=placed)
        recording = rows.save(folder / "training.npz")
        staging = folder / "candidate"
        shutil.rmtree(staging, ignore_errors=True)
        try:
            self._train(recording, staging)
            candidate = self._load(staging)
            self.candidate = candidate  # loaded in memory: benches score it against the truth
            verdict = compare(current, candidate, marks, labels.subset(hold))
            if verdict.serve:
                self._install(staging, room, verdict)
            return verdict
        finally:
            shutil.rmtree(staging, ignore_errors=True)

    def _marks(self) -> MomDataset:
        path = self.marks or newest_recording(self.data_dir)
        if path is None:
            raise MomlocError(
                f"no floor-mark recording in {self.data_dir} (learning.marks) to check against"
            )
        try:
            return MomDataset.load(path)
        except DatasetError as error:
            raise MomlocError(f"learning.marks: {error}") from None

    def _train(self, recording: Path, staging: Path) -> None:
        epochs = self.options.epochs
        if epochs is None:
            options = ["--time-budget", f"{self.options.time_budget_s:g}"]
        else:
            options = ["--epochs", str(epochs)]
        options += ["--policy", "prior"]
        process = spawn_train(recording, staging, options, nice_by=self.options.nice_by)
        errors: deque[str] = deque(maxlen=40)
        reader = threading.Thread(target=drain, args=(process.stderr, errors), daemon=True)
        reader.start()
        assert process.stdout is not None
        for line in process.stdout:
            if self._stop.is_set():
                process.terminate()
            update = progress_line(line)
            if update is not None and "epoch" in update:
                self.state.update(epoch=int(update["epoch"]), max_epochs=int(update["max_epochs"]))
        code = process.wait()
        reader.join(timeout=5)
        if self._stop.is_set():
            raise MomlocError("stopped")
        if code != 0:
            raise MomlocError(f"training failed: {failure_reason(list(errors), code)}")

    def _install(self, staging: Path, room: str, verdict: Verdict) -> None:
        meta_path = staging / "model.json"
        meta = json.loads(meta_path.read_text())
        parent = self.serving.runtime.model_dir if self.serving.runtime is not None else None
        meta["learning"] = {
            "room": room,
            "parent": None if parent is None else str(parent),
            "verdict": verdict.as_dict(),
            "time": time.time(),
        }
        atomic_write_json(meta_path, meta)
        final = model_path(self.data_dir)
        replace_folder(staging, final, ".previous")
        self.serving.reload_model(final)
        self.state["served"] += 1

    def status(self) -> dict[str, Any]:
        return {**self.state, "every_labels": self.options.every_labels}


def _load_runtime(path: Path) -> LocalizationModel:
    from models.mom.runtime import MomRuntime

    return MomRuntime.load(path)

"""Hot reload: swap the model when ``momloc train`` rewrites the model directory.

The watcher polls the signature (size and modification time) of ``encoder.onnx`` and
``model.json`` in the pipeline's current model directory. A change is acted on only once the
signature has stayed the same for one more poll, so a model still being written is never loaded
half-way. The swap goes through :meth:`Pipeline.reload_model`, which refuses a model that does not
fit the running cameras or does not run (``MomRuntime.load``'s test inference) and keeps the old
one; the outcome is kept for ``/v1/health``. A refused set of files is not retried until it
changes again.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any, Protocol

from common.errors import MomlocError
from common.worker_thread import WorkerThread

log = logging.getLogger("momloc.model_watch")
WATCHED = ("encoder.onnx", "model.json")

Signature = tuple[tuple[str, int, int], ...] | None


def signature(model_dir: Path | None) -> Signature:
    """(name, size, mtime_ns) of the watched files, or None when one is missing."""
    if model_dir is None:
        return None
    out = []
    for name in WATCHED:
        try:
            stat = (Path(model_dir) / name).stat()
        except OSError:
            return None
        out.append((name, stat.st_size, stat.st_mtime_ns))
    return tuple(out)


class Reloading(Protocol):
    """What the watcher needs of :class:`~service.pipeline.live.Pipeline`."""

    model_dir: Path | None

    def reload_model(self, model_dir: Path | None) -> dict[str, Any]: ...


class ModelWatcher:
    """Polls the pipeline's model directory and reloads it when its files change."""

    def __init__(self, pipeline: Reloading, interval_s: float = 2.0) -> None:
        self.pipeline = pipeline
        self.interval_s = interval_s
        self.last_reload: dict[str, Any] | None = None
        self._seen: Signature = signature(pipeline.model_dir)
        self._seen_dir = pipeline.model_dir
        self._pending: Signature = None
        self._worker = WorkerThread(self._run, "momloc-model-watch")
        self._stop = self._worker.stopping

    def start(self) -> None:
        self._worker.start()

    def stop(self) -> None:
        self._worker.stop()

    def _run(self) -> None:
        while not self._stop.wait(self.interval_s):
            self.poll()

    def poll(self) -> None:
        """One check (the thread calls this every ``interval_s``; tests call it directly)."""
        model_dir = self.pipeline.model_dir
        current = signature(model_dir)
        if model_dir != self._seen_dir:  # reloaded from elsewhere (REST): start from its state
            self._seen, self._seen_dir, self._pending = current, model_dir, None
            return
        if current is None or current == self._seen:
            self._pending = None
            return
        if current != self._pending:  # still changing, or just changed: wait one more poll
            self._pending = current
            return
        self._seen, self._pending = current, None
        try:
            info = self.pipeline.reload_model(model_dir)
            self.last_reload = {"time": time.time(), "ok": True, "path": str(model_dir)}
            log.info("model directory changed: reloaded %s", info.get("path"))
        except MomlocError as error:
            self.last_reload = {"time": time.time(), "ok": False, "error": str(error)}
            log.warning("model directory changed but the new model was refused: %s", error)

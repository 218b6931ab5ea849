"""The frame listener that collects self-labels while the daemon serves.

The pipeline hands every frame set's :class:`~service.stages.FrameResult` to its listeners on
its own thread (``service.pipeline.listeners``); this one only puts a reference into a bounded
queue and returns. A worker thread applies the rules (:func:`service.learning.labels.
select_labels`) and appends to the room's store (:mod:`service.learning.store`), so neither the
rules nor a slow disk can slow the pipeline: when the worker is behind, frame sets are dropped
(counted in ``dropped``), which costs labels, never frame rate. ``threaded=False`` runs the
worker's step inline (tests, offline benches: deterministic).

The store follows the model: a frame set localized by another model than the last one (a hot
reload) switches to that model's room (:func:`service.learning.store.room_key`).
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from service.learning.labels import BeyondMemory, LabelRules, select_labels
from service.learning.store import DEFAULT_MAX_BYTES, SelfLabelStore, room_folder, room_key
from service.stages import FrameResult, LocalizationModel

log = logging.getLogger("momloc.learning")
QUEUE_SIZE = 32


class SelfLabeler:
    """Frame listener: bounded queue -> rules -> the serving model's room store."""

    def __init__(
        self,
        data_dir: Path,
        *,
        rules: LabelRules | None = None,
        moved: Callable[[], set[int]] = set,
        max_bytes: int = DEFAULT_MAX_BYTES,
        threaded: bool = True,
        flush_s: float = 10.0,
    ) -> None:
        self.data_dir = Path(data_dir)
        self.rules = rules or LabelRules()
        self._moved = moved
        self.max_bytes, self.flush_s = max_bytes, flush_s
        self.threaded = threaded
        self._queue: queue.Queue[FrameResult | None] = queue.Queue(QUEUE_SIZE)
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._runtime: LocalizationModel | None = None
        self.store: SelfLabelStore | None = None
        self.room: str | None = None
        self._last_label: dict[int, float] = {}
        self._beyond = BeyondMemory()
        self.rejected: Counter[str] = Counter()
        self.dropped = 0
        self.frames = 0
        # called on the worker thread after the labels of each frame set, with the moved cameras
        self.followers: list[Callable[[FrameResult, set[int]], None]] = []

    def __call__(self, result: FrameResult) -> None:
        if result.runtime is None:
            return  # set-up mode: no positions to learn from
        if not self.threaded:
            self.step(result)
            return
        try:
            self._queue.put_nowait(result)
        except queue.Full:
            self.dropped += 1
            return
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="momloc-learning", daemon=True)
            self._thread.start()

    def _run(self) -> None:
        while True:
            result = self._queue.get()
            if result is None:
                return
            try:
                self.step(result)
            except Exception:  # never take the daemon down; the next frame set tries again
                log.exception("self-label step failed")

    def step(self, result: FrameResult) -> None:
        """Select one frame set's labels and keep them (the worker thread's job)."""
        store = self._store_for(result.runtime)
        if store is None:
            return
        moved = self._moved()
        selection = select_labels(result, self.rules, moved, self._last_label, self._beyond)
        with self._lock:
            self.frames += 1
            self.rejected.update(selection.rejected)
        if selection.labels is not None:
            store.add(selection.labels)
        for follower in self.followers:  # the self-healing job (service.learning.healer)
            follower(result, moved)

    def _store_for(self, runtime: LocalizationModel | None) -> SelfLabelStore | None:
        if runtime is None:
            return None
        if runtime is self._runtime:
            return self.store
        room = room_key(runtime.meta)
        with self._lock:
            if room != self.room:
                if self.store is not None:
                    self.store.flush()
                self.store = SelfLabelStore(
                    room_folder(self.data_dir, room),
                    runtime.image_sizes,
                    max_bytes=self.max_bytes,
                    flush_s=self.flush_s,
                )
                self.room = room
                self._last_label, self._beyond = {}, BeyondMemory()
            self._runtime = runtime
            return self.store

    def close(self) -> None:
        """Stop the worker and write what is pending."""
        if self._thread is not None:
            with contextlib.suppress(queue.Full):  # a stuck worker: given up after the join
                self._queue.put(None, timeout=2)
            self._thread.join(timeout=5)
            self._thread = None
        if self.store is not None:
            self.store.flush()

    def stats(self) -> dict[str, Any]:
        """``learning`` in ``/v1/health``: labels kept, rejected by reason, frame sets dropped."""
        store = self.store
        with self._lock:
            rejected = dict(self.rejected)
            frames = self.frames
        base = {"self_labels": 0, "stored_mb": 0.0, "max_mb": round(self.max_bytes / 1e6, 1)}
        return {
            "enabled": True,
            **(base if store is None else store.stats()),
            "room": self.room,
            "frames_seen": frames,
            "frames_dropped": self.dropped,
            "rejected": rejected,
        }

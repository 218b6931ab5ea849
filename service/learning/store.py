"""The self-label store: bounded, on disk, written atomically, one folder per room.

Layout: ``data_dir/learning/<room>/labels-<seq>.npz``, each file one flushed chunk of
:class:`~service.learning.labels.LabelBatch` rows plus the cameras' ``image_size``. Why chunks
and not one growing file: a chunk is written once, through :mod:`common.atomic` (a crash leaves
every earlier chunk whole and never a half-written one), and dropping the oldest labels to stay
under the cap is deleting a file, not rewriting the store. Rows wait in memory until
``flush_rows`` are pending or the oldest has waited ``flush_s``, so the disk sees a few writes a
minute, not one per frame.

Bound: after each flush the oldest chunks are deleted until the folder holds at most
``max_bytes`` (default 50 MB, ~100 000 labels with two cameras and keypoints): the newest labels
are the ones that describe the cameras as they are now.

*Room*: the labels belong to the floor frame of the floor marks a model was set up on. A model
trained from the set-up page names a new room (the SHA-256 of its ``model.json``); a model the
room learned itself (:mod:`service.learning.improve`) carries its parent's room in
``model.json["learning"]["room"]``, so learning goes on across its own models but starts afresh
with new marks (whose floor frame may differ).
"""

from __future__ import annotations

import hashlib
import json
import re
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from common.atomic import atomic_write
from service.learning.labels import FIELDS, LabelBatch

LEARNING = "learning"
CHUNK = re.compile(r"labels-(\d{6,})\.npz")
DEFAULT_MAX_BYTES = 50_000_000  # learning.max_mb's default; health reports MB of 10^6 bytes


def room_key(meta: dict[str, Any]) -> str:
    """The room a model's labels belong to (module docstring): 16 hex digits."""
    learned = meta.get("learning") or {}
    room = learned.get("room") if isinstance(learned, dict) else None
    if isinstance(room, str) and re.fullmatch(r"[0-9a-f]{16}", room):
        return room
    return hashlib.sha256(json.dumps(meta, sort_keys=True).encode()).hexdigest()[:16]


def room_folder(data_dir: Path, room: str) -> Path:
    return Path(data_dir) / LEARNING / room


class SelfLabelStore:
    """Append-only labels of one room, bounded on disk (module docstring); thread-safe."""

    def __init__(
        self,
        folder: Path,
        image_size: np.ndarray,
        *,
        max_bytes: int = DEFAULT_MAX_BYTES,
        flush_rows: int = 256,
        flush_s: float = 10.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.folder = Path(folder)
        self.image_size = np.asarray(image_size, np.int32)
        self.max_bytes, self.flush_rows, self.flush_s = int(max_bytes), flush_rows, flush_s
        self._clock = clock
        self._lock = threading.Lock()
        self._pending: list[LabelBatch] = []
        self._pending_rows = 0
        self._pending_since: float | None = None
        self._chunks: dict[int, tuple[int, int]] = {}  # seq -> (rows, bytes)
        self.write_error: str | None = None
        self._scan()

    def _scan(self) -> None:
        if not self.folder.is_dir():
            return
        for path in self.folder.iterdir():
            match = CHUNK.fullmatch(path.name)
            if match is None:
                continue
            try:
                with np.load(path) as data:
                    rows = int(data["t"].shape[0])
            except (OSError, ValueError, KeyError):
                continue  # not one of ours, or damaged: ignored, never read
            self._chunks[int(match.group(1))] = (rows, path.stat().st_size)

    # -- writing ---------------------------------------------------------------------------------

    def add(self, batch: LabelBatch) -> None:
        """Keep ``batch``; writes a chunk when one is due."""
        if batch.n == 0:
            return
        with self._lock:
            self._pending.append(batch)
            self._pending_rows += batch.n
            if self._pending_since is None:
                self._pending_since = self._clock()
            due = self._pending_rows >= self.flush_rows or (
                self._clock() - self._pending_since >= self.flush_s
            )
            if due:
                self._flush()

    def flush(self) -> None:
        """Write the pending labels now (at shutdown, before a training run reads the store)."""
        with self._lock:
            self._flush()

    def _flush(self) -> None:
        if not self._pending:
            return
        batch = LabelBatch.concat(self._pending)
        seq = max(self._chunks, default=0) + 1
        path = self.folder / f"labels-{seq:06d}.npz"
        arrays = {**batch.arrays(), "image_size": self.image_size}
        try:
            atomic_write(path, lambda tmp: _save(tmp, arrays))
        except OSError as error:  # a full disk: keep serving, say so in health, retry later
            self.write_error = f"{path}: {error.strerror or error}"
            self._pending_since = self._clock()
            return
        self.write_error = None
        self._chunks[seq] = (batch.n, path.stat().st_size)
        self._pending, self._pending_rows, self._pending_since = [], 0, None
        self._trim()

    def _trim(self) -> None:
        while len(self._chunks) > 1 and self._bytes() > self.max_bytes:
            oldest = min(self._chunks)
            (self.folder / f"labels-{oldest:06d}.npz").unlink(missing_ok=True)
            del self._chunks[oldest]

    def _bytes(self) -> int:
        return sum(size for _, size in self._chunks.values())

    # -- reading ---------------------------------------------------------------------------------

    @property
    def count(self) -> int:
        """Labels kept: on disk and waiting to be written."""
        with self._lock:
            return sum(rows for rows, _ in self._chunks.values()) + self._pending_rows

    @property
    def stored_bytes(self) -> int:
        with self._lock:
            return self._bytes()

    def load(self, since: float | None = None) -> LabelBatch | None:
        """Every label (written and pending) with ``t >= since``, oldest first; None if none."""
        with self._lock:
            self._flush()
            seqs = sorted(self._chunks)
        batches = []
        for seq in seqs:
            try:
                with np.load(self.folder / f"labels-{seq:06d}.npz") as data:
                    batch = LabelBatch.from_arrays({name: data[name] for name in FIELDS})
            except (OSError, ValueError, KeyError):
                continue  # trimmed meanwhile, or damaged
            if since is not None:
                batch = batch.subset(batch.t >= since)
            if batch.n:
                batches.append(batch)
        return LabelBatch.concat(batches) if batches else None

    def stats(self) -> dict[str, Any]:
        return {
            "self_labels": self.count,
            "stored_mb": round(self.stored_bytes / 1e6, 3),
            "max_mb": round(self.max_bytes / 1e6, 1),
            "write_error": self.write_error,
        }


def _save(path: Path, arrays: dict[str, np.ndarray]) -> None:
    with open(path, "wb") as handle:  # a file object: savez would append ".npz" to the name
        np.savez_compressed(handle, allow_pickle=False, **arrays)

"""The publisher contract: how outputs (zones, MQTT, ...) receive snapshots without slowing them.

:class:`service.pipeline.hub.Hub` calls ``offer(snapshot)`` for every snapshot, on the pipeline
thread, right after it makes it the newest. ``offer`` must return at once: it may do a few
microseconds of bounded work (the zone tracker's point-in-polygon tests) or store the snapshot in a
latest-value slot for a thread of its own (the MQTT publisher), but it never waits on a socket, a
lock held by I/O or an unbounded queue. An exception in ``offer`` is logged by the hub and the
pipeline goes on.

This is deliberately tiny; a general publisher registry (WebSocket hub, MQTT, file writer behind
one ``type`` key) can grow out of it.
"""

from __future__ import annotations

import threading
from typing import Any, Protocol, runtime_checkable

from service.snapshot import Snapshot


@runtime_checkable
class Publisher(Protocol):
    """An output fed by the hub."""

    name: str

    def offer(self, snapshot: Snapshot) -> None:
        """Take ``snapshot`` (pipeline thread; never blocks)."""
        ...

    def stats(self) -> dict[str, Any]:
        """Counters for ``/v1/health`` and ``/metrics``."""
        ...


class LatestSlot:
    """A one-item mailbox between threads: ``put`` overwrites (newest wins), ``take`` empties.

    ``overwritten`` counts values replaced before anyone took them (skipped by a slow reader).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._value: Any = None
        self.overwritten = 0

    def put(self, value: Any) -> None:
        with self._lock:
            if self._value is not None:
                self.overwritten += 1
            self._value = value

    def take(self) -> Any:
        with self._lock:
            value, self._value = self._value, None
            return value

    def peek(self) -> Any:
        with self._lock:
            return self._value

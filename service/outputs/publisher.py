"""How outputs (zones, MQTT, OSC) receive snapshots without slowing them.

The contract, :class:`Publisher` (``name``, ``offer`` that never blocks, ``stats``), is defined in
:mod:`service.snapshot` beside the value it takes, so the pipeline's hub types its publishers
without importing an output; it is re-exported here for the outputs.

Publishers that send over the network (MQTT, OSC) share :class:`ThreadedPublisher`: ``offer``
stores the snapshot in a :class:`LatestSlot` and wakes a sender thread of the publisher's own;
``start``/``stop`` run that thread with the app. Each declares the settings key it is built from
(``settings_key``) and builds itself from that section (``from_settings``):
``service.outputs.wiring.PUBLISHERS`` lists them, and a new output is one more entry there.
The zone monitor is a :class:`Publisher` but not threaded: it does its few microseconds of work on
the pipeline thread, so there is nothing to start. The Minecraft bridge is not a publisher of the
daemon at all: it is a WebSocket client of ``/v1/stream`` (``momloc bridge``).
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from common.worker_thread import WorkerThread
from service.snapshot import Publisher, Snapshot

__all__ = ["LatestSlot", "OutputContext", "Publisher", "ThreadedPublisher"]


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


@dataclass(frozen=True)
class OutputContext:
    """What a publisher may read of the daemon besides its own settings section."""

    health: Callable[[], dict[str, Any]]  # the small health summary (``wiring.health_summary``)
    occupancy: Callable[[], list[dict[str, Any]]]  # people per zone now
    zone_names: list[str]
    # the room's fall state now (``ZoneMonitor.fall_state``); None: falls are off
    fall_state: Callable[[], dict[str, Any] | None] = lambda: None


class ThreadedPublisher(ABC):
    """A publisher with a sender thread of its own, fed through a latest-value slot.

    ``offer`` (pipeline thread) never blocks: it overwrites the slot and wakes the sender only
    while it waits for a snapshot (``_hungry``, kept by the sender), not on every frame set.
    Subclasses write ``_run`` (loop until ``_stopping`` is set), ``stats`` and ``degraded``.
    """

    name: str
    settings_key: str  # the Settings attribute the publisher is built from

    def __init__(self) -> None:
        self._slot = LatestSlot()
        self._wake = threading.Event()
        self._sender = WorkerThread(self._run, f"momloc-{self.name}", join_s=3.0)
        self._stopping = self._sender.stopping
        self._hungry = True  # the sender waits for a snapshot (wake it only then)
        self.counters: dict[str, int] = {}
        self.last_error: str | None = None

    @classmethod
    @abstractmethod
    def from_settings(cls, settings: Any, context: OutputContext) -> ThreadedPublisher:
        """The publisher for its settings section (``settings_key``)."""

    def start(self) -> None:
        """Start the sender thread."""
        self._sender.start()

    def stop(self, timeout: float = 3.0) -> None:
        """Stop the sender thread (it finishes what it is sending)."""
        self._stopping.set()
        self._wake.set()  # a sender waiting for a snapshot sees the flag now
        self._sender.stop(timeout)

    def offer(self, snapshot: Snapshot) -> None:
        """Take ``snapshot`` (pipeline thread; never blocks)."""
        self._slot.put(snapshot)
        if self._hungry:
            self._wake.set()

    @abstractmethod
    def _run(self) -> None:
        """The sender thread: until ``_stopping`` is set."""

    @abstractmethod
    def stats(self) -> dict[str, Any]:
        """For ``/v1/health``."""

    @abstractmethod
    def degraded(self) -> str | None:
        """Why the output delivers nowhere now (``/v1/health`` says ``degraded``), or None."""

    def counters_exported(self) -> dict[str, int]:
        """Counters for ``/metrics`` as ``momloc_<name>_<key>`` (default: all of ``counters``)."""
        return dict(self.counters)

    def gauges_exported(self) -> dict[str, tuple[str, float]]:
        """Gauges for ``/metrics``: ``key -> (help, value)`` as ``momloc_<name>_<key>``."""
        return {}

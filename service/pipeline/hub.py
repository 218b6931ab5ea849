"""Fan-out of snapshots from the pipeline thread to REST, metrics and every WebSocket client.

Design: the hub keeps exactly one value per consumer. ``publish`` (any thread) replaces the newest
snapshot and, on the event loop, overwrites each subscriber's one-item slot and wakes it. A client
that reads slowly (or not at all) therefore skips snapshots instead of queueing them: memory per
client is constant and no client can delay another or the pipeline. The JSON text is encoded once
per snapshot, not once per client.

The value it fans out, and its wire format, are :mod:`service.snapshot`.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading

from service.snapshot import EMPTY, Publisher, Snapshot

log = logging.getLogger("momloc.hub")


class Subscription:
    """A WebSocket client's latest-value slot (lives on the event loop)."""

    def __init__(self) -> None:
        self._value: Snapshot | None = None
        self._event = asyncio.Event()
        self.delivered = 0
        self.skipped = 0

    def offer(self, snapshot: Snapshot) -> None:
        """Overwrite the slot (loop thread only); an unread value counts as skipped."""
        if self._value is not None:
            self.skipped += 1
        self._value = snapshot
        self._event.set()

    def take_nowait(self) -> Snapshot | None:
        """Empty the slot without waiting (None when nothing new arrived; the caller counts)."""
        value, self._value = self._value, None
        self._event.clear()
        return value

    async def next(self) -> Snapshot:
        """Wait for the slot to fill, then empty it."""
        await self._event.wait()
        self._event.clear()
        value, self._value = self._value, None
        assert value is not None
        self.delivered += 1
        return value


class Hub:
    """Newest snapshot for pollers, plus one :class:`Subscription` per streaming client."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._latest = EMPTY
        self._subscribers: set[Subscription] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._publishers: tuple[Publisher, ...] = ()  # zones, MQTT, OSC (service.outputs)
        self.published = 0
        self.sent = 0  # messages handed to clients
        self.sent_behind = 0  # ... of which a newer-by-2+ snapshot already existed
        self.max_behind = 0

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        """Attach the event loop that owns the subscribers (None detaches at shutdown)."""
        self._loop = loop

    def publish(self, snapshot: Snapshot) -> None:
        """Make ``snapshot`` the newest; safe from any thread, never blocks on clients."""
        with self._lock:
            self._latest = snapshot
            self.published += 1
        for publisher in self._publishers:
            try:
                publisher.offer(snapshot)
            except Exception:  # an output's bug must not stop the pipeline
                log.exception("publisher %s failed", publisher.name)
        loop = self._loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # loop closed since the check
                loop.call_soon_threadsafe(self._fan_out, snapshot)

    def add_publisher(self, publisher: Publisher) -> None:
        """Hand every snapshot to ``publisher.offer`` (pipeline thread; it must not block)."""
        self._publishers = (*self._publishers, publisher)

    def remove_publisher(self, publisher: Publisher) -> None:
        self._publishers = tuple(p for p in self._publishers if p is not publisher)

    def _fan_out(self, snapshot: Snapshot) -> None:
        for subscription in tuple(self._subscribers):
            subscription.offer(snapshot)

    def note_send(self, seq: int) -> int:
        """Record that ``seq`` is being sent; returns how many snapshots newer already exist.

        Server-side lag (loop thread only): >1 means the event loop could not keep up with the
        pipeline for this client, as opposed to the client or network being slow.
        """
        behind = self.latest().seq - seq
        self.sent += 1
        if behind > 1:
            self.sent_behind += 1
        self.max_behind = max(self.max_behind, behind)
        return behind

    def stream_stats(self) -> dict[str, int]:
        return {
            "clients": self.subscriber_count,
            "published": self.published,
            "sent": self.sent,
            "sent_behind": self.sent_behind,
            "max_behind": self.max_behind,
        }

    def latest(self) -> Snapshot:
        with self._lock:
            return self._latest

    def subscribe(self) -> Subscription:
        """New slot, pre-filled with the newest snapshot so a client gets data at once."""
        subscription = Subscription()
        latest = self.latest()
        if latest.seq > 0:
            subscription.offer(latest)
        self._subscribers.add(subscription)
        return subscription

    def unsubscribe(self, subscription: Subscription) -> None:
        self._subscribers.discard(subscription)

    @property
    def subscriber_count(self) -> int:
        return len(self._subscribers)

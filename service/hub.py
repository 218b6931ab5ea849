"""Fan-out of snapshots from the pipeline thread to REST, metrics and every WebSocket client.

Design: the hub keeps exactly one value per consumer. ``publish`` (any thread) replaces the newest
snapshot and, on the event loop, overwrites each subscriber's one-item slot and wakes it. A client
that reads slowly (or not at all) therefore skips snapshots instead of queueing them: memory per
client is constant and no client can delay another or the pipeline. The JSON text is encoded once
per snapshot, not once per client.

Wire format (version 1)::

    {"v": 1, "seq": 12, "t": 1732390000.123,
     "people": [{"id": 3, "x": 1.25, "y": 2.5, "vx": 0.4, "vy": 0.0,
                 "confidence": 0.9, "cameras": [0, 1]}]}

``t`` is the capture time of the frames the snapshot came from (unix seconds, wall clock), so a
client on the same host measures latency as receive time - ``t``. A person outside the floor area
the model was set up on carries ``"outside": true``, and only when the daemon is set to serve
them (``tracking.outside_area: flag``; by default they are not served at all).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

SCHEMA_VERSION = 1
log = logging.getLogger("momloc.hub")


@dataclass(frozen=True)
class Snapshot:
    """One published result; ``text`` is the exact JSON sent on the wire."""

    seq: int
    t: float
    people: list[dict[str, Any]]
    text: str = field(repr=False)

    @classmethod
    def build(cls, seq: int, t: float, people: Sequence[dict[str, Any]]) -> Snapshot:
        people = [dict(p) for p in people]
        body = {"v": SCHEMA_VERSION, "seq": seq, "t": t, "people": people}
        return cls(seq, t, people, json.dumps(body, separators=(",", ":")))

    def inside_only(self) -> Snapshot:
        """This snapshot without the people served flagged ``outside`` (the set-up area,
        ``service.chain``): what zones, counts and MQTT see unless asked for everyone."""
        if not any(p.get("outside") for p in self.people):
            return self
        return Snapshot.build(self.seq, self.t, [p for p in self.people if not p.get("outside")])

    def as_dict(self) -> dict[str, Any]:
        return {"v": SCHEMA_VERSION, "seq": self.seq, "t": self.t, "people": self.people}


EMPTY = Snapshot.build(0, 0.0, [])


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
        self._publishers: tuple[Any, ...] = ()  # service.publish.Publisher (zones, MQTT)
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
                log.exception("publisher %s failed", getattr(publisher, "name", publisher))
        loop = self._loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # loop closed since the check
                loop.call_soon_threadsafe(self._fan_out, snapshot)

    def add_publisher(self, publisher: Any) -> None:
        """Hand every snapshot to ``publisher.offer`` (pipeline thread; it must not block)."""
        self._publishers = (*self._publishers, publisher)

    def remove_publisher(self, publisher: Any) -> None:
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

"""Zones and falls in the running daemon: fed by the hub, events fanned out to clients and MQTT.

:class:`ZoneMonitor` is a :class:`service.outputs.publisher.Publisher`: the hub hands it every
snapshot on the pipeline thread, where it runs :class:`service.outputs.zones.ZoneTracker` (a few
point-in-polygon tests per person and zone: microseconds) and, unless falls are off,
:class:`service.outputs.falls.FallDetector`, gives their events one ``seq`` (one events stream)
and passes them on:

- to :class:`EventHub`, which fans them out to ``WS /v1/events`` clients. Unlike positions,
  events cannot be skipped (a missed leave would leave a room occupied forever), so each client
  gets a bounded queue; a client that falls ``max_queue`` events behind loses the oldest ones and
  the loss is counted (``dropped``), so memory stays bounded and nobody waits;
- to listeners (the MQTT publisher) as ``on_zone_events(events, occupancy)``, which must not block
  (fall events carry the room's fall state, ``falls``: the ids with an active fall).

A recent-events ring lets ``GET /v1/zones`` show what just happened without a WebSocket.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import threading
from collections import deque
from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

from service.outputs.falls import FallDetector
from service.outputs.zones import Zone, ZoneTracker
from service.snapshot import Snapshot

log = logging.getLogger("momloc.zones")


class EventSubscription:
    """One ``WS /v1/events`` client: a bounded queue of event JSON texts (loop thread only)."""

    def __init__(self, max_queue: int) -> None:
        self.queue: deque[str] = deque(maxlen=max_queue)
        self.event = asyncio.Event()
        self.dropped = 0

    def offer(self, text: str) -> None:
        if len(self.queue) == self.queue.maxlen:
            self.dropped += 1
        self.queue.append(text)
        self.event.set()

    async def next(self) -> str:
        while not self.queue:
            self.event.clear()
            await self.event.wait()
        return self.queue.popleft()


class EventHub:
    """Fans events from the pipeline thread out to WebSocket clients on the event loop."""

    def __init__(self, max_queue: int = 1000) -> None:
        self.max_queue = max_queue
        self._loop: asyncio.AbstractEventLoop | None = None
        self._subscribers: set[EventSubscription] = set()
        self.published = 0

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        self._loop = loop

    def publish(self, texts: Sequence[str]) -> None:
        """Any thread; never blocks."""
        self.published += len(texts)
        loop = self._loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(self._fan_out, tuple(texts))

    def _fan_out(self, texts: tuple[str, ...]) -> None:
        for subscription in tuple(self._subscribers):
            for text in texts:
                subscription.offer(text)

    def subscribe(self) -> EventSubscription:
        subscription = EventSubscription(self.max_queue)
        self._subscribers.add(subscription)
        return subscription

    def unsubscribe(self, subscription: EventSubscription) -> None:
        self._subscribers.discard(subscription)

    @property
    def subscriber_count(self) -> int:
        return len(self._subscribers)


@runtime_checkable
class ZoneListener(Protocol):
    """An output that also sends zone changes (the MQTT publisher)."""

    def on_zone_events(
        self, events: list[dict[str, Any]], occupancy: list[dict[str, Any]]
    ) -> None: ...


class ZoneMonitor:
    """Publisher that turns snapshots into zone occupancy and enter/leave events."""

    name = "zones"

    def __init__(
        self,
        zones: Sequence[Zone],
        events: EventHub | None = None,
        falls: FallDetector | None = None,
    ) -> None:
        self.tracker = ZoneTracker(zones)
        self.falls = falls
        self.events = events or EventHub()
        self._listeners: list[ZoneListener] = []
        self._lock = threading.Lock()  # occupancy is read by REST/metrics threads
        self.recent: deque[dict[str, Any]] = deque(maxlen=50)
        self.event_count = 0

    @property
    def zones(self) -> list[Zone]:
        return self.tracker.zones

    def add_listener(self, listener: ZoneListener) -> None:
        """``listener.on_zone_events(events, occupancy)`` after every snapshot with events."""
        self._listeners = [*self._listeners, listener]

    def offer(self, snapshot: Snapshot) -> None:
        if snapshot.seq <= 0:
            return
        people = snapshot.inside_only().people
        with self._lock:
            events = self.tracker.update(snapshot.t, people)
            if self.falls is not None:
                for event in self.falls.update(snapshot.t, people):
                    self.tracker.seq += 1  # one numbering for the whole events stream
                    events.append({"v": event["v"], "seq": self.tracker.seq, **event})
            if not events:
                return
            self.recent.extend(events)
            self.event_count += len(events)
            occupancy = self.tracker.occupancy()
        self.events.publish([json.dumps(e, separators=(",", ":")) for e in events])
        for listener in self._listeners:
            try:
                listener.on_zone_events(events, occupancy)
            except Exception:
                log.exception("zone listener failed")

    def occupancy(self) -> list[dict[str, Any]]:
        with self._lock:
            return self.tracker.occupancy()

    def fall_state(self) -> dict[str, Any] | None:
        """``{"active", "ids", "t"}`` of the room's falls; None when falls are off."""
        if self.falls is None:
            return None
        with self._lock:
            return self.falls.state()

    def describe(self) -> dict[str, Any]:
        """``GET /v1/zones``: polygons, occupancy, the fall state and the last events."""
        with self._lock:
            occupancy = {o["zone"]: o for o in self.tracker.occupancy()}
            recent = list(self.recent)[-20:]
            t = self.tracker.last_t
        described: dict[str, Any] = {
            "v": 1,
            "t": t,
            "zones": [{**z.as_dict(), **occupancy[z.name]} for z in self.zones],
            "recent_events": recent,
        }
        falls = self.fall_state()
        if falls is not None:
            described["falls"] = falls
        return described

    def stats(self) -> dict[str, Any]:
        return {
            "zones": len(self.zones),
            "events": self.event_count,
            "event_clients": self.events.subscriber_count,
            "falls": (self.fall_state() or {}).get("ids", []),
        }

"""MQTT publisher: positions, zone occupancy, events, availability and health to a broker.

Client choice: paho-mqtt 2.x (Eclipse; the client Home Assistant and aiomqtt themselves are built
on). The pipeline is a plain thread and the API's event loop belongs to uvicorn, so a client that
runs its own network thread (``loop_start``) and has last will, automatic reconnect with
exponential back-off and MQTT 3.1.1/5 built in fits better than aiomqtt, which would need an
asyncio loop of its own (or would compete with WebSocket clients on uvicorn's).

Topics (``{base}`` = ``mqtt.base_topic``, ``{room}`` = ``mqtt.room``):

==================================  ====  ========  ==========================================
topic                               QoS   retained  payload
==================================  ====  ========  ==========================================
``{base}/{room}/positions``         0     no        snapshot JSON v1 (``service.pipeline.hub``), <=
rate/s
``{base}/{room}/zones/{zone}``      1     yes       ``{"zone", "count", "ids", "t"}``, on change
``{base}/{room}/events``            1     no        enter/leave JSON (``service.outputs.zones``),
                                                    fall/fall_cleared (``service.outputs.falls``),
                                                    in order
``{base}/{room}/fall``              1     yes       ``{"active", "ids", "t"}``, on change (not
                                                    with ``falls.enabled: false``)
``{base}/{room}/availability``      1     yes       ``online`` on connect; ``offline`` as last
                                                    will and on clean shutdown
``{base}/{room}/health``            0     yes       health summary every ``health_interval_s``
==================================  ====  ========  ==========================================

Never slowing the pipeline (the design): ``offer`` (pipeline thread) only puts the snapshot in a
latest-value slot; zone changes overwrite a per-zone slot; events go to a bounded deque (oldest
dropped and counted). One sender thread of ours moves them to paho, whose own thread writes the
socket. paho queues QoS 0 messages without bound, so a broker that accepts the connection but
stops reading would grow memory forever: we therefore count the messages paho has not yet written
(``MQTTMessageInfo.is_published`` turns true when a QoS 0 message leaves the socket) and, past
``max_unsent``, drop new positions instead of handing them over. QoS 1 messages are bounded by
paho's ``max_queued_messages_set``. While the broker is away, positions are dropped (a stale
position is worthless), zone states and events wait, and paho reconnects with back-off; on every
(re)connect we publish ``online``, the discovery configs, every zone's occupancy and the fall
state again, so a broker restarted without persistence is whole again.
"""

from __future__ import annotations

import json
import logging
import secrets
import ssl
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from service.outputs.ha_discovery import discovery_messages
from service.outputs.publisher import OutputContext, ThreadedPublisher
from service.outputs.settings import MqttSettings
from service.snapshot import Snapshot

log = logging.getLogger("momloc.mqtt")

HealthSource = Callable[[], dict[str, Any]]


class MqttPublisher(ThreadedPublisher):
    """Publisher (see ``service.outputs.publisher``) to one broker; ``start`` / ``stop`` around
    serving."""

    name = "mqtt"
    settings_key = "mqtt"

    def __init__(
        self,
        settings: MqttSettings,
        *,
        health: HealthSource | None = None,
        occupancy: Callable[[], list[dict[str, Any]]] | None = None,
        discovery: Callable[[], list[tuple[str, str]]] | None = None,
        fall_state: Callable[[], dict[str, Any] | None] | None = None,
    ) -> None:
        super().__init__()
        self.settings = settings
        self._health = health
        self._occupancy = occupancy
        self._discovery = discovery
        self._fall_state = fall_state
        self._zones: dict[str, dict[str, Any]] = {}
        self._fall: dict[str, Any] | None = None  # the fall state to send (on change)
        self._events: deque[str] = deque(maxlen=settings.max_pending_events)
        self._lock = threading.Lock()
        self._unsent: list[Any] = []  # MQTTMessageInfo of QoS 0 messages paho has not written
        self._client: Any = None
        self.connected = False
        self.counters = {
            "connects": 0,
            "disconnects": 0,
            "connect_failures": 0,
            "positions_sent": 0,
            "positions_dropped_offline": 0,
            "positions_dropped_backpressure": 0,
            "zone_messages": 0,
            "fall_messages": 0,
            "events_sent": 0,
            "events_dropped": 0,
            "health_sent": 0,
        }

    @classmethod
    def from_settings(cls, settings: MqttSettings, context: OutputContext) -> MqttPublisher:
        """With Home Assistant discovery of the zones and the fall sensor
        (``service.outputs.ha_discovery``)."""
        return cls(
            settings,
            health=context.health,
            occupancy=context.occupancy,
            discovery=lambda: discovery_messages(
                settings, context.zone_names, context.fall_state() is not None
            ),
            fall_state=context.fall_state,
        )

    # -- topics ----------------------------------------------------------------------------------

    def topic(self, *levels: str) -> str:
        return self.settings.topic(*levels)

    # -- lifecycle -------------------------------------------------------------------------------

    def start(self) -> None:
        """Connect in the background (a broker that is down is retried, never waited for)."""
        from paho.mqtt.client import CallbackAPIVersion, Client

        s = self.settings
        client_id = s.client_id or f"momloc-{s.room}-{secrets.token_hex(3)}"
        client = Client(CallbackAPIVersion.VERSION2, client_id=client_id, clean_session=True)
        if s.username is not None:
            password = s.password.get_secret_value() if s.password else None
            client.username_pw_set(s.username, password)
        if s.tls or s.ca_file is not None:
            client.tls_set(
                ca_certs=str(s.ca_file) if s.ca_file else None, cert_reqs=ssl.CERT_REQUIRED
            )
        client.will_set(self.topic("availability"), "offline", qos=1, retain=True)
        client.reconnect_delay_set(s.reconnect_min_s, s.reconnect_max_s)  # type: ignore[arg-type]
        client.max_queued_messages_set(s.max_pending_events)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_connect_fail = self._on_connect_fail
        self._client = client
        client.connect_async(s.host, s.port, keepalive=s.keepalive)
        client.loop_start()
        super().start()

    def stop(self, timeout: float = 3.0) -> None:
        """Clean shutdown: flush events, publish ``offline`` (retained), disconnect."""
        super().stop(timeout)
        client = self._client
        if client is None:
            return
        if self.connected:
            info = client.publish(self.topic("availability"), "offline", qos=1, retain=True)
            try:
                info.wait_for_publish(timeout=timeout)
            except (RuntimeError, ValueError) as error:
                log.warning("mqtt: offline not confirmed: %s", error)
        client.disconnect()
        client.loop_stop()
        self._client = None

    # -- inputs (any thread, never block) --------------------------------------------------------

    def offer(self, snapshot: Snapshot) -> None:
        super().offer(snapshot if self.settings.include_outside else snapshot.inside_only())

    def on_zone_events(self, events: list[dict[str, Any]], occupancy: list[dict[str, Any]]) -> None:
        changed = {e["zone"] for e in events if "zone" in e}
        with self._lock:
            for item in occupancy:
                if item["zone"] in changed:
                    self._zones[item["zone"]] = item
            for event in events:
                if "falls" in event:  # a fall event carries the room's fall state after it
                    self._fall = {"active": bool(event["falls"]), "ids": event["falls"],
                                  "t": event["t"]}  # fmt: skip
                if len(self._events) == self._events.maxlen:
                    self.counters["events_dropped"] += 1
                self._events.append(json.dumps(event, separators=(",", ":")))
        self._wake.set()

    def publish_retained(self, topic: str, payload: str, qos: int = 1) -> bool:
        """One retained message (discovery configs, removals); False when not connected."""
        client = self._client
        if client is None or not self.connected:
            return False
        return client.publish(topic, payload, qos=qos, retain=True).rc == 0

    # -- paho callbacks (paho's thread) ----------------------------------------------------------

    def _on_connect(self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        if reason.is_failure:
            self.last_error = f"broker refused the connection: {reason}"
            log.warning("mqtt: %s", self.last_error)
            return
        self.connected = True
        self.counters["connects"] += 1
        self.last_error = None
        log.info("mqtt: connected to %s:%s", self.settings.host, self.settings.port)
        client.publish(self.topic("availability"), "online", qos=1, retain=True)
        for topic, payload in self._discovery() if self._discovery else []:
            client.publish(topic, payload, qos=1, retain=True)
        with self._lock:  # every zone again: the broker may have lost its retained messages
            for item in self._occupancy() if self._occupancy else []:
                self._zones[item["zone"]] = item
            self._fall = self._fall_state() if self._fall_state else None
        self._next_health = 0.0
        self._wake.set()

    def _on_disconnect(
        self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any
    ) -> None:
        was = self.connected
        self.connected = False
        with self._lock:
            self._unsent.clear()  # paho drops its unwritten QoS 0 packets on reconnect
        if was:
            self.counters["disconnects"] += 1
        if not self._stopping.is_set():
            self.last_error = f"disconnected: {reason}"
            log.warning("mqtt: %s; reconnecting", self.last_error)

    def _on_connect_fail(self, client: Any, userdata: Any) -> None:
        self.counters["connect_failures"] += 1
        self.last_error = f"cannot connect to {self.settings.host}:{self.settings.port}"

    # -- sender thread ---------------------------------------------------------------------------

    _next_health = 0.0

    def _run(self) -> None:
        interval = 1.0 / self.settings.rate
        next_position = 0.0
        while not self._stopping.is_set():
            now = time.monotonic()
            timeout = max(0.0, min(self._next_health - now, 1.0))
            self._hungry = now >= next_position
            if not self._hungry:
                timeout = min(timeout, next_position - now)
            elif self._slot.peek() is not None:
                timeout = 0.0
            self._wake.wait(timeout)
            self._wake.clear()
            try:
                if not self.connected:
                    if self._slot.take() is not None:
                        self.counters["positions_dropped_offline"] += 1
                    next_position = time.monotonic() + interval
                    continue
                self._send_zones_and_events()
                now = time.monotonic()
                if now >= next_position and self._slot.peek() is not None:
                    self._send_position(self._slot.take())
                    next_position = max(next_position + interval, now)
                if now >= self._next_health:
                    self._send_health()
                    self._next_health = now + self.settings.health_interval_s
            except Exception as error:  # keep going; shows in health
                self.last_error = f"{type(error).__name__}: {error}"
                log.exception("mqtt sender")
                self._stopping.wait(0.5)
        if self.connected:  # last events before the clean shutdown
            self._send_zones_and_events()

    def _send_zones_and_events(self) -> None:
        client = self._client
        with self._lock:
            zones, self._zones = self._zones, {}
            fall, self._fall = self._fall, None
            events = list(self._events)
            self._events.clear()
        for name, item in zones.items():
            payload = {"count": item["count"], "ids": item["ids"], "t": item.get("t")}
            client.publish(self.topic("zones", name), json.dumps(payload), qos=1, retain=True)
            self.counters["zone_messages"] += 1
        if fall is not None:
            client.publish(self.topic("fall"), json.dumps(fall), qos=1, retain=True)
            self.counters["fall_messages"] += 1
        for i, text in enumerate(events):
            info = client.publish(self.topic("events"), text, qos=1)
            if info.rc != 0:  # paho's queue is full or the link just dropped: keep the rest
                with self._lock:
                    self._events.extendleft(reversed(events[i:]))
                return
            self.counters["events_sent"] += 1

    def _backed_up(self) -> bool:
        with self._lock:
            self._unsent = [info for info in self._unsent if not info.is_published()]
            return len(self._unsent) >= self.settings.max_unsent

    def _send_position(self, snapshot: Snapshot | None) -> None:
        if snapshot is None:
            return
        if self._backed_up():
            self.counters["positions_dropped_backpressure"] += 1
            return
        info = self._client.publish(self.topic("positions"), snapshot.text, qos=0)
        if info.rc == 0:
            with self._lock:
                self._unsent.append(info)
            self.counters["positions_sent"] += 1
        else:
            self.counters["positions_dropped_offline"] += 1

    def _send_health(self) -> None:
        if self._health is None or self._backed_up():
            return
        info = self._client.publish(
            self.topic("health"), json.dumps(self._health()), qos=0, retain=True
        )
        if info.rc == 0:
            with self._lock:
                self._unsent.append(info)
            self.counters["health_sent"] += 1

    # -- introspection ---------------------------------------------------------------------------

    def degraded(self) -> str | None:
        if self.connected:
            return None
        broker = f"{self.settings.host}:{self.settings.port}"
        return f"not connected to the broker {broker} ({self.last_error or 'connecting'})"

    def counters_exported(self) -> dict[str, int]:
        keys = (
            "connects",
            "connect_failures",
            "positions_sent",
            "positions_dropped_offline",
            "positions_dropped_backpressure",
            "events_sent",
            "events_dropped",
        )
        return {key: self.counters[key] for key in keys}

    def gauges_exported(self) -> dict[str, tuple[str, float]]:
        return {"connected": ("1 while connected", int(self.connected))}

    def stats(self) -> dict[str, Any]:
        with self._lock:
            pending = len(self._events)
            unsent = len(self._unsent)
        return {
            "broker": f"{self.settings.host}:{self.settings.port}",
            "room": self.settings.room,
            "connected": self.connected,
            "pending_events": pending,
            "unsent": unsent,
            "positions_overwritten": self._slot.overwritten,
            "error": self.last_error,
            **self.counters,
        }

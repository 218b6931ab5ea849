"""Wires the optional outputs (zones, MQTT, Home Assistant discovery, OSC) to a daemon's hub.

``build_outputs`` is the one call ``service.daemon.build_daemon`` makes; ``service.api.zones``
starts and stops the MQTT link with the app and serves the zone routes. Keeping the wiring here
means the core daemon knows nothing about MQTT beyond "there may be outputs".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from service.outputs.ha_discovery import discovery_messages, removal_messages
from service.outputs.mqtt import MqttPublisher
from service.outputs.osc import OscPublisher
from service.outputs.zone_monitor import ZoneMonitor
from service.outputs.zones import Zone


@dataclass
class Outputs:
    """The daemon's outputs; each part is None when not configured."""

    zones: ZoneMonitor
    mqtt: MqttPublisher | None = None
    osc: OscPublisher | None = None

    def health(self) -> dict[str, Any]:
        out: dict[str, Any] = {"zones": self.zones.stats()}
        if self.mqtt is not None:
            out["mqtt"] = self.mqtt.stats()
        if self.osc is not None:
            out["osc"] = self.osc.stats()
        return out

    def degraded(self) -> dict[str, str]:
        """Each configured output that is not delivering now, with why (``/v1/health`` lists
        them and says ``degraded``: positions that reach no broker are not "ok")."""
        out: dict[str, str] = {}
        if self.mqtt is not None and not self.mqtt.connected:
            broker = f"{self.mqtt.settings.host}:{self.mqtt.settings.port}"
            why = self.mqtt.last_error or "connecting"
            out["mqtt"] = f"not connected to the broker {broker} ({why})"
        if self.osc is not None and self.osc.last_error is not None:
            out["osc"] = self.osc.last_error
        return out

    def remove_discovery(self) -> int:
        """Delete this room's Home Assistant entities (empty retained configs)."""
        if self.mqtt is None:
            return 0
        names = [z.name for z in self.zones.zones]
        sent = 0
        for topic, payload in removal_messages(self.mqtt.settings, names):
            sent += int(self.mqtt.publish_retained(topic, payload))
        return sent


def health_summary(daemon: Any) -> dict[str, Any]:
    """The small retained ``{base}/{room}/health`` payload (not the whole /v1/health)."""
    health = daemon.health()
    latest = daemon.hub.latest()
    return {
        "status": health["status"],
        "t": latest.t,
        "people": len(latest.inside_only().people),
        "fps": health["pipeline"]["fps"],
        "cameras": len(health["cameras"]),
        "cameras_connected": sum(1 for c in health["cameras"] if c["connected"]),
        "uptime_s": health["uptime_s"],
    }


def build_outputs(settings: Any, daemon: Any) -> Outputs:
    """Zone monitor (always; zero zones is fine) and, with ``mqtt`` settings, the publisher."""
    zones = [Zone.create(z.name, z.polygon, z.hold_s) for z in settings.zones]
    monitor = ZoneMonitor(zones)
    daemon.hub.add_publisher(monitor)
    outputs = Outputs(monitor)
    if settings.mqtt is not None:
        names = [z.name for z in zones]
        publisher = MqttPublisher(
            settings.mqtt,
            health=lambda: health_summary(daemon),
            occupancy=monitor.occupancy,
            discovery=lambda: discovery_messages(settings.mqtt, names),
        )
        daemon.hub.add_publisher(publisher)
        monitor.add_listener(publisher)
        outputs.mqtt = publisher
    if getattr(settings, "osc", None) is not None:
        outputs.osc = OscPublisher(settings.osc, occupancy=monitor.occupancy)
        daemon.hub.add_publisher(outputs.osc)
    return outputs


def output_metrics(daemon: Any) -> list[Any]:
    """Prometheus families: people per zone, events, MQTT link state and counters."""
    from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily

    outputs = getattr(daemon, "outputs", None)
    if outputs is None:
        return []
    people = GaugeMetricFamily("momloc_zone_people", "People inside the zone", labels=["zone"])
    occupied = GaugeMetricFamily(
        "momloc_zone_occupied", "1 while someone is inside", labels=["zone"]
    )
    for item in outputs.zones.occupancy():
        people.add_metric([item["zone"]], item["count"])
        occupied.add_metric([item["zone"]], int(item["count"] > 0))
    families = [
        people,
        occupied,
        CounterMetricFamily("momloc_zone_events", "Enter/leave events", outputs.zones.event_count),
    ]
    if outputs.mqtt is not None:
        stats = outputs.mqtt.stats()
        families.append(
            GaugeMetricFamily("momloc_mqtt_connected", "1 while connected", int(stats["connected"]))
        )
        for key in (
            "connects",
            "connect_failures",
            "positions_sent",
            "positions_dropped_offline",
            "positions_dropped_backpressure",
            "events_sent",
            "events_dropped",
        ):
            families.append(CounterMetricFamily(f"momloc_mqtt_{key}", f"MQTT {key}", stats[key]))
    if outputs.osc is not None:
        for key, value in outputs.osc.counters.items():
            families.append(CounterMetricFamily(f"momloc_osc_{key}", f"OSC {key}", value))
    return families

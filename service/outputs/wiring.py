"""Wires the optional outputs (zones, MQTT, Home Assistant discovery, OSC) to a daemon's hub.

``build_outputs`` is the one call ``service.daemon.build_daemon`` makes; ``service.api.lifespan``
starts and stops the publishers with the app and ``service.api.routes.zones`` serves the zone
routes. Keeping the wiring here means the core daemon knows nothing about MQTT beyond "there may
be outputs".

The zone monitor is always there (zero zones is fine). The publishers come from
:data:`PUBLISHERS`: each is built when its settings key (``ThreadedPublisher.settings_key``) is
set, in that order.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from service.outputs.falls import FallDetector
from service.outputs.ha_discovery import removal_messages
from service.outputs.mqtt import MqttPublisher
from service.outputs.osc import OscPublisher
from service.outputs.publisher import OutputContext, ThreadedPublisher
from service.outputs.zone_monitor import ZoneListener, ZoneMonitor
from service.outputs.zones import Zone

PUBLISHERS: tuple[type[ThreadedPublisher], ...] = (MqttPublisher, OscPublisher)


@dataclass
class Outputs:
    """The daemon's outputs: the zone monitor and the configured publishers by name."""

    zones: ZoneMonitor
    publishers: dict[str, ThreadedPublisher] = field(default_factory=dict)

    @property
    def mqtt(self) -> MqttPublisher | None:
        """The MQTT link (Home Assistant discovery is MQTT's), if configured."""
        publisher = self.publishers.get(MqttPublisher.name)
        return publisher if isinstance(publisher, MqttPublisher) else None

    def health(self) -> dict[str, Any]:
        out: dict[str, Any] = {"zones": self.zones.stats()}
        out.update({name: p.stats() for name, p in self.publishers.items()})
        return out

    def degraded(self) -> dict[str, str]:
        """Each configured output that is not delivering now, with why (``/v1/health`` lists
        them and says ``degraded``: positions that reach no broker are not "ok")."""
        out: dict[str, str] = {}
        for name, publisher in self.publishers.items():
            why = publisher.degraded()
            if why is not None:
                out[name] = why
        return out

    def remove_discovery(self) -> int:
        """Delete this room's Home Assistant entities (empty retained configs)."""
        mqtt = self.mqtt
        if mqtt is None:
            return 0
        names = [z.name for z in self.zones.zones]
        sent = 0
        for topic, payload in removal_messages(mqtt.settings, names):
            sent += int(mqtt.publish_retained(topic, payload))
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
    """Zone monitor (always; zero zones is fine) with the fall detector unless falls are off,
    and each publisher whose settings are set."""
    zones = [Zone.create(z.name, z.polygon, z.hold_s) for z in settings.zones]
    falls = FallDetector(settings.falls.rules(), zones) if settings.falls.enabled else None
    monitor = ZoneMonitor(zones, falls=falls)
    daemon.hub.add_publisher(monitor)
    outputs = Outputs(monitor)
    context = OutputContext(
        health=lambda: health_summary(daemon),
        occupancy=monitor.occupancy,
        zone_names=[z.name for z in zones],
        fall_state=monitor.fall_state,
    )
    for kind in PUBLISHERS:
        section = getattr(settings, kind.settings_key)
        if section is None:
            continue
        publisher = kind.from_settings(section, context)
        daemon.hub.add_publisher(publisher)
        if isinstance(publisher, ZoneListener):  # zone states and events go out there too
            monitor.add_listener(publisher)
        outputs.publishers[publisher.name] = publisher
    return outputs


def output_metrics(outputs: Outputs | None) -> list[Any]:
    """Prometheus families: people per zone, events, MQTT link state and counters."""
    from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily

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
        CounterMetricFamily(
            "momloc_zone_events", "Zone and fall events", outputs.zones.event_count
        ),
    ]
    fall_state = outputs.zones.fall_state()
    if fall_state is not None:
        families.append(
            GaugeMetricFamily("momloc_falls", "People with an active fall", len(fall_state["ids"]))
        )
    for name, publisher in outputs.publishers.items():
        for key, (text, value) in publisher.gauges_exported().items():
            families.append(GaugeMetricFamily(f"momloc_{name}_{key}", text, value))
        for key, value in publisher.counters_exported().items():
            families.append(
                CounterMetricFamily(f"momloc_{name}_{key}", f"{name.upper()} {key}", value)
            )
    return families

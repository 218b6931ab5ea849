"""Home Assistant MQTT discovery: the room as one device, each zone as two entities.

Home Assistant (HA) adds an entity when a JSON config arrives, retained, on
``<prefix>/<component>/<node_id>/<object_id>/config`` and removes it when an empty retained
message replaces that config. Per daemon (room) we announce one device ``MoM <room>`` with:

- per zone a ``binary_sensor`` (``device_class: occupancy``; ON while the zone's count > 0) and a
  ``sensor`` (people in the zone), both reading the retained ``{base}/{room}/zones/{zone}`` topic;
- one ``sensor`` with the number of people in the room, read from the retained health topic
  (positions at 10/s would flood HA's recorder);
- unless falls are off, one ``binary_sensor`` ``fall`` (``device_class: safety``: ON means
  unsafe) reading the retained ``{base}/{room}/fall`` topic, ON while someone in the room has an
  active fall (:mod:`service.outputs.falls`), with the ids as an attribute.

Every entity uses ``{base}/{room}/availability``, so HA greys the room out when the daemon stops
or dies (last will). Ids (``unique_id``, ``node_id``, ``object_id``) use only ``[A-Za-z0-9_-]``,
which zone and room names are validated to. Only documented keys are used (full names, not the
abbreviations), so the configs read the same as the HA documentation.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

from service.outputs.settings import MqttSettings

SW_VERSION = "0.1.0"


def node_id(settings: MqttSettings) -> str:
    return f"momloc_{settings.room}"


def device(settings: MqttSettings) -> dict[str, Any]:
    name = settings.home_assistant.device_name or f"MoM {settings.room}"
    return {
        "identifiers": [node_id(settings)],
        "name": name,
        "manufacturer": "MoM Localizer",
        "model": "momloc daemon",
        "sw_version": SW_VERSION,
    }


def _common(settings: MqttSettings, object_id: str) -> dict[str, Any]:
    return {
        "unique_id": f"{node_id(settings)}_{object_id}",
        "availability_topic": settings.topic("availability"),
        "payload_available": "online",
        "payload_not_available": "offline",
        "device": device(settings),
    }


def config_topic(settings: MqttSettings, component: str, object_id: str) -> str:
    return f"{settings.home_assistant.prefix}/{component}/{node_id(settings)}/{object_id}/config"


def discovery_configs(
    settings: MqttSettings, zones: Sequence[str], falls: bool = True
) -> list[tuple[str, dict]]:
    """``(config topic, config)`` for every entity of the room (``falls``: with the fall
    sensor)."""
    configs: list[tuple[str, dict[str, Any]]] = []
    for zone in zones:
        state_topic = settings.topic("zones", zone)
        occupied = {
            **_common(settings, f"{zone}_occupancy"),
            "name": f"{zone} occupancy",
            "state_topic": state_topic,
            "value_template": "{{ 'ON' if value_json.count > 0 else 'OFF' }}",
            "payload_on": "ON",
            "payload_off": "OFF",
            "device_class": "occupancy",
            "json_attributes_topic": state_topic,
            "json_attributes_template": "{{ {'ids': value_json.ids} | tojson }}",
        }
        count = {
            **_common(settings, f"{zone}_count"),
            "name": f"{zone} people",
            "state_topic": state_topic,
            "value_template": "{{ value_json.count }}",
            "state_class": "measurement",
            "unit_of_measurement": "people",
            "icon": "mdi:account-multiple",
        }
        configs.append((config_topic(settings, "binary_sensor", f"{zone}_occupancy"), occupied))
        configs.append((config_topic(settings, "sensor", f"{zone}_count"), count))
    people = {
        **_common(settings, "people"),
        "name": "people",
        "state_topic": settings.topic("health"),
        "value_template": "{{ value_json.people }}",
        "state_class": "measurement",
        "unit_of_measurement": "people",
        "icon": "mdi:account-group",
    }
    configs.append((config_topic(settings, "sensor", "people"), people))
    if falls:
        fall = {
            **_common(settings, "fall"),
            "name": "fall",
            "state_topic": settings.topic("fall"),
            "value_template": "{{ 'ON' if value_json.active else 'OFF' }}",
            "payload_on": "ON",
            "payload_off": "OFF",
            "device_class": "safety",
            "json_attributes_topic": settings.topic("fall"),
            "json_attributes_template": "{{ {'ids': value_json.ids} | tojson }}",
        }
        configs.append((config_topic(settings, "binary_sensor", "fall"), fall))
    return configs


def discovery_messages(
    settings: MqttSettings, zones: Sequence[str], falls: bool = True
) -> list[tuple[str, str]]:
    """Retained messages that announce the room (empty list when discovery is off)."""
    if not settings.home_assistant.discovery:
        return []
    configs = discovery_configs(settings, zones, falls)
    return [(topic, json.dumps(cfg)) for topic, cfg in configs]


def removal_messages(settings: MqttSettings, zones: Sequence[str]) -> list[tuple[str, str]]:
    """Empty retained payloads on every config topic (the fall sensor's too, which may have been
    announced before falls were turned off): HA deletes the entities."""
    return [(topic, "") for topic, _ in discovery_configs(settings, zones, falls=True)]

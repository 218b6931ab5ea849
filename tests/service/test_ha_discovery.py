"""Home Assistant discovery configs checked against HA's documented MQTT schema.

The option lists below are the documented configuration variables of HA's MQTT ``binary_sensor``
and ``sensor`` integrations and the discovery ``device`` map (home-assistant.io/integrations/
binary_sensor.mqtt, sensor.mqtt, mqtt#discovery). A key HA does not know, a missing required key,
a topic HA would not match or a template HA could not render fails here.
"""

from __future__ import annotations

import json
import re

import jinja2
import pytest

from service.outputs.ha_discovery import discovery_configs, discovery_messages, removal_messages
from service.outputs.settings import MqttSettings

COMMON = {
    "availability", "availability_mode", "availability_template", "availability_topic",
    "default_entity_id", "device", "device_class", "enabled_by_default", "encoding",
    "entity_category", "entity_picture", "expire_after", "force_update", "icon",
    "json_attributes_template", "json_attributes_topic", "name", "object_id",
    "payload_available", "payload_not_available", "platform", "qos", "state_topic", "unique_id",
    "value_template",
}  # fmt: skip
DOCUMENTED = {
    "binary_sensor": COMMON | {"off_delay", "payload_off", "payload_on"},
    "sensor": COMMON
    | {
        "last_reset_value_template",
        "options",
        "state_class",
        "suggested_display_precision",
        "unit_of_measurement",
    },
}
DEVICE_KEYS = {
    "configuration_url", "connections", "hw_version", "identifiers", "manufacturer", "model",
    "model_id", "name", "serial_number", "suggested_area", "sw_version", "via_device",
}  # fmt: skip
BINARY_DEVICE_CLASSES = {"occupancy", "presence", "motion", "safety"}  # those that fit (documented)
STATE_CLASSES = {"measurement", "total", "total_increasing"}
TOPIC = re.compile(r"^homeassistant/(binary_sensor|sensor)/[A-Za-z0-9_-]+/[A-Za-z0-9_-]+/config$")


def _settings(**ha) -> MqttSettings:
    return MqttSettings(host="broker", room="living-room", home_assistant={"discovery": True, **ha})


def _render(template: str, payload: dict) -> str:
    return jinja2.Environment().from_string(template).render(value_json=payload).strip()


def test_configs_use_only_documented_keys_and_valid_topics():
    configs = discovery_configs(_settings(), ["sofa", "desk"])
    assert len(configs) == 2 * 2 + 2  # per zone two, the room's people and fall sensors
    unique_ids = set()
    for topic, config in configs:
        match = TOPIC.match(topic)
        assert match, topic
        component = match.group(1)
        assert set(config) <= DOCUMENTED[component], set(config) - DOCUMENTED[component]
        assert config["state_topic"].startswith("momloc/living-room/")
        assert config["availability_topic"] == "momloc/living-room/availability"
        assert (config["payload_available"], config["payload_not_available"]) == (
            "online",
            "offline",
        )
        device = config["device"]
        assert set(device) <= DEVICE_KEYS and device["identifiers"] == ["momloc_living-room"]
        assert device["name"] == "MoM living-room"
        assert config["unique_id"] not in unique_ids  # HA requires unique_id with a device
        unique_ids.add(config["unique_id"])
        if component == "binary_sensor":
            assert config["device_class"] in BINARY_DEVICE_CLASSES
        else:
            assert config["state_class"] in STATE_CLASSES
        json.dumps(config)  # serialisable as HA receives it


def test_templates_render_the_zone_and_health_payloads_as_ha_would():
    by_id = {c["unique_id"]: c for _, c in discovery_configs(_settings(), ["sofa"])}
    occupied = by_id["momloc_living-room_sofa_occupancy"]
    count = by_id["momloc_living-room_sofa_count"]
    people = by_id["momloc_living-room_people"]
    zone_payload = {"count": 2, "ids": [3, 5], "t": 1.0}
    assert _render(occupied["value_template"], zone_payload) == occupied["payload_on"]
    assert _render(occupied["value_template"], {"count": 0, "ids": []}) == occupied["payload_off"]
    assert json.loads(_render(occupied["json_attributes_template"], zone_payload)) == {
        "ids": [3, 5]
    }
    assert _render(count["value_template"], zone_payload) == "2"
    assert people["state_topic"] == "momloc/living-room/health"
    assert _render(people["value_template"], {"people": 4, "status": "ok"}) == "4"


def test_the_fall_sensor_is_on_while_a_fall_is_active_and_can_be_left_out():
    by_id = {c["unique_id"]: c for _, c in discovery_configs(_settings(), ["sofa"])}
    fall = by_id["momloc_living-room_fall"]
    assert fall["device_class"] == "safety" and fall["state_topic"] == "momloc/living-room/fall"
    active = {"active": True, "ids": [3], "t": 5.0}
    assert _render(fall["value_template"], active) == fall["payload_on"]
    assert _render(fall["value_template"], {"active": False, "ids": [], "t": None}) == "OFF"
    assert json.loads(_render(fall["json_attributes_template"], active)) == {"ids": [3]}
    without = [c["unique_id"] for _, c in discovery_configs(_settings(), ["sofa"], falls=False)]
    assert "momloc_living-room_fall" not in without and len(without) == len(by_id) - 1
    # removal covers the fall sensor even when falls are off now (announced by an earlier run)
    assert any(t.endswith("/fall/config") for t, _ in removal_messages(_settings(), ["sofa"]))


def test_discovery_is_opt_in_and_removal_empties_every_config():
    off = MqttSettings(host="broker", room="r1")
    assert discovery_messages(off, ["sofa"]) == []
    on = _settings(prefix="homeassistant", device_name="Living room")
    messages = discovery_messages(on, ["sofa"])
    assert json.loads(messages[0][1])["device"]["name"] == "Living room"
    removals = removal_messages(on, ["sofa"])
    assert [t for t, _ in removals] == [t for t, _ in messages]
    assert all(payload == "" for _, payload in removals)


@pytest.mark.parametrize("room", ["a/b", "a+b", "#", "", "x y"])
def test_room_names_that_break_topics_or_ids_are_refused(room):
    with pytest.raises(ValueError, match="room"):
        MqttSettings(host="broker", room=room)

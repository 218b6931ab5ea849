"""Zones and MQTT settings: YAML, MOMLOC_* environment variables, one-line errors."""

from __future__ import annotations

import pytest

from common.errors import MomlocError
from service.demo import DEMO_ZONES, demo_settings
from service.outputs.settings import HomeAssistantSettings, MqttSettings, ZoneSettings
from service.settings import load_settings

CAMERAS = "cameras:\n  - {type: synthetic, index: 0}\n"


@pytest.fixture(autouse=True)
def _clean_env(monkeypatch):
    import os

    for key in list(os.environ):
        if key.startswith("MOMLOC_"):
            monkeypatch.delenv(key)


def _load(tmp_path, text: str):
    path = tmp_path / "momloc.yaml"
    path.write_text(CAMERAS + text)
    return load_settings(path)


def test_mqtt_is_off_by_default_and_four_lines_turn_it_on(tmp_path):
    assert _load(tmp_path, "").mqtt is None
    s = _load(tmp_path, "mqtt:\n  host: 192.168.1.10\n  room: kitchen\n").mqtt
    assert (s.host, s.port, s.base_topic, s.room, s.rate) == (
        "192.168.1.10",
        1883,
        "momloc",
        "kitchen",
        10.0,
    )
    assert s.topic("zones", "sofa") == "momloc/kitchen/zones/sofa"
    assert not s.home_assistant.discovery


def test_environment_variables_reach_serve_and_demo(tmp_path, monkeypatch):
    monkeypatch.setenv("MOMLOC_MQTT__HOST", "broker.local")
    monkeypatch.setenv("MOMLOC_MQTT__PORT", "1884")
    monkeypatch.setenv("MOMLOC_MQTT__HOME_ASSISTANT__DISCOVERY", "true")
    demo = demo_settings()
    mqtt = demo.mqtt
    assert mqtt is not None
    assert (mqtt.host, mqtt.port, mqtt.home_assistant.discovery) == (
        "broker.local", 1884, True,
    )  # fmt: skip
    assert [z.name for z in demo.zones] == [z["name"] for z in DEMO_ZONES]
    # environment wins over the file, key by key (room stays from YAML)
    s = _load(tmp_path, "mqtt:\n  host: from-yaml\n  port: 1\n  room: hall\n").mqtt
    assert (s.host, s.port, s.room) == ("broker.local", 1884, "hall")
    monkeypatch.setenv("MOMLOC_ZONES", '[{"name": "a", "polygon": [[0, 0], [1, 0], [1, 1]]}]')
    assert [z.name for z in demo_settings().zones] == ["a"]


@pytest.mark.parametrize(
    ("text", "line"),
    [
        ("mqtt:\n  host: h\n  hots: x\n", "mqtt.hots: Extra inputs are not permitted"),
        ("mqtt:\n  port: 1\n", "mqtt.host: Field required"),
        ("mqtt:\n  host: h\n  rate: 0\n", "mqtt.rate:"),
        ("mqtt:\n  host: h\n  base_topic: 'a/#'\n", "mqtt.base_topic:"),
        (
            "zones:\n  - {name: bow, polygon: [[0, 0], [2, 2], [2, 0], [0, 2]]}\n",
            "zones.0.polygon: the polygon intersects itself",
        ),
        (
            "zones:\n  - {name: tiny, polygon: [[0, 0], [1, 1]]}\n",
            "zones.0.polygon: a polygon needs",
        ),
        ("zones:\n  - {name: 'a b', polygon: [[0, 0], [1, 0], [1, 1]]}\n", "zones.0.name:"),
        ("zones:\n  - {name: a, polygon: [[0, 0], [1, 0], [1, 1]], hold: 1}\n", "zones.0.hold:"),
        (
            "zones:\n  - {name: a, polygon: [[0, 0], [1, 0], [1, 1]]}\n"
            "  - {name: a, polygon: [[0, 0], [2, 0], [2, 2]]}\n",
            "zones: Value error, zone names must be unique; repeated: a",
        ),
    ],
)
def test_bad_settings_are_one_line_naming_the_field(tmp_path, text, line):
    with pytest.raises(MomlocError) as caught:
        _load(tmp_path, text)
    message = str(caught.value)
    assert len(message.splitlines()) == 1, message
    assert line.replace("Value error, ", "") in message, message


def test_every_output_setting_is_documented():
    for model in (ZoneSettings, MqttSettings, HomeAssistantSettings):
        for name, field in model.model_fields.items():
            assert field.description, f"{model.__name__}.{name} has no description"

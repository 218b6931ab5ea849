"""The fall event through the real daemon: a simulated person falls, a client hears of it.

The scene is preset ``demo-fall`` (the demo's room and cameras: someone walks, stands, falls,
lies 20 s and gets up, at three places in turn), its boxes the simulator's (nanodet profile),
driven in lock-step (``tests.e2e.server.LockstepRig``: scene time, no wall clock in the
detector's rules). Postures need the model's set-up area height model: the shipped demo model
has one, so the tests serve it as it ships.
"""

from __future__ import annotations

import asyncio
import json
import uuid

import numpy as np
import pytest
import websockets

from service.outputs.falls import FallRules
from service.settings import DEMO_MODEL_DIR
from tests.e2e.mqtt_broker import Subscriber
from tests.e2e.server import running_server

pytestmark = pytest.mark.timeout(600)

SCENE = "demo-fall"
KITCHEN = [[2.0, 2.0], [4.0, 2.0], [4.0, 4.0], [2.0, 4.0]]  # holds the first fall, at (3, 3)


def _fall_server(monkeypatch: pytest.MonkeyPatch, **env: str):
    monkeypatch.setenv("MOMLOC_ZONES", json.dumps([{"name": "kitchen", "polygon": KITCHEN}]))
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    return running_server(
        scene=SCENE, people=0, lockstep=True, model_dir=DEMO_MODEL_DIR, detections="simulated"
    )


def test_a_fall_arrives_over_the_websocket_and_in_the_zones(monkeypatch):
    with _fall_server(monkeypatch) as srv:

        async def fall_events() -> list[dict]:
            got: list[dict] = []
            async with websockets.connect(srv.ws + "/v1/events") as ws:
                while not any(e["type"] == "fall_cleared" for e in got):
                    got.append(json.loads(await asyncio.wait_for(ws.recv(), 240)))
            return got

        events = asyncio.run(fall_events())
        falls = [e for e in events if e["type"] in ("fall", "fall_cleared")]
        fall, cleared = falls
        assert fall["type"] == "fall" and fall["falls"] == [fall["id"]]
        assert fall["zones"] == ["kitchen"] and np.hypot(fall["x"] - 3.0, fall["y"] - 3.0) < 0.8
        # reported once the person has read lying for lying_s, within 3 s of the first lying read
        assert FallRules().lying_s <= fall["t"] - fall["since"] <= 3.0
        assert cleared["id"] == fall["id"] and cleared["reason"] == "stood_up"
        assert cleared["since"] == fall["t"] and cleared["falls"] == []
        seqs = [e["seq"] for e in events]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # one stream, one numbering
        zones = srv.get("/v1/zones").json()
        assert zones["falls"]["active"] is False
        assert [e["type"] for e in zones["recent_events"]].count("fall") == 1


def test_a_fall_reaches_mqtt_and_home_assistant(monkeypatch, mosquitto):
    room = f"t{uuid.uuid4().hex[:8]}"
    sub = Subscriber(mosquitto.port, f"momloc/{room}/#", "homeassistant/#")
    env = {
        "MOMLOC_MQTT__HOST": "127.0.0.1",
        "MOMLOC_MQTT__PORT": str(mosquitto.port),
        "MOMLOC_MQTT__ROOM": room,
        "MOMLOC_MQTT__HOME_ASSISTANT__DISCOVERY": "true",
    }
    config_topic = f"homeassistant/binary_sensor/momloc_{room}/fall/config"
    state_topic = f"momloc/{room}/fall"
    try:
        with _fall_server(monkeypatch, **env):
            config = json.loads(sub.wait_for(lambda s: s.on(config_topic), timeout=120)[0].payload)
            assert config["device_class"] == "safety" and config["state_topic"] == state_topic
            assert config["availability_topic"] == f"momloc/{room}/availability"

            def states(s: Subscriber) -> list[dict]:
                return [json.loads(m.payload) for m in s.on(state_topic)]

            sub.wait_for(lambda s: any(st["active"] for st in states(s)), timeout=300)
            sub.wait_for(lambda s: not states(s)[-1]["active"], timeout=300)

            def events_of(s: Subscriber) -> list[dict]:
                return [json.loads(m.payload) for m in s.on(f"momloc/{room}/events")]

            # the event and the state are two publishes: the event may arrive after the state
            sub.wait_for(
                lambda s: any(e["type"] == "fall_cleared" for e in events_of(s)), timeout=60
            )
            events = events_of(sub)
            # a client that subscribes later (Home Assistant restarting) gets both, retained
            late = Subscriber(mosquitto.port, config_topic, state_topic)
            try:
                late.wait_for(lambda s: s.on(config_topic) and s.on(state_topic), timeout=60)
                retained = [*late.on(config_topic), *late.on(state_topic)]
                assert all(m.retain for m in retained)
                assert json.loads(late.on(state_topic)[-1].payload)["active"] is False
            finally:
                late.close()
        falls = [e for e in events if e["type"] in ("fall", "fall_cleared")]
        assert [e["type"] for e in falls] == ["fall", "fall_cleared"]
        on, off = (st for st in states(sub) if st["t"] is not None)
        assert on == {"active": True, "ids": [falls[0]["id"]], "t": falls[0]["t"]}
        assert off == {"active": False, "ids": [], "t": falls[1]["t"]}
        # what Home Assistant shows: its value_template over the retained state
        template = config["value_template"]
        assert template == "{{ 'ON' if value_json.active else 'OFF' }}"
    finally:
        sub.close()

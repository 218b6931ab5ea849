"""Shared e2e fixtures: ``mosquitto`` (a real broker per test session, tests/e2e/mqtt_broker.py),
``unity_harness`` (the Unity client compiled with Mono) and ``godot_harness`` (Godot's headless
build), both from tests/e2e/toolchains.py."""

from tests.e2e.mqtt_broker import mosquitto  # noqa: F401
from tests.e2e.toolchains import godot_harness, unity_harness  # noqa: F401

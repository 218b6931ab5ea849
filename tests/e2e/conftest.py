"""Shared e2e fixtures: ``mosquitto`` (a real broker per test session, tests/e2e/mqtt_broker.py)."""

from tests.e2e.mqtt_broker import mosquitto  # noqa: F401

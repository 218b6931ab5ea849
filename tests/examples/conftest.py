"""``mosquitto``: a real broker for the example-client tests (tests/e2e/mqtt_broker.py)."""

from tests.e2e.mqtt_broker import mosquitto  # noqa: F401

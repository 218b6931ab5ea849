"""Many rooms: two daemons (two synthetic rooms) into one real broker, read by the example."""

from __future__ import annotations

import re
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from tests.e2e.test_mqtt import HALVES, mqtt_daemon

pytestmark = pytest.mark.timeout(300)
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "mqtt_client.py"


def test_one_client_sees_every_room_through_one_broker(mosquitto):
    base = f"bldg{uuid.uuid4().hex[:6]}"
    with (
        mqtt_daemon(mosquitto.port, "kitchen", zones=HALVES, base_topic=base, rate=5),
        mqtt_daemon(mosquitto.port, "hall", zones=[], base_topic=base, rate=5, people=1),
    ):
        result = subprocess.run(
            [sys.executable, str(EXAMPLE), "--port", str(mosquitto.port), "--base", base,
             "--count", "60"],
            capture_output=True,
            text=True,
            timeout=120,
        )  # fmt: skip
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert len(lines) == 60, lines
    rooms = {m.group(1) for line in lines if (m := re.match(r"\[(\w+)\] positions seq \d+", line))}
    assert rooms == {"kitchen", "hall"}, lines
    assert any(re.match(r"\[kitchen\] zone (west|east): \d", line) for line in lines), lines
    assert "[hall] availability online" in lines or "[kitchen] availability online" in lines
    assert not [line for line in lines if "unreadable" in line]


def test_fall_events_print_where_the_person_is():
    sys.path.insert(0, str(EXAMPLE.parent))
    try:
        from mqtt_client import describe  # type: ignore[import-not-found]
    finally:
        sys.path.remove(str(EXAMPLE.parent))
    fall = b'{"v": 1, "seq": 9, "type": "fall", "id": 3, "t": 5.0, "since": 1.0, "x": 2.5, '
    fall += b'"y": -1.25, "zones": ["kitchen"], "falls": [3]}'
    line = describe("momloc/flat/events", fall, "momloc")
    assert line == "[flat] event fall #3 at (+2.50, -1.25) in kitchen"

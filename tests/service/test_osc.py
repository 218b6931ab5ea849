"""OSC bundle layout, the publisher's newest-wins slot, and the ``osc`` settings."""

from __future__ import annotations

import socket
import struct
import time

import pytest
from pythonosc.osc_bundle import OscBundle

from common.errors import MomlocError
from service.demo import demo_settings
from service.outputs.osc import OscPublisher, build_bundle
from service.outputs.settings import OscSettings
from service.settings import load_settings
from service.snapshot import Person, Snapshot

PEOPLE: list[Person] = [
    {"id": 3, "x": 1.25, "y": 2.5, "vx": 0.4, "vy": -0.1, "confidence": 0.9, "cameras": [0, 1]},
    {"id": 11, "x": 7.0, "y": 0.5, "vx": 0.0, "vy": 0.0, "confidence": 0.25, "cameras": [1]},
]
ZONES = [{"zone": "sofa", "count": 1, "ids": [3]}, {"zone": "door", "count": 0, "ids": []}]


def type_tags(dgram: bytes) -> str:
    """The OSC type tag string of one message datagram (python-osc keeps it private)."""
    end = dgram.index(b"\x00")
    start = (end + 4) & ~3  # address string padded to a multiple of 4
    return dgram[start + 1 : dgram.index(b"\x00", start)].decode()


def messages(dgram: bytes) -> list[tuple[str, str, list]]:
    bundle = OscBundle(dgram)
    return [(m.address, type_tags(m.dgram), list(m.params)) for m in bundle]


def test_bundle_holds_count_ids_people_and_zones_in_order():
    got = messages(build_bundle(Snapshot.build(5, 100.0, PEOPLE), ZONES))
    assert [(a, t) for a, t, _ in got] == [
        ("/momloc/count", "i"),
        ("/momloc/ids", "ii"),
        ("/momloc/person/3", "fffff"),
        ("/momloc/person/11", "fffff"),
        ("/momloc/zone/sofa", "i"),
        ("/momloc/zone/door", "i"),
    ]
    assert got[0][2] == [2] and got[1][2] == [3, 11]
    assert got[2][2] == pytest.approx([1.25, 2.5, 0.4, -0.1, 0.9], abs=1e-6)
    assert got[3][2] == pytest.approx([7.0, 0.5, 0.0, 0.0, 0.25], abs=1e-6)
    assert [m[2] for m in got[4:]] == [[1], [0]]
    # time tag 1 = "immediately" (receivers must not hold the bundle back)
    assert struct.unpack(">Q", build_bundle(Snapshot.build(1, 0.0, []))[8:16]) == (1,)


def test_empty_room_still_sends_count_zero_and_no_ids():
    got = messages(build_bundle(Snapshot.build(1, 0.0, []), None))
    assert got == [("/momloc/count", "i", [0]), ("/momloc/ids", "", [])]


def test_publisher_sends_the_newest_snapshot_to_a_udp_receiver():
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(20)
    port = receiver.getsockname()[1]
    publisher = OscPublisher(OscSettings(port=port, rate=50), occupancy=lambda: ZONES[:1])
    # offered before the thread runs: only the last one may go out (newest wins, no queue)
    for seq in range(1, 4):
        people: list[Person] = [{**PEOPLE[0], "x": float(seq)}]
        publisher.offer(Snapshot.build(seq, float(seq), people))
    publisher.start()
    try:
        first = messages(receiver.recv(65536))
        assert first[2][2][0] == 3.0 and first[-1] == ("/momloc/zone/sofa", "i", [1])
        assert publisher.stats()["snapshots_skipped"] == 2
        publisher.offer(Snapshot.build(4, 4.0, PEOPLE))
        second = messages(receiver.recv(65536))
        assert [a for a, _, _ in second][2:4] == ["/momloc/person/3", "/momloc/person/11"]
        deadline = time.time() + 20
        while publisher.stats()["bundles_sent"] < 2 and time.time() < deadline:
            time.sleep(0.01)
        assert publisher.stats()["bundles_sent"] == 2
        assert publisher.stats()["error"] is None
    finally:
        publisher.stop()
        receiver.close()


def test_environment_variables_reach_serve_and_demo(tmp_path, monkeypatch):
    assert demo_settings().osc is None  # off unless asked for
    monkeypatch.setenv("MOMLOC_OSC__HOST", "10.1.2.3")
    monkeypatch.setenv("MOMLOC_OSC__PORT", "7400")
    demo = demo_settings().osc
    assert demo is not None
    assert (demo.host, demo.port, demo.rate) == ("10.1.2.3", 7400, 30.0)
    path = tmp_path / "momloc.yaml"
    path.write_text("cameras: [{type: synthetic, index: 0}]\nosc: {host: a, port: 1, rate: 5}\n")
    s = load_settings(path).osc
    assert s is not None
    assert (s.host, s.port, s.rate) == ("10.1.2.3", 7400, 5.0)  # env wins key by key


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("osc: {port: 0}\n", "osc.port"),
        ("osc: {rate: 0}\n", "osc.rate"),
        ("osc: {hots: x}\n", "osc.hots"),
    ],
)
def test_bad_osc_settings_name_the_key(tmp_path, text, fragment):
    path = tmp_path / "momloc.yaml"
    path.write_text("cameras: [{type: synthetic, index: 0}]\n" + text)
    with pytest.raises(MomlocError, match=fragment.replace(".", r"\.")):
        load_settings(path)

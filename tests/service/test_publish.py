"""Publishers fed by the hub: zones from snapshots, bounded event queues, failures contained."""

from __future__ import annotations

import asyncio
import json

from service.outputs.falls import FallDetector, FallRules
from service.outputs.mqtt import MqttPublisher
from service.outputs.publisher import LatestSlot
from service.outputs.settings import MqttSettings
from service.outputs.zone_monitor import EventHub, ZoneMonitor
from service.outputs.zones import Zone
from service.pipeline.hub import Hub
from service.snapshot import Person, Snapshot
from tests.people import person

SQUARE = [(0, 0), (2, 0), (2, 2), (0, 2)]


def snap(seq: int, t: float, people: list[Person]) -> Snapshot:
    return Snapshot.build(seq, t, people)


def test_hub_feeds_publishers_and_a_failing_one_does_not_stop_the_others():
    hub = Hub()

    class Broken:
        name = "broken"

        def offer(self, snapshot: Snapshot) -> None:
            raise RuntimeError("boom")

        def stats(self) -> dict[str, int]:
            return {}

    seen: list[int] = []

    class Recorder:
        name = "recorder"

        def offer(self, snapshot: Snapshot) -> None:
            seen.append(snapshot.seq)

        def stats(self) -> dict[str, int]:
            return {"seen": len(seen)}

    recorder = Recorder()
    hub.add_publisher(Broken())
    hub.add_publisher(recorder)
    for seq in (1, 2, 3):
        hub.publish(snap(seq, float(seq), []))
    assert seen == [1, 2, 3] and hub.latest().seq == 3
    hub.remove_publisher(recorder)
    hub.publish(snap(4, 4.0, []))
    assert seen == [1, 2, 3]


def test_zone_monitor_turns_snapshots_into_events_and_occupancy():
    monitor = ZoneMonitor([Zone.create("sofa", SQUARE, hold_s=0.5)])
    calls = []

    class Listener:
        def on_zone_events(self, events, occupancy):
            calls.append(([e["type"] for e in events], occupancy[0]["count"]))

    monitor.add_listener(Listener())
    hub = Hub()
    hub.add_publisher(monitor)
    for i in range(30):  # 1 s inside at 30 fps, then 1 s outside
        hub.publish(snap(i + 1, 100 + i / 30, [person(4, 1.0, 1.0)]))
    for i in range(30):
        hub.publish(snap(i + 31, 101 + i / 30, [person(4, 5.0, 1.0)]))
    assert calls == [(["enter"], 1), (["leave"], 0)]
    described = monitor.describe()
    assert described["zones"][0]["name"] == "sofa" and described["zones"][0]["count"] == 0
    assert [e["type"] for e in described["recent_events"]] == ["enter", "leave"]
    assert described["recent_events"][1]["dwell_s"] == 1.0


def test_zone_and_fall_events_share_one_numbering_and_listeners_get_the_fall_state():
    zone = Zone.create("sofa", SQUARE, hold_s=0.5)
    monitor = ZoneMonitor([zone], falls=FallDetector(FallRules(lying_s=2.0), [zone]))
    calls = []

    class Listener:
        def on_zone_events(self, events, occupancy):
            calls.extend(events)

    monitor.add_listener(Listener())
    for i in range(60):  # stands in the zone for 1.7 s (min_standing_s: 1.5 s), then lies there
        someone = person(4, 1.0, 1.0)
        someone["posture"] = "standing" if i < 52 else "lying"
        monitor.offer(snap(i + 1, 100 + i / 30, [someone]))
    assert [(e["type"], e["seq"]) for e in calls] == [("enter", 1)]
    for i in range(60, 120):
        monitor.offer(snap(i + 1, 100 + i / 30, [{**person(4, 1.0, 1.0), "posture": "lying"}]))
    assert [(e["type"], e["seq"]) for e in calls] == [("enter", 1), ("fall", 2)]
    assert calls[1]["zones"] == ["sofa"] and calls[1]["falls"] == [4]
    assert monitor.describe()["falls"] == {"active": True, "ids": [4], "t": calls[1]["t"]}
    assert monitor.stats()["falls"] == [4]
    assert "falls" not in ZoneMonitor([zone]).describe()  # falls off: no fall state


def test_event_clients_have_bounded_queues_and_count_what_they_lose():
    async def scenario() -> None:
        hub = EventHub(max_queue=5)
        hub.bind(asyncio.get_running_loop())
        slow, fast = hub.subscribe(), hub.subscribe()
        got = []
        for i in range(12):
            hub.publish([json.dumps({"seq": i})])
            await asyncio.sleep(0)
            got.append(json.loads(await fast.next())["seq"])
        assert got == list(range(12))
        kept = [json.loads(await slow.next())["seq"] for _ in range(5)]
        assert kept == [7, 8, 9, 10, 11] and slow.dropped == 7 and not slow.queue

    asyncio.run(scenario())


def test_latest_slot_newest_wins():
    slot = LatestSlot()
    for value in range(5):
        slot.put(value)
    assert slot.take() == 4 and slot.take() is None and slot.overwritten == 4


def test_mqtt_offer_never_blocks_without_a_broker():
    """Not started (no broker at all): offering only fills the slot; events stay bounded."""
    publisher = MqttPublisher(MqttSettings(host="127.0.0.1", port=1, max_pending_events=3))
    for seq in range(1, 1001):
        publisher.offer(snap(seq, float(seq), []))
    publisher.on_zone_events(
        [{"zone": "a", "type": "enter", "id": i} for i in range(10)],
        [{"zone": "a", "count": 1, "ids": [1], "t": 1.0}],
    )
    stats = publisher.stats()
    assert stats["pending_events"] == 3 and stats["events_dropped"] == 7
    assert stats["positions_overwritten"] == 999 and not stats["connected"]

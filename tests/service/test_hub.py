"""Hub: newest value for pollers, one latest-value slot per subscriber, thread-safe publish."""

from __future__ import annotations

import asyncio
import json
import threading

from service.pipeline.hub import Hub
from service.snapshot import Snapshot
from tests.people import person


def snap(seq: int) -> Snapshot:
    return Snapshot.build(seq, 1000.0 + seq, [person(1, seq * 0.1, 0.0)])


def test_snapshot_wire_format():
    body = json.loads(snap(3).text)
    assert body == {
        "v": 1,
        "seq": 3,
        "t": 1003.0,
        "people": [
            {
                "id": 1,
                "x": 0.30000000000000004,
                "y": 0.0,
                "vx": 0.0,
                "vy": 0.0,
                "confidence": 1.0,
                "cameras": [0],
            }
        ],
    }
    assert snap(3).as_dict() == body


def test_slow_subscriber_skips_and_holds_one_value():
    async def scenario() -> None:
        hub = Hub()
        hub.bind(asyncio.get_running_loop())
        fast, slow = hub.subscribe(), hub.subscribe()
        for seq in range(1, 101):
            hub.publish(snap(seq))
            await asyncio.sleep(0)  # run the fan-out callback
            assert (await fast.next()).seq == seq
        # the slow one never read: it gets only the newest, and 99 were skipped, not queued
        assert (await slow.next()).seq == 100
        assert slow.skipped == 99 and slow.take_nowait() is None
        assert hub.latest().seq == 100
        hub.unsubscribe(slow)
        assert hub.subscriber_count == 1

    asyncio.run(scenario())


def test_publish_from_another_thread_and_prefill():
    async def scenario() -> None:
        hub = Hub()
        hub.bind(asyncio.get_running_loop())
        hub.publish(snap(1))
        late = hub.subscribe()  # a new client gets the newest value at once
        assert (await late.next()).seq == 1

        def publish_ten() -> None:
            for s in range(2, 12):
                hub.publish(snap(s))

        thread = threading.Thread(target=publish_ten)
        thread.start()
        thread.join()
        got = await asyncio.wait_for(late.next(), 2)
        while (more := late.take_nowait()) is not None:
            got = more
        await asyncio.sleep(0.05)
        while (more := late.take_nowait()) is not None:
            got = more
        assert got.seq == 11

    asyncio.run(scenario())


def test_publish_without_loop_keeps_latest():
    hub = Hub()
    hub.publish(snap(5))
    assert hub.latest().seq == 5 and hub.published == 1


def test_send_lag_bookkeeping():
    hub = Hub()
    for seq in range(1, 6):
        hub.publish(snap(seq))
    assert hub.note_send(5) == 0 and hub.note_send(4) == 1 and hub.note_send(2) == 3
    assert hub.stream_stats() == {
        "clients": 0,
        "published": 5,
        "sent": 3,
        "sent_behind": 1,
        "max_behind": 3,
    }

#!/usr/bin/env python3
"""Print every room's positions, zone changes and events (zones, falls) from an MQTT broker.

One daemon per room publishes under ``{base}/{room}/...``; this client subscribes with wildcards,
so it sees all rooms of a building through one broker. Needs only ``paho-mqtt`` 2.x
(``pip install paho-mqtt``); paho reconnects by itself when the broker restarts.

    python examples/mqtt_client.py --host 127.0.0.1 [--port 1883] [--base momloc] [--count N]

Lines printed (``room`` is the daemon's ``mqtt.room``)::

    [kitchen] positions seq 812  latency 14 ms  2 people  #3 (+1.25, +2.50)  #4 (+3.10, +0.80)
    [kitchen] zone sofa: 1 (#3)
    [kitchen] event enter sofa #3
    [kitchen] availability online
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time

from paho.mqtt.client import CallbackAPIVersion, Client


def describe(topic: str, payload: bytes, base: str) -> str | None:
    """One line for one message, or None for topics this client does not show."""
    levels = topic.split("/")
    base_levels = base.count("/") + 1
    if len(levels) <= base_levels + 1:
        return None
    room, rest = levels[base_levels], "/".join(levels[base_levels + 1 :])
    text = payload.decode(errors="replace")
    if rest == "positions":
        snap = json.loads(text)
        latency_ms = (time.time() - float(snap["t"])) * 1000
        people = "  ".join(f"#{p['id']} ({p['x']:+.2f}, {p['y']:+.2f})" for p in snap["people"])
        head = f"[{room}] positions seq {snap['seq']}  latency {latency_ms:.0f} ms"
        return f"{head}  {len(snap['people'])} people  {people}"
    if rest.startswith("zones/"):
        z = json.loads(text) if text else {"count": 0, "ids": []}
        ids = ", ".join(f"#{i}" for i in z["ids"])
        return f"[{room}] zone {rest[6:]}: {z['count']}" + (f" ({ids})" if ids else "")
    if rest == "events":
        e = json.loads(text)
        if "zone" not in e:  # fall, fall_cleared: where the person is, and the zones there
            zones = f" in {', '.join(e['zones'])}" if e.get("zones") else ""
            where = f" at ({e['x']:+.2f}, {e['y']:+.2f}){zones}" if "x" in e else ""
            return f"[{room}] event {e['type']} #{e['id']}{where}"
        dwell = f" after {e['dwell_s']:.1f} s" if "dwell_s" in e else ""
        return f"[{room}] event {e['type']} {e['zone']} #{e['id']}{dwell}"
    if rest == "availability":
        return f"[{room}] availability {text}"
    return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1", help="broker host")
    parser.add_argument("--port", type=int, default=1883, help="broker port")
    parser.add_argument("--base", default="momloc", help="the daemons' mqtt.base_topic")
    parser.add_argument("--username", default=None)
    parser.add_argument("--password", default=None)
    parser.add_argument("--count", type=int, default=None, help="stop after N lines")
    args = parser.parse_args(argv)

    done = threading.Event()
    printed = 0

    def on_connect(client, userdata, flags, reason, props):  # type: ignore[no-untyped-def]
        if reason.is_failure:
            print(f"broker refused the connection: {reason}", file=sys.stderr)
            return
        base = args.base
        topics = ["positions", "zones/+", "events", "availability"]
        client.subscribe([(f"{base}/+/{t}", 0 if t == "positions" else 1) for t in topics])

    def on_message(client, userdata, msg):  # type: ignore[no-untyped-def]
        nonlocal printed
        try:
            line = describe(msg.topic, bytes(msg.payload), args.base)
        except (ValueError, KeyError, IndexError) as error:
            line = f"{msg.topic}: unreadable payload ({error})"
        if line is None or done.is_set():
            return
        print(line, flush=True)
        printed += 1
        if args.count is not None and printed >= args.count:
            done.set()

    client = Client(CallbackAPIVersion.VERSION2)
    if args.username:
        client.username_pw_set(args.username, args.password)
    client.on_connect = on_connect
    client.on_message = on_message
    client.reconnect_delay_set(1, 10)
    try:
        client.connect(args.host, args.port, keepalive=30)
    except OSError as error:
        print(f"cannot connect to {args.host}:{args.port}: {error}", file=sys.stderr)
        return 2
    client.loop_start()
    try:
        while not done.wait(0.5):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        client.disconnect()
        client.loop_stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Print the positions streamed by a MoM Localizer daemon (``WS /v1/stream``).

Needs only the ``websockets`` package (``pip install websockets``). Reconnects with back-off when
the daemon restarts; a rejected token (close code 4401) stops it.

    python examples/python_client.py --url ws://127.0.0.1:8765/v1/stream [--token TOKEN]

Each message is one snapshot, schema version 1::

    {"v": 1, "seq": 12, "t": 1732390000.123,
     "people": [{"id": 3, "x": 1.25, "y": 2.5, "vx": 0.4, "vy": 0.0,
                 "confidence": 0.9, "cameras": [0, 1]}]}

x, y are metres on the floor; t is the capture time (unix seconds), so ``time.time() - t`` is
the end-to-end latency when client and daemon share a clock.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import time

from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed, InvalidStatus, InvalidURI

AUTH_CLOSE_CODE = 4401


def describe(snapshot: dict) -> str:
    """One line per snapshot: sequence number, latency and every person."""
    latency_ms = (time.time() - float(snapshot.get("t", 0.0))) * 1000.0
    people = snapshot.get("people", [])
    parts = [
        f"#{p['id']} ({p['x']:+.2f}, {p['y']:+.2f}) m  v=({p['vx']:+.2f}, {p['vy']:+.2f}) m/s"
        f"  conf {p['confidence']:.2f}  cams {p.get('cameras', [])}"
        for p in people
    ]
    head = f"seq {snapshot.get('seq')}  latency {latency_ms:.0f} ms  {len(people)} people"
    return "\n".join([head, *("  " + part for part in parts)])


async def stream(url: str, token: str | None, count: int | None, max_backoff: float) -> int:
    """Print snapshots until ``count`` were printed (forever if None); returns the exit code."""
    headers = {"Authorization": f"Bearer {token}"} if token else None
    printed = 0
    delay = 0.5
    while True:
        try:
            async with connect(url, additional_headers=headers) as ws:
                print(f"connected to {url}", file=sys.stderr, flush=True)
                delay = 0.5
                async for message in ws:
                    print(describe(json.loads(message)), flush=True)
                    printed += 1
                    if count is not None and printed >= count:
                        return 0
        except ConnectionClosed as closed:
            if closed.rcvd is not None and closed.rcvd.code == AUTH_CLOSE_CODE:
                print("error: the daemon rejected the token", file=sys.stderr)
                return 2
        except InvalidStatus as error:
            if error.response.status_code in (401, 403):
                print("error: the daemon rejected the token", file=sys.stderr)
                return 2
        except InvalidURI as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        except (OSError, TimeoutError) as error:
            print(f"cannot reach {url} ({error})", file=sys.stderr)
        print(f"reconnecting in {delay:.1f} s", file=sys.stderr, flush=True)
        await asyncio.sleep(delay)
        delay = min(delay * 2, max_backoff)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", default="ws://127.0.0.1:8765/v1/stream", help="%(default)s")
    parser.add_argument("--token", help="API token, when the daemon is configured with one")
    parser.add_argument("--count", type=int, help="exit after this many snapshots")
    parser.add_argument("--max-backoff", type=float, default=10.0, help="seconds (%(default)s)")
    args = parser.parse_args(argv)
    try:
        return asyncio.run(stream(args.url, args.token, args.count, args.max_backoff))
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())

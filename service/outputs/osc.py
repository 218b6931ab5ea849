"""OSC output: one UDP bundle per snapshot, for TouchDesigner, Max/MSP, Processing, Unreal, ...

Creative-coding tools speak Open Sound Control over UDP natively, so this publisher lets them use
the room without a WebSocket or JSON. Each bundle (time tag "immediately") holds, in this order:

=============================  =========================  ======================================
address                        arguments (OSC types)      meaning
=============================  =========================  ======================================
``/momloc/count``              ``n`` (i)                  people in the snapshot
``/momloc/ids``                ``id ...`` (i, one each)   the ids present, so a receiver can drop
                                                          the ones that left (no args: nobody)
``/momloc/person/<id>``        ``x y vx vy confidence``   floor metres, m/s, 0..1 (all f, 32 bit)
                                                          one message per person
``/momloc/zone/<name>``        ``count`` (i)              people inside each configured zone
=============================  =========================  ======================================

Why a bundle: the receiver gets one snapshot atomically (one datagram), never half of one, and a
lost datagram loses a whole snapshot rather than a few people. Floats are 32 bit because Max's
``udpreceive`` and TouchDesigner read ``f`` everywhere; doubles would need conversion there.

Never slowing the pipeline: ``offer`` (pipeline thread) only stores the snapshot in a latest-value
slot (``service.outputs.publisher.LatestSlot``); a thread of ours builds and sends at most ``rate``
bundles per second, always the newest snapshot. UDP has no back-pressure we could wait on: the
socket is non-blocking and a send that would block or fails is counted and dropped (the next
snapshot will replace it anyway). The host name is resolved in that thread (retried), never on the
pipeline.
"""

from __future__ import annotations

import logging
import socket
import time
from collections.abc import Callable
from typing import Any

from service.outputs.publisher import OutputContext, ThreadedPublisher
from service.outputs.settings import OscSettings
from service.snapshot import Snapshot

log = logging.getLogger("momloc.osc")

PREFIX = "/momloc"
Occupancy = Callable[[], list[dict[str, Any]]]


def build_bundle(snapshot: Snapshot, occupancy: list[dict[str, Any]] | None = None) -> bytes:
    """The OSC bundle (datagram bytes) for one snapshot; see the module docstring for the layout.

    >>> from service.snapshot import Snapshot
    >>> data = build_bundle(Snapshot.build(1, 0.0, []))
    >>> data[:8]
    b'#bundle\\x00'
    """
    from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
    from pythonosc.osc_message_builder import OscMessageBuilder

    def message(address: str, *args: tuple[Any, str]) -> Any:
        builder = OscMessageBuilder(address=address)
        for value, kind in args:
            builder.add_arg(value, kind)
        return builder.build()

    bundle = OscBundleBuilder(IMMEDIATELY)
    people = snapshot.people
    bundle.add_content(message(f"{PREFIX}/count", (len(people), "i")))
    bundle.add_content(message(f"{PREFIX}/ids", *((int(p["id"]), "i") for p in people)))
    for p in people:
        values = (p["x"], p["y"], p["vx"], p["vy"], p["confidence"])
        bundle.add_content(
            message(f"{PREFIX}/person/{int(p['id'])}", *((float(v), "f") for v in values))
        )
    for zone in occupancy or []:
        bundle.add_content(message(f"{PREFIX}/zone/{zone['zone']}", (int(zone["count"]), "i")))
    return bundle.build().dgram


class OscPublisher(ThreadedPublisher):
    """Publisher (see ``service.outputs.publisher``) sending bundles to one UDP receiver."""

    name = "osc"
    settings_key = "osc"

    def __init__(self, settings: OscSettings, *, occupancy: Occupancy | None = None) -> None:
        super().__init__()
        self.settings = settings
        self._occupancy = occupancy
        self.counters = {"bundles_sent": 0, "send_errors": 0, "resolve_failures": 0}
        self.address: tuple[Any, ...] | None = None

    @classmethod
    def from_settings(cls, settings: OscSettings, context: OutputContext) -> OscPublisher:
        return cls(settings, occupancy=context.occupancy)

    # -- sender thread ---------------------------------------------------------------------------

    def _resolve(self) -> tuple[socket.socket, tuple[Any, ...]] | None:
        s = self.settings
        try:
            family, kind, proto, _, address = socket.getaddrinfo(
                s.host, s.port, type=socket.SOCK_DGRAM
            )[0]
        except OSError as error:
            self.counters["resolve_failures"] += 1
            self.last_error = f"cannot resolve {s.host}: {error}"
            return None
        sock = socket.socket(family, kind, proto)
        sock.setblocking(False)
        self.address = address
        self.last_error = None
        return sock, address

    def _run(self) -> None:
        interval = 1.0 / self.settings.rate
        target = None
        next_send = 0.0
        while not self._stopping.is_set():
            if target is None:
                target = self._resolve()
                if target is None:
                    self._stopping.wait(2.0)
                    continue
            now = time.monotonic()
            if now < next_send:
                self._hungry = False
                self._stopping.wait(next_send - now)
                continue
            self._hungry = True
            if self._slot.peek() is None:
                self._wake.wait(1.0)
                self._wake.clear()
                continue
            snapshot = self._slot.take()
            try:
                occupancy = self._occupancy() if self._occupancy else None
                target[0].sendto(build_bundle(snapshot, occupancy), target[1])
                self.counters["bundles_sent"] += 1
                self.last_error = None  # delivering again (health shows only current trouble)
            except OSError as error:  # would block, no route, too large: drop this one
                self.counters["send_errors"] += 1
                self.last_error = f"send failed: {error}"
            except Exception as error:  # a bug must not kill the thread silently
                self.counters["send_errors"] += 1
                self.last_error = f"{type(error).__name__}: {error}"
                log.exception("osc sender")
            # on average <= rate; after a pause at most one bundle early, never a burst
            next_send = max(next_send + interval, now + 0.5 * interval)
        if target is not None:
            target[0].close()

    def degraded(self) -> str | None:
        return self.last_error

    def stats(self) -> dict[str, Any]:
        return {
            "target": f"{self.settings.host}:{self.settings.port}",
            "rate": self.settings.rate,
            "snapshots_skipped": self._slot.overwritten,
            "error": self.last_error,
            **self.counters,
        }

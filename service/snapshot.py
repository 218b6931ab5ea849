"""The value every client receives: one snapshot of the tracked people, and its JSON text.

Wire format (version 1)::

    {"v": 1, "seq": 12, "t": 1732390000.123,
     "people": [{"id": 3, "x": 1.25, "y": 2.5, "vx": 0.4, "vy": 0.0,
                 "confidence": 0.9, "cameras": [0, 1]}]}

``t`` is the capture time of the frames the snapshot came from (unix seconds, wall clock), so a
client on the same host measures latency as receive time - ``t``. A person outside the floor area
the model was set up on carries ``"outside": true``, and only when the daemon is set to serve
them (``tracking.outside_area: flag``; by default they are not served at all).

Optional since issue 27 (v1 clients ignore unknown keys): ``"posture"`` (``"standing"``,
``"sitting"`` or ``"lying"``, crouching counts as sitting) and ``"posture_confidence"`` (0..1)
when the model can tell (:mod:`service.tracking.posture`: it needs the set-up area's height
model; absent means unknown).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

SCHEMA_VERSION = 1


@dataclass(frozen=True)
class Snapshot:
    """One published result; ``text`` is the exact JSON sent on the wire."""

    seq: int
    t: float
    people: list[dict[str, Any]]
    text: str = field(repr=False)

    @classmethod
    def build(cls, seq: int, t: float, people: Sequence[dict[str, Any]]) -> Snapshot:
        people = [dict(p) for p in people]
        body = {"v": SCHEMA_VERSION, "seq": seq, "t": t, "people": people}
        return cls(seq, t, people, json.dumps(body, separators=(",", ":")))

    def inside_only(self) -> Snapshot:
        """This snapshot without the people served flagged ``outside`` (the set-up area,
        ``service.pipeline.chain``): what zones, counts and MQTT see unless asked for everyone."""
        if not any(p.get("outside") for p in self.people):
            return self
        return Snapshot.build(self.seq, self.t, [p for p in self.people if not p.get("outside")])

    def as_dict(self) -> dict[str, Any]:
        return {"v": SCHEMA_VERSION, "seq": self.seq, "t": self.t, "people": self.people}


EMPTY = Snapshot.build(0, 0.0, [])

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

:class:`Person` and :class:`SnapshotBody` are the wire format as types: the pipeline writes
people of that type, the API declares it as the response of ``/v1/positions`` (so ``/docs``
shows every field) and the clients' tests read it. They are ``TypedDict`` s, not pydantic models:
a person stays a plain dict at run time, so the hub encodes each snapshot's JSON at 30 Hz as
before, while mypy checks every writer and pydantic still derives the OpenAPI schema from them.
Imported from ``typing_extensions`` because pydantic reads a ``TypedDict`` only from there
before Python 3.12.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated, Any, Final, Literal, NotRequired, Protocol, runtime_checkable

from pydantic import ConfigDict, Field, with_config
from typing_extensions import TypedDict

SCHEMA_VERSION: Final = 1


@with_config(ConfigDict(extra="forbid"))  # the schema says: no other fields
class Person(TypedDict):
    """One tracked person in a snapshot."""

    id: Annotated[int, Field(description="Track id: the same person keeps it while tracked.")]
    x: Annotated[float, Field(description="Floor position x (m), the set-up's floor axes.")]
    y: Annotated[float, Field(description="Floor position y (m), the set-up's floor axes.")]
    vx: Annotated[float, Field(description="Velocity (m/s) along x.")]
    vy: Annotated[float, Field(description="Velocity (m/s) along y.")]
    confidence: Annotated[
        float, Field(ge=0.0, le=1.0, description="How steadily the track is measured, 0..1.")
    ]
    cameras: Annotated[
        list[int], Field(description="Cameras (indices) that see the person in this snapshot.")
    ]
    outside: NotRequired[
        Annotated[
            bool,
            Field(
                description="Present (true) only for a person outside the set-up area, served "
                "when tracking.outside_area is flag."
            ),
        ]
    ]
    posture: NotRequired[
        Annotated[
            Literal["standing", "sitting", "lying"],
            Field(
                description="From the box shape (crouching counts as sitting); absent: unknown "
                "(the model has no set-up height model)."
            ),
        ]
    ]
    posture_confidence: NotRequired[
        Annotated[float, Field(ge=0.0, le=1.0, description="Confidence of posture, 0..1.")]
    ]


@with_config(ConfigDict(extra="forbid"))
class SnapshotBody(TypedDict):
    """The JSON of one snapshot (``/v1/positions``, each ``/v1/stream`` message)."""

    v: Annotated[Literal[1], Field(description="Wire format version.")]
    seq: Annotated[int, Field(description="Snapshot number, increasing by one per frame set.")]
    t: Annotated[float, Field(description="Capture time of the frames (unix seconds).")]
    people: list[Person]


@dataclass(frozen=True)
class Snapshot:
    """One published result; ``text`` is the exact JSON sent on the wire."""

    seq: int
    t: float
    people: list[Person]
    text: str = field(repr=False)

    @classmethod
    def build(cls, seq: int, t: float, people: Sequence[Person]) -> Snapshot:
        copies = [p.copy() for p in people]
        body: SnapshotBody = {"v": SCHEMA_VERSION, "seq": seq, "t": t, "people": copies}
        return cls(seq, t, copies, json.dumps(body, separators=(",", ":")))

    def inside_only(self) -> Snapshot:
        """This snapshot without the people served flagged ``outside`` (the set-up area,
        ``service.pipeline.chain``): what zones, counts and MQTT see unless asked for everyone."""
        if not any(p.get("outside") for p in self.people):
            return self
        return Snapshot.build(self.seq, self.t, [p for p in self.people if not p.get("outside")])

    def as_dict(self) -> SnapshotBody:
        return {"v": SCHEMA_VERSION, "seq": self.seq, "t": self.t, "people": self.people}


EMPTY = Snapshot.build(0, 0.0, [])


@runtime_checkable
class Publisher(Protocol):
    """An output fed by the hub (``service.pipeline.hub.Hub.add_publisher``): zones, MQTT, OSC.

    The hub calls ``offer(snapshot)`` for every snapshot, on the pipeline thread, right after it
    makes it the newest. ``offer`` must return at once: it may do a few microseconds of bounded
    work (the zone tracker's point-in-polygon tests) or store the snapshot in a latest-value slot
    for a thread of its own (the MQTT publisher), but it never waits on a socket, a lock held by
    I/O or an unbounded queue. An exception in ``offer`` is logged by the hub and the pipeline
    goes on. Defined here, beside the value it takes, so the pipeline's hub and the outputs
    (``service.outputs``) share it without the pipeline importing an output.
    """

    name: str

    def offer(self, snapshot: Snapshot) -> None:
        """Take ``snapshot`` (pipeline thread; never blocks)."""
        ...

    def stats(self) -> dict[str, Any]:
        """Counters for ``/v1/health`` and ``/metrics``."""
        ...

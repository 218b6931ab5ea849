"""Wire-format people for tests (``service.snapshot.Person``), with the fields a test does not
care about filled in."""

from __future__ import annotations

from collections.abc import Sequence

from service.snapshot import Person


def person(
    track_id: int,
    x: float = 0.0,
    y: float = 0.0,
    *,
    vx: float = 0.0,
    vy: float = 0.0,
    confidence: float = 1.0,
    cameras: Sequence[int] = (0,),
) -> Person:
    return {
        "id": track_id,
        "x": x,
        "y": y,
        "vx": vx,
        "vy": vy,
        "confidence": confidence,
        "cameras": list(cameras),
    }

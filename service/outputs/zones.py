"""Zones: named floor polygons, who is inside each, and enter/leave events with dwell time.

Pure logic (no threads, no I/O) so it behaves the same live and on recordings, and is easy to
test. :class:`ZoneTracker` is fed one snapshot at a time (``update(t, people)``) and returns the
events that snapshot confirmed.

Geometry
--------
Polygons are in metres in the floor-mark frame (the snapshot's x, y). :func:`validate_polygon`
refuses fewer than 3 points, non-finite values, repeated consecutive vertices, zero area and
self-intersection (any two non-adjacent edges that touch or cross, including collinear overlap),
because the even-odd rule gives surprising answers on such shapes. :func:`point_in_polygon`
counts points *on* an edge or vertex as inside, so a zone's occupancy does not depend on which
way floating point rounds when someone stands exactly on the tape; concave polygons are handled
by the crossing rule (no convexity is assumed).

Hysteresis (why and how)
------------------------
Localization jitters by a few centimetres, so a person standing at a border would flap in and out
on every frame. A person's membership of a zone changes only after the raw inside/outside answer
has disagreed with the confirmed one for ``hold_s`` seconds (default 0.5) without interruption.
Time comes from the snapshot's ``t`` (capture time), never the wall clock, so a recording replays
the same events. A person whose id disappears from the snapshots counts as outside from the first
snapshot without them (the tracker already bridges short occlusions), so the leave event comes
``hold_s`` later, on a later snapshot.

Event JSON (one per ``WS /v1/events`` message and MQTT ``{base}/{room}/events`` message)::

    {"v": 1, "seq": 4, "type": "enter", "zone": "sofa", "id": 3, "t": 1732390000.6,
     "since": 1732390000.1, "count": 1, "ids": [3]}
    {"v": 1, "seq": 5, "type": "leave", "zone": "sofa", "id": 3, "t": 1732390012.9,
     "since": 1732390012.4, "dwell_s": 12.3, "count": 0, "ids": []}

``t`` is the capture time of the snapshot that confirmed the change, ``since`` the capture time
at which it began (first snapshot inside / outside); ``dwell_s`` = leave ``since`` - enter
``since``; ``count`` / ``ids`` the zone's occupancy after the event.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

EVENT_VERSION = 1
DEFAULT_HOLD_S = 0.5
_EPS = 1e-12

Point = tuple[float, float]


def _cross(o: Point, a: Point, b: Point) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _on_segment(p: Point, a: Point, b: Point, eps: float = 1e-9) -> bool:
    """``p`` lies on segment a-b (within ``eps`` metres of the line, inside its extent)."""
    length = math.hypot(b[0] - a[0], b[1] - a[1])
    if length < _EPS:
        return math.hypot(p[0] - a[0], p[1] - a[1]) <= eps
    if abs(_cross(a, b, p)) / length > eps:
        return False
    return (
        min(a[0], b[0]) - eps <= p[0] <= max(a[0], b[0]) + eps
        and min(a[1], b[1]) - eps <= p[1] <= max(a[1], b[1]) + eps
    )


def segments_touch(a: Point, b: Point, c: Point, d: Point) -> bool:
    """Segments a-b and c-d cross or touch (an endpoint on the other, collinear overlap)."""
    d1, d2 = _cross(c, d, a), _cross(c, d, b)
    d3, d4 = _cross(a, b, c), _cross(a, b, d)
    if ((d1 > 0 > d2) or (d1 < 0 < d2)) and ((d3 > 0 > d4) or (d3 < 0 < d4)):
        return True
    return (
        _on_segment(a, c, d) or _on_segment(b, c, d) or _on_segment(c, a, b) or _on_segment(d, a, b)
    )


def polygon_area(points: Sequence[Point]) -> float:
    """Signed area (shoelace; positive when counter-clockwise)."""
    n = len(points)
    return 0.5 * sum(
        points[i][0] * points[(i + 1) % n][1] - points[(i + 1) % n][0] * points[i][1]
        for i in range(n)
    )


def validate_polygon(raw: Iterable[Iterable[float]]) -> list[Point]:
    """The polygon as a list of (x, y) floats; ``ValueError`` saying what is wrong otherwise.

    A closing vertex equal to the first one is accepted and dropped.
    """
    points: list[Point] = []
    for i, vertex in enumerate(raw):
        values = list(vertex)
        if len(values) != 2:
            raise ValueError(f"point {i} must be [x, y], got {len(values)} values")
        x, y = float(values[0]), float(values[1])
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"point {i} is not finite: [{x}, {y}]")
        points.append((x, y))
    if len(points) >= 2 and points[0] == points[-1]:
        points.pop()
    if len(points) < 3:
        raise ValueError(f"a polygon needs at least 3 distinct points, got {len(points)}")
    n = len(points)
    for i in range(n):
        if (
            math.hypot(points[i][0] - points[(i + 1) % n][0], points[i][1] - points[(i + 1) % n][1])
            < 1e-9
        ):
            raise ValueError(f"points {i} and {(i + 1) % n} are the same")
    if max(abs(_cross(points[0], points[1], p)) for p in points) < 1e-9:
        raise ValueError("the polygon has no area (all points on one line)")
    for i in range(n):
        a, b = points[i], points[(i + 1) % n]
        for j in range(i + 1, n):
            if j == i or (j + 1) % n == i or j == (i + 1) % n:
                continue  # adjacent edges share a vertex by construction
            c, d = points[j], points[(j + 1) % n]
            if segments_touch(a, b, c, d):
                raise ValueError(f"the polygon intersects itself (edges {i} and {j})")
    # adjacent edges folding back onto each other (a spike) also overlap
    for i in range(n):
        prev, here, nxt = points[i - 1], points[i], points[(i + 1) % n]
        if abs(_cross(prev, here, nxt)) < 1e-12 and (
            (here[0] - prev[0]) * (nxt[0] - here[0]) + (here[1] - prev[1]) * (nxt[1] - here[1]) < 0
        ):
            raise ValueError(f"the polygon intersects itself (edges fold back at point {i})")
    if abs(polygon_area(points)) < 1e-9:
        raise ValueError("the polygon has no area (all points on one line)")
    return points


def point_in_polygon(x: float, y: float, polygon: Sequence[Point]) -> bool:
    """Even-odd crossing test; points on an edge or vertex count as inside."""
    n = len(polygon)
    p = (x, y)
    for i in range(n):
        if _on_segment(p, polygon[i], polygon[(i + 1) % n]):
            return True
    inside = False
    for i in range(n):
        (x1, y1), (x2, y2) = polygon[i], polygon[(i + 1) % n]
        if (y1 > y) != (y2 > y):  # half-open rule: each vertex counted once
            x_cross = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
            if x < x_cross:
                inside = not inside
    return inside


@dataclass(frozen=True)
class Zone:
    """A validated zone: name, polygon (metres) and hysteresis time."""

    name: str
    polygon: tuple[Point, ...]
    hold_s: float = DEFAULT_HOLD_S

    @classmethod
    def create(
        cls, name: str, polygon: Iterable[Iterable[float]], hold_s: float = DEFAULT_HOLD_S
    ) -> Zone:
        if not (math.isfinite(hold_s) and hold_s >= 0):
            raise ValueError("hold_s must be a finite number of seconds >= 0")
        return cls(name, tuple(validate_polygon(polygon)), float(hold_s))

    def contains(self, x: float, y: float) -> bool:
        return point_in_polygon(x, y, self.polygon)

    def as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "polygon": [list(p) for p in self.polygon],
            "hold_s": self.hold_s,
        }


@dataclass
class _Membership:
    inside: bool = False  # confirmed state
    entered: float | None = None  # ``since`` of the confirmed enter
    change_since: float | None = None  # start of the streak disagreeing with ``inside``


@dataclass
class ZoneState:
    """Occupancy of one zone after the latest snapshot."""

    zone: Zone
    members: dict[int, _Membership] = field(default_factory=dict)
    changed_t: float | None = None  # capture time of the last occupancy change

    @property
    def ids(self) -> list[int]:
        return sorted(pid for pid, m in self.members.items() if m.inside)

    @property
    def count(self) -> int:
        return len(self.ids)

    def occupancy(self) -> dict[str, Any]:
        return {"zone": self.zone.name, "count": self.count, "ids": self.ids, "t": self.changed_t}


class ZoneTracker:
    """Per-zone occupancy with hysteresis; ``update`` returns the events one snapshot confirms."""

    def __init__(self, zones: Sequence[Zone]) -> None:
        names = [z.name for z in zones]
        if len(names) != len(set(names)):
            raise ValueError("zone names must be unique")
        self.states = {z.name: ZoneState(z) for z in zones}
        self.seq = 0
        self.last_t: float | None = None

    @property
    def zones(self) -> list[Zone]:
        return [s.zone for s in self.states.values()]

    def update(self, t: float, people: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
        """Advance to capture time ``t`` with the snapshot's people (dicts with id, x, y)."""
        if self.last_t is not None and t < self.last_t:
            t = self.last_t  # never let time run backwards (a looped recording)
        self.last_t = t
        positions = {int(p["id"]): (float(p["x"]), float(p["y"])) for p in people}
        events: list[dict[str, Any]] = []
        for state in self.states.values():
            zone = state.zone
            raw = {pid: zone.contains(x, y) for pid, (x, y) in positions.items()}
            for pid in set(state.members) | {pid for pid, inside in raw.items() if inside}:
                member = state.members.setdefault(pid, _Membership())
                now_inside = raw.get(pid, False)
                if now_inside == member.inside:
                    member.change_since = None
                else:
                    if member.change_since is None:
                        member.change_since = t
                    if t - member.change_since >= zone.hold_s:
                        events.append(self._flip(state, pid, member, t))
                if not member.inside and member.change_since is None:
                    del state.members[pid]  # outside and settled: forget
        return events

    def _flip(self, state: ZoneState, pid: int, member: _Membership, t: float) -> dict[str, Any]:
        since = member.change_since if member.change_since is not None else t
        member.inside = not member.inside
        member.change_since = None
        state.changed_t = t
        self.seq += 1
        event: dict[str, Any] = {
            "v": EVENT_VERSION,
            "seq": self.seq,
            "type": "enter" if member.inside else "leave",
            "zone": state.zone.name,
            "id": pid,
            "t": t,
            "since": since,
        }
        if member.inside:
            member.entered = since
        else:
            entered = member.entered if member.entered is not None else since
            event["dwell_s"] = round(since - entered, 3)
            member.entered = None
        event["count"] = state.count
        event["ids"] = state.ids
        return event

    def occupancy(self) -> list[dict[str, Any]]:
        return [s.occupancy() for s in self.states.values()]

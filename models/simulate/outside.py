"""People beyond the set-up area: in view of the cameras, never labelled, never tracked.

Why: a real room is not empty outside the floor the marks cover. In the CMC room (Ong et al.,
IEEE TPAMI 2020) the detector returns ~9 boxes per frame of people outside the authors' tracking
area, and a model that never saw them localizes them inside its area (issue 23). A simulator
without them hides that failure, so a scene can put ``SceneConfig.outside_people`` extra people
in the *outside region*: ``outside_region`` when given (where people stand in a particular
room), else the room grown by ``outside_band`` metres on every side (open space beyond the
walls; 0 = the room itself), minus the set-up ``area``. That region is cut into up to
four strips (left and right of the area over the whole depth, then below and above it between
them); each outside person is put in one strip (probability proportional to its floor area)
and wanders there like the tracked people do (:class:`~models.simulate.people.Walkers`), so
nobody crosses the set-up area. The camera sees them with the same detector noise, occlusion
and misses as everyone else; :class:`~models.simulate.observation.FrameObservation` holds
them apart (``outside_*`` arrays).

``outside_posture`` (a name of :mod:`models.simulate.postures`) is the body they hold while they
move about; ``"standing"`` walks. Why a room may want another: the real CMC room's outside people
are boxed like seated people. In the far cameras their boxes are 0.73 of a standing person's at
the same foot point (relative to the in-area people's; a seated pose is about 0.72 of a
stature), and in the cameras beside them they cover an in-area person's reference box by more
than 10 % 2.6 % of the time. Standing simulated outside people gave 0.95 and 18 % and hid
in-area people the real ones do not; seated ones give 0.67 and 4 %
(``bench/results/sim_vs_real_occlusion.md``, which also has what each change did to the share
of people boxed by fewer than 3 cameras).

Determinism: strips are drawn from ``[seed, 11]`` and strip ``s``'s walkers from
``[seed, 12, s]``, streams no other part of the scene uses, so a scene without outside people
draws exactly what it drew before they existed.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from common.errors import MomlocError
from models.simulate.people import Walkers, WalkerStates, Walking
from models.simulate.postures import CODES, STANDING

MIN_STRIP = 0.5  # metres: narrower strips are left empty (no room to walk)

Rect = tuple[float, float, float, float]  # xmin, xmax, ymin, ymax (metres)


class Placed:
    """A :class:`Walking` group moved by ``offset`` (its walkers live in local coordinates)."""

    def __init__(self, walking: Walking, offset: tuple[float, float]) -> None:
        self.walking = walking
        self.offset = np.asarray(offset, float)
        self.heights = walking.heights

    def states(self, start: int, stop: int) -> WalkerStates:
        s = self.walking.states(start, stop)
        return dataclasses.replace(s, position=s.position + self.offset)


class Holding:
    """A :class:`Walking` group whose people all hold ``posture`` (a :data:`CODES` value)."""

    def __init__(self, walking: Walking, posture: int) -> None:
        self.walking = walking
        self.posture = posture
        self.heights = walking.heights

    def states(self, start: int, stop: int) -> WalkerStates:
        s = self.walking.states(start, stop)
        shape = s.heading.shape
        return dataclasses.replace(
            s, posture=np.full(shape, self.posture, np.int64), posture_weight=np.ones(shape)
        )


class Together:
    """Several :class:`Walking` groups as one: people concatenated in the groups' order."""

    def __init__(self, groups: list[Walking]) -> None:
        self.groups = groups
        self.heights = np.concatenate([g.heights for g in groups]) if groups else np.zeros(0)

    def states(self, start: int, stop: int) -> WalkerStates:
        parts = [g.states(start, stop) for g in self.groups]
        position, heading, phase, amplitude = (
            np.concatenate([getattr(p, key) for p in parts], axis=1) for key in _KEYS
        )
        if all(p.posture is None for p in parts):
            return WalkerStates(position, heading, phase, amplitude)
        held = [p.postures() for p in parts]
        return WalkerStates(
            position, heading, phase, amplitude,
            np.concatenate([code for code, _ in held], axis=1),
            np.concatenate([weight for _, weight in held], axis=1),
        )  # fmt: skip


_KEYS = ("position", "heading", "phase", "amplitude")


def strips(
    room: tuple[float, float], area: Rect, band: float, region: Rect | None = None
) -> list[Rect]:
    """The outside region (``region``, or the room grown by ``band``) minus ``area`` as up to
    four rectangles at least :data:`MIN_STRIP` wide each way: left, right, below, above."""
    x0, x1, y0, y1 = (
        region if region is not None else (-band, room[0] + band, -band, room[1] + band)
    )
    ax0, ax1, ay0, ay1 = area
    mx0, mx1 = max(ax0, x0), min(ax1, x1)  # the area's columns inside the region
    out = [
        (x0, min(ax0, x1), y0, y1),
        (max(ax1, x0), x1, y0, y1),
        (mx0, mx1, y0, min(ay0, y1)),
        (mx0, mx1, max(ay1, y0), y1),
    ]
    return [r for r in out if r[1] - r[0] >= MIN_STRIP and r[3] - r[2] >= MIN_STRIP]


def outside_walkers(
    room: tuple[float, float],
    area: Rect,
    band: float,
    count: int,
    fps: float,
    seed: int,
    region: Rect | None = None,
    posture: str = "standing",
) -> Walking:
    """``count`` people wandering the outside region, each kept to one strip, holding
    ``posture``."""
    rects = strips(room, area, band, region)
    if not rects:
        raise MomlocError(
            f"outside people: no floor outside the set-up area {area} in room {room} "
            f"(band {band} m): give a smaller area or an outside band"
        )
    sizes = np.array([(r[1] - r[0]) * (r[3] - r[2]) for r in rects])
    choice = np.random.default_rng([seed, 11]).choice(len(rects), count, p=sizes / sizes.sum())
    groups: list[Walking] = []
    for s, rect in enumerate(rects):
        n = int((choice == s).sum())
        if n:
            walkers = Walkers(
                (rect[1] - rect[0], rect[3] - rect[2]), n, fps, np.random.default_rng([seed, 12, s])
            )
            groups.append(Placed(walkers, (rect[0], rect[2])))
    together = Together(groups)
    return together if CODES[posture] == STANDING else Holding(together, CODES[posture])

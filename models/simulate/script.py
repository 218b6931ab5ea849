"""A person who follows a script: walk from point to point, stand, sit, crouch or lie down.

The set-up collection (:mod:`models.simulate.scripted`: walk to a floor mark, stand on it while
swaying and turning, walk on) and the posture scenes (someone sits on the sofa for an hour,
crouches to pick something up, falls) share one schedule: a list of :class:`Segment`. Each
segment moves from ``start`` to ``end`` (equal points: staying) over ``seconds`` in a posture.

While standing, the mid-hip sways by a few centimetres around the point and the body turns ±70°
back and forth (a user waiting on a mark). While sitting, crouching or lying it sways by
``HELD_SWAY_M`` only and faces ``heading``; the body morphs into the pose over the first
``ramp_s`` seconds of the segment (and back out over its last ``ramp_s`` when the next segment
is in another posture), so a fall is a lying segment with a short ramp.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from common.errors import MomlocError
from models.simulate import postures
from models.simulate.people import WalkerStates

SWAY_M = 0.04
SWAY_PERIOD_S = 3.1
TURN_RAD = 1.2
TURN_PERIOD_S = 9.0
STAND_AMPLITUDE = 0.15
HELD_SWAY_M = 0.01  # a seated or lying person shifts a little, never steps


@dataclass(frozen=True)
class Segment:
    """Move from ``start`` to ``end`` (metres) over ``seconds``; equal points mean staying.

    ``posture``: one of :data:`models.simulate.postures.NAMES`; ``heading`` (radians) the way a
    person in a held posture faces (None: a fixed direction drawn per person); ``ramp_s`` how
    long getting into (and out of) the posture takes."""

    start: tuple[float, float]
    end: tuple[float, float]
    seconds: float
    posture: str = "standing"
    heading: float | None = None
    ramp_s: float = 1.5

    def __post_init__(self) -> None:
        if self.posture not in postures.CODES:
            raise MomlocError(
                f"segment posture '{self.posture}' is not one of {', '.join(postures.NAMES)}"
            )
        if self.seconds <= 0 or self.ramp_s <= 0:
            raise MomlocError("segment seconds and ramp_s must be > 0")


class ScriptedWalker:
    """One person following ``segments`` back to back, then holding the last one's end."""

    count = 1

    def __init__(self, segments: list[Segment], fps: float, rng: np.random.Generator) -> None:
        if not segments:
            raise ValueError("a scripted walker needs at least one segment")
        self.segments = segments
        self.fps = float(fps)
        self.heights = rng.uniform(1.5, 1.95, 1)
        self._turn_offset = rng.uniform(-np.pi, np.pi)
        self._ends = np.cumsum([s.seconds for s in segments])
        self._held = any(s.posture != "standing" for s in segments)

    @property
    def duration_s(self) -> float:
        return float(self._ends[-1])

    def states(self, start: int, stop: int) -> WalkerStates:
        """States of frames ``start`` .. ``stop - 1`` (shapes [F, 1, ...])."""
        t = np.arange(start, stop) / self.fps
        index = np.minimum(np.searchsorted(self._ends, t, side="right"), len(self.segments) - 1)
        segments = [self.segments[i] for i in index]
        seconds = np.array([s.seconds for s in segments])
        begin = self._ends[index] - seconds
        a = np.array([s.start for s in segments])
        b = np.array([s.end for s in segments])
        fraction = np.clip((t - begin) / np.maximum(seconds, 1e-9), 0.0, 1.0)
        delta = b - a
        length = np.linalg.norm(delta, axis=1)
        walking = length > 1e-6
        code = np.array([postures.CODES[s.posture] for s in segments])
        held = code != postures.STANDING
        position = a + fraction[:, None] * delta
        sway = (
            np.stack(
                [
                    np.sin(2 * np.pi * t / SWAY_PERIOD_S),
                    np.sin(2 * np.pi * t / (1.37 * SWAY_PERIOD_S)),
                ],
                axis=1,
            )
            * np.where(held, HELD_SWAY_M, SWAY_M)[:, None]
        )
        position = np.where(walking[:, None], position, position + sway)
        standing_heading = self._turn_offset + TURN_RAD * np.sin(2 * np.pi * t / TURN_PERIOD_S)
        facing = np.array([self._turn_offset if s.heading is None else s.heading for s in segments])
        heading = np.where(walking, np.arctan2(delta[:, 1], delta[:, 0]), standing_heading)
        heading = np.where(held & ~walking, facing, heading)
        speed = np.where(walking, length / np.maximum(seconds, 1e-9), 0.0)
        amplitude = np.where(walking, np.clip(speed / 1.2, 0.3, 1.0), STAND_AMPLITUDE)
        amplitude = np.where(held, 0.0, amplitude)
        stride = 0.8 * self.heights[0]
        phase = (2 * np.pi * np.maximum(speed, 0.3) / stride * t) % (2 * np.pi)
        states = WalkerStates(
            position[:, None, :], heading[:, None], phase[:, None], amplitude[:, None]
        )
        if not self._held:
            return states
        ramp = np.array([s.ramp_s for s in segments])
        weight = np.clip((t - begin) / ramp, 0.0, 1.0)
        leaves = np.array(
            [i + 1 < len(self.segments) and self.segments[i + 1].posture != s.posture
             for i, s in zip(index, segments, strict=True)]
        )  # fmt: skip
        weight = np.where(leaves, np.minimum(weight, np.clip((self._ends[index] - t) / ramp, 0, 1)),
                          weight)  # fmt: skip
        return WalkerStates(
            states.position, states.heading, states.phase, states.amplitude,
            code[:, None], weight[:, None],
        )  # fmt: skip

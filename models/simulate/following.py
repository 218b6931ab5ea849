"""A simulated person who follows live set-up instructions, for the set-up flow without a human.

:mod:`scripted` plays a plan known in advance (``momloc collect --source synthetic``). The web
set-up flow instead runs on the live daemon: the page's session says "go to mark B2" whenever it
gets there, and the person in the synthetic scene must react. :class:`FollowingWalker` asks a
``target()`` callable (the daemon's current set-up instruction) each time the scene needs frames
it has not simulated yet, walks there and stands (swaying and turning, as :mod:`scripted` does).

Why it hurries (``SPEED_MPS`` = 3 m/s, faster than a person): the scene computes observations in
blocks of 64 frames (about 2 s) ahead, so a new instruction reaches the person up to one block
late; a real user has the same move time and no such lag, so a quick simulated person keeps the
recorded labels as right as a real one's.

States are remembered per frame (the recent ``HISTORY`` frames), so the renderer and the
observation blocks, which ask for the same frames separately, see the same person.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from models.simulate.people import WalkerStates
from models.simulate.scripted import (
    STAND_AMPLITUDE,
    SWAY_M,
    SWAY_PERIOD_S,
    TURN_PERIOD_S,
    TURN_RAD,
)

SPEED_MPS = 3.0
HISTORY = 4096  # frames remembered (over 2 minutes at 30 fps; blocks ask for the last few)

Target = Callable[[], tuple[float, float] | None]


class FollowingWalker:
    """One person walking to ``target()`` (None: stay where they are), frame by frame."""

    count = 1

    def __init__(self, fps: float, rng: np.random.Generator, start: tuple[float, float]) -> None:
        self.fps = float(fps)
        self.heights = rng.uniform(1.5, 1.95, 1)
        self.target: Target = lambda: None
        self._turn_offset = float(rng.uniform(-np.pi, np.pi))
        self._here = np.array(start, float)  # the walk's point at frame ``_next - 1``
        self._heading = self._turn_offset
        self._next = 0  # first frame not simulated yet
        self._frames: dict[int, tuple[float, float, float, float, float]] = {}

    def states(self, start: int, stop: int) -> WalkerStates:
        """States of frames ``start`` .. ``stop - 1`` (shapes [F, 1, ...])."""
        if stop > self._next:
            self._advance(stop)
        rows = [self._frames.get(i, self._frames[min(self._frames)]) for i in range(start, stop)]
        x, y, heading, phase, amplitude = (np.array(c, float) for c in zip(*rows, strict=True))
        return WalkerStates(
            np.stack([x, y], axis=1)[:, None, :],
            heading[:, None],
            phase[:, None],
            amplitude[:, None],
        )

    def _advance(self, stop: int) -> None:
        """Simulate frames ``_next`` .. ``stop - 1`` towards the target read now."""
        target = self.target()
        step = SPEED_MPS / self.fps
        stride = 0.8 * float(self.heights[0])
        for i in range(self._next, stop):
            t = i / self.fps
            delta = np.zeros(2) if target is None else np.asarray(target, float) - self._here
            distance = float(np.hypot(*delta))
            if distance > 1e-6:
                self._here = self._here + delta * min(1.0, step / distance)
                self._heading = math.atan2(delta[1], delta[0])
                phase = (2 * math.pi * SPEED_MPS / stride * t) % (2 * math.pi)
                self._frames[i] = (*self._here, self._heading, phase, 1.0)
            else:
                sway_x = SWAY_M * math.sin(2 * math.pi * t / SWAY_PERIOD_S)
                sway_y = SWAY_M * math.sin(2 * math.pi * t / (1.37 * SWAY_PERIOD_S))
                turn = self._turn_offset + TURN_RAD * math.sin(2 * math.pi * t / TURN_PERIOD_S)
                phase = (2 * math.pi * 0.3 / stride * t) % (2 * math.pi)
                x, y = self._here
                self._frames[i] = (x + sway_x, y + sway_y, turn, phase, STAND_AMPLITUDE)
        self._next = stop
        for old in [i for i in self._frames if i < stop - HISTORY]:
            del self._frames[old]


def install_follower(scene: Any) -> FollowingWalker:
    """Replace a one-person scene's walker by a follower starting in the middle of the room."""
    room = scene.config.room
    walker = FollowingWalker(
        scene.fps, np.random.default_rng([scene.seed, 0]), (room[0] / 2, room[1] / 2)
    )
    scene.walkers = walker
    return walker

"""Walking paths: people wander between random waypoints inside the room, pausing and turning.

Each person steers toward a waypoint with a bounded turn rate (about 150°/s) and slows down in
sharp turns, so paths are smooth curves rather than polylines. On arrival a new waypoint is drawn;
with probability ``PAUSE_PROBABILITY`` the person first stands for 1-4 s and looks around (turns
on the spot). Speeds are 0.8-1.5 m/s; the gait cadence follows the speed (stride length 0.8 H) so
legs never slide. People keep about 0.5 m apart (a soft repulsion), and never leave the room.

**Spacing.** Within ``separation`` metres of each other two people are pushed apart by
``repulsion`` of the overlap per integration step (defaults :data:`SEPARATION`,
:data:`REPULSION`: they keep about 0.5 m). A room may set its own (``SceneConfig.separation``,
``repulsion``): the real CMC room's eight walkers keep more room than that, their
nearest-neighbour distances' 5 / 10 / 25 / 50 % points are 0.42 / 0.46 / 0.58 / 0.72 m (CMC2),
which a softer, longer push gives (``cmc-room``: 1.0 m, 0.06: 0.41 / 0.48 / 0.59 / 0.73 m; the
defaults: 0.40 / 0.43 / 0.46 / 0.55 m; ``bench/results/sim_vs_real_occlusion.md``).

**The walk does not depend on the frame rate.** The push acts once per integration step, so a
scene that stepped once per frame at 4 fps (``cmc-room``: 0.3 m per step) let people come to
0.33 m of each other (5th percentile above) where the same walk at 15 fps keeps 0.40 m. Below
:data:`MIN_STEP_FPS` a frame is integrated in as many equal sub-steps as bring the step rate to
at least that (at 15 fps and above: one per frame, as before).

The state is integrated frame by frame (in sub-steps below 15 fps) and cached, so
``states(a, b)`` is random-access and reproducible for a given seed regardless of the order of
calls.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

MARGIN = 0.35  # metres kept from the walls
PAUSE_PROBABILITY = 0.3
TURN_RATE = 2.6  # rad/s
ACCELERATION = 1.5  # m/s²
SEPARATION = 0.5  # metres: people closer than this are pushed apart
REPULSION = 0.25  # share of the overlap undone per integration step
MIN_STEP_FPS = 15.0  # integration steps per second, at least
_CHUNK = 512
_KEEP = 128  # chunks kept in memory (65536 frames)


@dataclass(frozen=True)
class WalkerStates:
    """Per frame and person: floor position [F,P,2] (mid-hip), heading, gait phase, amplitude,
    and optionally a held posture (codes of :mod:`models.simulate.postures`) and how far the
    body has moved into it (0..1); None: everyone upright."""

    position: np.ndarray
    heading: np.ndarray
    phase: np.ndarray
    amplitude: np.ndarray
    posture: np.ndarray | None = None
    posture_weight: np.ndarray | None = None

    def postures(self) -> tuple[np.ndarray, np.ndarray]:
        """(codes [F,P] int, weights [F,P]): zeros (standing) when the states hold none."""
        if self.posture is None or self.posture_weight is None:
            zeros = np.zeros(self.heading.shape)
            return zeros.astype(np.int64), zeros
        return self.posture, self.posture_weight


class Walking(Protocol):
    """What a scene needs of its people: their heights and their states over a frame range
    (:class:`Walkers` for random walks, ``models.simulate.scripted`` for a set path)."""

    heights: np.ndarray

    def states(self, start: int, stop: int) -> WalkerStates: ...


class Walkers:
    """``count`` people in a ``room`` (width, depth metres), integrated at ``fps`` (at least
    :data:`MIN_STEP_FPS` steps a second), kept ``separation`` apart by ``repulsion``."""

    def __init__(
        self,
        room: tuple[float, float],
        count: int,
        fps: float,
        rng: np.random.Generator,
        separation: float = SEPARATION,
        repulsion: float = REPULSION,
    ) -> None:
        self.room = (float(room[0]), float(room[1]))
        self.count = count
        self.separation, self.repulsion = float(separation), float(repulsion)
        self.substeps = max(1, math.ceil(MIN_STEP_FPS / fps - 1e-9))
        self.dt = 1.0 / fps / self.substeps
        self._rng = rng
        self.heights = rng.uniform(1.5, 1.95, count)
        self._cruise = rng.uniform(0.8, 1.5, count)
        self._pos = self._random_points(count)
        self._target = self._random_points(count)
        self._heading = rng.uniform(-np.pi, np.pi, count)
        self._speed = np.zeros(count)
        self._phase = rng.uniform(0, 2 * np.pi, count)
        self._pause = np.zeros(count)
        self._look = self._heading.copy()
        # Chunks of [CHUNK, P, 5] (x, y, heading, phase, amplitude). A long-running demo would
        # grow them without bound, so only the newest _KEEP stay in memory; older ones are
        # replayed from the state saved at their start (a few hundred bytes each).
        self._chunks: dict[int, np.ndarray] = {}
        self._checkpoints: list[tuple] = []

    def _random_points(self, n: int) -> np.ndarray:
        width, depth = self.room
        lo = np.minimum(MARGIN, np.array([width, depth]) / 2)
        return self._rng.uniform(lo, np.array([width, depth]) - lo, size=(n, 2))

    def _step(self) -> np.ndarray:
        """One frame: :attr:`substeps` integration steps, the state after the last."""
        for _ in range(self.substeps - 1):
            self._advance()
        return self._advance()

    def _advance(self) -> np.ndarray:
        rng, dt = self._rng, self.dt
        to_target = self._target - self._pos
        distance = np.linalg.norm(to_target, axis=1)
        arrived = (distance < 0.3) & (self._pause <= 0)
        if arrived.any():
            n = int(arrived.sum())
            self._target[arrived] = self._random_points(n)
            pauses = rng.random(n) < PAUSE_PROBABILITY
            self._pause[arrived] = np.where(pauses, rng.uniform(1.0, 4.0, n), 0.0)
            self._look[arrived] = rng.uniform(-np.pi, np.pi, n)
            to_target = self._target - self._pos
        paused = self._pause > 0
        desired = np.where(paused, self._look, np.arctan2(to_target[:, 1], to_target[:, 0]))
        error = (desired - self._heading + np.pi) % (2 * np.pi) - np.pi
        self._heading += np.clip(error, -TURN_RATE * dt, TURN_RATE * dt)
        wanted = np.where(paused, 0.0, self._cruise * np.clip(np.cos(error), 0.15, 1.0))
        self._speed += np.clip(wanted - self._speed, -ACCELERATION * dt, ACCELERATION * dt)
        self._pause = np.maximum(self._pause - dt, 0.0)

        step = (
            self._speed[:, None] * dt * np.stack([np.cos(self._heading), np.sin(self._heading)], 1)
        )
        pos = self._pos + step
        if self.count > 1:  # soft repulsion keeps people from walking through each other
            diff = pos[:, None, :] - pos[None, :, :]
            dist = np.linalg.norm(diff, axis=-1) + np.eye(self.count)
            push = np.clip(self.separation - dist, 0.0, None) / dist * self.repulsion
            pos += (diff * push[..., None]).sum(axis=1)
        lo = np.minimum(MARGIN, np.array(self.room) / 2) * 0.5
        self._pos = np.clip(pos, lo, np.array(self.room) - lo)

        amplitude = np.clip(self._speed / 1.2, 0.0, 1.0)
        # Turning on the spot still moves the legs a little.
        amplitude = np.maximum(amplitude, 0.25 * (np.abs(error) > TURN_RATE * dt))
        stride = 0.8 * self.heights
        self._phase = (
            self._phase + 2 * np.pi * np.maximum(self._speed, 0.3 * amplitude) / stride * dt
        ) % (2 * np.pi)
        return np.column_stack([self._pos, self._heading, self._phase, amplitude])

    def _save(self) -> tuple:
        arrays = (self._pos, self._target, self._heading, self._speed, self._phase, self._pause,
                  self._look)  # fmt: skip
        return (*(a.copy() for a in arrays), copy.deepcopy(self._rng.bit_generator.state))

    def _restore(self, saved: tuple) -> None:
        (self._pos, self._target, self._heading, self._speed, self._phase, self._pause,
         self._look) = (a.copy() for a in saved[:-1])  # fmt: skip
        self._rng.bit_generator.state = copy.deepcopy(saved[-1])

    def _integrate(self) -> np.ndarray:
        return np.stack([self._step() for _ in range(_CHUNK)])

    def _chunk(self, index: int) -> np.ndarray:
        if index in self._chunks:
            return self._chunks[index]
        if index < len(self._checkpoints):  # evicted: replay it, then resume where we were
            live = self._save()
            self._restore(self._checkpoints[index])
            data = self._integrate()
            self._restore(live)
            return data
        while len(self._checkpoints) <= index:
            self._checkpoints.append(self._save())
            self._chunks[len(self._checkpoints) - 1] = self._integrate()
            if len(self._chunks) > _KEEP:
                del self._chunks[min(self._chunks)]
        return self._chunks[index]

    def states(self, start: int, stop: int) -> WalkerStates:
        """States of frames ``start`` .. ``stop - 1``."""
        if start < 0 or stop <= start:
            raise ValueError(f"bad frame range {start}..{stop}")
        first, last = start // _CHUNK, (stop - 1) // _CHUNK
        block = np.concatenate([self._chunk(i) for i in range(first, last + 1)])
        block = block[start - first * _CHUNK : stop - first * _CHUNK]
        return WalkerStates(block[..., :2], block[..., 2], block[..., 3], block[..., 4])

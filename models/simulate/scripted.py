"""A simulated person who follows set-up instructions, for unattended collection runs.

During a calibration-free set-up the user walks to a floor mark, stands on it while swaying and
turning in place, then walks to the next one (or walks between marks at a steady pace). This
module turns such a schedule into the same per-frame walker states as :mod:`people` (position of
the mid-hip floor point, heading, gait phase, amplitude), so the :class:`Scene` renders and detects
this person exactly like its random walkers, with the same cameras as ``simulate`` for that preset.

While standing, the mid-hip sways by a few centimetres around the mark and the body turns ±70°
back and forth: the label stays the mark, as it would for a real user.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from models.simulate.people import WalkerStates
from models.simulate.scene import Scene, SceneConfig

SWAY_M = 0.04
SWAY_PERIOD_S = 3.1
TURN_RAD = 1.2
TURN_PERIOD_S = 9.0
STAND_AMPLITUDE = 0.15


@dataclass(frozen=True)
class Segment:
    """Move from ``start`` to ``end`` (metres) over ``seconds``; equal points mean standing."""

    start: tuple[float, float]
    end: tuple[float, float]
    seconds: float


class ScriptedWalker:
    """One person following ``segments`` back to back, then standing at the last point."""

    count = 1

    def __init__(self, segments: list[Segment], fps: float, rng: np.random.Generator) -> None:
        if not segments:
            raise ValueError("a scripted walker needs at least one segment")
        self.segments = segments
        self.fps = float(fps)
        self.heights = rng.uniform(1.5, 1.95, 1)
        self._turn_offset = rng.uniform(-np.pi, np.pi)
        self._ends = np.cumsum([s.seconds for s in segments])

    @property
    def duration_s(self) -> float:
        return float(self._ends[-1])

    def states(self, start: int, stop: int) -> WalkerStates:
        """States of frames ``start`` .. ``stop - 1`` (shapes [F, 1, ...])."""
        t = np.arange(start, stop) / self.fps
        index = np.minimum(np.searchsorted(self._ends, t, side="right"), len(self.segments) - 1)
        begin = self._ends[index] - np.array([self.segments[i].seconds for i in index])
        a = np.array([self.segments[i].start for i in index])
        b = np.array([self.segments[i].end for i in index])
        seconds = np.array([self.segments[i].seconds for i in index])
        fraction = np.clip((t - begin) / np.maximum(seconds, 1e-9), 0.0, 1.0)
        delta = b - a
        length = np.linalg.norm(delta, axis=1)
        walking = length > 1e-6
        position = a + fraction[:, None] * delta
        sway = SWAY_M * np.stack(
            [np.sin(2 * np.pi * t / SWAY_PERIOD_S), np.sin(2 * np.pi * t / (1.37 * SWAY_PERIOD_S))],
            axis=1,
        )
        position = np.where(walking[:, None], position, position + sway)
        standing_heading = self._turn_offset + TURN_RAD * np.sin(2 * np.pi * t / TURN_PERIOD_S)
        heading = np.where(walking, np.arctan2(delta[:, 1], delta[:, 0]), standing_heading)
        speed = np.where(walking, length / np.maximum(seconds, 1e-9), 0.0)
        amplitude = np.where(walking, np.clip(speed / 1.2, 0.3, 1.0), STAND_AMPLITUDE)
        stride = 0.8 * self.heights[0]
        phase = (2 * np.pi * np.maximum(speed, 0.3) / stride * t) % (2 * np.pi)
        return WalkerStates(
            position[:, None, :], heading[:, None], phase[:, None], amplitude[:, None]
        )


def scripted_scene(config: SceneConfig, seed: int, segments: list[Segment]) -> Scene:
    """The scene of ``config`` and ``seed`` (cameras as ``simulate``) with one scripted person."""
    scene = Scene(dataclasses.replace(config, people=1), seed)
    scene.walkers = ScriptedWalker(segments, config.fps, np.random.default_rng([seed, 7]))
    return scene

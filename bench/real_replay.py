"""Real trajectories as simulator walkers: the people of an annotated data set (Wildtrack's
floor positions) walked through a :class:`~models.simulate.Scene` on the real cameras, so the
product's own simulator draws their bodies and its detector profile noises their boxes (edge
errors, misses, occlusion, false positives) exactly as it does for its random walkers.

Each annotated person is one walker; in frames where they are not annotated their position is
NaN, which the scene projects to no box in any camera (``FrameObservation.world`` keeps the NaN,
so the caller drops those rows). Heading follows the direction of travel between annotated
frames, the gait phase the distance walked, the swing amplitude the speed (as the random
walkers' do); heights are drawn as theirs (1.5-1.95 m).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from bench.real_data import FramePositions
from models.simulate.people import WalkerStates
from models.simulate.scene import Scene, SceneConfig

STILL_MPS = 0.2  # below this the body keeps its heading and stands (amplitude of a standing sway)


class ReplayWalkers:
    """Annotated positions [F, P, 2] (NaN: absent) as :class:`~models.simulate.people.Walking`."""

    def __init__(self, xy: np.ndarray, fps: float, rng: np.random.Generator) -> None:
        self.xy = np.asarray(xy, np.float64)
        frames, people = self.xy.shape[:2]
        self.heights = rng.uniform(1.5, 1.95, people)
        velocity = np.zeros_like(self.xy)
        velocity[1:] = (self.xy[1:] - self.xy[:-1]) * fps
        velocity = np.nan_to_num(velocity)
        speed = np.linalg.norm(velocity, axis=2)
        heading = np.arctan2(velocity[..., 1], velocity[..., 0])
        for f in range(1, frames):  # standing: keep the last heading
            still = speed[f] < STILL_MPS
            heading[f, still] = heading[f - 1, still]
        stride = 0.8 * self.heights[None]
        self.phase = (2 * np.pi * np.cumsum(speed / fps, axis=0) / stride) % (2 * np.pi)
        self.heading = heading
        self.amplitude = np.clip(speed / 1.2, 0.15, 1.0)

    def states(self, start: int, stop: int) -> WalkerStates:
        """States of frames ``start`` .. ``stop - 1``; frames past the annotation are empty."""
        index = np.arange(start, stop)
        inside = index < len(self.xy)
        safe = np.minimum(index, len(self.xy) - 1)
        position = np.where(inside[:, None, None], self.xy[safe], np.nan)
        return WalkerStates(position, self.heading[safe], self.phase[safe], self.amplitude[safe])


def trajectories(frames: Sequence[FramePositions]) -> tuple[np.ndarray, np.ndarray]:
    """Person ids [P] and positions [F, P, 2] (NaN where a person is not annotated)."""
    ids = np.unique(np.concatenate([f.ids for f in frames]))
    xy = np.full((len(frames), len(ids), 2), np.nan)
    for i, f in enumerate(frames):
        xy[i, np.searchsorted(ids, f.ids)] = f.xy
    return ids, xy


def replay_scene(config: SceneConfig, xy: np.ndarray, seed: int) -> Scene:
    """The scene of ``config`` (its cameras, fps, detector profile) walked by ``xy`` [F, P, 2]."""
    scene = Scene(dataclasses.replace(config, people=int(xy.shape[1])), seed)
    scene.walkers = ReplayWalkers(xy, config.fps, np.random.default_rng([seed, 7]))
    return scene

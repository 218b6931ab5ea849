"""Real trajectories as simulator walkers: the people of an annotated data set (Wildtrack's
floor positions) walked through a :class:`~models.simulate.Scene` on the real cameras, so the
product's own simulator draws their bodies and its detector profile noises their boxes (edge
errors, misses, occlusion, false positives) exactly as it does for its random walkers.

Each annotated person walks in a walker slot; in frames where a slot holds nobody its position is
NaN, which the scene projects to no box in any camera (``FrameObservation.world`` keeps the NaN,
so the caller drops those rows). Heading follows the direction of travel between annotated
frames, the gait phase the distance walked, the swing amplitude the speed (as the random
walkers' do); heights are drawn as theirs (1.5-1.95 m).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from bench.real.data import FramePositions
from models.simulate.people import WalkerStates
from models.simulate.scene import Scene, SceneConfig

STILL_MPS = 0.2  # below this the body keeps its heading and stands (amplitude of a standing sway)


def pack_slots(present: np.ndarray) -> np.ndarray:
    """Walker slot [P] of each person given ``present`` [F, P]: a slot is reused once its last
    person's annotated span (first to last frame) has ended, so a scene needs as many walkers as
    people are ever annotated at once (Wildtrack: ~40 of 313). The scene's occlusion test is
    quadratic in its walkers, so this is what keeps it fast."""
    frames = np.arange(len(present))
    first = np.array([frames[c].min() if c.any() else 0 for c in present.T])
    last = np.array([frames[c].max() if c.any() else -1 for c in present.T])
    free_from: list[int] = []  # per slot: first frame it is free again
    slot = np.zeros(present.shape[1], np.int64)
    for p in np.argsort(first, kind="stable"):
        open_slots = [s for s, f in enumerate(free_from) if f <= first[p]]
        s = open_slots[0] if open_slots else len(free_from)
        if s == len(free_from):
            free_from.append(0)
        free_from[s] = int(last[p]) + 2  # one empty frame between two people of a slot
        slot[p] = s
    return slot


class ReplayWalkers:
    """Annotated positions [F, P, 2] (NaN: absent) as :class:`~models.simulate.people.Walking`,
    packed into walker slots (:func:`pack_slots`); ``person`` [F, S] names the person in each
    slot (-1: empty)."""

    def __init__(self, xy: np.ndarray, fps: float, rng: np.random.Generator) -> None:
        xy = np.asarray(xy, np.float64)
        frames, people = xy.shape[:2]
        present = np.isfinite(xy).all(axis=2)
        velocity = np.zeros_like(xy)
        velocity[1:] = (xy[1:] - xy[:-1]) * fps
        velocity = np.nan_to_num(velocity)
        speed = np.linalg.norm(velocity, axis=2)
        heading = np.arctan2(velocity[..., 1], velocity[..., 0])
        for f in range(1, frames):  # standing: keep the last heading
            still = speed[f] < STILL_MPS
            heading[f, still] = heading[f - 1, still]
        slot = pack_slots(present)
        slots = int(slot.max()) + 1 if people else 1
        self.heights = rng.uniform(1.5, 1.95, slots)
        stride = 0.8 * self.heights[slot][None]
        phase = (2 * np.pi * np.cumsum(speed / fps, axis=0) / stride) % (2 * np.pi)
        amplitude = np.clip(speed / 1.2, 0.15, 1.0)
        self.person = np.full((frames, slots), -1, np.int64)
        self.xy = np.full((frames, slots, 2), np.nan)
        self.heading, self.phase = np.zeros((frames, slots)), np.zeros((frames, slots))
        self.amplitude = np.full((frames, slots), 0.15)
        f_idx, p_idx = np.nonzero(present)
        s_idx = slot[p_idx]
        self.person[f_idx, s_idx] = p_idx
        self.xy[f_idx, s_idx] = xy[f_idx, p_idx]
        self.heading[f_idx, s_idx] = heading[f_idx, p_idx]
        self.phase[f_idx, s_idx] = phase[f_idx, p_idx]
        self.amplitude[f_idx, s_idx] = amplitude[f_idx, p_idx]

    @property
    def slots(self) -> int:
        return self.xy.shape[1]

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


def replay_scene(config: SceneConfig, xy: np.ndarray, seed: int) -> tuple[Scene, ReplayWalkers]:
    """The scene of ``config`` (its cameras, fps, detector profile) walked by ``xy`` [F, P, 2],
    and its walkers (``walkers.person[frame, track]`` is the person behind an observation's
    ``track``)."""
    walkers = ReplayWalkers(xy, config.fps, np.random.default_rng([seed, 7]))
    scene = Scene(dataclasses.replace(config, people=walkers.slots), seed)
    scene.walkers = walkers
    return scene, walkers

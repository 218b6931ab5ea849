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

import numpy as np

from models.simulate.scene import Scene, SceneConfig
from models.simulate.script import (
    STAND_AMPLITUDE,
    SWAY_M,
    SWAY_PERIOD_S,
    TURN_PERIOD_S,
    TURN_RAD,
    ScriptedWalker,
    Segment,
)

__all__ = [
    "STAND_AMPLITUDE",
    "SWAY_M",
    "SWAY_PERIOD_S",
    "TURN_PERIOD_S",
    "TURN_RAD",
    "ScriptedWalker",
    "Segment",
    "scripted_scene",
]


def scripted_scene(config: SceneConfig, seed: int, segments: list[Segment]) -> Scene:
    """The scene of ``config`` and ``seed`` (cameras as ``simulate``) with one scripted person."""
    scene = Scene(dataclasses.replace(config, people=1), seed)
    scene.walkers = ScriptedWalker(segments, config.fps, np.random.default_rng([seed, 7]))
    return scene

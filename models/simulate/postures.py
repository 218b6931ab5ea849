"""Bodies that are not walking: sitting, crouching and lying on the floor.

:func:`models.simulate.skeleton.body_points` builds a walking or standing body in body-local
coordinates (forward, left, up; units of the height H, floor at 0). A posture replaces those
points by a held pose, blended in by a weight 0..1, so getting up, sitting down or falling is a
straight-line morph of every point between the two poses over the transition (not an
anatomical motion, but what a detector and the localizer see: a box and joints that go from one
shape to the other in the transition's time).

The poses, with Drillis & Contini's segment lengths (``skeleton.THIGH``, ``SHIN``...):

- **sitting**: the pelvis on a seat ``SEAT`` H high (0.44 m for a 1.75 m person: chairs are
  43-48 cm, sofas 40-45 cm), thighs level and forward, shins down to the floor, the trunk upright
  and leaning back a little, hands on the thighs. Feet land ~0.25 H ahead of the mid-hip: the
  reason the bottom of a seated person's box is not under their hips.
- **crouching**: a squat to pick something up: pelvis at ~0.2 H, knees forward, the trunk bent
  45° forward, hands near the floor.
- **lying**: on the back along the heading (head forward of the mid-hip, feet behind), every
  point at most ~0.15 H above the floor.

The mid-hip floor point stays the person's position (the label) in every posture: it is where a
seated person is on the floor plan (on the seat), and it is the body's centre when lying.
"""

from __future__ import annotations

import numpy as np

STANDING, SITTING, CROUCHING, LYING = 0, 1, 2, 3
NAMES = ("standing", "sitting", "crouching", "lying")
CODES = {name: i for i, name in enumerate(NAMES)}
SEAT = 0.25  # seat height in units of H


def _sitting(names: tuple[str, ...], standing: np.ndarray) -> np.ndarray:
    """Sitting pose [M, 3] from the upright standing pose [M, 3] (hip at z = 0)."""
    pose = standing.copy()
    index = {name: i for i, name in enumerate(names)}
    upper = [i for name, i in index.items() if not _is_leg(name)]
    lean = 0.12  # radians back
    f, u = pose[upper, 0], pose[upper, 2]
    pose[upper, 0] = f * np.cos(lean) - u * np.sin(lean)
    pose[upper, 2] = f * np.sin(lean) + u * np.cos(lean) + SEAT
    for side, sign in (("left", 1.0), ("right", -1.0)):
        knee_z = SEAT + 0.01
        pose[index[f"{side}_hip"]] = (0.0, sign * 0.058, SEAT)
        pose[index[f"{side}_knee"]] = (0.24, sign * 0.065, knee_z)
        pose[index[f"{side}_ankle"]] = (0.27, sign * 0.065, 0.039)
        pose[index[f"{side}_toe"]] = (0.38, sign * 0.07, 0.015)
        pose[index[f"{side}_heel"]] = (0.235, sign * 0.062, 0.02)
        shoulder = pose[index[f"{side}_shoulder"]]
        pose[index[f"{side}_elbow"]] = (shoulder[0] + 0.02, sign * 0.13, SEAT + 0.11)
        pose[index[f"{side}_wrist"]] = (0.16, sign * 0.1, SEAT + 0.06)
        pose[index[f"{side}_hand"]] = (0.2, sign * 0.09, SEAT + 0.055)
    pose[index["mid_hip"], 2] = SEAT + 0.01
    return pose


def _crouching(names: tuple[str, ...], standing: np.ndarray) -> np.ndarray:
    """A squat [M, 3]: pelvis low, knees forward, trunk bent 45° forward, hands down."""
    pose = standing.copy()
    index = {name: i for i, name in enumerate(names)}
    hip_z = 0.2
    upper = [i for name, i in index.items() if not _is_leg(name)]
    bend = np.pi / 4
    f, u = pose[upper, 0], pose[upper, 2]
    pose[upper, 0] = f * np.cos(bend) + u * np.sin(bend) - 0.05
    pose[upper, 2] = -f * np.sin(bend) + u * np.cos(bend) + hip_z
    for side, sign in (("left", 1.0), ("right", -1.0)):
        pose[index[f"{side}_hip"]] = (-0.05, sign * 0.06, hip_z)
        pose[index[f"{side}_knee"]] = (0.17, sign * 0.09, 0.29)
        pose[index[f"{side}_ankle"]] = (0.08, sign * 0.07, 0.039)
        pose[index[f"{side}_toe"]] = (0.19, sign * 0.075, 0.015)
        pose[index[f"{side}_heel"]] = (0.045, sign * 0.065, 0.02)
        shoulder = pose[index[f"{side}_shoulder"]]
        pose[index[f"{side}_elbow"]] = (shoulder[0] + 0.08, sign * 0.12, shoulder[2] - 0.16)
        pose[index[f"{side}_wrist"]] = (shoulder[0] + 0.14, sign * 0.1, shoulder[2] - 0.29)
        pose[index[f"{side}_hand"]] = (shoulder[0] + 0.16, sign * 0.1, shoulder[2] - 0.33)
    pose[index["mid_hip"]] = (-0.05, 0.0, hip_z + 0.01)
    return pose


def _lying(standing: np.ndarray) -> np.ndarray:
    """On the back [M, 3]: the standing body turned 90° about its left axis, head forward."""
    pose = standing.copy()
    pose[:, 0] = standing[:, 2]  # up becomes forward: the head lies ahead of the hips
    pose[:, 2] = 0.075 + np.clip(standing[:, 0], -0.05, None)  # the front faces up
    return pose


def _is_leg(name: str) -> bool:
    return name.split("_")[-1] in ("hip", "knee", "ankle", "toe", "heel") or name == "mid_hip"


def held_poses(names: tuple[str, ...], standing: np.ndarray) -> np.ndarray:
    """Poses [4, M, 3] of every posture code (standing first) from the standing pose [M, 3]
    with the mid-hip at z = 0 and the feet at -(hip height)."""
    up = standing.copy()
    return np.stack([up, _sitting(names, up), _crouching(names, up), _lying(up)])


def blend(
    walking: np.ndarray, held: np.ndarray, posture: np.ndarray, weight: np.ndarray
) -> np.ndarray:
    """Local points [..., M, 3]: ``walking`` (floor at 0) morphed toward the held pose of
    ``posture`` [...] (codes, floor at 0: ``held`` [4, M, 3]) by ``weight`` [...] in 0..1;
    standing (code 0) keeps the walking points whatever the weight."""
    target = held[np.asarray(posture, int)]
    w = np.where(np.asarray(posture) == STANDING, 0.0, np.clip(weight, 0.0, 1.0))[..., None, None]
    return walking + w * (target - walking)

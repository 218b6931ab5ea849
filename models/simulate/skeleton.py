"""Articulated walking humans: COCO-17 joints plus the body volume the camera sees.

A person is a set of 3D points: the 17 COCO joints followed by auxiliary points (head centre,
neck, chest, abdomen, mid-hip, toes, heels, hands, crown). Every point with a positive radius is a
sphere of the body volume; limbs and torso are the convex hulls of their spheres (capsules), so the
tight box of the projected body is the box of the projected spheres, which is both cheap and
correct for the detector-like boxes (a box of joints alone would be 10-20 % too small: it misses
the head top, the feet and the flesh around the limbs).

Proportions follow Drillis & Contini's segment lengths as fractions of the height H (hip 0.53 H,
knee 0.285 H, shoulder 0.818 H, upper arm 0.186 H, forearm 0.146 H). The walking cycle is a
sagittal-plane model: hips swing ±25° in antiphase, knees flex during the swing phase, arms swing
against the legs, and the pelvis rises so the lower ankle always touches the floor (which gives
the natural vertical bob). ``amplitude`` 0 is standing still, 1 a normal walk.
"""

from __future__ import annotations

import functools

import numpy as np

from models.simulate import postures

COCO_KEYPOINTS = (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
    "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
)  # fmt: skip
AUX_POINTS = (
    "head", "neck", "chest", "abdomen", "mid_hip", "left_toe", "right_toe", "left_heel",
    "right_heel", "left_hand", "right_hand", "crown",
)  # fmt: skip
POINT_NAMES = COCO_KEYPOINTS + AUX_POINTS
P = {name: i for i, name in enumerate(POINT_NAMES)}
NUM_POINTS = len(POINT_NAMES)
MID_HIP = P["mid_hip"]
HEAD = P["head"]

# Sphere radius of each point as a fraction of body height (0: not part of the volume).
_RADII = {
    "nose": 0.012, "left_eye": 0.01, "right_eye": 0.01, "left_ear": 0.014, "right_ear": 0.014,
    "head": 0.066, "crown": 0.045, "neck": 0.035, "chest": 0.085, "abdomen": 0.075,
    "mid_hip": 0.07, "left_shoulder": 0.042, "right_shoulder": 0.042, "left_elbow": 0.032,
    "right_elbow": 0.032, "left_wrist": 0.025, "right_wrist": 0.025, "left_hand": 0.03,
    "right_hand": 0.03, "left_hip": 0.058, "right_hip": 0.058, "left_knee": 0.042,
    "right_knee": 0.042, "left_ankle": 0.03, "right_ankle": 0.03, "left_toe": 0.022,
    "right_toe": 0.022, "left_heel": 0.026, "right_heel": 0.026,
}  # fmt: skip
RADII = np.array([_RADII.get(name, 0.0) for name in POINT_NAMES])

THIGH, SHIN, UPPER_ARM, FOREARM = 0.245, 0.246, 0.186, 0.146
ANKLE_HEIGHT = 0.039


def _leg(hip_flex: np.ndarray, knee_flex: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Knee and ankle offsets (forward, up) from the hip, in units of H."""
    knee = np.stack([THIGH * np.sin(hip_flex), -THIGH * np.cos(hip_flex)], -1)
    shin = hip_flex - knee_flex
    ankle = knee + np.stack([SHIN * np.sin(shin), -SHIN * np.cos(shin)], -1)
    return knee, ankle


def _arm(flex: np.ndarray, elbow: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Elbow, wrist and hand offsets (forward, up) from the shoulder, in units of H."""
    e = np.stack([UPPER_ARM * np.sin(flex), -UPPER_ARM * np.cos(flex)], -1)
    fore = flex + elbow
    direction = np.stack([np.sin(fore), -np.cos(fore)], -1)
    w = e + FOREARM * direction
    return e, w, w + 0.05 * direction


def body_points(
    position: np.ndarray,
    heading: np.ndarray,
    phase: np.ndarray,
    amplitude: np.ndarray,
    height: np.ndarray,
    posture: np.ndarray | None = None,
    posture_weight: np.ndarray | None = None,
) -> np.ndarray:
    """World points [..., NUM_POINTS, 3] of people at ``position`` [..., 2] (mid-hip floor point).

    ``heading`` (radians, walking direction in the floor frame), ``phase`` (gait phase, radians),
    ``amplitude`` (0 standing .. 1 walking) and ``height`` (metres) broadcast against the
    people dimensions of ``position``. ``posture`` (codes of :mod:`models.simulate.postures`)
    and ``posture_weight`` (0..1) morph the body into a held pose (sitting, crouching, lying).
    """
    shape = np.broadcast_shapes(
        position.shape[:-1],
        np.shape(heading),
        np.shape(phase),
        np.shape(amplitude),
        np.shape(height),
    )
    local = _walking_pose(np.broadcast_to(amplitude, shape), np.broadcast_to(phase, shape))
    lowest = np.minimum(local[..., P["left_ankle"], 2], local[..., P["right_ankle"], 2])
    local[..., 2] += (ANKLE_HEIGHT - lowest)[..., None]
    if posture is not None and posture_weight is not None:
        local = postures.blend(local, _held_poses(), posture, posture_weight)

    h = np.broadcast_to(height, shape)[..., None]
    cos, sin = np.cos(heading)[..., None], np.sin(heading)[..., None]
    fwd, left, up = local[..., 0] * h, local[..., 1] * h, local[..., 2] * h
    world = np.empty_like(local)
    world[..., 0] = position[..., None, 0] + fwd * cos - left * sin
    world[..., 1] = position[..., None, 1] + fwd * sin + left * cos
    world[..., 2] = up
    return world


@functools.cache
def _held_poses() -> np.ndarray:
    """[4, NUM_POINTS, 3] local poses of the posture codes (built once)."""
    zero = np.zeros(())
    return postures.held_poses(POINT_NAMES, _walking_pose(zero, zero))


def _walking_pose(a: np.ndarray, ph: np.ndarray) -> np.ndarray:
    """Local points [..., NUM_POINTS, 3] (forward, left, up; units of H), mid-hip at z = 0."""
    shape = a.shape
    local = np.zeros((*shape, NUM_POINTS, 3))

    def put(name: str, forward: np.ndarray | float, left: float, up: np.ndarray | float) -> None:
        local[..., P[name], 0] = forward
        local[..., P[name], 1] = left
        local[..., P[name], 2] = up

    for side, sign, offset in (("left", 1.0, 0.0), ("right", -1.0, np.pi)):
        hip_flex = a * 0.42 * np.sin(ph + offset)
        knee_flex = 0.05 + a * (0.12 + 0.75 * np.clip(np.cos(ph + offset), 0.0, None))
        knee, ankle = _leg(hip_flex, knee_flex)
        put(f"{side}_hip", 0.0, sign * 0.058, 0.0)
        put(f"{side}_knee", knee[..., 0], sign * 0.06, knee[..., 1])
        put(f"{side}_ankle", ankle[..., 0], sign * 0.062, ankle[..., 1])
        foot = hip_flex - knee_flex  # the foot stays roughly level; heel strike tilts it a little
        tilt = 0.3 * np.sin(foot)
        put(
            f"{side}_toe",
            ankle[..., 0] + 0.12 * np.cos(tilt),
            sign * 0.07,
            ankle[..., 1] - ANKLE_HEIGHT * 0.6 + 0.12 * np.sin(tilt),
        )
        put(f"{side}_heel", ankle[..., 0] - 0.035, sign * 0.062, ankle[..., 1] - ANKLE_HEIGHT * 0.5)
        arm_flex = -a * 0.35 * np.sin(ph + offset)
        elbow, wrist, hand = _arm(
            arm_flex, 0.25 + a * 0.25 * np.clip(-np.sin(ph + offset), 0, None)
        )
        put(f"{side}_shoulder", 0.012, sign * 0.105, 0.288)
        put(f"{side}_elbow", 0.012 + elbow[..., 0], sign * 0.125, 0.288 + elbow[..., 1])
        put(f"{side}_wrist", 0.012 + wrist[..., 0], sign * 0.12, 0.288 + wrist[..., 1])
        put(f"{side}_hand", 0.012 + hand[..., 0], sign * 0.115, 0.288 + hand[..., 1])
        put(f"{side}_eye", 0.062, sign * 0.03, 0.412)
        put(f"{side}_ear", 0.005, sign * 0.068, 0.402)
    put("nose", 0.078, 0.0, 0.395)
    put("head", 0.012, 0.0, 0.404)
    put("crown", -0.005, 0.0, 0.42)
    put("neck", 0.01, 0.0, 0.32)
    put("chest", 0.02, 0.0, 0.22)
    put("abdomen", 0.015, 0.0, 0.10)
    put("mid_hip", 0.0, 0.0, 0.01)
    return local

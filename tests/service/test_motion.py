"""Motion models: a standing person converges, a walking one is followed, noise per measurement."""

from __future__ import annotations

import numpy as np

from service.tracking.motion import ConstantVelocity, StandOrWalk

FPS = 15.0
R = np.eye(2) * 0.1**2


def feed(model, measurements: np.ndarray) -> np.ndarray:
    out = []
    for z in measurements:
        model.predict(1 / FPS)
        model.correct(z, R)
        out.append(model.mean[:2].copy())
    return np.array(out)


def step_rms(path: np.ndarray) -> float:
    return float(np.sqrt((np.diff(path, axis=0) ** 2).sum(axis=1).mean()))


def test_standing_person_converges_instead_of_jittering():
    rng = np.random.default_rng(0)
    z = np.array([3.0, 4.0]) + rng.normal(0, 0.1, (150, 2))  # 10 s standing, 10 cm noise
    imm, cv = StandOrWalk(z[0], R), ConstantVelocity(z[0], R, accel_std=1.0)
    imm_path, cv_path = feed(imm, z[1:]), feed(cv, z[1:])
    assert imm.standing > 0.7
    late = slice(45, None)  # after 3 s
    # Measured: 2.0 cm against 4.0 cm RMS frame to frame (10 cm noise per frame).
    assert step_rms(imm_path[late]) < 0.6 * step_rms(cv_path[late])
    assert step_rms(imm_path[late]) < 0.025
    assert np.linalg.norm(imm_path[-1] - [3.0, 4.0]) < 0.08


def test_walking_person_is_followed_and_stopping_is_noticed():
    rng = np.random.default_rng(1)
    t = np.arange(90) / FPS
    walk = np.stack([1.0 + 1.2 * t, np.full_like(t, 2.0)], axis=1)
    stop = np.tile(walk[-1], (60, 1))
    truth = np.concatenate([walk, stop])
    imm = StandOrWalk(truth[0], R)
    path = feed(imm, truth[1:] + rng.normal(0, 0.1, (len(truth) - 1, 2)))
    walking = np.linalg.norm(path[30:88] - truth[31:89], axis=1)
    assert walking.mean() < 0.12  # no lag to speak of at 1.2 m/s
    assert imm.standing > 0.8  # after 4 s stopped
    assert np.linalg.norm(path[-1] - truth[-1]) < 0.08


def test_measurement_covariance_steers_the_correction():
    """A measurement uncertain along x (a camera looking along x) moves the state along y."""
    for model in (ConstantVelocity(np.zeros(2), R), StandOrWalk(np.zeros(2), R)):
        sight = np.diag([1.0**2, 0.03**2])
        model.correct(np.array([0.5, 0.5]), sight)
        x, y = model.mean[:2]
        assert abs(x) < 0.01 and y > 0.45

"""The keypoint-noise benchmark's statistics on synthetic numbers whose answers are known.

Pure numpy: MediaPipe (own venv, numpy < 2) is imported only inside the benchmark's run.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bench.keypoints.keypoint_noise import (
    MAD_TO_SIGMA,
    People,
    add_profile_noise,
    bootstrap_excess,
    box_statistics,
    calibrate_gross,
    excess_sigma,
    fit_sigma_pixels,
    found_flags,
    gross_rate,
    pooled_gross,
    robust_spread,
    simulator_keypoints,
)
from models.simulate.noise import detect, keypoint_noise_scale


def test_robust_spread_of_known_values() -> None:
    # median 3, absolute deviations 2, 1, 0, 1, 2 → MAD 1.
    assert robust_spread([1, 2, 3, 4, 5]) == pytest.approx(MAD_TO_SIGMA)
    assert robust_spread([1, 2, 3, 4, 5, np.nan]) == pytest.approx(MAD_TO_SIGMA)
    assert math.isnan(robust_spread([1.0]))
    assert math.isnan(robust_spread([]))


def test_robust_spread_recovers_a_normal_sigma_and_ignores_outliers() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(5.0, 2.0, 200_000)
    assert robust_spread(x) == pytest.approx(2.0, rel=0.01)
    x[:1000] = 1e6  # 0.5 % wild values barely move it (the standard deviation would explode)
    assert robust_spread(x) == pytest.approx(2.0, rel=0.02)


def test_excess_sigma() -> None:
    assert excess_sigma(5.0, 3.0) == pytest.approx(4.0)
    assert excess_sigma(3.0, 5.0) == 0.0
    assert excess_sigma(2.0, 0.0) == 2.0
    assert math.isnan(excess_sigma(math.nan, 1.0))


def test_excess_of_independent_noise_is_its_sigma() -> None:
    rng = np.random.default_rng(1)
    base = rng.normal(0.0, 0.3, 400_000)
    noisy = base + rng.normal(0.0, 0.4, base.size)
    assert excess_sigma(robust_spread(noisy), robust_spread(base)) == pytest.approx(0.4, rel=0.02)


def test_fit_recovers_sigma_and_pixels() -> None:
    heights = [40.0, 80.0, 160.0]
    spreads = [0.02 * h + 1.5 for h in heights]
    sigma, pixels = fit_sigma_pixels(heights, spreads, [10, 100, 5])
    assert sigma == pytest.approx(0.02)
    assert pixels == pytest.approx(1.5)
    # Two bins solve it exactly; NaN points are left out.
    sigma, pixels = fit_sigma_pixels([50.0, 100.0, np.nan], [2.0, 3.0, 7.0])
    assert (sigma, pixels) == pytest.approx((0.02, 1.0))


def test_fit_stays_non_negative() -> None:
    # Spreads falling with height: the unconstrained slope is negative → pixels only (mean).
    sigma, pixels = fit_sigma_pixels([50.0, 100.0], [5.0, 3.0])
    assert sigma == 0.0 and pixels == pytest.approx(4.0)
    # Weighted: the heavier point dominates the constant.
    sigma, pixels = fit_sigma_pixels([50.0, 100.0], [5.0, 3.0], [3.0, 1.0])
    assert sigma == 0.0 and pixels == pytest.approx(4.5)
    # Proportional with a negative intercept → sigma only, through the origin.
    sigma, pixels = fit_sigma_pixels([50.0, 100.0], [0.5, 2.0])
    assert pixels == 0.0 and sigma == pytest.approx((50 * 0.5 + 100 * 2.0) / (50**2 + 100**2))
    # One point: the better of the two one-coefficient fits (both exact: sigma only first).
    sigma, pixels = fit_sigma_pixels([50.0], [2.0])
    assert sigma * 50 + pixels == pytest.approx(2.0)
    assert all(math.isnan(v) for v in fit_sigma_pixels([], []))


def _person(joints: dict[int, tuple[float, float, float]]) -> np.ndarray:
    kp = np.full((17, 3), np.nan)
    for j, value in joints.items():
        kp[j] = value
    return kp


def test_box_statistics_in_units_of_height() -> None:
    box = [10.0, 100.0, 30.0, 200.0]  # h 100, centre x 20
    kp = _person(
        {0: (21, 108, 0.9), 11: (18, 150, 0.9), 12: (24, 150, 0.8), 15: (15, 195, 0.9),
         16: (25, 190, 0.9)},
    )  # fmt: skip
    stats = box_statistics(np.array([box]), kp[None], 0.05)
    assert stats["foot"][0] == pytest.approx(0.05)  # lower ankle at 195
    assert stats["head"][0] == pytest.approx(0.08)
    assert stats["hip_x"][0] == pytest.approx(0.01)  # mean hip x 21


def test_box_statistics_respect_the_confidence_floor() -> None:
    box = [0.0, 0.0, 10.0, 50.0]
    kp = _person({0: (5, 4, 0.01), 11: (4, 25, 0.9), 12: (8, 25, 0.02), 15: (5, 45, 0.9),
                       16: (5, 49, 0.03)})  # fmt: skip
    stats = box_statistics(np.array([box]), kp[None], 0.05)
    assert math.isnan(stats["head"][0])  # nose below the floor
    assert stats["foot"][0] == pytest.approx(0.1)  # only the left ankle counts
    assert stats["hip_x"][0] == pytest.approx(-0.02)  # only the left hip
    none = box_statistics(np.array([box]), np.full((1, 17, 3), np.nan), 0.05)
    assert all(math.isnan(v[0]) for v in none.values())


def test_found_flags() -> None:
    kp = np.stack(
        [
            _person({0: (5, 4, 0.9), 15: (5, 45, 0.9)}),
            _person({0: (5, 4, 0.9), 15: (5, 45, 0.01)}),
            np.full((17, 3), np.nan),
        ]
    )
    flags = found_flags(kp, 0.05)
    assert flags["pose"].tolist() == [True, True, False]
    assert flags["ankle"].tolist() == [True, False, False]
    assert flags["nose"].tolist() == [True, True, False]
    assert flags["both"].tolist() == [True, False, False]


def test_gross_rate() -> None:
    assert gross_rate([0.0, 0.1, 0.5, -0.4, np.nan], 0.0, 0.25) == pytest.approx(0.5)
    assert math.isnan(gross_rate([np.nan], 0.0, 0.25))


def test_bootstrap_interval_brackets_the_excess() -> None:
    rng = np.random.default_rng(2)
    values = rng.normal(0.0, 0.05, 400)
    low, high = bootstrap_excess(values, 0.03, rng, 500)
    assert low < excess_sigma(robust_spread(values), 0.03) < high
    assert low == pytest.approx(0.04, abs=0.01) and high == pytest.approx(0.04, abs=0.01)
    assert all(math.isnan(v) for v in bootstrap_excess(values[:1], 0.03, rng, 10))


def test_pooled_gross_centres_each_bin_on_its_own_median() -> None:
    # Two bins with different medians (a bias that differs by height) and no outliers: nothing
    # is gross, although the small people are 0.4 off the overall median.
    heights = np.array([50.0] * 10 + [80.0] * 30)
    values = np.array([0.0] * 10 + [0.4] * 30)
    assert pooled_gross(values, heights)[0] == 0.0
    assert gross_rate(values, float(np.median(values)), 0.25) == 0.25  # about the overall median
    values[:2] = 0.5  # two gross of ten in the < 60 px bin
    total, rates = pooled_gross(values, heights)
    assert rates[0] == pytest.approx(0.2) and rates[1] == 0.0 and math.isnan(rates[2])
    assert total == pytest.approx(2 / 40)  # pooled by people
    assert pooled_gross(values, heights, [1, 3, 0])[0] == pytest.approx(0.05)  # reweighted


def _box_person(height: float) -> np.ndarray:
    """Exact keypoints of an upright person in the box (0, 0, 0.4 h, h), as the exact profile
    gives them (confidence 0.9: not occluded)."""
    return _person(
        {0: (0.2 * height, 0.08 * height, 0.9), 11: (0.18 * height, 0.5 * height, 0.9),
         12: (0.22 * height, 0.5 * height, 0.9), 15: (0.18 * height, 0.95 * height, 0.9),
         16: (0.22 * height, 0.93 * height, 0.9)},
    )  # fmt: skip


def test_noise_scale_is_the_simulators() -> None:
    # The helper against what models.simulate.noise.detect really draws: one person, 100 px,
    # nose turned away (occluded: three times the noise), no misses, no gross errors.
    profile = simulator_keypoints(0.02, 1.0)
    model = profile_with(profile)
    n, h = 40_000, 100.0
    true = np.tile([300.0, 190.0, 340.0, 290.0], (n, 1))[:, None, None]
    joints = np.full((n, 1, 1, 17, 2), [320.0, 240.0])
    away = np.zeros((n, 1, 1, 17), bool)
    away[..., 0] = True
    _, kp = detect(true, np.full((n, 1, 1), 4.0), joints, away, np.array([[640, 480]]), model,
                   np.random.default_rng(5))  # fmt: skip
    error = kp[:, 0, 0, :, :2] - [320.0, 240.0]
    scale = keypoint_noise_scale(profile, np.array(h), away[0, 0, 0])
    assert scale[0] == pytest.approx(9.0) and scale[11] == pytest.approx(3.0)  # 3 · (0.02 h + 1)
    assert error[:, 0].std(0) == pytest.approx([scale[0]] * 2, rel=0.02)
    assert error[:, 11].std(0) == pytest.approx([scale[11]] * 2, rel=0.02)
    # the bench's noise is the same: the exact profile marks occluded joints by confidence < 0.4
    exact = np.tile(_box_person(h), (n, 1, 1))
    exact[:, 0, 2] = 0.2
    people = People(np.tile([0.0, 0.0, 40.0, h], (n, 1)), exact, ("",) * n, np.zeros(n, bool))
    noisy = add_profile_noise(people, profile, np.random.default_rng(3))
    assert (noisy - exact)[:, 0, :2].std(0) == pytest.approx([scale[0]] * 2, rel=0.02)
    assert (noisy - exact)[:, 11, :2].std(0) == pytest.approx([scale[11]] * 2, rel=0.02)
    assert np.array_equal(noisy[..., 2], exact[..., 2], equal_nan=True)


def profile_with(keypoints):
    """The exact profile (no box noise or misses) with this keypoint block."""
    from models.simulate import DetectorProfile

    return dataclasses.replace(DetectorProfile.exact(), keypoints=keypoints)


def test_gross_rate_is_calibrated_through_the_simulators_statistic() -> None:
    # Real: 20 % of the people have the lower ankle 0.6 h too high (gross), the rest exact.
    n, h = 3000, 80.0
    sim_kp = np.tile(_box_person(h), (n, 1, 1))
    boxes = np.tile([0.0, 0.0, 0.4 * h, h], (n, 1))
    real_kp = sim_kp.copy()
    real_kp[: n // 5, [15, 16], 1] -= 0.6 * h
    tags = ("",) * n
    real = People(boxes, real_kp, tags, np.zeros(n, bool))
    sim = People(boxes, sim_kp, tags, np.zeros(n, bool))
    out = calibrate_gross(real, sim, 0.0, 0.5, 0.05, seed=0)
    limbs = out["limbs"]
    assert limbs["statistic"] == "foot" and limbs["measured"] == pytest.approx(0.2)
    assert limbs["simulated"] == pytest.approx(0.2, abs=0.01) and limbs["reached"]
    # a wild pair of ankles lands anywhere in the box, often not gross: the event rate is higher
    assert limbs["rate"] > 0.3 and limbs["simulated_per_joint_model"] < 0.1
    assert out["head"]["rate"] == 0.0 and out["torso"]["rate"] == 0.0  # nothing gross there


def test_profile_noise_moves_a_whole_group_into_the_box() -> None:
    n, h = 20_000, 100.0
    exact = np.tile(_box_person(h), (n, 1, 1))
    people = People(np.tile([0.0, 0.0, 40.0, h], (n, 1)), exact, ("",) * n, np.zeros(n, bool))
    model = simulator_keypoints(0.0, 0.0, {"limbs": 0.3})
    noisy = add_profile_noise(people, model, np.random.default_rng(4))
    moved = np.abs(noisy - exact)[..., :2].max(-1) > 0
    assert moved[:, 15].mean() == pytest.approx(0.3, abs=0.015)
    assert (moved[:, 15] == moved[:, 16]).all() and not moved[:, [0, 11, 12]].any()
    inside = (noisy[..., 0] >= 0) & (noisy[..., 0] <= 40) & (noisy[..., 1] >= 0)
    assert (inside & (noisy[..., 1] <= h))[moved].all()

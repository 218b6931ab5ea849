"""Mean-estimator sampling: statistics, normalisation, masking, determinism, batch independence."""

import numpy as np
import pytest

from common.errors import MomlocError
from models.mom.sampling import (
    InferenceSampler,
    SamplerConfig,
    random_draws,
    sample_estimators,
    subset_weights,
)

SIZES = np.array([[640, 480], [1920, 1080]])
BOX = [100.0, 40.0, 220.0, 400.0]


def boxes(n: int = 4) -> np.ndarray:
    out = np.tile(np.array([BOX, [800, 300, 1000, 900]], np.float32), (n, 1, 1))
    out[1, 1] = np.nan
    return out


def test_training_estimators_shape_mask_and_bounds():
    est, mask = sample_estimators(SamplerConfig(), boxes(), SIZES, np.random.default_rng(0))
    assert est.shape == (4, 2, 14, 2) and mask.shape == (4, 2)  # 12 estimators + 2 corners
    assert mask[1, 1] == 0 and mask.sum() == 7
    assert (est[1, 1] == 0).all()
    lo = 2 * np.array(BOX[:2]) / SIZES[0] - 1
    hi = 2 * np.array(BOX[2:]) / SIZES[0] - 1
    assert (est[:, 0] >= lo - 1e-6).all() and (est[:, 0] <= hi + 1e-6).all()


def test_estimators_centre_on_box_centre_with_spread_shrinking_with_m():
    """Averaged estimators converge to the normalised box centre (the CLT premise)."""
    config = SamplerConfig()
    many = np.tile(np.array([[BOX]], np.float32), (4000, 1, 1))
    est, _ = sample_estimators(config, many, SIZES[:1], np.random.default_rng(1))
    centre = 2 * np.array([160.0, 220.0]) / SIZES[0] - 1
    np.testing.assert_allclose(est[..., :12, :].reshape(-1, 2).mean(axis=0), centre, atol=2e-3)
    np.testing.assert_allclose(
        est[0, 0, 12:],
        [2 * np.array(BOX[:2]) / SIZES[0] - 1, 2 * np.array(BOX[2:]) / SIZES[0] - 1],
        atol=1e-6,
    )
    # m varies: single-point estimators spread like the box, full means barely spread
    draws = random_draws(np.random.default_rng(2), (20000,), config)
    weights = subset_weights(draws.keys, draws.frac, np.ones(config.num_points, bool))
    m = (weights > 0).sum(axis=-1)
    assert m.min() == 1 and m.max() == config.num_points
    means = (weights @ draws.unit)[..., 0]
    assert means[m == 1].std() > 0.25 and means[m == config.num_points].std() < 0.1


def test_subset_weights_only_use_available_points():
    rng = np.random.default_rng(3)
    available = rng.random((50, 17)) > 0.5
    available[0] = False
    weights = subset_weights(rng.random((50, 12, 17)), rng.random((50, 12)) + 1e-3, available)
    assert (weights[~np.broadcast_to(available[:, None], weights.shape)] == 0).all()
    np.testing.assert_allclose(weights[1:].sum(axis=-1), 1.0, atol=1e-6)
    assert (weights[0] == 0).all()


def test_inference_is_deterministic_and_batch_independent():
    sampler = InferenceSampler(SamplerConfig(draws=8))
    data = boxes(6) + np.arange(6, dtype=np.float32)[:, None, None]
    full, mask = sampler(data, SIZES)
    again, _ = InferenceSampler(SamplerConfig(draws=8))(data, SIZES)
    single, _ = sampler(data[3:4], SIZES)
    shuffled, _ = sampler(data[::-1], SIZES)
    assert full.shape == (6, 8, 2, 14, 2)
    np.testing.assert_array_equal(full, again)
    np.testing.assert_array_equal(full[3], single[0])
    np.testing.assert_array_equal(full[::-1], shuffled)
    assert (full[1, :, 1] == 0).all() and mask[1, 1] == 0


def test_keypoint_mode_uses_visible_keypoints_only():
    rng = np.random.default_rng(4)
    kp = np.concatenate([rng.uniform(0, 400, (3, 2, 17, 2)), np.ones((3, 2, 17, 1))], -1)
    kp[0, 0, 5:] = np.nan  # only 5 keypoints visible
    kp[2, 1] = np.nan  # camera unseen
    kp = kp.astype(np.float32)
    config = SamplerConfig(observation="keypoints")
    est, mask = sample_estimators(config, boxes(3), SIZES, rng, kp)
    assert mask[2, 1] == 0 and mask[0, 0] == 1 and (est[2, 1] == 0).all()
    visible = 2 * kp[0, 0, :5, :2] / SIZES[0] - 1
    assert (est[0, 0] >= visible.min(0) - 1e-5).all() and (est[0, 0] <= visible.max(0) + 1e-5).all()
    inf, _ = InferenceSampler(config)(boxes(3), SIZES, kp)
    single, _ = InferenceSampler(config)(boxes(3)[:1], SIZES, kp[:1])
    np.testing.assert_array_equal(inf[0], single[0])


def test_keypoint_mode_without_keypoints_is_a_user_error():
    with pytest.raises(MomlocError, match="keypoints"):
        sample_estimators(
            SamplerConfig(observation="keypoints"), boxes(), SIZES, np.random.default_rng(0)
        )
    with pytest.raises(MomlocError, match="observation"):
        SamplerConfig(observation="depth")

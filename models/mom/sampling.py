"""Mean-estimator sampling (paper Eq. 7), shared by training and serving.

Why one module for both: the encoder only ever sees mean estimators, so training and inference must
build them the same way. From each camera's observation we take ``n`` points on the body (bbox
mode: points inside the box; keypoint mode: the visible keypoints) and form ``E = 12`` mean
estimators, each the mean of a random subset of ``m`` points, ``1 <= m <= n``, ``m`` varying. The
result per camera is ``[12, 2]`` in normalised pixels (``2 * p / image_size - 1``, so every
resolution looks alike to the network); a missing camera gives zeros and mask 0.

Beyond the paper, ``extent`` (default on) appends two rows per camera: the observation's min and
max corners (measured: ``bench/results/sampling.md``): the estimators locate the body's mass well
but carry its extent (the foot point, which gives depth when only one camera sees the person) only
noisily.

Every estimator is a weighted mean ``W @ points`` with ``W`` an ``[E, n]`` matrix of ``1/m`` on the
chosen subset. A subset is drawn as "the ``m`` points with the smallest random keys", with
``m = ceil(frac * n_visible)``. That formulation lets keypoint mode use the same random numbers
whatever the number of visible keypoints.

* Training (:func:`sample_estimators`): fresh points, keys and ``m`` for every row, camera and
  epoch — the paper's near-infinite supply of ``(X̄, Ȳ)`` pairs.
* Inference (:func:`inference_estimators`): ``D`` fixed draws from a scrambled Sobol sequence with
  a fixed seed (stored in ``model.json`` so a different numpy cannot change them). Each row uses
  only its own observation and the fixed draws, so a result never depends on batch composition.
  The encoder's predictions are averaged over the ``D`` draws: with the paper's input alone one
  draw is much worse than many; with the extent rows (below) the sampled points matter far less,
  so ``D = 4`` keeps the encoder fast (``bench/results/sampling.md``).

Keypoint mode leaves a camera out when its box holds no visible keypoint (the pose estimator
found no pose, often for small people on real video: ``bench/results/keypoint_noise.md``).
Measured and rejected (``bench/results/sampling.md``): such a camera reading a template pose
placed in its box (joints at Drillis & Contini's heights), in training and serving alike, for
every pose-less box or only for small ones: a wash over the five stream scenes (it recovers
small people where they are small, and localizes the pose-less false boxes where people are
large).

Point distributions for bbox mode: ``"uniform"`` (uniform in the box, as in the paper) or
``"body"`` (a narrower, body-like horizontal spread: x ~ clipped normal around the box centre,
y uniform). They tie on indoor-2cam (``bench/results/sampling.md``), so the default stays the
paper's uniform points.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from common.errors import MomlocError

NUM_ESTIMATORS = 12
DEFAULT_DISTRIBUTION = "uniform"
BODY_SIGMA = 0.17  # horizontal spread of "body" points, in box widths
KEYPOINT_MIN_CONFIDENCE = 0.05


@dataclass(frozen=True)
class SamplerConfig:
    """Sampler settings, stored in ``model.json`` so serving rebuilds exactly the same inputs."""

    observation: str = "bbox"  # "bbox" | "keypoints"
    num_points: int = 20  # n: points sampled per box (bbox mode)
    num_estimators: int = NUM_ESTIMATORS  # E
    distribution: str = DEFAULT_DISTRIBUTION  # "uniform" | "body" (bbox mode)
    draws: int = 4  # D: fixed draws averaged at inference (measured: 4 ≈ 32 with extent rows)
    extent: bool = True  # append the observation's corners (min, max) as two extra rows
    seed: int = 20240601  # seed of the fixed inference draws

    def __post_init__(self) -> None:
        if self.observation not in ("bbox", "keypoints"):
            raise MomlocError(f"observation '{self.observation}': expected bbox or keypoints")
        if self.distribution not in ("uniform", "body"):
            raise MomlocError(f"sampler distribution '{self.distribution}': unknown")
        if self.num_points < 1 or self.num_estimators < 1 or self.draws < 1:
            raise MomlocError("sampler: num_points, num_estimators and draws must be >= 1")

    def to_dict(self) -> dict:
        return asdict(self)

    @property
    def rows(self) -> int:
        """Rows per camera in the encoder input: E estimators (+ 2 corner rows with extent)."""
        return self.num_estimators + (2 if self.extent else 0)


@dataclass(frozen=True)
class Draws:
    """Random numbers defining one or more draws of estimators.

    ``unit`` [..., n, 2]: points in the unit box (bbox mode); ``keys`` [..., E, n]: subset keys;
    ``frac`` [..., E]: subset size as a fraction of the available points, in (0, 1].
    """

    unit: np.ndarray
    keys: np.ndarray
    frac: np.ndarray
    extra: dict = field(default_factory=dict)


def _unit_points(u: np.ndarray, distribution: str) -> np.ndarray:
    """Map uniform [0,1)^2 numbers to points in the unit box with the chosen distribution."""
    if distribution == "uniform":
        return u
    from scipy.special import ndtri  # inverse normal CDF; scipy is a serving dependency

    x = 0.5 + BODY_SIGMA * ndtri(np.clip(u[..., 0], 1e-6, 1 - 1e-6))
    return np.stack([np.clip(x, 0.0, 1.0), u[..., 1]], axis=-1)


def unit_mean(config: SamplerConfig) -> np.ndarray:
    """Expected sample point in the unit box: the decoder's target is box origin + size * this."""
    return np.array([0.5, 0.5], dtype=np.float64)  # both distributions are symmetric about 0.5


def random_draws(rng: np.random.Generator, shape: tuple[int, ...], config: SamplerConfig) -> Draws:
    """Fresh random draws with leading ``shape`` (training)."""
    n, e = _points_per_draw(config), config.num_estimators
    f32 = np.float32  # half the memory: 100 000 rows × 9 cameras × 12 × 20 keys is large
    unit = _unit_points(rng.random((*shape, n, 2), dtype=f32), config.distribution)
    keys = rng.random((*shape, e, n), dtype=f32)
    frac = 1.0 - rng.random((*shape, e), dtype=f32)  # (0, 1]
    return Draws(unit.astype(np.float32), keys.astype(np.float32), frac.astype(np.float32))


def fixed_draws(config: SamplerConfig) -> Draws:
    """The ``D`` deterministic inference draws (scrambled Sobol points, fixed seed)."""
    from scipy.stats import qmc

    n, e, d = _points_per_draw(config), config.num_estimators, config.draws
    sobol = qmc.Sobol(d=2, scramble=True, seed=config.seed)
    u = sobol.random(_pow2(d * n))[: d * n].reshape(d, n, 2)
    rng = np.random.default_rng(config.seed)
    keys = rng.random((d, e, n))
    # subset sizes spread evenly over (0, 1] in every draw, shuffled per draw
    base = (np.arange(e) + 0.5) / e
    frac = np.stack([rng.permutation(base) for _ in range(d)]) + 0.5 / e
    return Draws(
        _unit_points(u, config.distribution).astype(np.float32),
        keys.astype(np.float32),
        np.minimum(frac, 1.0).astype(np.float32),
    )


def draws_to_json(draws: Draws) -> dict:
    return {k: getattr(draws, k).round(7).tolist() for k in ("unit", "keys", "frac")}


def draws_from_json(data: dict) -> Draws:
    unit, keys, frac = (np.asarray(data[k], dtype=np.float32) for k in ("unit", "keys", "frac"))
    return Draws(unit, keys, frac)


def _pow2(n: int) -> int:
    return 1 << max(0, (n - 1).bit_length())


def _points_per_draw(config: SamplerConfig) -> int:
    return config.num_points if config.observation == "bbox" else 17


def subset_weights(keys: np.ndarray, frac: np.ndarray, available: np.ndarray) -> np.ndarray:
    """Weights [..., E, n] of subset means: the m available points with the smallest keys.

    ``available`` [..., n] bool (broadcast over E); m = ceil(frac * count), at least 1. Rows with
    nothing available get all-zero weights. One sort finds the m-th smallest key as a threshold.
    """
    avail = available[..., None, :]
    keys = np.where(avail, keys, np.inf)
    count = avail.sum(axis=-1)  # [..., 1]
    m = np.clip(np.ceil(frac * count), 1, keys.shape[-1]).astype(np.int64)
    threshold = np.take_along_axis(np.sort(keys, axis=-1), m[..., None] - 1, axis=-1)
    chosen = (keys <= threshold) & avail
    weights = chosen / np.maximum(chosen.sum(axis=-1, keepdims=True), 1)
    return weights.astype(np.float32)


def normalise_pixels(pixels: np.ndarray, image_size: np.ndarray) -> np.ndarray:
    """Pixels [..., K, ..., 2] → [-1, 1] per camera; ``image_size`` [K, 2] aligned on axis K."""
    return 2.0 * pixels / image_size - 1.0


def unit_estimators(draws: Draws) -> np.ndarray:
    """Estimators in the unit box [..., E, 2]: box mode needs only these plus each box."""
    weights = subset_weights(draws.keys, draws.frac, np.ones(draws.keys.shape[-1], bool))
    return weights @ draws.unit


def box_estimators(boxes: np.ndarray, image_size: np.ndarray, unit: np.ndarray) -> np.ndarray:
    """Estimators from boxes [B, K, 4] and unit estimators [B|1, (D,) K|1, E, 2].

    Returns [B, K, E, 2] (training) or [B, D, K, E, 2] (inference, unit has a D axis).
    """
    size = np.asarray(image_size, dtype=np.float32)
    lo = normalise_pixels(boxes[..., :2], size)  # [B, K, 2]
    extent = 2.0 * (boxes[..., 2:] - boxes[..., :2]) / size
    shape = (boxes.shape[0],) + (1,) * (unit.ndim - 4) + (boxes.shape[1], 1, 2)
    return lo.reshape(shape) + extent.reshape(shape) * unit


def keypoint_estimators(keypoints: np.ndarray, image_size: np.ndarray, draws: Draws) -> np.ndarray:
    """Estimators [B, ..., K, E, 2] from keypoints [B, K, J, 3]: subsets of visible keypoints."""
    size = np.asarray(image_size, dtype=np.float32)[:, None, :]
    xy = normalise_pixels(keypoints[..., :2], size)  # [B, K, J, 2]
    visible = keypoint_visible(keypoints)
    extra_dims = draws.keys.ndim - 4  # 1 when the draws carry a D axis (inference)
    vis = visible.reshape(visible.shape[:1] + (1,) * extra_dims + visible.shape[1:])
    weights = subset_weights(draws.keys, draws.frac, vis)  # [B, ..., K, E, J]
    xy = np.nan_to_num(xy.reshape(xy.shape[:1] + (1,) * extra_dims + xy.shape[1:]))
    return weights @ xy


def keypoint_visible(
    keypoints: np.ndarray, min_confidence: float = KEYPOINT_MIN_CONFIDENCE
) -> np.ndarray:
    """Bool [..., J]: keypoint finite with confidence at least ``min_confidence`` (the models'
    floor unless given)."""
    finite = np.isfinite(keypoints).all(axis=-1)
    return finite & (np.nan_to_num(keypoints[..., 2]) >= min_confidence)


def observation_mask(
    config: SamplerConfig, boxes: np.ndarray, keypoints: np.ndarray | None
) -> np.ndarray:
    """Float [B, K]: 1 where the camera observes the person in the configured mode."""
    if config.observation == "bbox":
        return np.isfinite(boxes).all(axis=-1).astype(np.float32)
    return np.any(keypoint_visible(_need_keypoints(keypoints)), axis=-1).astype(np.float32)


def observation_center(
    config: SamplerConfig, boxes: np.ndarray, image_size: np.ndarray, keypoints: np.ndarray | None
) -> np.ndarray:
    """Expected mean pixel per camera [B, K, 2] in normalised units (the decoder's target)."""
    size = np.asarray(image_size, dtype=np.float32)
    if config.observation == "bbox":
        centre = boxes[..., :2] + (boxes[..., 2:] - boxes[..., :2]) * unit_mean(config)
        return np.nan_to_num(normalise_pixels(centre, size)).astype(np.float32)
    kp = _need_keypoints(keypoints)
    vis = keypoint_visible(kp)
    xy = np.where(vis[..., None], kp[..., :2], 0.0).sum(axis=-2)
    mean = xy / np.maximum(vis.sum(axis=-1, keepdims=True), 1)
    seen = np.any(vis, axis=-1)[..., None]
    return np.where(seen, normalise_pixels(mean, size), 0.0).astype(np.float32)


def observation_corners(
    config: SamplerConfig, boxes: np.ndarray, image_size: np.ndarray, keypoints: np.ndarray | None
) -> np.ndarray:
    """Normalised (min, max) corners per camera [B, K, 2, 2]: the box, or the keypoints' hull.

    Why: mean estimators describe where the body's mass is; with one view, depth comes from the
    body's extent (the foot point), which the estimators only carry noisily.
    """
    size = np.asarray(image_size, dtype=np.float32)
    if config.observation == "bbox":
        corners = np.stack([boxes[..., :2], boxes[..., 2:]], axis=-2)
    else:
        kp = _need_keypoints(keypoints)
        vis = keypoint_visible(kp)[..., None]
        lo = np.where(vis, kp[..., :2], np.inf).min(axis=-2)
        hi = np.where(vis, kp[..., :2], -np.inf).max(axis=-2)
        corners = np.stack([lo, hi], axis=-2)
    corners = normalise_pixels(corners, size[:, None, :])
    return np.where(np.isfinite(corners), corners, 0.0).astype(np.float32)


def _need_keypoints(keypoints: np.ndarray | None) -> np.ndarray:
    if keypoints is None:
        raise MomlocError("keypoints: required in keypoint observation mode but not given")
    return keypoints


def sample_estimators(
    config: SamplerConfig,
    boxes: np.ndarray,
    image_size: np.ndarray,
    rng: np.random.Generator,
    keypoints: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Training: fresh estimators [B, K, E, 2] and mask [B, K] (missing camera → zeros, 0)."""
    b, k = boxes.shape[:2]
    mask = observation_mask(config, boxes, keypoints)
    draws = random_draws(rng, (b, k), config)
    if config.observation == "bbox":
        est = box_estimators(np.nan_to_num(boxes), image_size, unit_estimators(draws))
    else:
        est = keypoint_estimators(_need_keypoints(keypoints), image_size, draws)
    if config.extent:
        corners = observation_corners(config, boxes, image_size, keypoints)
        est = np.concatenate([est, corners], axis=-2)
    return (est * mask[..., None, None]).astype(np.float32), mask


class InferenceSampler:
    """Deterministic estimators for serving: fixed draws, per-row only (batch-independent)."""

    def __init__(self, config: SamplerConfig, draws: Draws | None = None) -> None:
        self.config = config
        self.draws = fixed_draws(config) if draws is None else draws
        # [1, D, 1, ...]: a leading batch axis and a camera axis to broadcast against
        unit, keys, frac = self.draws.unit, self.draws.keys, self.draws.frac
        self._kp_draws = Draws(unit[None, :, None], keys[None, :, None], frac[None, :, None])
        self._unit = unit_estimators(self._kp_draws)  # [1, D, 1, E, 2], fixed once

    def __call__(
        self, boxes: np.ndarray, image_size: np.ndarray, keypoints: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Estimators [B, D, K, E, 2] and mask [B, K]."""
        mask = observation_mask(self.config, boxes, keypoints)
        if self.config.observation == "bbox":
            est = box_estimators(np.nan_to_num(boxes), image_size, self._unit)
        else:
            est = keypoint_estimators(_need_keypoints(keypoints), image_size, self._kp_draws)
        if self.config.extent:
            corners = observation_corners(self.config, boxes, image_size, keypoints)
            corners = np.broadcast_to(corners[:, None], (*est.shape[:-2], 2, 2))
            est = np.concatenate([est, corners], axis=-2)
        return (est * mask[:, None, :, None, None]).astype(np.float32), mask

"""Detector-like noise: what a real person detector makes of the true projected body.

How blind the detector is comes from a :class:`~models.simulate.profile.DetectorProfile` (data,
measured on real-looking frames; the default is the shipped detector's). Per camera, person and
frame, in this order:

1. **Behind the camera / out of view.** No box (NaN) when the mid-hip is behind the camera or the
   true box does not overlap the image.
2. **Truncation at the border.** The box is clipped to the image; a clipped box shorter than
   ``min_height_px`` is missed. The truncated fraction of its area raises the miss probability
   (``miss.truncation`` table).
3. **Occlusion between people.** A nearer person covers a farther one where their body region (the
   nearer person's clipped true box narrowed to 70 % of its width: a box overestimates a body by
   its empty corners) overlaps the farther one's box, measured on a 12×8 grid of sample points.
   The covered fraction raises the miss probability (``miss.occlusion``); covered ≥
   ``occlusion_shrink.above`` → the box moves toward the box of the uncovered samples by a random
   fraction U(blend) (a detector boxes the visible part, sometimes guessing the hidden extent).
4. **Misses by size**: ``miss.height_px``/``probability`` at the box height rescaled to the
   profile's reference frame height. The three causes combine as independent ones.
5. **Scale error**: the box is scaled about its centre by ``1 + s``, ``s ~ N(0, scale_sigma)``,
   clipped to ``±scale_clip``.
6. **Edge errors**: bottom and top edges move by ``(bias + sigma · z) · h`` (image y down, tables
   over box height), side edges by ``side_sigma · z · h``, ``h`` the box height before noise. The
   box is then clipped to the image again (detectors never report boxes outside the frame) and
   kept at least one pixel wide and tall.

**Correlation over time.** A detector makes the same mistake in consecutive frames (same pose,
same background), so temporal smoothing cannot average its noise away faster than it could on
real video. Scale and edge errors are, per camera, person and edge, an AR(1) sequence with
correlation ``exp(-Δt / edges.correlation_s)``. Misses persist too: per camera and person a
latent AR(1) normal ``z`` with ``miss.correlation_s``, and the person is missed when
``Φ(z) < p`` (a Gaussian copula). Why this and not a two-state Markov chain: the miss probability
changes from frame to frame with size and occlusion, and the copula keeps *exactly* the profile's
miss probability in every frame while making misses come in runs (lag-1 correlation of the miss
indicator > 0, growing with the correlation time). A correlation time of 0 gives independent
draws. Keypoint noise is, per camera, person, joint and axis, an AR(1) sequence with
``keypoints.correlation_s`` (a pose estimator misplaces an ankle the same way while the pose and
the crop stay the same; with 0 the draws are independent per frame). Occlusion blending is drawn
independently per frame.

Keypoints (COCO-17), as a pose estimator on each found box gives them (the profile's
``keypoints`` block, measured for MediaPipe by ``bench/keypoints/keypoint_noise.py``):

1. **No pose**: with probability ``keypoints.miss`` by box height (at the reference height) the
   estimator finds no pose in the box: every joint NaN, the box still reported. A latent AR(1)
   with ``keypoints.correlation_s`` (a Gaussian copula, as for the box misses).
2. **Noise**: the projected joints plus ``N(0, sigma · h + pixels)`` pixels, with confidence
   U(0.55, 0.95). A joint inside a nearer person's body region, or a face point turned away from
   the camera, is occluded: confidence U(0.05, 0.35) and three times the noise
   (:func:`keypoint_noise_scale`).
3. **Gross errors**: per person and joint group (head, torso, limbs), with the group's
   ``keypoints.gross`` rate, the whole group goes wild: each of its found joints lands anywhere
   in the box instead, keeping its confidence (a collapsed or swapped pose takes both ankles,
   not one; independent per frame). One event per group, not per joint, because what the rate
   is measured on is a group statistic: ``bench/keypoints/keypoint_noise.py`` counts how often the
   lower ankle (box bottom minus the lowest ankle) is gross on real video. With independent
   per-joint draws both ankles had to go wild, and land high, for that statistic to turn gross: at
   the per-joint limb rate 0.208 the simulated foot statistic was gross 0.027 of the time, against
   0.154 for MediaPipe (``bench/results/keypoint_noise.md``, 2026-12-03). The profile's rates
   are calibrated through this model (``calibrate_gross`` there) so that the simulated
   statistics are gross as often as the real ones (limbs 0.327 per person).

Joints outside the image, and every joint of a missed detection, are NaN.

False positives (boxes where nobody is) are drawn by :mod:`models.simulate.false_positives`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from models.simulate.profile import KEYPOINT_GROUPS, DetectorProfile, KeypointModel

_GRID_X, _GRID_Y = 8, 12
_BODY_WIDTH = 0.7
OCCLUDED_NOISE = 3.0  # an occluded or turned-away joint's noise, times a visible one's


def keypoint_noise_scale(
    model: KeypointModel, height: np.ndarray, occluded: np.ndarray
) -> np.ndarray:
    """The keypoint noise's standard deviation in pixels, ``sigma · h + pixels``, times
    :data:`OCCLUDED_NOISE` on occluded joints: ``height`` [...] box heights (px), ``occluded``
    [..., J] bool → [..., J]. The one formula the simulator draws with and
    ``bench.keypoints.keypoint_noise`` calibrates through."""
    scale = model.sigma * np.asarray(height, float)[..., None] + model.pixels
    return np.where(occluded, OCCLUDED_NOISE * scale, scale)


def correlated_normals(
    white: np.ndarray, history: np.ndarray, fps: float, correlation_time: float
) -> np.ndarray:
    """Unit-variance normals with autocorrelation exp(-|Δt| / correlation_time), along axis 0.

    ``white`` [F, ...] are this block's i.i.d. draws and ``history`` [H, ...] the previous
    block's, so the filtered sequence runs on smoothly across block boundaries while every block
    stays computable on its own (a truncated AR(1) filter).
    """
    if correlation_time <= 0:
        return white
    rho = float(np.exp(-1.0 / (fps * correlation_time)))
    taps = min(len(history) + 1, int(np.ceil(np.log(1e-3) / np.log(rho))) + 1)
    kernel = rho ** np.arange(taps)
    kernel /= np.sqrt((kernel**2).sum())  # unit variance despite the truncation
    series = np.concatenate([history, white])
    offset = len(history)
    out = np.zeros_like(white)
    for lag, weight in enumerate(kernel):
        out += weight * series[offset - lag : offset - lag + len(white)]
    return out


def _area(boxes: np.ndarray) -> np.ndarray:
    return np.clip(boxes[..., 2] - boxes[..., 0], 0, None) * np.clip(
        boxes[..., 3] - boxes[..., 1], 0, None
    )


def _clip(boxes: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Clip [..., K, P, 4] boxes to the images of size [K, 2]."""
    w = size[:, 0, None].astype(float)
    h = size[:, 1, None].astype(float)
    out = boxes.copy()
    out[..., 0] = np.clip(out[..., 0], 0, w)
    out[..., 2] = np.clip(out[..., 2], 0, w)
    out[..., 1] = np.clip(out[..., 1], 0, h)
    out[..., 3] = np.clip(out[..., 3], 0, h)
    return out


def _body_regions(clipped: np.ndarray) -> np.ndarray:
    """The part of each box that is really body: narrowed to ``_BODY_WIDTH`` of its width."""
    centre = (clipped[..., 0] + clipped[..., 2]) / 2
    half = (clipped[..., 2] - clipped[..., 0]) * _BODY_WIDTH / 2
    return np.stack([centre - half, clipped[..., 1], centre + half, clipped[..., 3]], -1)


def _covered(points: np.ndarray, regions: np.ndarray, nearer: np.ndarray) -> np.ndarray:
    """Points [F,K,P,G,2] covered by any nearer person's region [F,K,P,4]; nearer [F,K,P,P]."""
    x, y = points[..., None, 0], points[..., None, 1]  # [F,K,P,G,1]
    r = regions[:, :, None, None, :, :]  # [F,K,1,1,Q,4]
    inside = (x >= r[..., 0]) & (x <= r[..., 2]) & (y >= r[..., 1]) & (y <= r[..., 3])
    return (inside & nearer[:, :, :, None, :]).any(-1)  # NaN regions compare False


def detect(
    true_boxes: np.ndarray,
    depth: np.ndarray,
    joints: np.ndarray,
    face_away: np.ndarray,
    image_size: np.ndarray,
    profile: DetectorProfile,
    rng: np.random.Generator,
    normals: np.ndarray | None = None,
    miss_latent: np.ndarray | None = None,
    keypoint_draws: KeypointDraws | None = None,
    hidden: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Noisy boxes [F,K,P,4] and keypoints [F,K,P,17,3] from the true geometry.

    ``hidden`` [F,K,P]: the fraction of each body that furniture hides (its ``true_boxes`` are
    already those of the visible part); it raises the miss probability like an occlusion between
    people does (the larger of the two counts).

    ``normals`` [F,K,P,5]: standard normal draws for the scale error and the four edge errors,
    ``miss_latent`` [F,K,P]: the latent normals of the miss decision, ``keypoint_draws``: those
    of the keypoint noise and pose misses (temporally correlated ones from
    :func:`correlated_normals`); each drawn i.i.d. when None.

    ``true_boxes`` [F,K,P,4] unclipped (NaN: behind the camera), ``depth`` [F,K,P] of the mid-hip,
    ``joints`` [F,K,P,17,2] projected joints (NaN behind the camera), ``face_away`` [F,K,P,17]
    bool (face points turned away), ``image_size`` [K,2].
    """
    f, k, p = depth.shape
    clipped = _clip(true_boxes, image_size)
    true_area = _area(true_boxes)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = _area(clipped) / true_area
    seen = np.isfinite(true_boxes).all(-1) & (fraction > 0)
    clipped_height = clipped[..., 3] - clipped[..., 1]
    found = seen & (clipped_height >= profile.min_height_px)
    regions = np.where(seen[..., None], _body_regions(clipped), np.nan)

    # Occlusion on a grid of sample points inside each clipped box.
    gx = (np.arange(_GRID_X) + 0.5) / _GRID_X
    gy = (np.arange(_GRID_Y) + 0.5) / _GRID_Y
    grid_u, grid_v = np.meshgrid(gx, gy)
    u, v = grid_u.ravel(), grid_v.ravel()
    x0, y0, x1, y1 = (clipped[..., i, None] for i in range(4))
    samples = np.stack([x0 + (x1 - x0) * u, y0 + (y1 - y0) * v], -1)  # [F,K,P,G,2]
    nearer = depth[..., None, :] < depth[..., :, None] - 0.1  # [F,K,P(i),P(j)]: j nearer than i
    nearer &= ~np.eye(p, dtype=bool)
    covered = _covered(samples, regions, nearer)
    occluded = covered.mean(-1)
    free = ~covered
    cell = np.stack([(x1 - x0) / _GRID_X / 2, (y1 - y0) / _GRID_Y / 2], -1)[..., 0, :]
    # min / max over the uncovered samples; an all-covered box gives NaN (it is missed anyway).
    # Masked with ±inf rather than nanmin, which warns, and silencing warnings is not
    # thread-safe (live demo camera workers share a scene).
    low = np.where(free[..., None], samples, np.inf).min(axis=-2)
    high = np.where(free[..., None], samples, -np.inf).max(axis=-2)
    none_free = ~np.any(free, axis=-1)[..., None]
    visible_box = np.concatenate(
        [np.where(none_free, np.nan, low - cell), np.where(none_free, np.nan, high + cell)], -1
    )
    shrink = (occluded >= profile.shrink_above) & found
    blend = rng.uniform(*profile.shrink_blend, (f, k, p))[..., None]
    boxes = np.where(shrink[..., None], clipped + blend * (visible_box - clipped), clipped)

    image_height = image_size[:, 1, None].astype(float)  # [K, 1] broadcasts over [F, K, P]
    truncated = np.where(seen, 1.0 - np.nan_to_num(fraction), 1.0)
    covered_any = occluded if hidden is None else np.maximum(occluded, hidden)
    miss = profile.miss_probability(
        np.nan_to_num(clipped_height), image_height, covered_any, truncated
    )
    if miss_latent is None:
        miss_latent = rng.standard_normal((f, k, p))
    found &= ndtr(miss_latent) >= miss

    height = boxes[..., 3] - boxes[..., 1]
    centre = (boxes[..., :2] + boxes[..., 2:]) / 2
    half = (boxes[..., 2:] - boxes[..., :2]) / 2
    if normals is None:
        normals = rng.standard_normal((f, k, p, 5))
    edges = profile.edges
    clip = edges.scale_clip
    scale = 1.0 + np.clip(normals[..., 0] * edges.scale_sigma, -clip, clip)
    boxes = np.concatenate([centre - half * scale[..., None], centre + half * scale[..., None]], -1)
    ref = profile.reference_height(np.nan_to_num(height), image_height)
    side = edges.side_sigma(ref)
    shift = np.stack(
        [
            side * normals[..., 1],
            edges.top_bias(ref) + edges.top_sigma(ref) * normals[..., 2],
            side * normals[..., 3],
            edges.bottom_bias(ref) + edges.bottom_sigma(ref) * normals[..., 4],
        ],
        -1,
    )
    boxes = boxes + shift * height[..., None]
    boxes = _clip(boxes, image_size)
    boxes[..., 2:] = np.maximum(boxes[..., 2:], boxes[..., :2] + 1.0)
    boxes = np.where(found[..., None], boxes, np.nan)

    posed = found & _pose_found(height, image_size, profile, rng, keypoint_draws)
    keypoints = _keypoints(
        joints,
        face_away,
        regions,
        nearer,
        height,
        posed,
        image_size,
        profile,
        rng,
        None if keypoint_draws is None else keypoint_draws.normals,
    )
    return boxes, gross_errors(keypoints, boxes, profile.keypoints, rng)


@dataclass(frozen=True)
class KeypointDraws:
    """Standard normals of one block's keypoints: the pixel noise [F,K,P,17,2] and the latent of
    the pose-miss decision [F,K,P] (pass no ``KeypointDraws`` at all for i.i.d. draws from the
    block's generator)."""

    normals: np.ndarray
    miss_latent: np.ndarray


def _pose_found(
    height: np.ndarray,
    image_size: np.ndarray,
    profile: DetectorProfile,
    rng: np.random.Generator,
    draws: KeypointDraws | None,
) -> np.ndarray | bool:
    """[F,K,P] whether the pose estimator finds a pose in the person's box (the profile's
    ``keypoints.miss`` by box height, a Gaussian copula as for the box misses)."""
    model = profile.keypoints
    if not model.misses:
        return True
    ref = profile.reference_height(np.nan_to_num(height), image_size[:, 1, None].astype(float))
    latent = rng.standard_normal(height.shape) if draws is None else draws.miss_latent
    return ndtr(latent) >= model.miss(ref)


def gross_errors(
    keypoints: np.ndarray, boxes: np.ndarray, model: KeypointModel, rng: np.random.Generator
) -> np.ndarray:
    """Keypoints [F,K,P,J,3] with gross errors: per person and joint group of
    :data:`~models.simulate.profile.KEYPOINT_GROUPS`, at the group's rate, every found joint of
    the group moved to its own uniform place inside the person's box [F,K,P,4] (a collapsed or
    swapped pose puts the group's joints anywhere on the body). The draws come last from the
    block's generator (one uniform per person and group, then the places), so the boxes drawn
    before them do not depend on the rates."""
    rates = np.asarray(model.gross)
    if not (rates > 0).any():
        return keypoints
    f, k, p, j, _ = keypoints.shape
    event = rng.random((f, k, p, len(KEYPOINT_GROUPS)))
    wild = np.zeros((f, k, p, j), bool)
    for g, joints in enumerate(KEYPOINT_GROUPS.values()):
        members = list(joints)
        wild[..., members] = event[..., g, None] < rates[members]
    wild &= np.isfinite(keypoints[..., 0])
    u = rng.random((f, k, p, j, 2))
    lo, hi = boxes[..., None, :2], boxes[..., None, 2:]
    out = keypoints.copy()
    out[..., :2] = np.where(wild[..., None], lo + u * (hi - lo), keypoints[..., :2])
    return out


def _keypoints(
    joints: np.ndarray,
    face_away: np.ndarray,
    regions: np.ndarray,
    nearer: np.ndarray,
    height: np.ndarray,
    found: np.ndarray,
    image_size: np.ndarray,
    profile: DetectorProfile,
    rng: np.random.Generator,
    normals: np.ndarray | None,
) -> np.ndarray:
    f, k, p, j, _ = joints.shape
    occluded = _covered(joints, regions, nearer) | face_away
    sigma = keypoint_noise_scale(profile.keypoints, height, occluded)
    if normals is None:
        normals = rng.normal(0.0, 1.0, (f, k, p, j, 2))
    noisy = joints + normals * sigma[..., None]
    confidence = np.where(
        occluded, rng.uniform(0.05, 0.35, (f, k, p, j)), rng.uniform(0.55, 0.95, (f, k, p, j))
    )
    w = image_size[:, 0, None, None]
    h = image_size[:, 1, None, None]
    inside = (noisy[..., 0] >= 0) & (noisy[..., 0] < w) & (noisy[..., 1] >= 0)
    inside &= (noisy[..., 1] < h) & found[..., None]
    out = np.concatenate([noisy, confidence[..., None]], -1)
    return np.where(inside[..., None], out, np.nan)

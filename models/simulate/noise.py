"""Detector-like noise: what a real person detector makes of the true projected body.

The defaults are deliberately no kinder than a real detector (SSDLite / YOLO on 640×480 webcam
frames), so accuracy figures measured on synthetic scenes mean something. Per camera, person and
frame, independently, in this order:

1. **Behind the camera / out of view.** No box (NaN) when the mid-hip is behind the camera or the
   true box does not overlap the image.
2. **Truncation at the border.** The box is clipped to the image. If less than
   ``min_visible_fraction`` (30 %) of the true box area remains, or the clipped box is less than
   ``min_box_height`` (16 px) tall, the person is missed.
3. **Occlusion between people.** A nearer person covers a farther one where their body region (the
   nearer person's clipped true box narrowed to 70 % of its width: a box overestimates a body by
   its empty corners) overlaps the farther one's box, measured on a 12×8 grid of sample points.
   Covered ≥ ``occlusion_miss`` (70 %) → missed. Covered ≥ ``occlusion_shrink`` (15 %) → the box
   moves toward the box of the uncovered samples by a random fraction U(0.5, 1) (a detector boxes
   the visible part, sometimes guessing the hidden extent).
4. **Random misses** with probability ``miss_rate`` (3 %).
5. **Scale error**: the box is scaled about its centre by ``1 + s``, ``s ~ N(0, scale)``,
   ``scale`` = 5 %, clipped to ±15 %.
6. **Jitter**: each of the four edges moves by ``N(0, jitter · h)``, ``jitter`` = 3 %, ``h`` the
   box height before noise. The box is then clipped to the image again (detectors never report
   boxes outside the frame) and kept at least one pixel wide and tall.

Scale error and jitter are correlated in time like a real detector's (the same pose and
background give the same mistake in consecutive frames): per camera, person and edge an AR(1)
sequence with correlation ``exp(-Δt / correlation_time)``, ``correlation_time`` = 0.2 s (0.72
from frame to frame at 15 fps), so temporal smoothing cannot average the noise away faster than
it could on real video. Misses, occlusion blending and keypoint noise are drawn independently per
frame.

Keypoints (COCO-17) are the projected joints plus ``N(0, keypoint_sigma · h + keypoint_pixels)``
pixel noise, with confidence U(0.55, 0.95). A joint inside a nearer person's body region, or a
face point turned away from the camera, is occluded: confidence U(0.05, 0.35) and three times the
noise. Joints outside the image, and every joint of a missed detection, are NaN.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

_GRID_X, _GRID_Y = 8, 12
_BODY_WIDTH = 0.7


@dataclass(frozen=True)
class NoiseConfig:
    """Detector noise parameters; the defaults are the documented realistic ones, keep them."""

    jitter: float = 0.03
    scale: float = 0.05
    miss_rate: float = 0.03
    min_visible_fraction: float = 0.3
    min_box_height: float = 16.0
    correlation_time: float = 0.2
    occlusion_miss: float = 0.7
    occlusion_shrink: float = 0.15
    keypoint_sigma: float = 0.015
    keypoint_pixels: float = 1.0

    @classmethod
    def exact(cls) -> NoiseConfig:
        """No random noise (still truncation and occlusion): for debugging and geometry tests."""
        return cls(jitter=0.0, scale=0.0, miss_rate=0.0, keypoint_sigma=0.0, keypoint_pixels=0.0)


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
    config: NoiseConfig,
    rng: np.random.Generator,
    normals: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Noisy boxes [F,K,P,4] and keypoints [F,K,P,17,3] from the true geometry.

    ``normals`` [F,K,P,5]: standard normal draws for the scale error and the four edge jitters
    (temporally correlated ones from :func:`correlated_normals`); drawn i.i.d. when None.

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
    found = seen & (fraction >= config.min_visible_fraction)
    found &= clipped[..., 3] - clipped[..., 1] >= config.min_box_height
    regions = np.where(seen[..., None], _body_regions(clipped), np.nan)

    # Occlusion on a grid of sample points inside each clipped box.
    gx = (np.arange(_GRID_X) + 0.5) / _GRID_X
    gy = (np.arange(_GRID_Y) + 0.5) / _GRID_Y
    u, v = np.meshgrid(gx, gy)
    u, v = u.ravel(), v.ravel()
    x0, y0, x1, y1 = (clipped[..., i, None] for i in range(4))
    samples = np.stack([x0 + (x1 - x0) * u, y0 + (y1 - y0) * v], -1)  # [F,K,P,G,2]
    nearer = depth[..., None, :] < depth[..., :, None] - 0.1  # [F,K,P(i),P(j)]: j nearer than i
    nearer &= ~np.eye(p, dtype=bool)
    covered = _covered(samples, regions, nearer)
    occluded = covered.mean(-1)
    found &= occluded < config.occlusion_miss
    free = ~covered
    big = np.where(free[..., None], samples, np.nan)
    cell = np.stack([(x1 - x0) / _GRID_X / 2, (y1 - y0) / _GRID_Y / 2], -1)[..., 0, :]
    with warnings.catch_warnings():  # all-covered boxes give all-NaN slices, which is fine
        warnings.simplefilter("ignore", RuntimeWarning)
        visible_box = np.concatenate(
            [np.nanmin(big, axis=-2) - cell, np.nanmax(big, axis=-2) + cell], -1
        )
    shrink = (occluded >= config.occlusion_shrink) & found
    blend = rng.uniform(0.5, 1.0, (f, k, p))[..., None]
    boxes = np.where(shrink[..., None], clipped + blend * (visible_box - clipped), clipped)

    found &= rng.random((f, k, p)) >= config.miss_rate

    height = boxes[..., 3] - boxes[..., 1]
    centre = (boxes[..., :2] + boxes[..., 2:]) / 2
    half = (boxes[..., 2:] - boxes[..., :2]) / 2
    if normals is None:
        normals = rng.standard_normal((f, k, p, 5))
    scale = 1.0 + np.clip(normals[..., 0] * config.scale, -0.15, 0.15)
    boxes = np.concatenate([centre - half * scale[..., None], centre + half * scale[..., None]], -1)
    boxes = boxes + normals[..., 1:] * (config.jitter * height)[..., None]
    boxes = _clip(boxes, image_size)
    boxes[..., 2:] = np.maximum(boxes[..., 2:], boxes[..., :2] + 1.0)
    boxes = np.where(found[..., None], boxes, np.nan)

    keypoints = _keypoints(
        joints, face_away, regions, nearer, height, found, image_size, config, rng
    )
    return boxes, keypoints


def _keypoints(
    joints: np.ndarray,
    face_away: np.ndarray,
    regions: np.ndarray,
    nearer: np.ndarray,
    height: np.ndarray,
    found: np.ndarray,
    image_size: np.ndarray,
    config: NoiseConfig,
    rng: np.random.Generator,
) -> np.ndarray:
    f, k, p, j, _ = joints.shape
    occluded = _covered(joints, regions, nearer) | face_away
    sigma = config.keypoint_sigma * height[..., None] + config.keypoint_pixels
    sigma = np.where(occluded, 3.0 * sigma, sigma)
    noisy = joints + rng.normal(0.0, 1.0, (f, k, p, j, 2)) * sigma[..., None]
    confidence = np.where(
        occluded, rng.uniform(0.05, 0.35, (f, k, p, j)), rng.uniform(0.55, 0.95, (f, k, p, j))
    )
    w = image_size[:, 0, None, None]
    h = image_size[:, 1, None, None]
    inside = (noisy[..., 0] >= 0) & (noisy[..., 0] < w) & (noisy[..., 1] >= 0)
    inside &= (noisy[..., 1] < h) & found[..., None]
    out = np.concatenate([noisy, confidence[..., None]], -1)
    return np.where(inside[..., None], out, np.nan)

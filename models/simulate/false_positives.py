"""False positives: boxes a detector reports where nobody is, with the persistence real ones have.

A real detector's false boxes are not white noise: a coat on a chair, a plant or a door frame is
"seen" as a person for a while from the same spot, and now and then something random in the lower
part of the image (where people's bodies usually are) fires for a few frames. The model, per
camera, as a birth-death process:

- **Births**: per frame and camera, ``slots`` independent Bernoulli draws with probability
  ``rate / slots``, where ``rate = per_frame / E[lifetime]``, so the stationary mean count per
  frame and camera is the profile's ``false_positives.per_frame``.
- **Lifetime**: geometric with mean ``persistence_s · fps`` frames, truncated at one block
  (:data:`~models.simulate.scene.BLOCK` frames; ``rate`` uses the truncated mean, so the count stays
  exact). The box keeps its place and size for its whole life, with a small per-frame edge jitter.
- **Place and size**: with probability ``hotspot_share`` at one of the camera's ``hotspots``
  (furniture-like places fixed per scene and camera, each with its own size), else anywhere across
  the image with its bottom edge in the ``bottom`` band (fractions of the image height). Heights
  are log-uniform in ``height_px`` (given at the profile's reference height, rescaled to each
  camera's image), widths ``aspect`` times the height.

Why births per block: block ``b`` of a scene is computed on its own (``observe(i)`` must not
depend on what was observed before), and a false box born in block ``b - 1`` may still be visible
in block ``b``. Births of a block are a pure function of ``(seed, block)``, lifetimes never exceed
a block, so block ``b`` needs only the births of blocks ``b - 1`` and ``b``: the same box appears
identically whichever block is asked for first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models.simulate.profile import DetectorProfile


@dataclass(frozen=True)
class Births:
    """False boxes born in one block: per [frame, camera, slot] a flag, lifetime and box."""

    born: np.ndarray  # [F, K, S] bool
    lifetime: np.ndarray  # [F, K, S] int, frames
    boxes: np.ndarray  # [F, K, S, 4] pixels, clipped to the image


def mean_lifetime(profile: DetectorProfile, fps: float, block: int) -> tuple[float, float]:
    """(geometric parameter q, mean lifetime in frames after truncation at ``block``)."""
    frames = max(1.0, profile.false_positives.persistence_s * fps)
    q = 1.0 / frames
    return q, (1.0 - (1.0 - q) ** block) / q


def slot_count(profile: DetectorProfile, fps: float, block: int) -> tuple[int, float]:
    """(slots per frame and camera, birth probability per slot)."""
    _, life = mean_lifetime(profile, fps, block)
    rate = profile.false_positives.per_frame / life
    slots = max(2, math.ceil(4 * rate))
    return slots, rate / slots


def hotspots(
    profile: DetectorProfile, image_sizes: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Per camera ``H`` fixed places: [K, H, 3] = x centre, bottom y, height (own pixels)."""
    fp = profile.false_positives
    k, h = len(image_sizes), fp.hotspots
    size = image_sizes.astype(float)[:, None, :]
    x = rng.uniform(0.1, 0.9, (k, h)) * size[..., 0]
    bottom = rng.uniform(*fp.bottom, (k, h)) * size[..., 1]
    height = _log_uniform(rng, fp.height_px, (k, h)) * size[..., 1] / profile.reference_height_px
    return np.stack([x, bottom, height], -1)


def births(
    profile: DetectorProfile,
    fps: float,
    frames: int,
    image_sizes: np.ndarray,
    places: np.ndarray,
    rng: np.random.Generator,
) -> Births:
    """The false boxes born in one block of ``frames`` frames (all draws fixed-shape)."""
    fp = profile.false_positives
    k = len(image_sizes)
    slots, p = slot_count(profile, fps, frames)
    q, _ = mean_lifetime(profile, fps, frames)
    shape = (frames, k, slots)
    born = rng.random(shape) < p
    lifetime = np.minimum(rng.geometric(q, shape), frames)
    size = image_sizes.astype(float)[None, :, None, :]  # [1, K, 1, 2]
    scale = size[..., 1] / profile.reference_height_px
    height = _log_uniform(rng, fp.height_px, shape) * scale
    x = rng.uniform(0.0, 1.0, shape) * size[..., 0]
    bottom = rng.uniform(*fp.bottom, shape) * size[..., 1]
    at_spot = rng.random(shape) < fp.hotspot_share
    if fp.hotspots > 0:
        spot = rng.integers(0, fp.hotspots, shape)
        chosen = places[np.arange(k)[None, :, None], spot]  # [F, K, S, 3]
        jiggle = rng.uniform(0.9, 1.1, shape)
        x = np.where(at_spot, chosen[..., 0], x)
        bottom = np.where(at_spot, chosen[..., 1], bottom)
        height = np.where(at_spot, chosen[..., 2] * jiggle, height)
    width = height * rng.uniform(*fp.aspect, shape)
    boxes = np.stack([x - width / 2, bottom - height, x + width / 2, bottom], -1)
    return Births(born, lifetime, _clip(boxes, image_sizes))


def visible(
    previous: Births,
    current: Births,
    profile: DetectorProfile,
    image_sizes: np.ndarray,
    rng: np.random.Generator,
) -> np.ndarray:
    """False boxes visible in the frames of ``current``'s block: [F, K, Q, 4], NaN-padded."""
    f = current.born.shape[0]
    born = np.concatenate([previous.born, current.born])  # [2F, K, S]
    life = np.concatenate([previous.lifetime, current.lifetime])
    boxes = np.concatenate([previous.boxes, current.boxes])
    t0 = np.arange(-f, f)[:, None, None]
    frames = np.arange(f)[:, None, None, None]  # [F, 1, 1, 1] against births [2F, K, S]
    active = born & (t0 <= frames) & (frames < t0 + life)  # [F, 2F, K, S]
    active = active.transpose(0, 2, 1, 3).reshape(f, born.shape[1], -1)  # [F, K, N]
    flat = boxes.transpose(1, 0, 2, 3).reshape(born.shape[1], -1, 4)  # [K, N, 4]
    count = active.sum(-1)
    q = int(count.max()) if count.size else 0
    out = np.full((f, born.shape[1], q, 4), np.nan)
    if q == 0:
        return out
    ff, kk, nn = np.nonzero(active)
    rank = np.cumsum(active, -1)[ff, kk, nn] - 1
    out[ff, kk, rank] = flat[kk, nn]
    height = out[..., 3] - out[..., 1]
    jitter = rng.standard_normal(out.shape) * (profile.false_positives.jitter * height)[..., None]
    out = _clip(out + jitter, image_sizes)
    out[..., 2:] = np.maximum(out[..., 2:], out[..., :2] + 1.0)
    return out


def _log_uniform(
    rng: np.random.Generator, span: tuple[float, float], shape: tuple[int, ...]
) -> np.ndarray:
    return np.exp(rng.uniform(np.log(span[0]), np.log(span[1]), shape))


def _clip(boxes: np.ndarray, image_sizes: np.ndarray) -> np.ndarray:
    """Clip [..., K, S, 4] boxes to camera k's image."""
    w = image_sizes[:, 0, None].astype(float)
    h = image_sizes[:, 1, None].astype(float)
    out = boxes.copy()
    out[..., 0::2] = np.clip(out[..., 0::2], 0, w[..., None])
    out[..., 1::2] = np.clip(out[..., 1::2], 0, h[..., None])
    return out

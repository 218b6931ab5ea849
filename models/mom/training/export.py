"""Write a trained model directory: ``encoder.onnx`` + ``model.json`` (+ the torch checkpoint).

The ONNX graph takes the runtime's deterministic estimators and does the rest in one call:

* inputs ``estimators`` float32 [B, D, K, E, 2] (normalised pixels, see :mod:`models.mom.sampling`)
  and ``mask`` float32 [B, K] (1 = camera sees the person); B and D are dynamic;
* output ``world`` float32 [B, 2] in metres (the D draws averaged, normalisation undone).

``model.json`` carries everything serving needs without torch: cameras, image sizes, observation
mode, sampler settings and its fixed draws, world normalisation, the decoder matrices P̄_k in
*pixel* units (acting on ``(x, y, 0, 1)`` with x, y in metres), training metrics, a version and
``world_bounds`` (:func:`world_bounds`: the floor area the training positions cover, which the
daemon's map shows by default).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
import torch

from common.atomic import atomic_write, atomic_write_json
from models.mom.sampling import SamplerConfig, draws_to_json, fixed_draws
from models.mom.training.torch_model import DrawAverage, MomEncoder

MODEL_FORMAT = "mom-model-v1"
ONNX_NAME = "encoder.onnx"
JSON_NAME = "model.json"
CHECKPOINT_NAME = "model.pt"
OPSET = 17


def export_encoder(
    encoder: MomEncoder, centre: np.ndarray, scale: float, path: Path, num_estimators: int
) -> None:
    """ONNX export with dynamic batch and draw axes."""
    wrapper = DrawAverage(encoder, centre, scale).eval()
    k = encoder.num_cameras
    example = (torch.zeros(2, 3, k, num_estimators, 2), torch.ones(2, k))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the legacy exporter announces its deprecation
        torch.onnx.export(
            wrapper,
            example,
            str(path),
            dynamo=False,
            input_names=["estimators", "mask"],
            output_names=["world"],
            dynamic_axes={
                "estimators": {0: "batch", 1: "draws"},
                "mask": {0: "batch"},
                "world": {0: "batch"},
            },
            opset_version=OPSET,
        )


def pixel_decoder(
    matrices: np.ndarray, centre: np.ndarray, scale: float, sizes: np.ndarray
) -> np.ndarray:
    """P̄_k from normalised units to pixels and metres: ``A_k · P̄_k · T`` (z column kept 0)."""
    to_norm = np.array(
        [[1 / scale, 0, -centre[0] / scale], [0, 1 / scale, -centre[1] / scale], [0, 0, 1]]
    )
    out = []
    for matrix, (w, h) in zip(matrices, sizes, strict=True):
        to_pixels = np.array([[w / 2, 0, w / 2], [0, h / 2, h / 2], [0, 0, 1]])
        homography = to_pixels @ matrix[:, [0, 1, 3]] @ to_norm
        homography = homography / np.abs(homography[2]).max()
        out.append(np.insert(homography, 2, 0.0, axis=1))
    return np.stack(out)


def world_bounds(world: np.ndarray) -> dict[str, float] | None:
    """Extent (metres) of the training positions ``world`` [N, 2+]: for a floor-mark recording
    the marks' extent, for dense labels the area walked. None without a finite position."""
    xy = np.asarray(world, np.float64)[:, :2]
    xy = xy[np.isfinite(xy).all(axis=1)]
    if not len(xy):
        return None
    (xmin, ymin), (xmax, ymax) = xy.min(axis=0), xy.max(axis=0)
    return {"xmin": float(xmin), "xmax": float(xmax), "ymin": float(ymin), "ymax": float(ymax)}


def write_model_dir(
    out_dir: Path,
    *,
    encoder: MomEncoder,
    decoder_matrices: np.ndarray,
    sampler: SamplerConfig,
    image_sizes: np.ndarray,
    centre: np.ndarray,
    scale: float,
    checkpoint: dict,
    metrics: dict,
    settings: dict,
    floor_prior: dict | None = None,
    extra: dict[str, Any] | None = None,
    world_bounds: dict[str, float] | None = None,
    setup_area: dict | None = None,
) -> None:
    """Write all three files, each atomically (:mod:`common.atomic`), ``model.json`` last and
    once, complete with the ``floor_prior`` entry and any ``extra`` top-level entries (e.g. the
    demo model's provenance), so a reader (the daemon's hot reload) never sees a half-written
    or intermediate model."""
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write(
        out_dir / ONNX_NAME, lambda tmp: export_encoder(encoder, centre, scale, tmp, sampler.rows)
    )
    atomic_write(out_dir / CHECKPOINT_NAME, lambda tmp: torch.save(checkpoint, tmp))
    meta = {
        "format": MODEL_FORMAT,
        "version": 1,
        "num_cameras": int(encoder.num_cameras),
        "image_sizes": np.asarray(image_sizes).astype(int).tolist(),
        "observation": sampler.observation,
        "sampler": sampler.to_dict(),
        "draws": draws_to_json(fixed_draws(sampler)),
        "normalisation": {"centre": [float(c) for c in centre], "scale": float(scale)},
        "encoder": {
            "file": ONNX_NAME,
            "inputs": {
                "estimators": "float32 [B, D, K, E, 2] normalised pixels 2p/size-1",
                "mask": "float32 [B, K] 1 = camera sees the person",
            },
            "output": {"world": "float32 [B, 2] metres, mean over the D draws"},
        },
        "decoder": {
            "matrices": pixel_decoder(decoder_matrices, centre, scale, image_sizes).tolist(),
            "acts_on": "(x, y, 0, 1) in metres -> homogeneous pixels of the body's mean point",
        },
        "checkpoint": CHECKPOINT_NAME,
        "settings": settings,
        "metrics": metrics,
    }
    if floor_prior is not None:
        meta["floor_prior"] = floor_prior
    if world_bounds is not None:
        meta["world_bounds"] = world_bounds
    if setup_area is not None:
        meta["setup_area"] = setup_area
    clashes = set(extra or {}) & set(meta)
    if clashes:
        raise ValueError(f"extra model.json entries would replace {sorted(clashes)}")
    atomic_write_json(out_dir / JSON_NAME, {**meta, **(extra or {})})

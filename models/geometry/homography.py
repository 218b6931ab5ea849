"""Plane homographies: a robust fit from noisy correspondences, mapping, and the local Jacobian.

Why a homography: every image point that lies on one world plane (the floor under a person's
feet, or the plane at a fixed height through a person's middle) is related to its floor position
by a 3×3 projective map, whatever the camera's pose and focal length. Four or more floor marks
seen by a camera fix it, with no calibration.

The fit (:func:`fit_homography`) is the project's Hartley-normalised DLT
(:func:`models.geometry.dlt.fit_dlt`: both point sets moved to centroid 0, mean distance sqrt 2, so
pixels and metres get equal say in the SVD) followed by a robust
refinement of the *transfer* error in the destination plane (metres on the floor when fitting
pixel → floor) with ``scipy.optimize.least_squares`` and a soft-L1 loss: DLT minimises an
algebraic error that over-weights far points, and a few bad boxes (occlusion, a second person
behind) must not pull the map. The refinement keeps ``H[2, 2] = 1`` *in normalised coordinates*,
which is safe because there the centroid of the data maps to a finite point.

What labelled floor marks need on top (per-mark medians, marks whose boxes are not the person,
degenerate marks) is :mod:`models.geometry.mark_fit`. Numpy + scipy only: used at serving time too.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from scipy.optimize import least_squares

from common.errors import MomlocError
from models.geometry.dlt import fit_dlt, hartley_normaliser


def apply_homography(h: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Map [..., 2] points through H [3, 3]; NaN where a point maps to infinity or is NaN."""
    points = np.asarray(points, dtype=np.float64)
    hom = points @ h[:, :2].T + h[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        w = hom[..., 2:3]
        out = hom[..., :2] / np.where(np.abs(w) < 1e-12, np.nan, w)
    return out


def homography_jacobian(h: np.ndarray, points: np.ndarray) -> np.ndarray:
    """d(H p)/dp at [..., 2] points → [..., 2, 2] (rows: output x, y; columns: input u, v).

    How far a small move in the source plane goes in the destination plane: a pixel of box
    noise at the far end of the room is many centimetres on the floor, which is what the
    per-camera error model needs.
    """
    points = np.asarray(points, dtype=np.float64)
    hom = points @ h[:, :2].T + h[:, 2]
    w = hom[..., 2][..., None, None]
    xy = (hom[..., :2] / hom[..., 2:3])[..., :, None]  # [..., 2, 1]
    return (h[:2, :2] - xy * h[2, :2]) / w


def _transform(t: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ t[:2, :2].T + t[:2, 2]


def fit_homography(
    src: np.ndarray,
    dst: np.ndarray,
    *,
    weights: np.ndarray | None = None,
    loss: Literal["linear", "soft_l1", "huber", "cauchy", "arctan"] = "soft_l1",
    scale: float = 0.15,
    max_nfev: int = 200,
) -> np.ndarray:
    """Robust H [3, 3] with dst ~ H src: normalised DLT, then least-squares on the transfer error.

    ``scale`` is the soft-L1/Huber knee in destination units (0.15 m on the floor: errors past
    it count linearly, so outliers pull less). ``loss="linear"`` gives plain least squares.
    ``weights`` [M] scale each pair's residual (1 / its noise std, relative): the knee then
    applies to the weighted residual.
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    h_dlt = fit_dlt(src, dst, what="homography")
    ts, td = hartley_normaliser(src), hartley_normaliser(dst)
    s, d = _transform(ts, src), _transform(td, dst)
    h0 = td @ h_dlt @ np.linalg.inv(ts)  # the same map in normalised coordinates
    if abs(h0[2, 2]) < 1e-12:
        raise MomlocError("homography: the data centroid maps to infinity")
    h0 = h0 / h0[2, 2]
    weight = np.ones((len(s), 1)) if weights is None else np.asarray(weights, np.float64)[:, None]

    def residual(p: np.ndarray) -> np.ndarray:
        hom = s @ p[:6].reshape(2, 3)[:, :2].T + p[:6].reshape(2, 3)[:, 2]
        w = s @ p[6:8] + 1.0
        return ((hom / w[:, None] - d) * weight).ravel()

    f_scale = scale * td[0, 0]  # destination units → normalised units
    start = np.concatenate([h0[:2].ravel(), h0[2, :2]])
    result = least_squares(residual, start, loss=loss, f_scale=f_scale, max_nfev=max_nfev)
    h_n = np.vstack([result.x[:6].reshape(2, 3), [*result.x[6:8], 1.0]])
    h = np.linalg.inv(td) @ h_n @ ts
    return h / np.linalg.norm(h)

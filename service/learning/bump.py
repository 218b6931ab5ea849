"""The bump as one image transform: fitted to the positions the other cameras give.

Why (rather than refitting the moved camera's maps): a bump rotates the camera by a few degrees
and the room stays put, so the camera's new image is its former image through one homography
``H`` (:mod:`models.mom.image_transform`); the former maps, encoder and decoder still hold once
its boxes are mapped back. Refitting the maps from scratch fits 16 numbers per map to positions
that are, with two cameras, single views long along the other camera's line of sight: it needed
300-400 positions (~2 minutes of walking) to get within 1.2-1.3× of the pre-bump error
(``bench/results/self_healing.md``). The transform has 3 (roll and shift: a small pan or tilt
moves the image about as a shift, and a bump leaves the focal length, so no scale) or 8 (a
homography: also the perspective of a larger pan or tilt) unknowns, every position constrains
all of them through the former maps, and the repair keeps the one that does better on held-out
positions.

Fit: minimise over ``H`` the Mahalanobis distances between the moved camera's single-view
position under the former maps, its boxes mapped back by ``H``, and each reference, under the
sum of the reference's covariance (long along the other cameras' lines of sight) and the
single view's own (long along the moved camera's): each reference then constrains ``H`` only
where it is sure. A soft-L1 loss keeps a wrongly paired box from pulling the fit. The single
views' covariances depend on ``H`` a little, so the fit is repeated ``ROUNDS`` times with them
recomputed at the last solution. ``H`` is parametrised about the image centre (``Δ`` after any
transform the camera already has, so a second bump composes).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from common.errors import MomlocError
from models.geometry.floor_prior import FloorPrior
from models.mom.image_transform import boxes_to_model

ROUNDS = 2
LOSS_SCALE = 2.0  # Mahalanobis distance past which a pair counts as an outlier (soft-L1)
DOFS = (3, 8)  # roll and shift, homography


def delta(params: np.ndarray, size: np.ndarray) -> np.ndarray:
    """The image transform [3, 3] about the image centre for ``params`` (3: roll and shift, 8:
    homography; zeros: the identity)."""
    p = np.asarray(params, dtype=np.float64)
    if len(p) not in DOFS:
        raise ValueError(f"{len(p)} transform parameters: expected one of {DOFS}")
    m = np.eye(3)
    if len(p) == 3:
        c, s = np.cos(p[0]), np.sin(p[0])
        m[:2, :2] = [[c, -s], [s, c]]
        m[:2, 2] = p[1:3]
    else:
        m[:2, :2] += p[:4].reshape(2, 2)
        m[:2, 2] = p[4:6]
        m[2, :2] = p[6:8] / float(np.hypot(*size))
    centre = np.asarray(size, dtype=np.float64) / 2
    to_centre, back = np.eye(3), np.eye(3)
    to_centre[:2, 2], back[:2, 2] = -centre, centre
    return back @ m @ to_centre


def fit(
    prior: FloorPrior,
    camera: int,
    world: np.ndarray,
    cov: np.ndarray,
    box: np.ndarray,
    former: np.ndarray | None = None,
    dof: int = DOFS[0],
) -> np.ndarray:
    """``H`` [3, 3] (the model's image → camera ``camera``'s current image) that best explains
    references ``world`` [N, 2] (covariances ``cov`` [N, 2, 2]) by the camera's boxes ``box``
    [N, 4] under ``prior``'s maps (module docstring); ``former``: its transform so far."""
    if prior.cameras[camera] is None:
        raise MomlocError(f"camera {camera} has no floor map to transform")
    if len(world) < dof:
        raise MomlocError(f"{len(world)} positions for {dof} unknowns")
    size = np.asarray(prior.image_size[camera], dtype=np.float64)
    start = np.eye(3) if former is None else np.asarray(former, dtype=np.float64)
    world = np.asarray(world, dtype=np.float64)
    reference_cov = np.asarray(cov, dtype=np.float64)
    params = np.zeros(dof)
    scale = {3: np.r_[0.01, 10.0, 10.0], 8: np.r_[[0.01] * 4, 10.0, 10.0, 0.1, 0.1]}[dof]
    for _ in range(ROUNDS):
        h = delta(params, size) @ start
        _, own_cov, ok = _single_views(prior, camera, h, box)
        total = np.where(ok[:, None, None], reference_cov + own_cov, np.eye(2))
        whiten = np.linalg.cholesky(np.linalg.inv(total)).transpose(0, 2, 1)  # W = Lᵀ L
        if ok.sum() < dof:
            raise MomlocError(f"only {int(ok.sum())} boxes map onto the floor")

        def residuals(
            p: np.ndarray, whiten: np.ndarray = whiten, ok: np.ndarray = ok
        ) -> np.ndarray:
            xy, _, seen = _single_views(prior, camera, delta(p, size) @ start, box[ok])
            r = (whiten[ok] @ (np.nan_to_num(xy) - world[ok])[..., None])[..., 0]
            return np.where(seen[:, None], r, 10.0 * LOSS_SCALE).ravel()

        params = least_squares(
            residuals, params, loss="soft_l1", f_scale=LOSS_SCALE, x_scale=scale
        ).x
    return delta(params, size) @ start


def _single_views(
    prior: FloorPrior, camera: int, h: np.ndarray, box: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The camera's own positions [N, 2], covariances [N, 2, 2] and which are defined [N], from
    its boxes mapped back by ``h``."""
    boxes = np.full((len(box), prior.num_cameras, 4), np.nan)
    boxes[:, camera] = boxes_to_model(h, box)
    xy, cov = prior.predict_covariance(boxes)
    ok = np.isfinite(xy).all(axis=1) & np.isfinite(cov).all(axis=(1, 2))
    return xy, np.where(ok[:, None, None], cov, np.eye(2)), ok

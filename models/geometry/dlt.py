"""The one direct linear transform (DLT) fit: a projective map from matched points, by SVD.

One function for both maps the project fits, because they are one algorithm:

- 3×4 **camera matrix** P from 3D world points to pixels (``models.geometry.calibrated_baseline``:
  the calibrated triangulation baseline, from chessboard corners);
- 3×3 **plane homography** H from 2D points to 2D points (``models.geometry.homography``: floor
  marks ↔ pixels for the floor prior; ``models.mom.training.torch_model``: the decoder's initial
  P̄_k, floor ↔ pixel means, stored as 3×4 with a zero z column).

Each pair ``x ↔ u`` (``x`` homogeneous, n + 1 values) gives two rows of ``A p = 0`` for the
unknown matrix ``p`` (3 × (n + 1)): ``[x, 0, -u₀ x]`` and ``[0, x, -u₁ x]``; ``p`` is the right
singular vector of the smallest singular value. Both point sets are Hartley-normalised first
(centroid 0, mean distance √dim): without it the system mixes metres and hundreds of pixels and
the SVD loses digits (Hartley & Zisserman, *Multiple View Geometry*, §4.4). The result is
denormalised and scaled to unit Frobenius norm (its sign is arbitrary).

Minimal counts: 4 pairs for a homography (8 unknowns), 6 for a camera matrix (11). Points in a
degenerate configuration (collinear for H, coplanar for P) leave a second near-zero singular
value and raise :class:`~common.errors.MomlocError` naming ``what``.
"""

from __future__ import annotations

import numpy as np

from common.errors import MomlocError

MIN_PAIRS = {2: 4, 3: 6}  # source dimension -> pairs needed
DEGENERATE_RATIO = 1e-9  # second-smallest / largest singular value below this: no unique fit


def hartley_normaliser(points: np.ndarray) -> np.ndarray:
    """[d+1, d+1] similarity moving ``points`` [M, d] to centroid 0, mean distance sqrt(d)."""
    dim = points.shape[1]
    centre = points.mean(axis=0)
    scale = np.sqrt(dim) / max(float(np.linalg.norm(points - centre, axis=1).mean()), 1e-12)
    transform = np.eye(dim + 1) * scale
    transform[:dim, dim] = -scale * centre
    transform[dim, dim] = 1.0
    return transform


def homogeneous(points: np.ndarray) -> np.ndarray:
    """[..., d] → [..., d + 1] with a trailing 1."""
    return np.concatenate([points, np.ones((*points.shape[:-1], 1))], axis=-1)


def fit_dlt(src: np.ndarray, dst: np.ndarray, what: str = "DLT fit") -> np.ndarray:
    """Matrix M with ``dst ~ M · [src, 1]``: [3, 3] from 2D ``src`` [N, 2], [3, 4] from 3D
    ``src`` [N, 3]; ``dst`` [N, 2] (pixels). Unit Frobenius norm. See the module docstring."""
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    if src.ndim != 2 or src.shape[1] not in MIN_PAIRS:
        raise MomlocError(f"{what}: source points must be [N, 2] or [N, 3], got {src.shape}")
    need = MIN_PAIRS[src.shape[1]]
    if dst.shape != (len(src), 2) or len(src) < need:
        raise MomlocError(
            f"{what}: need >= {need} matched points, got {src.shape[0]} ({src.shape}/{dst.shape})"
        )
    t_src, t_dst = hartley_normaliser(src), hartley_normaliser(dst)
    x = homogeneous(src) @ t_src.T
    u = homogeneous(dst) @ t_dst.T
    zero = np.zeros_like(x)
    rows = np.concatenate(
        [
            np.concatenate([x, zero, -u[:, :1] * x], axis=1),
            np.concatenate([zero, x, -u[:, 1:2] * x], axis=1),
        ]
    )
    if len(rows) < rows.shape[1]:  # minimal pairs (4 for H): square up so vt holds the null vector
        rows = np.concatenate([rows, np.zeros((rows.shape[1] - len(rows), rows.shape[1]))])
    _, singular, vt = np.linalg.svd(rows, full_matrices=False)
    if singular[-2] < DEGENERATE_RATIO * singular[0]:
        shape = "collinear" if src.shape[1] == 2 else "coplanar or collinear"
        raise MomlocError(f"{what}: the points are degenerate ({shape}, or too few distinct)")
    fitted = np.linalg.inv(t_dst) @ vt[-1].reshape(3, src.shape[1] + 1) @ t_src
    return fitted / np.linalg.norm(fitted)

"""Plane homographies: a robust fit from noisy correspondences, mapping, and the local Jacobian.

Why a homography: every image point that lies on one world plane (the floor under a person's
feet, or the plane at a fixed height through a person's middle) is related to its floor position
by a 3×3 projective map, whatever the camera's pose and focal length. Four or more floor marks
seen by a camera fix it, with no calibration.

The fit (:func:`fit_homography`) is the project's Hartley-normalised DLT
(:func:`models.dlt.fit_dlt`: both point sets moved to centroid 0, mean distance sqrt 2, so pixels
and metres get equal say in the SVD) followed by a robust
refinement of the *transfer* error in the destination plane (metres on the floor when fitting
pixel → floor) with ``scipy.optimize.least_squares`` and a soft-L1 loss: DLT minimises an
algebraic error that over-weights far points, and a few bad boxes (occlusion, a second person
behind) must not pull the map. The refinement keeps ``H[2, 2] = 1`` *in normalised coordinates*,
which is safe because there the centroid of the data maps to a finite point.

:func:`fit_plane_to_image` adds what labelled floor marks need (many noisy rows per mark: fit
the per-mark medians, in the direction where the noise is), :func:`degenerate_reason` says when
the marks cannot fix a map at all. Numpy + scipy only: used at serving time too.
"""

from __future__ import annotations

import math
from itertools import combinations
from typing import Literal

import numpy as np
from scipy.optimize import least_squares

from models.dlt import fit_dlt, hartley_normaliser
from models.errors import MomlocError


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


def fit_plane_to_image(
    world: np.ndarray, pixels: np.ndarray, height: np.ndarray, distinct_m: float = 0.05
) -> np.ndarray:
    """Floor → image H [3, 3] from rows ``world`` [M, 2] ↔ ``pixels`` [M, 2], box ``height`` [M].

    Rows at the same floor position (a mark) are first reduced to their median pixel: the
    sway of the person and the detector noise are then averaged away *before* the fit, where a
    per-row regression of floor on noisy pixels would shrink the map towards the marks
    (errors-in-variables), centimetres off outside them. Marks whose median pixel is off the
    plane map the others agree on (another object's box) are left out (:func:`consensus`).
    The fit runs floor → pixel with residuals in box heights (detector noise grows with box
    size), weighted by the square root of the rows behind each point. Dense data (every row its
    own position) is fitted row by row the same way. Invert the result for the pixel → floor
    map.
    """
    keys = np.round(world / distinct_m).astype(np.int64)
    _, group, count = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    order = np.argsort(group.ravel(), kind="stable")
    pieces = np.split(order, np.cumsum(count)[:-1])

    def medians(values: np.ndarray) -> np.ndarray:
        return np.stack([np.median(values[rows], axis=0) for rows in pieces])

    pos, pix, hgt = medians(world), medians(pixels), medians(height)
    if len(pos) < len(world):
        inliers = consensus(pos, pix, hgt, np.sqrt(count))
        pos, pix, hgt, count = pos[inliers], pix[inliers], hgt[inliers], count[inliers]
    ref = float(np.median(hgt))
    return fit_homography(pos, pix, weights=np.sqrt(count) * ref / hgt, scale=0.1 * ref)


CONSENSUS_MIN = 6  # marks needed before any is left out (4 fix a homography, 2 check it)
CONSENSUS_TOL = 1.0  # box heights: a mark's median pixel this far off the map is another object
CONSENSUS_SUBSETS = 500
CONSENSUS_MAX = 64  # more positions: dense data (a walk), fitted row by row, no marks to judge


def consensus(pos: np.ndarray, pix: np.ndarray, hgt: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Which marks [M] agree with one plane map: the best-supported consensus of 4-mark fits.

    Why: a camera's median pixel at a mark is another object's when that camera hardly saw the
    person there and a lasting false box (furniture) was most of its boxes; the still-person rule
    of the recording cannot tell the two apart (:mod:`service.setup.keep_rule`), geometry can:
    the person's marks all lie on one plane map, the false box's mark does not. Each 4-mark
    subset's exact homography scores the ``weight`` (sqrt of the rows) of the marks within
    ``CONSENSUS_TOL`` box heights of it (ties: the smaller weighted error); then every mark is
    judged again against the robust fit to that consensus, and the marks within tolerance kept
    (a map through 4 noisy marks alone left true marks out: 3 x 3 x 6 s, seed 7, walk error
    1.47 m, 1.01 m with no consensus, 0.24 m with this second look). Measured 2026-12-02 on
    3 x 3 x 20 s recordings of the synthetic room with the ``nanodet`` profile, 3-epoch models,
    4 check marks off the grid: median error 1.65 m -> 0.18 m (seed 3) and 4.90 m -> 0.15 m
    (seed 5); ``ideal`` profile unchanged (0.07 m). Tolerance 0.5 box heights was worse (1.04 /
    0.39 m: occluded boxes shrink and move the median more than that), 0.75-1.0 alike, 1.5 and
    more rejected nothing; one body height is the round figure kept. With fewer than
    ``CONSENSUS_MIN`` marks, more than ``CONSENSUS_MAX`` positions (dense data), or a consensus
    under ``CONSENSUS_MIN - 1``, all are kept. Subsets: all up to ``CONSENSUS_SUBSETS``, else a
    fixed random sample (deterministic).
    """
    m = len(pos)
    keep = np.ones(m, bool)
    if m < CONSENSUS_MIN or m > CONSENSUS_MAX:
        return keep
    subsets: list[tuple[int, ...]]
    if math.comb(m, 4) <= CONSENSUS_SUBSETS:
        subsets = list(combinations(range(m), 4))
    else:
        rng = np.random.default_rng(0)
        subsets = [tuple(rng.choice(m, 4, replace=False)) for _ in range(CONSENSUS_SUBSETS)]
    best, best_score = keep, (-np.inf, -np.inf)
    for subset in subsets:
        try:
            h = fit_dlt(pos[list(subset)], pix[list(subset)], what="homography")
        except MomlocError:
            continue  # three of the four on a line
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            error = np.linalg.norm(apply_homography(h, pos) - pix, axis=1) / hgt
        inliers = np.isfinite(error) & (error <= CONSENSUS_TOL)
        score = (float(weight[inliers].sum()), -float((weight * error)[inliers].sum()))
        if score > best_score:  # most support; among equals the closest fit
            best, best_score = inliers, score
    if best.sum() < CONSENSUS_MIN - 1:
        return keep
    # judge every mark again against the map fitted to the whole consensus (a 4-mark map is
    # noisy): only marks off that map are left out
    ref = float(np.median(hgt[best]))
    h = fit_homography(
        pos[best], pix[best], weights=weight[best] * ref / hgt[best], scale=0.1 * ref
    )
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        error = np.linalg.norm(apply_homography(h, pos) - pix, axis=1) / hgt
    refined = np.isfinite(error) & (error <= CONSENSUS_TOL)
    return refined if refined.sum() >= CONSENSUS_MIN - 1 else keep


def degenerate_reason(
    world: np.ndarray, distinct_m: float = 0.05, collinear: float = 0.05
) -> str | None:
    """Why these floor positions [M, 2] cannot fix a homography, or None when they can.

    Positions closer than ``distinct_m`` count as one; a set whose minor/major spread ratio is
    under ``collinear`` counts as a line. A homography needs 4 positions with no 3 on a line:
    checked as "not all on a line, nor all but one" (leave-one-out, up to 64 positions).
    """
    distinct = np.unique(np.round(world / distinct_m), axis=0) * distinct_m
    if len(distinct) < 4:
        return f"{len(distinct)} distinct floor positions (need 4)"

    def flat(points: np.ndarray) -> bool:
        sing = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
        return sing[0] == 0 or sing[1] < collinear * sing[0]

    if flat(distinct):
        return "floor positions on one line"
    if len(distinct) <= 64 and any(flat(np.delete(distinct, i, 0)) for i in range(len(distinct))):
        return "all floor positions but one on a line"
    return None

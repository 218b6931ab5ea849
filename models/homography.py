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

import itertools
import math
from typing import Literal

import numpy as np
from scipy.optimize import least_squares

from models.dlt import fit_dlt, hartley_normaliser
from models.errors import MomlocError

# Consensus over marks (:func:`consensus`): a point farther than this many box heights from the
# map is not the person at that mark. The person sways on the mark and a per-mark median of a
# detector's edges is off by a few percent of the box height; boxes that are not the person are
# off by far more (0.7-5 box heights in the measurement quoted there).
CONSENSUS_TOLERANCE = 0.15
# Repeated boxes (:func:`repeated_boxes`): one camera's box at marks this far apart on the floor,
# within these tolerances, is a static false positive. A person a metre farther from a camera
# 10 m away changes box height by 10 %, so 3 % does not catch real people; a static false box's
# per-mark medians agree to about 1 %.
REPEAT_APART_M = 1.0
REPEAT_PIXEL_TOLERANCE = 0.05
REPEAT_HEIGHT_TOLERANCE = 0.03
MAX_MARKS = 256  # more floor positions than this: dense data, no repeated-box check
CONSENSUS_SUBSETS = 2000  # try every 4-point subset up to this many (16 marks: 1,820)
# Otherwise (dense data, rows ~ points) this many random ones: with 85 % inliers (dense nanodet
# rows at 0.15 box heights) a sample is clean with p = 0.52, so 300 miss a clean one with
# p < 1e-90.
CONSENSUS_SAMPLES = 300


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
    (errors-in-variables), centimetres off outside them. The fit runs floor → pixel with
    residuals in box heights (detector noise grows with box size), weighted by the square root
    of the rows behind each point. Dense data (every row its own position) is fitted row by row
    the same way. Invert the result for the pixel → floor map.
    """
    keys = np.round(world / distinct_m).astype(np.int64)
    _, group, count = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    order = np.argsort(group.ravel(), kind="stable")
    pieces = np.split(order, np.cumsum(count)[:-1])

    def medians(values: np.ndarray) -> np.ndarray:
        return np.stack([np.median(values[rows], axis=0) for rows in pieces])

    pos, pix, hgt = medians(world), medians(pixels), medians(height)
    # Dense rows (each its own position) are not marks: the pairwise check would cost O(M²).
    keep = ~repeated_boxes(pos, pix, hgt) if len(pos) <= MAX_MARKS else np.ones(len(pos), bool)
    if keep.sum() < 4:
        raise MomlocError(
            f"homography: degenerate boxes ({int((~keep).sum())} of {len(keep)} floor positions "
            "show one box, repeated: a static false positive, not the person)"
        )
    keep[keep] = consensus(pos[keep], pix[keep], hgt[keep])
    pos, pix, hgt, count = pos[keep], pix[keep], hgt[keep], count[keep]
    ref = float(np.median(hgt))
    return fit_homography(pos, pix, weights=np.sqrt(count) * ref / hgt, scale=0.1 * ref)


def repeated_boxes(
    world: np.ndarray,
    pixels: np.ndarray,
    height: np.ndarray,
    apart_m: float = REPEAT_APART_M,
    pixel_tolerance: float = REPEAT_PIXEL_TOLERANCE,
    height_tolerance: float = REPEAT_HEIGHT_TOLERANCE,
) -> np.ndarray:
    """[M] bool: points whose box (pixel and height) another point more than ``apart_m`` away
    on the floor repeats, within ``pixel_tolerance`` box heights and ``height_tolerance``
    relative height.

    A person at two floor points a metre apart never gives one camera the same box (the floor
    → image map is one-to-one, and the box height changes with the distance), but a static false
    positive (a coat on a chair) does, at every mark where it is the only box because the person
    is out of that camera's view. Measured on the synthetic 3x3 set-up (nanodet profile,
    6 s per mark): camera 1 reported one such box at two far marks (medians 3 px and 0 px apart
    in height 177 px), and with a cut box and a wrong one beside them, four wrong points of nine
    fitted a near-degenerate map that outvoted the five right ones in :func:`consensus`. All
    copies are dropped: which one (if any) was the person cannot be told.
    """
    floor = np.linalg.norm(world[:, None] - world[None], axis=-1)
    scale = np.minimum(height[:, None], height[None])
    same_place = np.linalg.norm(pixels[:, None] - pixels[None], axis=-1) <= pixel_tolerance * scale
    same_size = np.abs(np.log(height[:, None] / height[None])) <= height_tolerance
    return np.any((floor > apart_m) & same_place & same_size, axis=1)


def consensus(
    world: np.ndarray,
    pixels: np.ndarray,
    height: np.ndarray,
    tolerance: float = CONSENSUS_TOLERANCE,
    subsets: int = CONSENSUS_SUBSETS,
    samples: int = CONSENSUS_SAMPLES,
) -> np.ndarray:
    """[M] bool: the points consistent with the floor → image map most of them agree on.

    RANSAC over the (per-mark) points ``world`` [M, 2] ↔ ``pixels`` [M, 2]: every 4-point
    homography (all subsets when there are at most ``subsets``, else ``samples`` random ones
    with a fixed seed) is scored by how many points it maps within ``tolerance`` box heights
    (``height`` [M]) of their pixel; the largest set wins (ties: the smaller summed error).
    With fewer than 6 points there is no redundancy to judge by, and all are kept.

    Why: at a mark, the box a camera reports may not be the person's. A static false positive
    (a coat on a chair) is the only box while the person is out of that camera's view, and a
    person whose feet are below the image gives a box whose noisy bottom edge ends a few pixels
    inside the border, so it looks whole. Measured on the synthetic 3x3 set-up with the nanodet
    profile: 3 of 18 mark × camera medians were such boxes (100-530 px from the person's foot
    pixel); the soft-L1 refinement alone cannot reject them with 9 points for 8 unknowns, and the
    floor prior ended 2.5 m (median) off over the room.
    """
    m = len(world)
    everything = np.ones(m, dtype=bool)
    if m < 6:
        return everything
    if math.comb(m, 4) <= subsets:
        tried = np.array(list(itertools.combinations(range(m), 4)))
    else:
        rng = np.random.default_rng(0)
        tried = np.array([rng.choice(m, 4, replace=False) for _ in range(samples)])
    best, best_key = everything, (0, np.inf)
    for subset in tried:
        try:
            h = fit_dlt(world[subset], pixels[subset], what="homography")
        except MomlocError:  # three of the four on a line
            continue
        with np.errstate(all="ignore"):
            error = np.linalg.norm(apply_homography(h, world) - pixels, axis=1) / height
        inliers = np.nan_to_num(error, nan=np.inf) <= tolerance
        key = (int(inliers.sum()), float(error[inliers].sum()))
        if key[0] > best_key[0] or (key[0] == best_key[0] and key[1] < best_key[1]):
            best, best_key = inliers, key
    return best if best_key[0] >= 4 else everything


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

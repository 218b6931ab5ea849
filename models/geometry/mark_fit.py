"""A floor → image map from floor marks: per-mark medians, marks whose boxes are not the
person, and the robust fit.

What labelled floor marks need beyond plane geometry (:mod:`models.geometry.homography`): many noisy
rows per mark (fit the per-mark medians, in the direction where the noise is,
:func:`fit_plane_to_image`), marks where a camera's box is not the person standing there
(:func:`repeated_boxes`, :func:`consensus`), and when marks cannot fix a map at all
(:func:`degenerate_reason`). Numpy only at serving time; used by :mod:`models.geometry.floor_prior`.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from common.errors import MomlocError
from models.geometry.dlt import fit_dlt
from models.geometry.homography import apply_homography, fit_homography, homography_jacobian

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
# People's box heights agree with the map's scale within this (log units, ~25 %): a box that is
# not the person, or a wrong map, breaks the agreement. The detector's scale error (5 %) and
# pose (bending, turning) stay well inside it.
CONSENSUS_HEIGHT_SPREAD = 0.25
CONSENSUS_SUBSETS = 2000  # try every 4-point subset up to this many (16 marks: 1,820)
# Otherwise (dense data, rows ~ points) this many random ones: with 85 % inliers (dense nanodet
# rows at 0.15 box heights) a sample is clean with p = 0.52, so 300 miss a clean one with
# p < 1e-90.
CONSENSUS_SAMPLES = 300


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


def lateral_scale(jacobian: np.ndarray) -> np.ndarray:
    """[...] pixels per metre across the line of sight: the larger singular value of each
    [..., 2, 2] floor → image Jacobian (the other one is foreshortened with depth)."""
    frobenius = (jacobian**2).sum(axis=(-2, -1))
    det = np.linalg.det(np.nan_to_num(jacobian))
    return np.sqrt((frobenius + np.sqrt(np.maximum(frobenius**2 - 4 * det**2, 0.0))) / 2)


def consensus(
    world: np.ndarray,
    pixels: np.ndarray,
    height: np.ndarray,
    tolerance: float = CONSENSUS_TOLERANCE,
    subsets: int = CONSENSUS_SUBSETS,
    samples: int = CONSENSUS_SAMPLES,
    height_spread: float = CONSENSUS_HEIGHT_SPREAD,
) -> np.ndarray:
    """[M] bool: the points consistent with the floor → image map most of them agree on.

    RANSAC over the (per-mark) points ``world`` [M, 2] ↔ ``pixels`` [M, 2]: every 4-point
    homography (all subsets when there are at most ``subsets``, else ``samples`` random ones
    with a fixed seed) is scored by how many points it maps within ``tolerance`` box heights
    (``height`` [M]) of their pixel *and* whose box height agrees with the map's scale there:
    the person who walked the marks has one height, so box height divided by the map's
    pixels per metre across the line of sight (:func:`lateral_scale`) is about the same at every
    mark (within ``height_spread``, in log units, of the set's median). The largest set wins
    (ties: the smaller summed error). With fewer than 6 points there is no redundancy to judge
    by, and all are kept.

    Why: at a mark, the box a camera reports may not be the person's. A static false positive
    (a coat on a chair) is the only box while the person is out of that camera's view, and a
    person whose feet are below the image gives a box whose noisy bottom edge ends a few pixels
    inside the border, so it looks whole. The soft-L1 refinement alone cannot reject such boxes
    with 9 points for 8 unknowns, and with two wrong points a 4-point map ties the right one on
    the pixels alone: the height check breaks the tie. Figures:
    ``bench/results/design_measurements.md`` (mark selection).
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
    # Looser when nothing agrees: a short recording's medians are noisier, and a 4-point map
    # of noisy points has a distorted scale for the height check.
    for tol, spread in ((tolerance, height_spread), (2 * tolerance, height_spread),
                        (2 * tolerance, np.inf)):  # fmt: skip
        best, count = _best_subset(world, pixels, height, tried, tol, spread)
        if count >= 4:
            break
    else:
        return everything
    # Judge every mark again against the map fitted to the consensus (marks only: dense rows are
    # many, and the minimal sets' consensus is kept as it is there).
    for _ in range(2 if m <= MAX_MARKS else 0):
        try:
            h = fit_homography(world[best], pixels[best], weights=1.0 / height[best])
        except MomlocError:
            break
        again, _ = _agreeing(h, world, pixels, height, tol, spread)
        if again.sum() < 4 or (again == best).all():
            break
        best = again
    return best


def _agreeing(
    h: np.ndarray,
    world: np.ndarray,
    pixels: np.ndarray,
    height: np.ndarray,
    tolerance: float,
    height_spread: float,
) -> tuple[np.ndarray, np.ndarray]:
    """[M] bool: the points map ``h`` puts within ``tolerance`` box heights of their pixel and
    whose box height agrees with its scale (see :func:`consensus`); and [M] those transfer
    errors in box heights."""
    with np.errstate(all="ignore"):
        error = np.linalg.norm(apply_homography(h, world) - pixels, axis=1) / height
        size = np.log(height / lateral_scale(homography_jacobian(h, world)))
    inliers = np.nan_to_num(error, nan=np.inf) <= tolerance
    if inliers.sum() >= 4:  # one person: box height / (pixels per metre) is their height
        off = np.abs(size - np.median(size[inliers]))
        inliers &= np.nan_to_num(off, nan=np.inf) <= height_spread
    return inliers, error


def _best_subset(
    world: np.ndarray,
    pixels: np.ndarray,
    height: np.ndarray,
    tried: np.ndarray,
    tolerance: float,
    height_spread: float,
) -> tuple[np.ndarray, int]:
    """The largest agreeing set over the 4-point maps of ``tried`` (ties: smaller error)."""
    best, best_key = np.ones(len(world), dtype=bool), (0, np.inf)
    for subset in tried:
        try:
            h = fit_dlt(world[subset], pixels[subset], what="homography")
        except MomlocError:  # three of the four on a line
            continue
        inliers, error = _agreeing(h, world, pixels, height, tolerance, height_spread)
        key = (int(inliers.sum()), float(error[inliers].sum()))
        if key[0] > best_key[0] or (key[0] == best_key[0] and key[1] < best_key[1]):
            best, best_key = inliers, key
    return best, best_key[0]


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

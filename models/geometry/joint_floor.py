"""The cameras' floor maps fitted jointly: floor marks plus moments where several cameras saw one
person, every camera agreeing on where that person stood (a bundle adjustment on the floor plane).

Why: self-labels (:mod:`service.learning.labels`) pair every camera's box with the position the
serving model fused from them. Refitting each camera's floor map on those positions one camera
at a time (what :meth:`models.geometry.floor_prior.FloorPrior.fit` does with any rows) pulls each
map only part of the way towards the others: the position is the model in service's compromise
between its own cameras, errors included, so the refitted model stays near the one that made the
labels. Here the positions are unknowns too. Each camera's floor → image homography of the foot
point and each moment's floor position are fitted together so that every camera's box bottom is
where its map puts the shared position, and every camera's map puts each floor mark where that
camera saw the person standing on it. The marks fix the floor frame (where the origin is, the
metre, the axes); the moments fix the maps between and beyond the marks, through the cameras'
agreement alone. Measured on the simulated 2-camera room (4 marks, 3 people walking, and 8 other
4-mark recordings; ``bench/results/joint_floor.md``): the refitted geometry went from the
one-camera refit's error to about that of a geometry fitted on a dense recording's true
positions, and was never worse than the one-camera refit.

Model: residuals in box heights in each camera's image (the detector's edge noise grows with the
box; an image residual is isotropic where a floor one is long along the line of sight), a
soft-L1 loss with its knee at ``LOSS_SCALE`` box heights (a wrong pairing that slipped through the
self-label rules, a box of two people), each mark's per-camera median pixel weighted by the square
root of its rows (as :func:`models.geometry.mark_fit.fit_plane_to_image`). Only the foot point:
the centre map holds for one person's height, and the moments are of people of all heights.
Boxes cut at the left, right or bottom border leave the foot point out. A sparse trust-region
solve (``scipy.optimize.least_squares``, each residual touches one camera's 8 parameters and one
moment's 2) over at most ``MAX_MOMENTS`` moments (the maps have 8 unknowns each; thousands of
moments fix them, and the solve stays a few seconds in the daemon's background thread), started
from a one-camera fit on the marks and those moments only (a full store holds ~100 000 labels);
every moment's position is then triangulated with the fitted maps.

Rejected: iterating the one-camera refit (refit, fuse each label again with the refitted
geometry, refit): it improved one set-up and made two others worse
(``bench/results/self_learning_policy.md``): each round fuses with the floor error model's
weights, long along each line of sight, and refits each map to its own fused positions, where
the joint solve weighs every view's image residual alike and moves maps and positions at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix

from common.errors import MomlocError
from models.geometry.calibrated_baseline import truncated
from models.geometry.floor_prior import DISTINCT_M, FloorPrior, image_points
from models.geometry.homography import apply_homography, homography_jacobian

LOSS_SCALE = 0.05  # box heights: about the detector's bottom-edge noise (robust knee)
MAX_MOMENTS = 3000
MAX_EVALUATIONS = 400
TRIANGULATE_STEPS = 8


@dataclass(frozen=True)
class JointFloor:
    """The jointly fitted foot maps and every moment's position on them."""

    world: np.ndarray  # [N, 2] metres; the given position where fewer than 2 usable views
    placed: np.ndarray  # [N] bool: triangulated with the fitted maps (2 or more usable views)
    maps: tuple[np.ndarray | None, ...]  # per camera floor → image homography of the foot point
    moments: int  # moments in the joint solve
    moved_m: float  # median distance the positions moved from the given ones

    def describe(self) -> str:
        return (
            f"floor maps fitted jointly on {self.moments} moments; positions moved "
            f"{self.moved_m:.3f} m (median)"
        )


def _foot(boxes: np.ndarray, size: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Foot pixels [N, K, 2], box heights [N, K], usable [N, K] (seen, foot not cut)."""
    seen = np.isfinite(boxes).all(axis=-1)
    safe = np.where(seen[..., None], boxes, 0.0)
    usable: np.ndarray = seen & ~truncated(safe, size, "lrb")
    return image_points(safe)["foot"], np.maximum(safe[..., 3] - safe[..., 1], 1.0), usable


def _mark_points(
    world: np.ndarray, pixels: np.ndarray, height: np.ndarray, usable: np.ndarray
) -> list[tuple[int, np.ndarray, np.ndarray, float, float]]:
    """Per (mark, camera): (camera, mark xy, median foot pixel, median height, sqrt rows)."""
    keys = np.round(world / DISTINCT_M).astype(np.int64)
    _, mark = np.unique(keys, axis=0, return_inverse=True)
    mark = mark.ravel()
    out = []
    for m in np.unique(mark):
        for k in range(usable.shape[1]):
            rows = (mark == m) & usable[:, k]
            if rows.any():
                out.append((
                    k, np.median(world[rows], axis=0), np.median(pixels[rows, k], axis=0),
                    float(np.median(height[rows, k])), float(np.sqrt(rows.sum())),
                ))  # fmt: skip
    return out


def triangulate(
    maps: tuple[np.ndarray | None, ...],
    pixels: np.ndarray,
    height: np.ndarray,
    usable: np.ndarray,
    start: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """[N, 2] floor positions minimising the views' squared foot-pixel error (box heights),
    Gauss-Newton from ``start``, and [N] which of them it placed; ``start`` (not placed) where
    fewer than two usable views, or where the solve came out non-finite."""
    z = np.asarray(start, np.float64).copy()
    cams = [k for k, h in enumerate(maps) if h is not None]
    two = usable[:, cams].sum(axis=1) >= 2
    for _ in range(TRIANGULATE_STEPS):
        normal = np.zeros((len(z), 2, 2))
        gradient = np.zeros((len(z), 2))
        for k in cams:
            h = maps[k]
            assert h is not None
            w = usable[:, k][:, None] / height[:, k][:, None]
            r = np.nan_to_num((apply_homography(h, z) - pixels[:, k]) * w)
            j = np.nan_to_num(homography_jacobian(h, z) * w[..., None])
            normal += j.transpose(0, 2, 1) @ j
            gradient += (j.transpose(0, 2, 1) @ r[..., None])[..., 0]
        safe = np.where(two[:, None, None], normal, np.eye(2))
        step = np.linalg.solve(safe + np.eye(2) * 1e-12, gradient[..., None])[..., 0]
        z = np.where(two[:, None], z - step, z)
    placed = two & np.isfinite(z).all(axis=1)
    return np.where(placed[:, None], z, start), placed


def fit_joint_floor(
    marks_world: np.ndarray,
    marks_boxes: np.ndarray,
    world: np.ndarray,
    boxes: np.ndarray,
    image_size: np.ndarray,
    *,
    max_moments: int = MAX_MOMENTS,
    seed: int = 0,
) -> JointFloor:
    """Fit the foot maps jointly on floor marks (``marks_world`` [M, 2], ``marks_boxes``
    [M, K, 4]) and moments (``boxes`` [N, K, 4], NaN = unseen, ``world`` [N, 2] their positions
    so far: the starting point); see the module docstring. :class:`MomlocError` when no map
    can be started or the solve fails."""
    size = np.asarray(image_size, np.float64)
    marks_world = np.asarray(marks_world, np.float64)[:, :2]
    world = np.asarray(world, np.float64)[:, :2]
    marks_boxes, boxes = np.asarray(marks_boxes, np.float64), np.asarray(boxes, np.float64)
    pixels, height, usable = _foot(boxes, size)
    chosen = np.flatnonzero(usable.sum(axis=1) >= 2)
    if len(chosen) > max_moments:
        chosen = np.sort(np.random.default_rng(seed).choice(chosen, max_moments, replace=False))
    start = FloorPrior.fit_arrays(
        np.concatenate([marks_world, world[chosen]]),
        np.concatenate([marks_boxes, boxes[chosen]]), size, points=("foot",),
    )  # fmt: skip
    cams = [k for k, c in enumerate(start.cameras) if c is not None]
    first = {k: np.linalg.inv(start.cameras[k].maps[0]) for k in cams}  # type: ignore[union-attr]
    unfitted = [k for k in range(boxes.shape[1]) if k not in first]
    usable[:, unfitted] = False
    chosen = chosen[usable[chosen].sum(axis=1) >= 2]
    m_pix, m_height, m_usable = _foot(marks_boxes, size)
    m_usable[:, unfitted] = False
    marks = _mark_points(marks_world, m_pix, m_height, m_usable)
    if not len(chosen) or not marks:
        raise MomlocError("joint floor fit: no moment seen by two cameras, or no mark")
    maps = _solve(first, marks, world[chosen], pixels[chosen], height[chosen], usable[chosen])
    fitted = tuple(maps.get(k) for k in range(boxes.shape[1]))
    refined, placed = triangulate(fitted, pixels, height, usable, world)
    moved = float(np.median(np.linalg.norm(refined - world, axis=1)))
    return JointFloor(refined, placed, fitted, len(chosen), moved)


def _solve(
    first: dict[int, np.ndarray],
    marks: list[tuple[int, np.ndarray, np.ndarray, float, float]],
    world: np.ndarray,
    pixels: np.ndarray,
    height: np.ndarray,
    usable: np.ndarray,
) -> dict[int, np.ndarray]:
    """The sparse least-squares solve: 8 parameters per camera (a multiplicative update of its
    starting map in a floor frame normalised to unit spread, so the 8 are of one scale), 2 per
    moment (metres)."""
    cams = sorted(first)
    slot = {k: i for i, k in enumerate(cams)}
    mark_cam = np.array([slot[m[0]] for m in marks])
    mark_xy = np.array([m[1] for m in marks])
    mark_px = np.array([m[2] for m in marks])
    mark_w = np.array([m[4] / m[3] for m in marks])[:, None]
    moment, camera = np.nonzero(usable)
    view_cam = np.array([slot[int(k)] for k in camera], dtype=np.int64)
    view_px = pixels[moment, camera]
    view_w = (1.0 / height[moment, camera])[:, None]
    n_cam, n_moment = len(cams), len(world)
    # Update H_k = H0_k @ (I + D_k) with D in a floor frame normalised to unit spread.
    centre = world.mean(axis=0)
    spread = max(float(np.linalg.norm(world - centre, axis=1).mean()), 1e-6)
    norm = np.array([[1 / spread, 0, -centre[0] / spread], [0, 1 / spread, -centre[1] / spread],
                     [0, 0, 1]])  # fmt: skip
    back = np.linalg.inv(norm)

    def maps_of(p: np.ndarray) -> list[np.ndarray]:
        out = []
        for i, k in enumerate(cams):
            d = np.append(p[8 * i : 8 * i + 8], 0.0).reshape(3, 3)
            out.append(first[k] @ back @ (np.eye(3) + d) @ norm)
        return out

    def residual(p: np.ndarray) -> np.ndarray:
        hs = maps_of(p)
        z = p[8 * n_cam :].reshape(n_moment, 2)
        out_marks = np.empty((len(marks), 2))
        out_views = np.empty((len(view_cam), 2))
        for i, h in enumerate(hs):
            s = mark_cam == i
            out_marks[s] = (apply_homography(h, mark_xy[s]) - mark_px[s]) * mark_w[s]
            v = view_cam == i
            out_views[v] = (apply_homography(h, z[moment[v]]) - view_px[v]) * view_w[v]
        return np.nan_to_num(np.concatenate([out_marks, out_views]).ravel(), nan=1e3)

    sparsity = _sparsity(mark_cam, view_cam, moment, n_cam, n_moment)
    start = np.concatenate([np.zeros(8 * n_cam), world.ravel()])
    try:
        result = least_squares(
            residual, start, jac_sparsity=sparsity, loss="soft_l1", f_scale=LOSS_SCALE,
            x_scale="jac", max_nfev=MAX_EVALUATIONS,
        )  # fmt: skip
    except (ValueError, np.linalg.LinAlgError) as error:
        raise MomlocError(f"joint floor fit: {error}") from None
    if not np.isfinite(result.x).all():
        raise MomlocError("joint floor fit: the solve diverged")
    return dict(zip(cams, maps_of(result.x), strict=True))


def _sparsity(
    mark_cam: np.ndarray, view_cam: np.ndarray, moment: np.ndarray, n_cam: int, n_moment: int
) -> coo_matrix:
    """Which parameters each residual depends on: its camera's 8, and a view's moment's 2."""
    cam = np.concatenate([mark_cam, view_cam])
    row = np.repeat(np.arange(2 * len(cam)), 8)
    col = (8 * np.repeat(cam, 2)[:, None] + np.arange(8)).ravel()
    first_view = 2 * len(mark_cam)
    view_row = np.repeat(np.arange(first_view, 2 * len(cam)), 2)
    view_col = (8 * n_cam + 2 * np.repeat(moment, 2)[:, None] + np.arange(2)).ravel()
    rows, cols = np.concatenate([row, view_row]), np.concatenate([col, view_col])
    shape = (2 * len(cam), 8 * n_cam + 2 * n_moment)
    return coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=shape)

"""The paper's calibrated classical baseline ("PnP + Triangulation"), from boxes and 3×4 matrices.

This is what a careful engineer would build *with* calibration, to measure what MoM's
calibration-free promise costs or gains. Two ways to get a floor position from person boxes:

``triangulate``
    Linear (DLT) triangulation of the box centre across the cameras that see the person (SVD of
    the stacked ``u p3 - p1``, ``v p3 - p2`` rows, Hartley & Zisserman §12.2), then the floor point
    is the triangulated point's x, y (the body centre stands above the floor point). Rows seen by
    one camera only fall back to ``foot``.
``foot``
    Back-project each view's foot point (bottom-centre of the box) onto the floor plane z = 0
    through the plane homography ``[p1 p2 p4]`` of P, and average over the views. Works with a
    single view.

Views whose box touches the image border are truncated and are left out while enough others
remain: for ``triangulate`` a box cut at any border (its centre moves), while two others remain;
for ``foot`` a box cut at the bottom (its foot point rises), while one other remains. On the
simulated presets this helps; also dropping side-cut boxes from ``foot`` measured worse.

Realistic calibration error (:func:`chessboard_calibration`) re-estimates each P by DLT from
noisy 2D-3D correspondences, as a user with a printed chessboard and a tape measure would get
them; the defaults in :class:`ChessboardSetup` are documented there. Nothing here imports torch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from common.errors import MomlocError
from models.geometry.dlt import fit_dlt, homogeneous

METHODS = ("triangulate", "foot")
_BORDER_PX = 2.0


def project(projection: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Pinhole projection of [..., 3] world points to [..., 2] pixels."""
    h = homogeneous(np.asarray(points, dtype=np.float64)) @ projection.T
    return h[..., :2] / h[..., 2:3]


def depth_sign(projection: np.ndarray, points: np.ndarray) -> np.ndarray:
    """+1 where a point is in front of the camera, for P of either overall sign."""
    w = homogeneous(np.asarray(points, dtype=np.float64)) @ projection[2]
    return np.sign(w * np.linalg.det(projection[:, :3]))


def box_points(boxes: np.ndarray) -> dict[str, np.ndarray]:
    """Centre and foot (bottom-centre) of each box, [..., 2] pixels each."""
    u = 0.5 * (boxes[..., 0] + boxes[..., 2])
    return {
        "centre": np.stack([u, 0.5 * (boxes[..., 1] + boxes[..., 3])], axis=-1),
        "foot": np.stack([u, boxes[..., 3]], axis=-1),
    }


def triangulate(projections: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """DLT triangulation of [N, K, 2] pixels (NaN = unseen) → [N, 3]; NaN with < 2 views."""
    projections = np.asarray(projections, dtype=np.float64)
    pixels = np.asarray(pixels, dtype=np.float64)
    seen = np.isfinite(pixels).all(axis=-1)  # [N, K]
    p = projections / np.linalg.norm(projections, axis=(1, 2), keepdims=True)
    uv = np.where(seen[..., None], pixels, 0.0)
    rows_u = uv[..., 0:1] * p[None, :, 2] - p[None, :, 0]  # [N, K, 4]
    rows_v = uv[..., 1:2] * p[None, :, 2] - p[None, :, 1]
    a = np.concatenate([rows_u, rows_v], axis=1) * np.concatenate([seen, seen], axis=1)[..., None]
    a /= np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
    _, _, vt = np.linalg.svd(a)
    x = vt[:, -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = x[:, :3] / x[:, 3:4]
    out[seen.sum(axis=1) < 2] = np.nan
    return out


def floor_backproject(
    projections: np.ndarray, pixels: np.ndarray, height: float = 0.0
) -> np.ndarray:
    """Each view's pixel [N, K, 2] on the plane z = height → [N, K, 2] floor x, y (NaN if unseen
    or if the ray meets the plane behind the camera, e.g. a point above the horizon)."""
    projections = np.asarray(projections, dtype=np.float64)
    pixels = np.asarray(pixels, dtype=np.float64)
    out = np.full(pixels.shape, np.nan)
    for k, p in enumerate(projections):
        plane = np.stack([p[:, 0], p[:, 1], p[:, 2] * height + p[:, 3]], axis=1)
        seen = np.isfinite(pixels[:, k]).all(axis=-1)
        h = homogeneous(pixels[seen, k]) @ np.linalg.inv(plane).T
        xy = h[:, :2] / h[:, 2:3]
        point = np.concatenate([xy, np.full((len(xy), 1), height)], axis=1)
        xy[depth_sign(p, point) <= 0] = np.nan
        out[seen, k] = xy
    return out


def truncated(
    boxes: np.ndarray,
    image_size: np.ndarray | None,
    edges: str = "ltrb",
    margin: float | np.ndarray = _BORDER_PX,
) -> np.ndarray:
    """Bool [N, K]: the box touches one of the image ``edges`` (l, t, r, b) within ``margin``
    pixels (2 px, or one margin per box [N, K])."""
    if image_size is None:
        return np.zeros(boxes.shape[:2], dtype=bool)
    size = np.asarray(image_size, dtype=np.float64)  # [K, 2]
    near = np.zeros(boxes.shape[:2], dtype=bool)
    with np.errstate(invalid="ignore"):
        if "l" in edges:
            near |= boxes[..., 0] <= margin
        if "t" in edges:
            near |= boxes[..., 1] <= margin
        if "r" in edges:
            near |= boxes[..., 2] >= size[:, 0] - margin
        if "b" in edges:
            near |= boxes[..., 3] >= size[:, 1] - margin
    return near


def _prefer_whole(seen: np.ndarray, cut: np.ndarray, minimum: int) -> np.ndarray:
    """Views to use: untruncated ones where at least ``minimum`` remain, else every seen view."""
    whole = seen & ~cut
    enough = whole.sum(axis=1) >= minimum
    return np.where(enough[:, None], whole, seen)


def localize(
    boxes: np.ndarray,
    projections: np.ndarray,
    *,
    method: str = "triangulate",
    image_size: np.ndarray | None = None,
) -> np.ndarray:
    """Floor positions [N, 2] from boxes [N, K, 4] (NaN = unseen) and matrices [K, 3, 4].

    NaN rows where nothing usable is seen. ``image_size`` [K, 2] enables the truncation rule.
    """
    if method not in METHODS:
        raise MomlocError(f"baseline method '{method}': expected one of {', '.join(METHODS)}")
    boxes = np.asarray(boxes, dtype=np.float64)
    projections = np.asarray(projections, dtype=np.float64)
    if boxes.ndim != 3 or projections.shape != (boxes.shape[1], 3, 4):
        raise MomlocError(
            f"baseline: boxes {boxes.shape} and matrices {projections.shape} do not match"
        )
    seen = np.isfinite(boxes).all(axis=-1)
    points = box_points(boxes)

    use = _prefer_whole(seen, truncated(boxes, image_size, "b"), 1)
    feet = floor_backproject(projections, np.where(use[..., None], points["foot"], np.nan))
    valid = np.isfinite(feet).all(axis=-1)
    count = valid.sum(axis=1)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(valid[..., None], feet, 0.0).sum(axis=1) / count
    if method == "triangulate":
        use = _prefer_whole(seen, truncated(boxes, image_size), 2)
        centre = triangulate(projections, np.where(use[..., None], points["centre"], np.nan))
        ok = np.isfinite(centre).all(axis=1)
        out[ok] = centre[ok, :2]
    return out


@dataclass(frozen=True)
class ChessboardSetup:
    """How a user calibrates one camera with a printed chessboard and a tape measure.

    Defaults: 4 board placements × 3×3 inner corners = 36 correspondences (the 20-40 a patient
    user collects), 10 cm squares (an A3 print), boards standing 0-1.5 m high where people walk,
    facing the camera within ±40° yaw and ±25° pitch; corner detection noise 1 px (std per
    coordinate); each placement measured with a tape to 5 mm (std per axis) and 1° of tilt.
    """

    placements: int = 4
    corners: tuple[int, int] = (3, 3)
    square: float = 0.10
    height: tuple[float, float] = (0.0, 1.5)
    yaw_deg: float = 40.0
    pitch_deg: float = 25.0
    pixel_noise: float = 1.0
    placement_noise: float = 0.005
    tilt_noise_deg: float = 1.0


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    axis = axis / np.linalg.norm(axis)
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


def camera_centre(projection: np.ndarray) -> np.ndarray:
    """World position of the camera: the right null vector of P."""
    c = np.linalg.svd(projection)[2][-1]
    return c[:3] / c[3]


def _board(
    setup: ChessboardSetup, centre: np.ndarray, facing: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Corner positions [M, 3] of a board centred at ``centre`` turned towards ``facing``."""
    normal = facing - centre
    normal[2] = 0.0
    normal /= np.linalg.norm(normal)
    yaw = np.radians(rng.uniform(-setup.yaw_deg, setup.yaw_deg))
    normal = _rotation(np.array([0.0, 0, 1]), yaw) @ normal
    right = np.cross([0.0, 0, 1], normal)
    right /= np.linalg.norm(right)
    pitch = np.radians(rng.uniform(-setup.pitch_deg, setup.pitch_deg))
    up = _rotation(right, pitch) @ np.array([0.0, 0, 1])
    rows, cols = setup.corners
    i, j = np.meshgrid(np.arange(rows) - (rows - 1) / 2, np.arange(cols) - (cols - 1) / 2)
    grid = setup.square * np.stack([j.ravel(), i.ravel()], axis=1)
    return centre + grid[:, :1] * right + grid[:, 1:] * up


def chessboard_calibration(
    projection: np.ndarray,
    image_size: tuple[int, int],
    floor_points: np.ndarray,
    rng: np.random.Generator,
    setup: ChessboardSetup | None = None,
    observe: Callable[[np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """Re-estimate one camera's P from a simulated chessboard session (see ChessboardSetup).

    ``floor_points`` [M, 2] are places the board may stand (where people walk in view of this
    camera); ``observe`` maps true 3D points [M, 3] to pixels [M, 2] (pass the simulator's camera
    with its lens distortion; default: the pinhole ``projection``). The user's tape-measured 3D
    positions carry the placement error; the detected corners carry the pixel noise.
    """
    setup = setup or ChessboardSetup()
    observe = observe or (lambda points: project(projection, points))
    eye = camera_centre(projection)
    width, height = image_size
    measured, seen = [], []
    for _ in range(setup.placements):
        for _attempt in range(200):
            xy = floor_points[rng.integers(len(floor_points))]
            centre = np.array([*xy[:2], rng.uniform(*setup.height)])
            true = _board(setup, centre, eye, rng)
            pix = observe(true)
            inside = (pix[:, 0] > 0) & (pix[:, 0] < width) & (pix[:, 1] > 0) & (pix[:, 1] < height)
            if inside.all() and (depth_sign(projection, true) > 0).all():
                break
        else:
            raise MomlocError("calibration: no chessboard placement is visible to the camera")
        tilt = _rotation(rng.normal(size=3), np.radians(rng.normal(0, setup.tilt_noise_deg)))
        origin = true.mean(axis=0)
        believed = (true - origin) @ tilt.T + origin + rng.normal(0, setup.placement_noise, 3)
        measured.append(believed)
        seen.append(pix + rng.normal(0, setup.pixel_noise, pix.shape))
    return fit_dlt(np.concatenate(measured), np.concatenate(seen), what="calibration")

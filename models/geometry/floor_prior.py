"""A calibration-free geometric floor prior: per-camera plane homographies from the floor marks.

Why: a learned model trained on a handful of floor marks cannot interpolate between them (an MLP
on 4 marks is ~1 m off over the room), but geometry can. A person's box bottom-centre (the *foot*
point) lies on the floor plane, so pixel → floor is a homography for each camera, fixed by the
marks alone (no chessboard, no camera pose). The box *centre* is on a plane at about half the
person's height: also a homography, less noisy (the scale error of a box leaves its centre in
place) but biased for people taller or shorter than whoever walked the marks. With a pose
detector, the middle of the confident ankles (COCO-17) is a third, less noisy floor point.

Model, per camera k and image point p in ``points`` ("foot", "centre", "ankle"; "both" = foot +
centre, the default for box-only detectors; "all" = the three):

* ``G_kp`` pixel → floor, fitted on the training rows: the rows of each mark reduced to their
  median pixel, then a robust floor → pixel homography (:mod:`models.geometry.mark_fit`), inverted.
* Error model: the residuals of the training rows, mapped back to pixels and divided by the box
  height (detector noise grows with box size), give a pixel covariance ``S_k`` per unit box
  height over all the camera's points jointly (the foot and the centre share the box's bottom
  edge, so their errors are correlated). A view's floor covariance is ``J S_k J^T h²`` with ``J``
  the homography's Jacobian at the pixel: one pixel far away is many centimetres on the floor,
  and only along the camera's line of sight. Two terms the marks cannot show are added: the
  spread of people's heights for the centre (``HEIGHT_SPREAD``) and the stride for the ankles
  (``ANKLE_STRIDE_M``, on the floor).
* Fusion: generalised least squares over every point of every view (information-weighted). Two
  cameras that each know the position well only across their line of sight combine like a
  triangulation. Unseen views (NaN boxes) carry no information; a point on a box cut by the
  image border (the foot when the bottom or a side is cut, the centre for any cut) has its
  variance multiplied by ``cut_inflation`` (default 25: a fallback, used when nothing better is
  seen), a point beyond the plane's horizon is dropped.

Degenerate data: a camera whose usable rows show fewer than 4 distinct floor positions, or
positions all on one line but one (no homography is determined), gets no prior (``None``) and is
ignored at prediction; :class:`MomlocError` only when *no* camera can be fitted.

Serving: numpy only; ``to_json``/``from_json`` round-trip through ``model.json``. Example::

    prior = FloorPrior.fit(data)                 # data: MomDataset of the marks
    xy, std = prior.predict(boxes)               # boxes [B, K, 4], NaN = unseen
    err = prior.reprojection_error(boxes, xy)    # [B, K] pixels: the decoder's job
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from common.errors import MomlocError
from common.row_memo import RowMemo
from models.data.dataset import MomDataset
from models.geometry.calibrated_baseline import box_points, truncated
from models.geometry.homography import apply_homography, homography_jacobian
from models.geometry.mark_fit import MAX_MARKS, degenerate_reason, fit_plane_to_image

POINTS = ("foot", "centre", "ankle")
SETS = {"both": ("foot", "centre"), "all": POINTS}
CUT_EDGES = {"foot": "lrb", "centre": "ltrb", "ankle": ""}  # a cut here: unfit for fitting
# At prediction a cut only spoils one pixel axis: (edges that bias u, edges that bias v).
CUT_AXES = {"foot": ("lr", "b"), "centre": ("lr", "tb"), "ankle": ("", "")}
ANKLES = (15, 16)  # COCO-17 left and right ankle
MIN_CONFIDENCE = 0.5  # keypoints below this confidence count as unseen
ANKLE_STRIDE_M = 0.1  # floor std of the ankles' middle about the point under the hips
HEIGHT_SPREAD = 0.06  # std of people's heights / mean height (adults ~ 6 %)
MIN_ROWS = 8
CUT_MARGIN = 0.05  # a mark's median box this close to the border (box heights) counts as cut
DISTINCT_M = 0.05  # positions closer than this count as one mark
COLLINEAR = 0.05  # minor/major spread ratio under which positions count as a line
MIN_NOISE = 0.002  # floor of the per-unit-height pixel std (noise-free data stays invertible)
_UNSEEN_STD = 1e6  # std multiplier that removes a measurement from the fusion
_FORMAT = "floor-prior-v1"


@dataclass(frozen=True)
class CameraPrior:
    """One camera's fitted maps (point name → pixel→floor H) and joint pixel noise [2P, 2P]."""

    points: tuple[str, ...]
    maps: tuple[np.ndarray, ...]
    signs: tuple[float, ...]  # sign of the homogeneous w of floor points in front of the camera
    noise: np.ndarray
    rows: int
    marks: int


def _robust_covariance(r: np.ndarray) -> np.ndarray:
    """Second moment [D, D] of residual rows [M, D] after dropping rows past 4 robust stds."""
    mad = 1.4826 * np.median(np.abs(r - np.median(r, axis=0)), axis=0)
    keep = (np.abs(r) <= 4 * np.maximum(mad, MIN_NOISE)).all(axis=1)
    r = r[keep] if keep.sum() >= MIN_ROWS else r
    cov = r.T @ r / len(r)
    return cov + np.eye(len(cov)) * MIN_NOISE**2


def _box_height(boxes: np.ndarray) -> np.ndarray:
    return np.maximum(boxes[..., 3] - boxes[..., 1], 1.0)


def image_points(boxes: np.ndarray, keypoints: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Foot (box bottom-centre), centre and, with COCO-17 ``keypoints`` [..., 17, 3], the ankle
    point (mean of the confident ankles, NaN if none): [..., 2] pixels each."""
    points = box_points(boxes)
    if keypoints is not None:
        ankles = np.asarray(keypoints, dtype=np.float64)[..., ANKLES, :]
        ok = (ankles[..., 2] >= MIN_CONFIDENCE) & np.isfinite(ankles[..., :2]).all(axis=-1)
        count = ok.sum(axis=-1)[..., None]
        with np.errstate(invalid="ignore", divide="ignore"):
            points["ankle"] = np.where(ok[..., None], ankles[..., :2], 0.0).sum(axis=-2) / count
    else:
        points["ankle"] = np.full(points["foot"].shape, np.nan)
    return points


def _residual(
    g: np.ndarray, pixels: np.ndarray, world: np.ndarray, boxes: np.ndarray, rows: np.ndarray
) -> np.ndarray:
    """Training pixel residuals [M, 2] of a pixel → floor map, per unit box height."""
    predicted = apply_homography(np.linalg.inv(g), world[rows])
    return (pixels[rows] - predicted) / _box_height(boxes[rows])[:, None]


def _cut_marks(
    world: np.ndarray, boxes: np.ndarray, seen: np.ndarray, size: np.ndarray, edges: str
) -> np.ndarray:
    """[N] bool: rows of a floor position whose median box ends within ``CUT_MARGIN`` box
    heights of one of the image ``edges``: the person is cut there.

    A detector's box of a person cut by the border ends a few pixels inside it in many frames
    (its edge error: the nanodet profile's bottom edge is 10 % of the box height), so the rows
    that look whole are the same cut person, and the mark's median pixel is wrong; a 2 px test of
    a single box misses it. Dense data (more than ``MAX_MARKS`` floor positions) is left to the
    per-box 2 px test: the margin cost the stream regression gate there. Figures:
    ``bench/results/design_measurements.md`` (cut marks).
    """
    keys = np.round(world / DISTINCT_M).astype(np.int64)
    _, mark = np.unique(keys, axis=0, return_inverse=True)
    mark = mark.ravel()
    marks = np.unique(mark[seen])
    if not len(marks) or mark.max() + 1 > MAX_MARKS:  # dense data: the per-box test alone
        return np.zeros(len(world), dtype=bool)
    median = np.stack([np.median(boxes[(mark == m) & seen], axis=0) for m in marks])
    margin = CUT_MARGIN * np.maximum(median[:, 3] - median[:, 1], 1.0)
    cut = truncated(median[:, None], size[None], edges, margin[:, None])[:, 0]
    return np.isin(mark, marks[cut])


def _fit_camera(
    world: np.ndarray,
    boxes: np.ndarray,
    keypoints: np.ndarray | None,
    size: np.ndarray,
    points: tuple[str, ...],
) -> tuple[CameraPrior | None, str]:
    seen = np.isfinite(boxes).all(axis=-1)
    pixels = image_points(boxes, keypoints)
    fitted, maps, signs, usable = [], [], [], []
    reasons = []
    for name in points:
        ok = seen & ~truncated(boxes[:, None], size[None], CUT_EDGES[name])[:, 0]
        whole = ok & ~_cut_marks(world, boxes, seen, size, CUT_EDGES[name])
        if (
            whole.sum() >= MIN_ROWS
            and degenerate_reason(world[whole], DISTINCT_M, COLLINEAR) is None
        ):
            ok = whole  # else the cut marks stay: without them no map at all (e.g. 2x2 marks)
        ok &= np.isfinite(pixels[name]).all(axis=-1)
        if ok.sum() < MIN_ROWS:
            reasons.append(f"{name}: {ok.sum()} uncut rows")
            continue
        why = degenerate_reason(world[ok], DISTINCT_M, COLLINEAR)
        if why:
            reasons.append(f"{name}: {why}")
            continue
        try:
            h = fit_plane_to_image(world[ok], pixels[name][ok], _box_height(boxes[ok]), DISTINCT_M)
            g = np.linalg.inv(h)
        except MomlocError as exc:  # e.g. the marks' pixels on one line (seen edge-on)
            reasons.append(f"{name}: {exc}")
            continue
        w = pixels[name][ok] @ g[2, :2] + g[2, 2]
        fitted.append(name)
        maps.append(g)
        signs.append(float(np.sign(np.median(w))))
        usable.append(ok)
    if not fitted:
        return None, "; ".join(reasons)
    both = np.logical_and.reduce(usable)
    named = list(zip(fitted, maps, usable, strict=True))
    if both.sum() >= MIN_ROWS:  # joint covariance: the points share box edges
        joint = [_residual(g, pixels[n], world, boxes, both) for n, g, _ in named]
        noise = _robust_covariance(np.concatenate(joint, axis=1))
    else:  # too few rows where every point is usable: independent points
        noise = np.zeros((2 * len(named), 2 * len(named)))
        for i, (n, g, ok) in enumerate(named):
            block = _robust_covariance(_residual(g, pixels[n], world, boxes, ok))
            noise[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = block
        both = usable[0]
    marks = len(np.unique(np.round(world[both] / DISTINCT_M), axis=0))
    prior = CameraPrior(tuple(fitted), tuple(maps), tuple(signs), noise, int(seen.sum()), marks)
    return prior, "; ".join(reasons)


@dataclass(frozen=True)
class FloorPrior:
    """Per-camera floor homographies with an error model, fused into one floor estimate."""

    cameras: tuple[CameraPrior | None, ...]
    image_size: np.ndarray  # [K, 2]
    cut_inflation: float = 25.0
    height_spread: float = HEIGHT_SPREAD
    notes: tuple[str, ...] = ()  # why a camera or a point was left out
    # Per camera, the view of each box seen lately: a view depends on its own camera's box
    # alone, and the chain asks for each box many times per frame set (common.row_memo).
    _seen: dict[int, RowMemo[tuple[np.ndarray, np.ndarray]]] = field(
        default_factory=dict, init=False, compare=False, repr=False
    )

    @property
    def num_cameras(self) -> int:
        return len(self.cameras)

    @classmethod
    def fit(
        cls,
        dataset: MomDataset,
        *,
        points: str | tuple[str, ...] = "both",
        cut_inflation: float = 25.0,
        height_spread: float = HEIGHT_SPREAD,
    ) -> FloorPrior:
        """Fit from a :class:`~models.data.dataset.MomDataset` (its ``world``, ``boxes``, sizes)."""
        return cls.fit_arrays(
            dataset.world,
            dataset.boxes,
            dataset.image_size,
            keypoints=dataset.keypoints,
            points=points,
            cut_inflation=cut_inflation,
            height_spread=height_spread,
        )

    @classmethod
    def fit_arrays(
        cls,
        world: np.ndarray,
        boxes: np.ndarray,
        image_size: np.ndarray,
        *,
        keypoints: np.ndarray | None = None,
        points: str | tuple[str, ...] = "both",
        cut_inflation: float = 25.0,
        height_spread: float = HEIGHT_SPREAD,
    ) -> FloorPrior:
        """Fit from ``world`` [N, 2|3] metres, ``boxes`` [N, K, 4] pixels, ``image_size`` [K, 2].

        ``points``: "foot", "centre", "both" (default: measured best from 6 marks on, see
        ``bench/results/floor_prior_study.md``) or a tuple of names from :data:`POINTS`.
        """
        names = SETS.get(points, (points,)) if isinstance(points, str) else points
        if not names or any(name not in POINTS for name in names):
            raise MomlocError(
                f"floor prior points {points!r}: expected foot, centre, ankle, both or all"
            )
        if "ankle" in names and keypoints is None:
            raise MomlocError("floor prior: the ankle point needs keypoints in the data set")
        world = np.asarray(world, dtype=np.float64)[:, :2]
        boxes = np.asarray(boxes, dtype=np.float64)
        size = np.asarray(image_size, dtype=np.float64)
        if boxes.ndim != 3 or boxes.shape[0] != len(world) or size.shape != (boxes.shape[1], 2):
            raise MomlocError(
                f"floor prior: boxes {boxes.shape}, world {world.shape} and image sizes "
                f"{size.shape} do not match"
            )
        cameras, notes = [], []
        for k in range(boxes.shape[1]):
            kp = None if keypoints is None else np.asarray(keypoints)[:, k]
            prior, why = _fit_camera(world, boxes[:, k], kp, size[k], tuple(names))
            cameras.append(prior)
            if why:
                notes.append(f"camera {k}: {why}")
        if all(c is None for c in cameras):
            raise MomlocError(
                "floor prior: no camera sees 4 floor marks off one line (" + "; ".join(notes) + ")"
            )
        return cls(tuple(cameras), size, float(cut_inflation), float(height_spread), tuple(notes))

    def views(
        self, boxes: np.ndarray, keypoints: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per-camera floor estimates [B, K, 2] and information matrices [B, K, 2, 2].

        Zero information (and a zero estimate) where a camera has no prior or sees nothing
        usable. The lead model can take these as features; :meth:`predict` fuses them.
        """
        boxes = np.asarray(boxes, dtype=np.float64)
        if boxes.ndim != 3 or boxes.shape[1:] != (self.num_cameras, 4):
            raise MomlocError(
                f"floor prior: boxes {boxes.shape} are not [B, {self.num_cameras}, 4]"
            )
        n = boxes.shape[0]
        est = np.zeros((n, self.num_cameras, 2))
        info = np.zeros((n, self.num_cameras, 2, 2))
        for k, cam in enumerate(self.cameras):
            if cam is not None:
                kp = None if keypoints is None else np.asarray(keypoints, np.float64)[:, k]
                est[:, k], info[:, k] = self._remembered_view(k, cam, boxes[:, k], kp)
        return est, info

    def _remembered_view(
        self, k: int, cam: CameraPrior, boxes: np.ndarray, keypoints: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_camera_view` of camera ``k``'s rows, each distinct row computed once."""
        if len(boxes) == 0:
            return np.zeros((0, 2)), np.zeros((0, 2, 2))
        keys = [
            row.tobytes() if keypoints is None else row.tobytes() + keypoints[i].tobytes()
            for i, row in enumerate(boxes)
        ]

        def compute(rows: list[int]) -> list[tuple[np.ndarray, np.ndarray]]:
            kp = None if keypoints is None else keypoints[rows]
            est, info = self._camera_view(cam, boxes[rows], kp, self.image_size[k])
            return list(zip(est, info, strict=True))

        memo = self._seen.get(k)
        if memo is None:
            memo = self._seen[k] = RowMemo()
        views = memo.rows(keys, compute)
        return np.stack([v[0] for v in views]), np.stack([v[1] for v in views])

    def _camera_view(
        self, cam: CameraPrior, boxes: np.ndarray, keypoints: np.ndarray | None, size: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        seen = np.isfinite(boxes).all(axis=-1)
        safe = np.where(seen[:, None], boxes, [0.0, 0.0, size[0], size[1]])
        pixels = image_points(safe, keypoints)
        height = _box_height(safe)
        zs, jacobians, scales = [], [], []
        for name, g, sign in zip(cam.points, cam.maps, cam.signs, strict=True):
            pix = np.where(np.isfinite(pixels[name]), pixels[name], 0.5 * size)
            xy = apply_homography(g, pix)
            w = pix @ g[2, :2] + g[2, 2]
            valid = seen & (np.sign(w) == sign) & np.isfinite(pixels[name]).all(axis=1)
            for edges in CUT_AXES[name]:
                cut = truncated(safe[:, None], size[None], edges)[:, 0]
                scale = np.where(cut, np.sqrt(self.cut_inflation), 1.0)
                scales.append(np.where(valid, scale, _UNSEEN_STD) * height)
            zs.append(np.where(valid[:, None], xy, 0.0))
            jac = homography_jacobian(g, pix)
            jacobians.append(np.where(valid[:, None, None], jac, np.eye(2)))
        p = len(cam.points)
        jac = np.zeros((len(boxes), 2 * p, 2 * p))
        for i, j in enumerate(jacobians):
            jac[:, 2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = j
        d = np.stack(scales, axis=1)  # [B, 2P]: per point u, v
        pixel_cov = (cam.noise + self._height_cov(cam))[None] * d[:, :, None] * d[:, None, :]
        floor_cov = jac @ pixel_cov @ jac.transpose(0, 2, 1)
        if "ankle" in cam.points:  # mid-stride the ankles' middle is off the hip's floor point
            i = 2 * cam.points.index("ankle")
            floor_cov[:, i : i + 2, i : i + 2] += np.eye(2) * ANKLE_STRIDE_M**2
        weight = np.linalg.inv(floor_cov)  # [B, 2P, 2P]
        a = np.tile(np.eye(2), (p, 1))  # [2P, 2]: every point measures the same floor x, y
        info = a.T @ weight @ a
        eta = a.T @ weight @ np.concatenate(zs, axis=1)[:, :, None]
        info = np.where(seen[:, None, None], info, 0.0)
        est = np.linalg.solve(info + np.eye(2) * 1e-12, eta)[..., 0]
        return np.where(seen[:, None], est, 0.0), info

    def _height_cov(self, cam: CameraPrior) -> np.ndarray:
        """Pixel covariance per unit box height from people's heights (centre point v only).

        The centre homography holds for the height of whoever walked the marks: a person
        ``HEIGHT_SPREAD`` taller has a box that much taller and a centre half that much higher,
        which the training residuals (one person) cannot show.
        """
        cov = np.zeros_like(cam.noise)
        for i, name in enumerate(cam.points):
            if name == "centre":
                cov[2 * i + 1, 2 * i + 1] = (0.5 * self.height_spread) ** 2
        return cov

    def predict(
        self, boxes: np.ndarray, keypoints: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Fused floor positions [B, 2] (metres) and their std [B] (metres, RMS over x and y).

        NaN position and infinite std for rows that no fitted camera sees.
        """
        xy, cov = self.predict_covariance(boxes, keypoints)
        std = np.sqrt(np.clip(np.trace(cov, axis1=1, axis2=2) / 2, 0.0, None))
        return xy, np.where(np.isfinite(xy).all(axis=1), std, np.inf)

    def predict_covariance(
        self, boxes: np.ndarray, keypoints: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Fused floor positions [B, 2] and their GLS covariance [B, 2, 2] (m²): long along a
        lone camera's line of sight, short across it (the tracker's measurement noise). NaN
        for rows no fitted camera sees."""
        est, info = self.views(boxes, keypoints)
        total = info.sum(axis=1)
        eta = (info @ est[..., None]).sum(axis=1)
        has = np.trace(total, axis1=1, axis2=2) > 1e-9
        safe = np.where(has[:, None, None], total, np.eye(2))
        xy = np.linalg.solve(safe, eta)[..., 0]
        cov = np.linalg.inv(safe)
        return np.where(has[:, None], xy, np.nan), np.where(has[:, None, None], cov, np.nan)

    def reproject(self, world: np.ndarray, point: str = "foot") -> np.ndarray:
        """Floor positions [B, 2] → the expected ``point`` pixel [B, K, 2] in every camera.

        The inverse maps play the MoM decoder's part (association scoring, the camera-moved
        alert): NaN for a camera without a fitted map for that point.
        """
        world = np.asarray(world, dtype=np.float64)[:, :2]
        out = np.full((len(world), self.num_cameras, 2), np.nan)
        for k, cam in enumerate(self.cameras):
            if cam is not None and point in cam.points:
                g = cam.maps[cam.points.index(point)]
                out[:, k] = apply_homography(np.linalg.inv(g), world)
        return out

    def reprojection_error(
        self,
        boxes: np.ndarray,
        world: np.ndarray,
        point: str = "foot",
        keypoints: np.ndarray | None = None,
    ) -> np.ndarray:
        """Pixel distance [B, K] between each box's ``point`` and :meth:`reproject` (NaN unseen)."""
        observed = image_points(np.asarray(boxes, dtype=np.float64), keypoints)[point]
        return np.linalg.norm(observed - self.reproject(world, point), axis=-1)

    def to_json(self) -> dict:
        """Plain-JSON form for ``model.json`` (lists and numbers only)."""
        return {
            "format": _FORMAT,
            "image_size": self.image_size.tolist(),
            "cut_inflation": self.cut_inflation,
            "height_spread": self.height_spread,
            "notes": list(self.notes),
            "cameras": [
                None
                if c is None
                else {
                    "points": list(c.points),
                    "maps": [g.tolist() for g in c.maps],
                    "signs": list(c.signs),
                    "noise": c.noise.tolist(),
                    "rows": c.rows,
                    "marks": c.marks,
                }
                for c in self.cameras
            ],
        }

    @classmethod
    def from_json(cls, data: dict) -> FloorPrior:
        """Inverse of :meth:`to_json`; a malformed entry raises :class:`MomlocError`."""
        try:
            if data["format"] != _FORMAT:
                raise MomlocError(f"floor prior: format {data['format']!r} is not {_FORMAT}")
            cameras = tuple(
                None
                if c is None
                else CameraPrior(
                    tuple(c["points"]),
                    tuple(np.asarray(g, dtype=np.float64).reshape(3, 3) for g in c["maps"]),
                    tuple(float(s) for s in c["signs"]),
                    np.asarray(c["noise"], dtype=np.float64),
                    int(c["rows"]),
                    int(c["marks"]),
                )
                for c in data["cameras"]
            )
            size = np.asarray(data["image_size"], dtype=np.float64).reshape(len(cameras), 2)
            return cls(
                cameras,
                size,
                float(data["cut_inflation"]),
                float(data["height_spread"]),
                tuple(data.get("notes", ())),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise MomlocError(f"floor prior: malformed model.json entry ({exc})") from exc

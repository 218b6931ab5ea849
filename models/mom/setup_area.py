"""Where a model was set up: the floor its labels cover and what each camera saw there.

Why: a learned map answers *inside* its training area whatever it is shown. On the real CMC room
(issue 23) the encoder of a model trained on people walking in a 4.3 × 3.4 m area put 67–94 % of
the boxes of people standing *beyond* that area (in the rest of the room, in view of the same
cameras) inside it, and those boxes were the bulk of the served false positives. The floor-mark
geometry (:mod:`models.geometry.floor_prior`, one plane map per camera) extrapolates honestly: a box
beyond the marks lands beyond them. So a model carries its set-up area and the runtime

1. localizes a row by the floor geometry whenever that geometry puts it outside the area (the
   encoder's answer there is an extrapolation it was never trained for), and
2. tells the chain which positions are inside, so the daemon can drop the others or serve them
   flagged (setting ``tracking.outside_area``).

The area, fitted from the training rows:

- **floor**: the convex hull of the labelled positions, widened by ``margin_m`` (a person a step
  beyond the outermost mark is still being set up for; the map's extent and zones are drawn
  inside it). Rejected: the labels' bounding box (a diagonal walk or an L-shaped room would claim
  floor nobody stood on) and a concave hull (its shape depends on a radius chosen per room, and
  marks are sparse by design).
- **per camera**: the convex hull of the box bottom centres it saw in training, widened by
  ``image_margin`` box heights, and how tall a person standing at each foot pixel looks (log
  height quadratic in the foot pixel, fitted on the training boxes; with few rows the range of
  heights widened by ``height_factor``). A row whose every seen box lies outside its camera's
  region, or is far taller or shorter than a person there (a fragment of an occluded body, two
  people in one box), shows no person the model was set up for: the check that still works for
  a camera without a floor map.

Serving: numpy only; ``to_json``/``from_json`` round-trip through ``model.json`` (key
``setup_area``); models written before it have no area and everything counts as inside.

Example::

    area = SetupArea.fit(world, boxes, image_size)
    inside = area.contains(xy)              # [B] bool, positions in metres
    seen_there = area.boxes_in_region(boxes)  # [B] bool
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from common.errors import MomlocError

DEFAULT_MARGIN_M = 0.5  # floor beyond the outermost label that still counts as set up
IMAGE_MARGIN = 0.5  # box heights beyond the training foot points that still count as seen
HEIGHT_FACTOR = 1.5  # box heights this much beyond the training range still count as seen
HEIGHT_SIGMAS = 4.0  # a box this many robust stds off the height expected at its foot is odd
MIN_LOG_TOLERANCE = float(np.log(1.3))  # ... and never closer than 30 % to it
MIN_HEIGHT_ROWS = 24  # fewer training boxes: the height range alone
FOOT_ROW_STEPS = 8  # CameraRegion.foot_row: the expected height varies slowly with the foot row
_FORMAT = "setup-area-v1"


def _hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull vertices [V, 2] of ``points`` [N, 2] (monotone chain).

    Fewer than 3 distinct or collinear points give the degenerate hull (1 or 2 vertices): the
    distance below then measures from a point or a segment, which is what a single mark or a
    line of marks covers."""
    pts = np.unique(np.round(np.asarray(points, np.float64), 6), axis=0)
    if len(pts) < 3:
        return pts

    def half(seq: np.ndarray) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for p in seq:
            while len(out) >= 2 and _cross(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def distance_outside(hull: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance [N] from ``points`` [N, 2] to the convex polygon ``hull`` (0 inside); NaN for
    a non-finite point."""
    points = np.asarray(points, np.float64).reshape(-1, 2)
    if len(hull) == 0:
        return np.full(len(points), np.inf)
    # distance to the nearest edge (or vertex) of the boundary
    starts = hull
    ends = np.roll(hull, -1, axis=0) if len(hull) > 1 else hull
    seg = ends - starts  # [V, 2]
    length2 = np.maximum((seg**2).sum(axis=1), 1e-18)
    rel = points[:, None, :] - starts[None]  # [N, V, 2]
    along = np.clip((rel * seg[None]).sum(axis=2) / length2[None], 0.0, 1.0)
    nearest = starts[None] + along[..., None] * seg[None]
    edge_distance = np.linalg.norm(points[:, None, :] - nearest, axis=2).min(axis=1)
    if len(hull) >= 3:
        crosses = seg[None, :, 0] * rel[..., 1] - seg[None, :, 1] * rel[..., 0]  # [N, V]
        inside = (crosses >= 0).all(axis=1)
        edge_distance = np.where(inside, 0.0, edge_distance)
    return np.where(np.isfinite(points).all(axis=1), edge_distance, np.nan)


def _foot_and_height(boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bottom centre [..., 2] and height [...] of boxes [..., 4]."""
    foot = np.stack([0.5 * (boxes[..., 0] + boxes[..., 2]), boxes[..., 3]], axis=-1)
    return foot, boxes[..., 3] - boxes[..., 1]


def _height_features(foot: np.ndarray) -> np.ndarray:
    """Quadratic terms [N, 6] of the foot pixel (in thousands of pixels, for conditioning)."""
    u, v = foot[:, 0] / 1000.0, foot[:, 1] / 1000.0
    return np.stack([np.ones_like(u), v, u, v * v, u * v, u * u], axis=1)


def _fit_height(foot: np.ndarray, height: np.ndarray) -> tuple[np.ndarray, float] | None:
    """log box height as a quadratic function of the foot pixel, and the residuals' robust std
    (1.4826 MAD): how tall a person standing there looks to this camera."""
    ok = height > 1.0
    if ok.sum() < MIN_HEIGHT_ROWS:
        return None
    x, y = _height_features(foot[ok]), np.log(height[ok])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    residual = y - x @ coef
    spread = 1.4826 * float(np.median(np.abs(residual - np.median(residual))))
    return coef, spread


@dataclass(frozen=True)
class CameraRegion:
    """Where one camera's training boxes stood in its image, and how tall they were: overall
    and, with enough rows, as expected at each foot pixel (a box much shorter than a person
    standing there is a fragment of an occluded body or a false box; much taller, two people
    in one box)."""

    foot_hull: np.ndarray  # [V, 2] pixels, counter-clockwise
    height_range: tuple[float, float]  # pixels, as seen in training
    height_model: np.ndarray | None = None  # [6] log-height coefficients (_height_features)
    height_spread: float = 0.0  # robust std of the log-height residuals

    def expected_height(self, foot: np.ndarray) -> np.ndarray | None:
        """[N] pixels: how tall a person standing at the foot pixels [N, 2] looks to this
        camera; None without a fitted height model (too few training rows)."""
        if self.height_model is None:
            return None
        return np.exp(_height_features(np.asarray(foot, np.float64)) @ self.height_model)

    def foot_row(
        self, u: np.ndarray, row: np.ndarray, share: float, start: np.ndarray
    ) -> np.ndarray | None:
        """[N] image rows of the feet of people standing at columns ``u`` [N] when the rows
        ``row`` [N] lie ``share`` of their standing height above their feet (a box centre: 0.5;
        a seated head's top: its share of a standing height): the fixed point of ``foot = row +
        share * expected_height(u, foot)``, iterated from ``start`` [N]; None without a fitted
        height model. One solver for every caller that places a standing body from part of it
        (the posture's standing boxes, the tracker's floor pixels), so they agree."""
        u = np.asarray(u, np.float64)
        row = np.asarray(row, np.float64)
        foot = np.array(start, dtype=np.float64, copy=True)
        for _ in range(FOOT_ROW_STEPS):
            height = self.expected_height(np.stack([u, foot], 1))
            if height is None:
                return None
            foot = row + share * height
        return foot

    def plausible_height(self, foot: np.ndarray, height: np.ndarray, factor: float) -> np.ndarray:
        """[N] bool: the heights fit what this camera saw at those foot pixels."""
        if self.height_model is None:
            low, high = self.height_range
            return (height >= low / factor) & (height <= high * factor)
        expected = _height_features(foot) @ self.height_model
        tolerance = max(HEIGHT_SIGMAS * self.height_spread, MIN_LOG_TOLERANCE)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.abs(np.log(np.maximum(height, 1e-6)) - expected) <= tolerance


@dataclass(frozen=True)
class SetupArea:
    """The floor a model was set up on and each camera's training region (module docstring)."""

    floor: np.ndarray  # [V, 2] metres, counter-clockwise convex hull of the labels
    margin_m: float
    cameras: tuple[CameraRegion | None, ...]
    image_margin: float = IMAGE_MARGIN
    height_factor: float = HEIGHT_FACTOR

    @classmethod
    def fit(
        cls,
        world: np.ndarray,
        boxes: np.ndarray,
        *,
        margin_m: float = DEFAULT_MARGIN_M,
    ) -> SetupArea:
        """From training positions ``world`` [N, 2+] (metres) and boxes [N, K, 4] (NaN unseen)."""
        xy = np.asarray(world, np.float64)[:, :2]
        xy = xy[np.isfinite(xy).all(axis=1)]
        if not len(xy):
            raise MomlocError("set-up area: no finite training position")
        boxes = np.asarray(boxes, np.float64)
        regions: list[CameraRegion | None] = []
        for k in range(boxes.shape[1]):
            b = boxes[:, k]
            b = b[np.isfinite(b).all(axis=1)]
            if not len(b):
                regions.append(None)
                continue
            foot, height = _foot_and_height(b)
            model = _fit_height(foot, height)
            regions.append(
                CameraRegion(
                    _hull(foot),
                    (float(height.min()), float(height.max())),
                    None if model is None else model[0],
                    0.0 if model is None else model[1],
                )
            )
        return cls(_hull(xy), float(margin_m), tuple(regions))

    @property
    def num_cameras(self) -> int:
        return len(self.cameras)

    def contains(self, world: np.ndarray) -> np.ndarray:
        """[B] bool: the floor position [B, 2] is within ``margin_m`` of the labelled floor.
        A non-finite position counts as inside (nothing says it is elsewhere)."""
        distance = distance_outside(self.floor, world)
        return ~(distance > self.margin_m + 1e-9)

    def boxes_in_region(self, boxes: np.ndarray) -> np.ndarray:
        """[B] bool: some seen box [B, K, 4] lies where its camera saw training boxes (foot
        point within ``image_margin`` box heights of the training foot points) and is as tall
        as a person standing there (:meth:`CameraRegion.plausible_height`). A row with no seen
        box, or seen only by cameras without a region, counts as in the region."""
        boxes = np.asarray(boxes, np.float64)
        if boxes.ndim != 3 or boxes.shape[1] != self.num_cameras:
            raise MomlocError(
                f"set-up area: boxes {boxes.shape} are not [B, {self.num_cameras}, 4]"
            )
        judged = np.zeros(len(boxes), dtype=bool)
        somewhere = np.zeros(len(boxes), dtype=bool)
        for k, region in enumerate(self.cameras):
            seen = np.isfinite(boxes[:, k]).all(axis=1)
            if region is None or not seen.any():
                continue
            foot, height = _foot_and_height(np.where(seen[:, None], boxes[:, k], 0.0))
            near = distance_outside(region.foot_hull, foot) <= self.image_margin * height
            sized = region.plausible_height(foot, height, self.height_factor)
            judged |= seen
            somewhere |= seen & near & sized
        return somewhere | ~judged

    def to_json(self) -> dict:
        """Plain-JSON form for ``model.json``."""
        return {
            "format": _FORMAT,
            "floor": np.round(self.floor, 4).tolist(),
            "margin_m": self.margin_m,
            "image_margin": self.image_margin,
            "height_factor": self.height_factor,
            "cameras": [
                None
                if c is None
                else {
                    "foot_hull": np.round(c.foot_hull, 2).tolist(),
                    "height_range": list(c.height_range),
                    "height_model": None if c.height_model is None else c.height_model.tolist(),
                    "height_spread": c.height_spread,
                }
                for c in self.cameras
            ],
        }

    @classmethod
    def from_json(cls, data: dict) -> SetupArea:
        """Inverse of :meth:`to_json`; a malformed entry raises :class:`MomlocError`."""
        try:
            if data["format"] != _FORMAT:
                raise MomlocError(f"setup_area: format {data['format']!r} is not {_FORMAT}")
            cameras = tuple(
                None
                if c is None
                else CameraRegion(
                    np.asarray(c["foot_hull"], np.float64).reshape(-1, 2),
                    (float(c["height_range"][0]), float(c["height_range"][1])),
                    None
                    if c.get("height_model") is None
                    else np.asarray(c["height_model"], np.float64).reshape(6),
                    float(c.get("height_spread", 0.0)),
                )
                for c in data["cameras"]
            )
            return cls(
                np.asarray(data["floor"], np.float64).reshape(-1, 2),
                float(data["margin_m"]),
                cameras,
                float(data["image_margin"]),
                float(data["height_factor"]),
            )
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise MomlocError(f"setup_area: malformed model.json entry ({exc})") from exc

"""Rendered camera frames: the furnished room of ``models.simulate.room`` with people painted in.

A frame is a copy of the camera's cached background with the people painted far to near (by
mid-hip depth, so nearer people cover farther ones). Each body part is the convex hull of circles
around the projected skeleton points (``skeleton.body_points``: the COCO-17 joints the walking
cycle animates plus auxiliary points), each circle's radius scaled by ``focal · size / depth``,
so sizes follow the pinhole perspective point by point and the painted person fills the true box
the simulator reports (the box is the union of the ``skeleton.RADII`` spheres; the drawn radii
below are a little slimmer where those spheres are bulky, never larger).

What the figures have:

- **proportions** on the COCO-17 skeleton the simulator animates: the shirt ends at the hip
  joints (it used to reach mid-thigh, which made legs look short), shoulders slope below the
  chin, a skin neck, slimmer arms;
- **clothing**: per person shirt, trousers (or shorts), sleeves, an open jacket, shoes, skin and
  hair colours and hair style (short, long, bald), from muted real-world palettes;
- **shading**: a directional light from the room's lamp (or the sun outdoors), projected into
  the image per person; every part is three nested hulls (shadow side, mid tone, lit side)
  offset toward the light, far-side limbs darker, a soft outline and a floor shadow.

Recall of the shipped detectors on these figures by person height, and what was tried on the
people it misses: ``bench/results/render_recall.md`` (``bench/detector/render_recall.py``; the
previous renderer in ``render_recall_before.md``). Cost: the background once per camera, then a
few CPU-ms per frame and person, Python overhead per part dominating (inner bands are drawn
without anti-aliasing): ``bench/results/demo_cost.md``.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import cv2
import numpy as np

from models.simulate.camera import NEAR, PinholeCamera, project_points
from models.simulate.furniture import Occluders
from models.simulate.room import Decor, Furniture, render_background, room_decor
from models.simulate.skeleton import HEAD, MID_HIP, NUM_POINTS, RADII, P

__all__ = ["Look", "Renderer", "appearance", "draw_people", "render_background"]

_SHIRTS = [(40, 40, 170), (170, 90, 40), (60, 130, 60), (50, 150, 200), (130, 60, 130),
           (225, 225, 225), (60, 60, 60), (120, 100, 70), (110, 60, 150), (40, 90, 170),
           (160, 160, 90), (90, 70, 50), (150, 120, 110), (35, 35, 40), (170, 180, 190),
           (70, 50, 120)]  # fmt: skip
_TROUSERS = [(110, 60, 30), (40, 40, 40), (90, 90, 90), (120, 75, 45), (55, 50, 45),
             (100, 140, 160), (60, 80, 100), (25, 25, 30)]  # fmt: skip
_SKIN = [(170, 200, 240), (150, 180, 230), (120, 155, 210), (90, 125, 180), (60, 85, 125)]
_HAIR = [(20, 20, 25), (30, 45, 70), (60, 100, 150), (140, 140, 150), (40, 30, 30),
         (80, 150, 200)]  # fmt: skip
_SHOES = [(25, 25, 25), (235, 235, 235), (30, 50, 90), (80, 80, 80)]


@dataclass(frozen=True)
class Look:
    """One person's clothes (BGR float colours) and styles."""

    shirt: np.ndarray
    jacket: np.ndarray | None  # open jacket over the shirt (sleeves and torso sides)
    trousers: np.ndarray
    skin: np.ndarray
    hair: np.ndarray
    shoes: np.ndarray
    long_sleeves: bool
    shorts: bool
    hair_style: str  # "short", "long" or "bald"

    def colour(self, part: str) -> np.ndarray:
        outer = self.jacket if self.jacket is not None else self.shirt
        return {
            "torso": outer,
            "upper_arm": outer,
            "forearm": outer if self.long_sleeves or self.jacket is not None else self.skin,
            "thigh": self.trousers,
            "shin": self.skin if self.shorts else self.trousers,
            "pelvis": self.trousers,
            "shoe": self.shoes,
            "skin": self.skin,
            "front": self.shirt,
        }[part]

    @functools.cached_property
    def shades(self) -> dict[tuple[str, bool], Shade]:
        """Every part's paint colours, near-side and far-side (darker): computed once per person,
        since per-band colour arithmetic in Python was a third of a frame's drawing cost."""
        return {
            (part, far): Shade.of(self.colour(part) * (0.8 if far else 1.0))
            for part in _PART_NAMES
            for far in (False, True)
        }


@dataclass(frozen=True)
class Shade:
    """The colours a part is painted with: one per nested band, the single tone of a part too
    small for bands, and its outline (BGR lists, as OpenCV takes them)."""

    bands: tuple[list[float], ...]
    flat: list[float]
    outline: list[float]

    @classmethod
    def of(cls, colour: np.ndarray) -> Shade:
        def tone(gain: float, add: float) -> list[float]:
            return np.minimum(colour * gain + add, 255.0).tolist()

        return cls(
            bands=tuple(tone(gain, add) for _, _, gain, add in _BANDS),
            flat=tone(0.9, 0.0),
            outline=(colour * 0.5).tolist(),
        )


def appearance(rng: np.random.Generator, people: int) -> list[Look]:
    """Clothes, skin and hair of each person (deterministic for a generator state)."""

    def pick(table: list, scale: tuple[float, float] = (0.85, 1.1)) -> np.ndarray:
        colour = np.array(table[rng.integers(len(table))], float) * rng.uniform(*scale)
        return np.clip(colour, 0, 255)

    looks = []
    for _ in range(people):
        shirt, trousers, skin = pick(_SHIRTS), pick(_TROUSERS), pick(_SKIN, (0.95, 1.05))
        hair, shoes = pick(_HAIR), pick(_SHOES)
        jacket = pick(_SHIRTS) if rng.random() < 0.3 else None
        looks.append(Look(
            shirt=shirt, jacket=jacket, trousers=trousers, skin=skin, hair=hair, shoes=shoes,
            long_sleeves=bool(rng.random() < 0.55), shorts=bool(rng.random() < 0.12),
            hair_style=str(rng.choice(["short", "long", "bald"], p=[0.6, 0.3, 0.1])),
        ))  # fmt: skip
    return looks


# Extra points derived from the skeleton (index NUM_POINTS + i), as (base point, offset in units
# of height along (forward, left, up) of the body): a lowered shoulder line for the torso
# outline, the waist above the hip joints, the back of the head for long hair, a shirt front.
_EXTRA = (
    ("left_shoulder", (0.0, -0.01, -0.018)), ("right_shoulder", (0.0, 0.01, -0.018)),
    ("left_hip", (0.0, -0.005, 0.055)), ("right_hip", (0.0, 0.005, 0.055)),
    ("head", (-0.03, 0.0, -0.06)), ("chest", (0.07, 0.0, 0.04)), ("abdomen", (0.07, 0.0, -0.07)),
)  # fmt: skip
X = {name: NUM_POINTS + i for i, name in enumerate(
    ("l_shoulder_line", "r_shoulder_line", "l_waist", "r_waist", "hair_back", "front_top",
     "front_bottom"))}  # fmt: skip
# Drawn radius (fraction of height) of every point: skeleton.RADII, slimmer arms, and the extras.
_DRAW = RADII.copy()
for _name, _r in (("left_shoulder", 0.036), ("right_shoulder", 0.036), ("left_elbow", 0.029),
                  ("right_elbow", 0.029), ("left_wrist", 0.023), ("right_wrist", 0.023),
                  ("neck", 0.03)):  # fmt: skip
    _DRAW[P[_name]] = _r
DRAW_RADII = np.concatenate([_DRAW, [0.04, 0.04, 0.06, 0.06, 0.05, 0.018, 0.018]])

# (layer, points, part, side): layer 0 legs, 1 torso and arms (the neck and head follow, see
# _head). Within a layer parts are painted far to near by their mean depth.
_SHAPES: list[tuple[int, tuple[int, ...], str, str]] = []
for _s in ("left", "right"):
    _SHAPES += [
        (0, (P[f"{_s}_hip"], P[f"{_s}_knee"]), "thigh", _s),
        (0, (P[f"{_s}_knee"], P[f"{_s}_ankle"]), "shin", _s),
        (0, (P[f"{_s}_ankle"], P[f"{_s}_toe"], P[f"{_s}_heel"]), "shoe", _s),
        (1, (P[f"{_s}_shoulder"], P[f"{_s}_elbow"]), "upper_arm", _s),
        (1, (P[f"{_s}_elbow"], P[f"{_s}_wrist"]), "forearm", _s),
        (1, (P[f"{_s}_wrist"], P[f"{_s}_hand"]), "skin", _s),
    ]
_SHAPES += [
    (0, (P["left_hip"], P["right_hip"], P["mid_hip"]), "pelvis", ""),
    (1, (X["l_shoulder_line"], X["r_shoulder_line"], P["chest"], P["abdomen"], X["l_waist"],
         X["r_waist"]), "torso", ""),
]  # fmt: skip
_PART_NAMES = sorted({part for _, _, part, _ in _SHAPES} | {"front"})
_PART_LAYER = np.array([layer for layer, *_ in _SHAPES])
_PART_SIDED = np.array([bool(side) for *_, side in _SHAPES])
_PART_IDX = np.array([list(idx) + [idx[0]] * (6 - len(idx)) for _, idx, _, _ in _SHAPES])
_PART_MASK = np.array([[i < len(idx) for i in range(6)] for _, idx, _, _ in _SHAPES])
_CIRCLE = np.stack([np.cos(np.linspace(0, 2 * np.pi, 12, endpoint=False)),
                    np.sin(np.linspace(0, 2 * np.pi, 12, endpoint=False))], 1)  # fmt: skip
# Nested hulls of a part: (offset toward the light, radius, brightness, added), in units of r.
_BANDS = ((0.0, 1.0, 0.7, 0.0), (0.22, 0.76, 1.0, 0.0), (0.45, 0.4, 1.16, 10.0))
_SHAPE_POINTS = [list(idx) for _, idx, _, _ in _SHAPES]
_FRONT = [X["front_top"], X["front_bottom"]]


def with_extra_points(points: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """Body points [P, M, 3] followed by the renderer's derived points [P, len(_EXTRA), 3]."""
    forward = points[:, P["nose"], :2] - points[:, HEAD, :2]
    forward /= np.maximum(np.linalg.norm(forward, axis=1, keepdims=True), 1e-9)
    left = np.stack([-forward[:, 1], forward[:, 0]], 1)
    extra = np.empty((len(points), len(_EXTRA), 3))
    for i, (base, (f, lt, up)) in enumerate(_EXTRA):
        h = heights[:, None]
        extra[:, i, :2] = points[:, P[base], :2] + (f * forward + lt * left) * h
        extra[:, i, 2] = points[:, P[base], 2] + up * heights
    return np.concatenate([points, extra], 1)


def light_direction(pixels: np.ndarray, anchor: np.ndarray, light: np.ndarray,
                    camera: PinholeCamera) -> np.ndarray:  # fmt: skip
    """Unit image vector [2] from a person's chest toward the light (world point ``light``)."""
    toward = light - anchor
    toward = anchor + 0.3 * toward / max(float(np.linalg.norm(toward)), 1e-9)
    (end,), _ = camera.project_depth(toward[None])
    d = end - pixels
    n = float(np.linalg.norm(d))
    return d / n if n > 1e-6 else np.array([0.0, -1.0])


def draw_people(image: np.ndarray, camera: PinholeCamera, points: np.ndarray,
                heights: np.ndarray, looks: list[Look], light: np.ndarray,
                occluders: np.ndarray | None = None) -> None:  # fmt: skip
    """Paint people [P, M, 3] (world points) into ``image`` in place, far to near.

    ``occluders`` [H, W]: the depth of furniture that stands in the room at each pixel
    (:meth:`models.simulate.furniture.Occluders.depth_map`): where it is nearer than the body
    part painted there, the pixels painted before that person are put back."""
    points = with_extra_points(points, heights)
    pixels, depth, magnification = project_points(
        points, camera.K, camera.R, camera.t, np.asarray(camera.distortion), with_scale=True
    )
    scale = camera.K[0, 0] * heights[:, None] * magnification / np.maximum(depth, NEAR)
    radius, box_radius = DRAW_RADII * scale, RADII * scale[:, :NUM_POINTS]
    h, w = image.shape[:2]
    volume = RADII > 0
    for person in np.argsort(-depth[:, MID_HIP]):
        if (depth[person, :NUM_POINTS][volume] <= NEAR).any():
            continue  # partly behind the camera: a real camera would not see it whole either
        px, r, d = pixels[person], radius[person], depth[person]
        body = px[:NUM_POINTS]
        lo = (body - box_radius[person][:, None]).min(0)
        hi = (body + box_radius[person][:, None]).max(0)
        if hi[0] < 0 or hi[1] < 0 or lo[0] >= w or lo[1] >= h:
            continue
        _shadow(image, camera, points[person, MID_HIP], heights[person], occluders)
        toward = light_direction(px[P["chest"]], points[person, P["chest"]], light, camera)
        rings = [
            np.round(
                (px[:, None] + r[:, None, None] * (off * toward + size * _CIRCLE)) * 16
            ).astype(np.int32)
            for off, size, _, _ in _BANDS
        ]
        roi = _occluded_roi(occluders, lo, hi, d)
        before = None if roi is None else image[roi].copy()
        _paint_person(image, rings, r, d, looks[person])
        _head(image, px, r, d, looks[person], toward)
        if roi is not None and before is not None and occluders is not None:
            behind = occluders[roi] < _depth_buffer(rings[0], px, r, d, roi)
            image[roi][behind] = before[behind]


def _occluded_roi(occluders: np.ndarray | None, lo: np.ndarray, hi: np.ndarray,
                  d: np.ndarray) -> tuple[slice, slice] | None:  # fmt: skip
    """The pixels of a person's box where furniture may hide them (None: nowhere)."""
    if occluders is None:
        return None
    h, w = occluders.shape
    x0, y0 = (max(int(v) - 2, 0) for v in lo)
    x1, y1 = min(int(hi[0]) + 3, w), min(int(hi[1]) + 3, h)
    if x1 <= x0 or y1 <= y0:
        return None
    roi = (slice(y0, y1), slice(x0, x1))
    if not (occluders[roi] < d[:NUM_POINTS].max()).any():
        return None
    return roi


def _depth_buffer(ring: np.ndarray, px: np.ndarray, r: np.ndarray, d: np.ndarray,
                  roi: tuple[slice, slice]) -> np.ndarray:  # fmt: skip
    """Depth [h, w] of the body at each pixel of ``roi`` (inf off the body): every part's hull
    filled with its mean depth, far to near, then the head disc."""
    y, x = roi
    buffer = np.full((y.stop - y.start, x.stop - x.start), np.inf, np.float32)
    origin = np.array([x.start, y.start]) * 16
    part_depth = np.where(_PART_MASK, d[_PART_IDX], 0.0).sum(1) / _PART_MASK.sum(1)
    for s in np.argsort(-part_depth).tolist():
        idx = _PART_IDX[s][_PART_MASK[s]]
        poly = cv2.convexHull((ring[idx].reshape(-1, 2) - origin).astype(np.int32))
        cv2.fillConvexPoly(buffer, poly, float(part_depth[s]), cv2.LINE_8, 4)
    for point in (P["neck"], HEAD):
        centre = tuple(int(v) for v in np.round(px[point] * 16 - origin))
        cv2.circle(buffer, centre, max(int(r[point] * 16 * 1.1), 16), float(d[point]), -1,
                   cv2.LINE_8, 4)  # fmt: skip
    return buffer


def _paint_person(image: np.ndarray, rings: list[np.ndarray], r: np.ndarray, d: np.ndarray,
                  look: Look) -> None:  # fmt: skip
    part_depth = np.where(_PART_MASK, d[_PART_IDX], 0.0).sum(1) / _PART_MASK.sum(1)
    part_size = np.where(_PART_MASK, r[_PART_IDX], 0.0).max(1)
    far = (_PART_SIDED & (d[_PART_IDX[:, 0]] > d[P["chest"]] + 0.02)).tolist()
    facing = d[P["nose"]] < d[HEAD]
    shades = look.shades
    for s in np.lexsort((-part_depth, _PART_LAYER)).tolist():
        part = _SHAPES[s][2]
        _shaded(image, rings, _SHAPE_POINTS[s], float(part_size[s]), shades[part, far[s]])
        if part == "torso" and look.jacket is not None and facing:
            _shaded(image, rings, _FRONT, float(r[_FRONT].max()), shades["front", False], 1)


def _shaded(image: np.ndarray, rings: list[np.ndarray], idx: list[int], size: float,
            shade: Shade, bands: int = 3) -> None:  # fmt: skip
    """A part as nested convex hulls (shadow side, mid tone, lit side) and a soft outline.

    ``size`` is the part's largest radius in pixels: small parts get fewer bands, since
    sub-pixel bands cost time and are invisible."""
    n = 1 if size < 2.0 else 2 if size < 4.0 else bands
    for band in range(n):
        poly = cv2.convexHull(rings[band][idx].reshape(-1, 2))
        # Only the silhouette is anti-aliased: band edges inside it cost 3x as much with AA and
        # are soft anyway (neighbouring tones).
        cv2.fillConvexPoly(image, poly, shade.bands[band] if n > 1 else shade.flat,
                           cv2.LINE_AA if band == 0 else cv2.LINE_8, 4)  # fmt: skip
        if band == 0 and size > 2.5:
            cv2.polylines(image, [poly], True, shade.outline, 1, cv2.LINE_AA, 4)


def _disc(image: np.ndarray, centre: np.ndarray, radius: float, colour: np.ndarray) -> None:
    cv2.circle(image, tuple(int(v) for v in np.round(centre * 16)), max(int(radius * 16), 12),
               np.clip(colour, 0, 255).tolist(), -1, cv2.LINE_AA, 4)  # fmt: skip


def _head(image: np.ndarray, px: np.ndarray, r: np.ndarray, d: np.ndarray, look: Look,
          toward: np.ndarray) -> None:  # fmt: skip
    """Neck, face and hair: hair on the back and top, the face toward the camera when facing it."""
    centre, crown, radius = px[HEAD], px[P["crown"]], r[HEAD]
    neck = [P["neck"], HEAD]
    poly = cv2.convexHull(np.round(
        (px[neck, None] + np.array([r[P["neck"]], r[P["neck"]]])[:, None, None] * _CIRCLE) * 16
    ).astype(np.int32).reshape(-1, 2))  # fmt: skip
    cv2.fillConvexPoly(image, poly, (look.skin * 0.8).tolist(), cv2.LINE_AA, 4)
    hair, skin = look.hair, look.skin
    facing = d[P["nose"]] < d[HEAD]
    back = px[X["hair_back"]]
    if look.hair_style == "long":
        ring = np.concatenate([crown + radius * 1.05 * _CIRCLE, back + radius * 0.8 * _CIRCLE])
        cv2.fillConvexPoly(image, cv2.convexHull(np.round(ring * 16).astype(np.int32)),
                           hair.tolist(), cv2.LINE_AA, 4)  # fmt: skip
    lit = centre + 0.3 * radius * toward
    if facing:
        if look.hair_style != "bald":
            _disc(image, crown, r[P["crown"]] * 1.15, hair)
        face = 0.8 * centre + 0.2 * px[P["nose"]]
        _disc(image, face, radius * 0.88, skin * 0.8)
        _disc(image, 0.7 * face + 0.3 * lit, radius * 0.6, skin)
        eyes = [P["left_eye"], P["right_eye"]]
        if radius > 9 and (d[eyes] < d[HEAD]).all():
            for eye in eyes:
                _disc(image, px[eye], radius * 0.08, skin * 0.35)
    else:
        _disc(image, centre, radius, skin * 0.85)
        if look.hair_style == "bald":
            _disc(image, 0.6 * centre + 0.4 * lit, radius * 0.7, skin)
        else:
            _disc(image, 0.5 * centre + 0.5 * crown, radius * 0.98, hair * 0.85)
            _disc(image, 0.4 * centre + 0.4 * crown + 0.2 * lit, radius * 0.6, hair * 1.15)


def _shadow(image: np.ndarray, camera: PinholeCamera, floor: np.ndarray, height: float,
            occluders: np.ndarray | None = None) -> None:  # fmt: skip
    """A soft dark ellipse on the floor under the person (darkens, does not paint), except
    where furniture (``occluders``: its depth per pixel) stands in front of it."""
    ring = np.zeros((12, 3))
    ring[:, :2] = floor[:2] + 0.14 * height * _CIRCLE
    pixels, depth = camera.project_depth(ring)
    if (depth <= NEAR).any():
        return
    poly = np.round(pixels).astype(np.int32)
    x0, y0 = np.maximum(poly.min(0), 0)
    x1, y1 = np.minimum(poly.max(0) + 1, [image.shape[1], image.shape[0]])
    if x1 <= x0 or y1 <= y0:
        return
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillConvexPoly(mask, poly - [x0, y0], 1)
    if occluders is not None:
        mask[occluders[y0:y1, x0:x1] < depth.min()] = 0
    roi = image[y0:y1, x0:x1]
    roi[mask > 0] = (roi[mask > 0] * 0.8).astype(np.uint8)


class Renderer:
    """Caches each camera's background; ``frame`` returns a fresh uint8 BGR image."""

    def __init__(self, room: tuple[float, float], wall_height: float, looks: list[Look],
                 outdoor: bool = False, furniture: tuple[Furniture, ...] = ()) -> None:  # fmt: skip
        self.room = room
        self.outdoor = outdoor
        self.wall_height = wall_height
        self.looks = looks
        self.decor: Decor | None = None if outdoor else room_decor(room, wall_height)
        if self.decor is not None and furniture:
            self.decor = dataclasses.replace(
                self.decor, furniture=self.decor.furniture + tuple(furniture)
            )
        self.occluders = Occluders(furniture)
        self._depths: dict[int, tuple[PinholeCamera, np.ndarray | None]] = {}
        width, depth = room
        # The room's lamp over its centre; outdoors a high sun in the south-west.
        self.light = (np.array([width / 2, depth / 2, wall_height - 0.3]) if not outdoor
                      else np.array([-30.0, -40.0, 60.0]))  # fmt: skip
        self._backgrounds: dict[int, tuple[PinholeCamera, np.ndarray]] = {}

    def background(self, camera: PinholeCamera) -> np.ndarray:
        cached = self._backgrounds.get(id(camera))
        if cached is None or cached[0] is not camera:
            background = render_background(
                camera, self.room, self.wall_height, self.outdoor, decor=self.decor
            )
            cached = (camera, background)
            self._backgrounds[id(camera)] = cached
        return cached[1]

    def frame(self, camera: PinholeCamera, points: np.ndarray, heights: np.ndarray) -> np.ndarray:
        return self.draw(self.background(camera), camera, points, heights)

    def draw(self, background: np.ndarray, camera: PinholeCamera, points: np.ndarray,
             heights: np.ndarray) -> np.ndarray:  # fmt: skip
        """A copy of ``background`` with the people painted in."""
        image = background.copy()
        draw_people(image, camera, points, heights, self.looks, self.light,
                    self._occluder_depth(camera))  # fmt: skip
        return image

    def _occluder_depth(self, camera: PinholeCamera) -> np.ndarray | None:
        cached = self._depths.get(id(camera))
        if cached is None or cached[0] is not camera:
            cached = (camera, self.occluders.depth_map(camera))
            self._depths[id(camera)] = cached
        return cached[1]

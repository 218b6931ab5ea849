"""Rendered camera frames: a plain shaded room with crudely drawn, detector-friendly humanoids.

The background of each camera is ray-cast once (floor with a 1 m tile grid, walls with a
baseboard, ceiling, lit by a lamp over the room centre) and cached; a frame is a copy of it with
the people painted far to near. Each body part is the convex hull of its body-volume spheres
(the same spheres that define the true box), so the painted person fills its true box and has
perspective-correct size. Parts are flat-coloured with simple shading (far-side limbs darker, a
darker outline), clothes and skin tones vary per person, and a soft shadow grounds each person:
an SSDLite person detector finds such figures at 120-220 px tall (ARCHITECTURE.md).

Cost: one background copy plus about twenty anti-aliased polygon fills per person, a few ms per
640×480 frame (see bench/results/simulate_render.md).
"""

from __future__ import annotations

import cv2
import numpy as np

from models.simulate.camera import NEAR, PinholeCamera, project_points
from models.simulate.skeleton import HEAD, MID_HIP, RADII, P

_SHIRTS = [(40, 40, 200), (200, 90, 30), (40, 150, 40), (30, 160, 220), (150, 40, 150),
           (230, 230, 230), (60, 60, 60), (140, 100, 40), (90, 40, 180), (20, 110, 200),
           (180, 160, 60), (110, 60, 30)]  # fmt: skip
_TROUSERS = [(90, 50, 30), (40, 40, 40), (80, 80, 80), (60, 40, 25), (50, 45, 40),
             (110, 70, 40)]  # fmt: skip
_SKIN = [(170, 200, 240), (140, 175, 225), (110, 145, 200), (80, 110, 160), (60, 80, 120)]
_HAIR = [(20, 20, 25), (30, 45, 70), (60, 100, 150), (120, 120, 130), (40, 30, 30)]
_SHOES = [(25, 25, 25), (240, 240, 240), (30, 50, 90)]

# (layer, points, part, side): layer 0 legs, 1 torso and arms, 2 neck and head.
_SHAPES = []
for _side in ("left", "right"):
    _SHAPES += [
        (0, (f"{_side}_hip", f"{_side}_knee"), "trousers", _side),
        (0, (f"{_side}_knee", f"{_side}_ankle"), "trousers", _side),
        (0, (f"{_side}_ankle", f"{_side}_toe", f"{_side}_heel"), "shoes", _side),
        (1, (f"{_side}_shoulder", f"{_side}_elbow"), "shirt", _side),
        (1, (f"{_side}_elbow", f"{_side}_wrist"), "sleeve", _side),
        (1, (f"{_side}_hand",), "skin", _side),
    ]
_SHAPES += [
    (0, ("left_hip", "right_hip", "mid_hip"), "trousers", ""),
    (1, ("left_shoulder", "right_shoulder", "chest", "abdomen", "left_hip", "right_hip"),
     "shirt", ""),
    (2, ("neck", "head"), "skin", ""),
]  # fmt: skip
_SHAPES_IDX = [(layer, [P[n] for n in names], part, side) for layer, names, part, side in _SHAPES]
_CIRCLE = np.stack([np.cos(np.linspace(0, 2 * np.pi, 12, endpoint=False)),
                    np.sin(np.linspace(0, 2 * np.pi, 12, endpoint=False))], 1)  # fmt: skip


def appearance(rng: np.random.Generator, people: int) -> list[dict[str, np.ndarray]]:
    """Clothes, skin and hair colours (BGR float) of each person."""
    out = []
    for _ in range(people):
        pick = {name: np.array(table[rng.integers(len(table))], float) * rng.uniform(0.85, 1.1)
                for name, table in (("shirt", _SHIRTS), ("trousers", _TROUSERS), ("skin", _SKIN),
                                    ("hair", _HAIR), ("shoes", _SHOES))}  # fmt: skip
        pick["sleeve"] = pick["shirt"] if rng.random() < 0.5 else pick["skin"]
        out.append({k: np.clip(v, 0, 255) for k, v in pick.items()})
    return out


def render_background(camera: PinholeCamera, room: tuple[float, float], wall_height: float,
                      outdoor: bool = False, grain: float = 2.0) -> np.ndarray:  # fmt: skip
    """Ray-cast the empty room (or an open square) as seen by ``camera``: uint8 BGR [H, W, 3]."""
    w, h = camera.image_size
    u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    K = camera.K
    y = (v - K[1, 2]) / K[1, 1]
    x = (u - K[0, 2] - K[0, 1] * y) / K[0, 0]
    k1, k2 = camera.distortion
    xu, yu = x, y
    for _ in range(6):  # invert the radial distortion by fixed-point iteration
        r2 = xu * xu + yu * yu
        factor = 1 + k1 * r2 + k2 * r2 * r2
        xu, yu = x / factor, y / factor
    rays = np.stack([xu, yu, np.ones_like(xu)], -1) @ camera.R  # world directions
    origin = camera.position
    width, depth = room
    best = np.full(rays.shape[:2], np.inf)
    surface = np.zeros(rays.shape[:2], dtype=np.int8)
    planes = [(2, 0.0, 0), (2, wall_height, 1), (0, 0.0, 2), (0, width, 3), (1, 0.0, 4),
              (1, depth, 5)]  # fmt: skip
    if outdoor:  # ground only; rays that miss it see the sky
        planes = planes[:1]
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, value, sid in planes:
            t = (value - origin[axis]) / rays[..., axis]
            better = (t > 1e-6) & (t < best)
            best = np.where(better, t, best)
            surface = np.where(better, sid, surface)
    best_raw = best
    best = np.where(np.isfinite(best), best, 50.0)
    hit = origin + rays * best[..., None]
    base = np.array([[150, 165, 175], [225, 225, 222], [185, 200, 212], [170, 190, 205],
                     [200, 210, 218], [178, 195, 208]], float)  # fmt: skip
    colour = base[surface]
    lamp = np.array([width / 2, depth / 2, wall_height - 0.3])
    to_lamp = lamp - hit
    distance = np.linalg.norm(to_lamp, axis=-1)
    normals = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], float)
    lambert = np.clip((normals[surface] * to_lamp).sum(-1) / distance, 0, 1)
    light = 0.55 + 0.45 * lambert * np.clip(4.0 / (1.0 + 0.08 * distance**2), 0, 1)
    floor = surface == 0
    grid = (np.abs(hit[..., 0] - np.round(hit[..., 0])) < 0.012) | (
        np.abs(hit[..., 1] - np.round(hit[..., 1])) < 0.012
    )
    light = np.where(floor & grid, light * 0.82, light)
    light = np.where((surface >= 2) & (hit[..., 2] < 0.08), light * 0.55, light)  # baseboard
    light = np.where(surface == 1, 0.9 + 0.1 * lambert, light)  # the ceiling is lit indirectly
    if outdoor:
        inside = (hit[..., 0] >= 0) & (hit[..., 0] <= width) & (hit[..., 1] >= 0)
        inside &= hit[..., 1] <= depth
        grass = floor & ~inside
        colour = np.where(grass[..., None], [70.0, 140.0, 95.0], colour)
        sky = ~np.isfinite(best_raw)
        elevation = np.clip(rays[..., 2] / np.linalg.norm(rays, axis=-1), 0, 1)[..., None]
        sky_colour = np.array([235.0, 215.0, 190.0]) * (1 - elevation) + [210, 160, 110] * elevation
        colour = np.where(sky[..., None], sky_colour, colour)
        light = np.where(sky | grass, 1.0, np.where(floor & inside, 0.75 + 0.25 * light, light))
    texture = np.random.default_rng(0).normal(0, grain, light.shape)  # faint sensor grain
    return np.clip(colour * light[..., None] + texture[..., None], 0, 255).astype(np.uint8)


def _hull(centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Polygon (int32 [N, 1, 2], 1/16 px fixed point) of the convex hull of circles."""
    ring = (centres[:, None, :] + radii[:, None, None] * _CIRCLE).reshape(-1, 2)
    return cv2.convexHull(np.round(ring * 16).astype(np.int32))


def draw_people(
    image: np.ndarray,
    camera: PinholeCamera,
    points: np.ndarray,
    heights: np.ndarray,
    looks: list[dict[str, np.ndarray]],
) -> None:
    """Paint people [P, M, 3] (world points) into ``image`` in place, far to near."""
    pixels, depth, magnification = project_points(
        points, camera.K, camera.R, camera.t, np.asarray(camera.distortion), with_scale=True
    )
    radius = camera.K[0, 0] * RADII * heights[:, None] * magnification / np.maximum(depth, NEAR)
    order = np.argsort(-depth[:, MID_HIP])
    h, w = image.shape[:2]
    for person in order:
        volume = RADII > 0
        if (depth[person, volume] <= NEAR).any():
            continue  # partly behind the camera: a real camera would not see it whole either
        px, r, d = pixels[person], radius[person], depth[person]
        lo, hi = (px - r[:, None]).min(0), (px + r[:, None]).max(0)
        if hi[0] < 0 or hi[1] < 0 or lo[0] >= w or lo[1] >= h:
            continue
        look = looks[person]
        _shadow(image, camera, points[person, MID_HIP], heights[person])
        shapes = sorted(_SHAPES_IDX, key=lambda s: (s[0], -d[s[1][0]] if s[0] < 2 else 0.0))
        torso_depth = d[P["chest"]]
        for _layer, idx, part, side in shapes:
            shade = 0.78 if side and d[idx[0]] > torso_depth + 0.02 else 1.0
            colour = look[part] * shade
            poly = _hull(px[idx], r[idx])
            cv2.fillConvexPoly(image, poly, colour.tolist(), cv2.LINE_AA, 4)
            if r[idx].max() > 2.5:
                cv2.polylines(image, [poly], True, (colour * 0.55).tolist(), 1, cv2.LINE_AA, 4)
            if r[idx].max() > 4:  # a lit stripe toward the lamp gives the part some roundness
                lit = _hull(px[idx] - [0.25, 0.35] * r[idx][:, None], r[idx] * 0.45)
                cv2.fillConvexPoly(
                    image, lit, np.clip(colour * 1.18 + 12, 0, 255).tolist(), cv2.LINE_AA, 4
                )
        _head(image, px, r, d, look)


def _head(image: np.ndarray, px: np.ndarray, r: np.ndarray, d: np.ndarray,
          look: dict[str, np.ndarray]) -> None:  # fmt: skip
    """Face and hair: hair on the back of the head, face toward the camera when facing it."""
    centre, crown, radius = px[HEAD], px[P["crown"]], r[HEAD]
    hair = look["hair"].tolist()

    def disc(c: np.ndarray, rad: float, colour: list[float]) -> None:
        cv2.circle(image, tuple(np.round(c * 16).astype(int)), max(int(rad * 16), 16), colour,
                   -1, cv2.LINE_AA, 4)  # fmt: skip

    if d[P["nose"]] < d[HEAD]:  # facing the camera
        disc(centre, radius, hair)
        disc(crown, r[P["crown"]] * 1.1, hair)
        face = 0.75 * centre + 0.25 * px[P["nose"]]
        disc(face, radius * 0.85, look["skin"].tolist())
        eyes = [P["left_eye"], P["right_eye"]]
        if radius > 6 and (d[eyes] < d[HEAD]).all():
            for eye in eyes:
                disc(px[eye], radius * 0.1, (40, 40, 40))
    else:
        disc(centre, radius, look["skin"].tolist())
        disc(crown, r[P["crown"]] * 1.12, hair)
        disc(centre, radius * 0.92, hair)


def _shadow(image: np.ndarray, camera: PinholeCamera, floor: np.ndarray, height: float) -> None:
    """A soft dark ellipse on the floor under the person (darkens, does not paint)."""
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
    roi = image[y0:y1, x0:x1]
    roi[mask > 0] = (roi[mask > 0] * 0.8).astype(np.uint8)


class Renderer:
    """Caches each camera's background; ``frame`` returns a fresh uint8 BGR image."""

    def __init__(self, room: tuple[float, float], wall_height: float,
                 looks: list[dict[str, np.ndarray]], outdoor: bool = False) -> None:  # fmt: skip
        self.room = room
        self.outdoor = outdoor
        self.wall_height = wall_height
        self.looks = looks
        self._backgrounds: dict[int, tuple[PinholeCamera, np.ndarray]] = {}

    def background(self, camera: PinholeCamera) -> np.ndarray:
        cached = self._backgrounds.get(id(camera))
        if cached is None or cached[0] is not camera:
            background = render_background(camera, self.room, self.wall_height, self.outdoor)
            cached = (camera, background)
            self._backgrounds[id(camera)] = cached
        return cached[1]

    def frame(self, camera: PinholeCamera, points: np.ndarray, heights: np.ndarray) -> np.ndarray:
        return self.draw(self.background(camera), camera, points, heights)

    def draw(self, background: np.ndarray, camera: PinholeCamera, points: np.ndarray,
             heights: np.ndarray) -> np.ndarray:  # fmt: skip
        """A copy of ``background`` with the people painted in."""
        image = background.copy()
        draw_people(image, camera, points, heights, self.looks)
        return image

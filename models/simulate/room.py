"""The empty room each simulated camera sees, ray-cast once per camera and cached by the renderer.

A room has painted walls (one accent wall), a floor of tiles, wooden planks or carpet, a ceiling,
a door, windows and framed pictures (flat decals on the walls) and a few furniture boxes standing
against the walls (cabinets, bookshelves with coloured book rows, a sofa block), lit by a lamp
over the room centre. Everything is drawn from the room's size alone (seeded by it), so every
camera of a scene sees the same room and a preset always looks the same.

Why structure at all: on a plain two-tone room a detector only has to find "the blob that is not
wall", which flatters it; real rooms have edges, furniture and colour patches near people.
Why nothing person-like: the furniture is wide and boxy (no coat stands, plants or floor lamps)
and stands within 0.3 m of a wall, where people do not walk (``people.MARGIN``), so a person is
never behind this furniture (the renderer paints people over the background) and the detector's
false boxes stay the detector's, not the scene's. A box that would contain a camera is left out.
Furniture that does stand where people are (sofas, tables, desks) is a scene's own
(``SceneConfig.furniture``, :mod:`models.simulate.furniture`), drawn with this room and hiding
the people behind it.

Cost: about 30-60 ms per 640×480 camera, once (vectorised ray casting over all pixels).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.simulate.camera import PinholeCamera

_PAINT = np.array([[200, 210, 218], [178, 195, 208], [185, 200, 212], [170, 190, 205],
                   [205, 205, 200], [190, 205, 190], [215, 200, 185], [170, 170, 175]],
                  float)  # fmt: skip
_WOOD = np.array([[70, 110, 150], [90, 130, 170], [50, 80, 115], [110, 150, 185]], float)
_FURNITURE = np.array([[60, 90, 125], [235, 235, 232], [45, 45, 50], [140, 150, 155],
                       [100, 125, 150], [120, 90, 70]], float)  # fmt: skip
_BOOKS = np.array([[40, 40, 160], [150, 70, 30], [40, 120, 40], [30, 150, 200], [200, 200, 200],
                   [120, 40, 120], [30, 30, 30]], float)  # fmt: skip


@dataclass(frozen=True)
class Furniture:
    """An axis-aligned box ``lo``..``hi`` (world metres) of one colour; ``shelves`` draws book
    rows on its faces."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    colour: tuple[float, float, float]
    shelves: bool = False


@dataclass(frozen=True)
class Decal:
    """A flat rectangle on wall ``wall`` (2: x=0, 3: x=W, 4: y=0, 5: y=D): along-wall span
    ``a0``..``a1`` and height ``z0``..``z1`` metres; ``frame`` is the border colour."""

    wall: int
    a0: float
    a1: float
    z0: float
    z1: float
    colour: tuple[float, float, float]
    frame: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Decor:
    walls: np.ndarray  # [6, 3] base colour of floor, ceiling, 4 walls (surface ids 0..5)
    floor: str  # "tiles", "planks" or "carpet"
    furniture: tuple[Furniture, ...]
    decals: tuple[Decal, ...]


def room_decor(room: tuple[float, float], wall_height: float) -> Decor:
    """A furnished room of ``room`` = (width, depth) metres, the same every time for a size."""
    width, depth = room
    rng = np.random.default_rng([round(width * 100), round(depth * 100), 17])
    paint = _PAINT[rng.permutation(len(_PAINT))[:2]]
    walls = np.array([[150, 165, 175], [225, 225, 222], *([paint[0]] * 4)], float)
    walls[2 + rng.integers(4)] = paint[1]  # one accent wall
    floor = ("tiles", "planks", "carpet")[rng.integers(3)]
    if floor == "planks":
        walls[0] = _WOOD[rng.integers(len(_WOOD))]
    elif floor == "carpet":
        walls[0] = rng.choice([[120, 120, 125], [95, 110, 130], [130, 140, 120]])
    furniture: list[Furniture] = []
    decals: list[Decal] = []
    # Slots along each wall (two, or four on walls of 7 m and more), clear of the corners and
    # the wall centre where ring_cameras hang.
    for wall in (2, 3, 4, 5):
        length = depth if wall in (2, 3) else width
        slots = (0.3, 0.7) if length < 7.0 else (0.2, 0.36, 0.64, 0.8)
        for fraction in slots:
            kind = rng.choice(["cabinet", "shelf", "sofa", "window", "picture", "door", "none"],
                              p=[0.2, 0.14, 0.1, 0.2, 0.2, 0.12, 0.04])  # fmt: skip
            span = min({"cabinet": 1.4, "shelf": 1.0, "sofa": 1.9, "window": 1.3, "picture": 0.7,
                        "door": 0.9, "none": 0.0}[kind], 0.6 * length / len(slots))  # fmt: skip
            centre = fraction * length + rng.uniform(-0.2, 0.2) * length / len(slots)
            a0, a1 = centre - span / 2, centre + span / 2
            if kind in ("cabinet", "shelf", "sofa"):
                top = {"cabinet": rng.uniform(0.5, 0.9), "shelf": rng.uniform(1.5, 1.9),
                       "sofa": 0.8}[kind]  # fmt: skip
                thick = 0.28 if kind != "shelf" else 0.3
                colour = _FURNITURE[rng.integers(len(_FURNITURE))]
                furniture.append(_against(wall, a0, a1, top, thick, width, depth, colour,
                                          kind == "shelf"))  # fmt: skip
            elif kind == "window":
                decals.append(Decal(wall, a0, a1, 0.9, min(2.1, wall_height - 0.3),
                                    (235, 225, 205), (245, 245, 245)))  # fmt: skip
            elif kind == "picture":
                colour = tuple(rng.uniform(40, 200, 3))
                decals.append(Decal(wall, a0, a1, 1.3, 1.3 + 0.7 * span, colour, (40, 50, 60)))
            elif kind == "door":
                decals.append(Decal(wall, a0, a1, 0.0, 2.05, tuple(_WOOD[rng.integers(4)] * 0.9),
                                    (230, 230, 230)))  # fmt: skip
    return Decor(walls, floor, tuple(furniture), tuple(decals))


def _against(wall: int, a0: float, a1: float, top: float, thick: float, width: float,
             depth: float, colour: np.ndarray, shelves: bool) -> Furniture:  # fmt: skip
    if wall == 2:
        lo, hi = (0.0, a0, 0.0), (thick, a1, top)
    elif wall == 3:
        lo, hi = (width - thick, a0, 0.0), (width, a1, top)
    elif wall == 4:
        lo, hi = (a0, 0.0, 0.0), (a1, thick, top)
    else:
        lo, hi = (a0, depth - thick, 0.0), (a1, depth, top)
    red, green, blue = (float(c) for c in colour)
    return Furniture(lo, hi, (red, green, blue), shelves)


def camera_rays(camera: PinholeCamera) -> np.ndarray:
    """World direction [H, W, 3] of every pixel centre's ray (undistorted)."""
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
    return np.stack([xu, yu, np.ones_like(xu)], -1) @ camera.R


def render_background(camera: PinholeCamera, room: tuple[float, float], wall_height: float,
                      outdoor: bool = False, grain: float = 2.0,
                      decor: Decor | None = None) -> np.ndarray:  # fmt: skip
    """Ray-cast the empty room (or an open square) as seen by ``camera``: uint8 BGR [H, W, 3].

    ``decor`` defaults to :func:`room_decor` of the room (indoors); outdoors has none.
    """
    rays = camera_rays(camera)
    origin = camera.position
    width, depth = room
    if decor is None and not outdoor:
        decor = room_decor(room, wall_height)
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
        box_id = np.full(rays.shape[:2], -1, np.int16)
        box_normal = np.zeros(rays.shape[:2], np.int8)
        for i, item in enumerate(decor.furniture if decor else ()):
            lo, hi = np.array(item.lo), np.array(item.hi)
            if np.all(origin > lo - 0.3) and np.all(origin < hi + 0.3):
                continue  # a camera hangs there: leave the box out rather than fill the view
            window = _window(camera, lo, hi)
            if window is None:
                continue
            r = rays[window]
            t0, t1 = (lo - origin) / r, (hi - origin) / r
            near = np.minimum(t0, t1)
            enter = near.max(-1)
            leave = np.maximum(t0, t1).min(-1)
            hit = (enter <= leave) & (enter > 1e-6) & (enter < best[window])
            axis = near.argmax(-1)
            sign = np.take_along_axis(r, axis[..., None], -1)[..., 0] < 0
            best[window] = np.where(hit, enter, best[window])
            box_id[window] = np.where(hit, i, box_id[window])
            # Normal id of the face entered: against the ray along the entry axis.
            box_normal[window] = np.where(hit, 2 * axis + sign, box_normal[window])
    best_raw = best
    best = np.where(np.isfinite(best), best, 50.0)
    hit = origin + rays * best[..., None]
    base = decor.walls if decor else np.array([[150, 165, 175], *[[200, 210, 218]] * 5], float)
    colour = base[surface]
    normal_id = np.array([5, 4, 1, 0, 3, 2])[surface]  # rows of _NORMAL_BY_ID below
    on_box = box_id >= 0
    if decor:
        colour, normal_id = _paint(decor, hit, surface, colour, normal_id, on_box, box_id,
                                   box_normal)  # fmt: skip
    lamp = np.array([width / 2, depth / 2, wall_height - 0.3])
    to_lamp = lamp - hit
    distance = np.linalg.norm(to_lamp, axis=-1)
    normals = _NORMAL_BY_ID[normal_id]
    lambert = np.clip((normals * to_lamp).sum(-1) / distance, 0, 1)
    light = 0.55 + 0.45 * lambert * np.clip(4.0 / (1.0 + 0.08 * distance**2), 0, 1)
    floor = (surface == 0) & ~on_box
    if not decor or decor.floor == "tiles":
        grid = (np.abs(hit[..., 0] - np.round(hit[..., 0])) < 0.012) | (
            np.abs(hit[..., 1] - np.round(hit[..., 1])) < 0.012
        )
        light = np.where(floor & grid, light * 0.82, light)
    light = np.where((surface >= 2) & ~on_box & (hit[..., 2] < 0.08), light * 0.55, light)
    light = np.where((surface == 1) & ~on_box, 0.9 + 0.1 * lambert, light)  # lit indirectly
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


def _window(camera: PinholeCamera, lo: np.ndarray, hi: np.ndarray) -> tuple[slice, slice] | None:
    """Pixel rows and columns that can see the box ``lo``..``hi`` (None: none can).

    Ray-casting only there makes a furnished room cost little more than an empty one. The
    window is the projected corners' bounds plus a 5 % margin (lens distortion bows edges);
    the whole image when a corner is behind the camera."""
    w, h = camera.image_size
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])  # fmt: skip
    pixels, depth = camera.project_depth(corners)
    if (depth <= 0.05).any():
        return slice(0, h), slice(0, w)
    m = 0.05 * max(w, h)
    x0, y0 = np.floor(pixels.min(0) - m).astype(int)
    x1, y1 = np.ceil(pixels.max(0) + m).astype(int)
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x1 <= x0 or y1 <= y0:
        return None
    return slice(y0, y1), slice(x0, x1)


# Outward normal by id: 2a is -axis a, 2a + 1 is +axis a. A box face entered along axis a by a
# ray going +a faces -a (id 2a), by a ray going -a faces +a (id 2a + 1); the floor is 5 (+z).
_NORMAL_BY_ID = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]],
                         float)  # fmt: skip


def _paint(decor: Decor, hit: np.ndarray, surface: np.ndarray, colour: np.ndarray,
           normal_id: np.ndarray, on_box: np.ndarray, box_id: np.ndarray,
           box_normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Floor pattern, wall decals and furniture colours on the ray-cast hit points."""
    colour = colour.copy()
    floor = (surface == 0) & ~on_box
    if decor.floor == "planks":  # 0.2 m planks along x, each its own shade, dark seams
        plank = np.floor(hit[..., 1] / 0.2)
        offset = (plank * 0.37) % 1.0
        board = np.floor(hit[..., 0] / 1.2 + offset)
        shade = 0.88 + 0.12 * ((np.sin(plank * 12.9898 + board * 78.233) * 43758.5453) % 1.0)
        seam = (np.abs(hit[..., 1] / 0.2 - np.round(hit[..., 1] / 0.2)) < 0.04) | (
            np.abs(hit[..., 0] / 1.2 + offset - np.round(hit[..., 0] / 1.2 + offset)) < 0.006
        )
        shade = np.where(seam, 0.7, shade)
        colour = np.where(floor[..., None], colour * shade[..., None], colour)
    for decal in decor.decals:
        along = hit[..., 1] if decal.wall in (2, 3) else hit[..., 0]
        z = hit[..., 2]
        on = (surface == decal.wall) & ~on_box & (along >= decal.a0) & (along <= decal.a1)
        on &= (z >= decal.z0) & (z <= decal.z1)
        if decal.frame is not None:
            border = 0.05
            inner = on & (along >= decal.a0 + border) & (along <= decal.a1 - border)
            inner &= (z >= decal.z0 + (border if decal.z0 > 0 else 0)) & (z <= decal.z1 - border)
            colour = np.where((on & ~inner)[..., None], decal.frame, colour)
            on = inner
        colour = np.where(on[..., None], decal.colour, colour)
    for i, item in enumerate(decor.furniture):
        mine = box_id == i
        if not mine.any():
            continue
        paint = np.broadcast_to(np.array(item.colour), colour.shape)
        if item.shelves:  # rows of books between shelf boards every 0.38 m
            z = hit[..., 2]
            row = np.floor(z / 0.38)
            along = np.where(np.isin(box_normal, (0, 1)), hit[..., 1], hit[..., 0])
            book = np.floor(along / 0.045 + row * 0.5)
            pick = (np.sin(book * 12.9898 + row * 78.233) * 43758.5453) % 1.0 * len(_BOOKS)
            books = _BOOKS[pick.astype(int) % len(_BOOKS)]
            board = (z % 0.38) < 0.03
            tall = (z % 0.38) < 0.03 + 0.3 * (0.7 + 0.3 * ((book * 0.618) % 1.0))
            front = box_normal != 5  # not the top face
            paint = np.where((front & tall & ~board)[..., None], books, paint)
        colour = np.where(mine[..., None], paint, colour)
    normal_id = np.where(on_box, box_normal, normal_id)
    return colour, normal_id

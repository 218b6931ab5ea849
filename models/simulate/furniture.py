"""Furniture standing in the room, and what it hides: sofas, tables, desks and chairs.

The room's own furniture (:func:`models.simulate.room.room_decor`) stands against the walls,
where nobody walks, so it never hides anyone. The pieces here stand where people sit, and a
table or a sofa back between a camera and a person hides their legs:

- in the **detections** (:class:`Occluders.hidden`): a body point is hidden when the segment
  from a camera to it crosses a piece; the simulated box is the box of the visible body points'
  spheres (what a detector returns for the visible body), hidden joints count as occluded for
  the pose estimator, and the hidden share of the body raises the miss probability like an
  occlusion between people;
- in the **drawn frames** (:meth:`Occluders.depth_map`): the renderer paints a person, then puts
  back the pixels where a piece is nearer than that part of the body.

Each piece is a few axis-aligned boxes (:class:`~models.simulate.room.Furniture`): a sofa is its
seat, back and arms, so a seated person is seen over the seat and through nothing.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from models.simulate.camera import PinholeCamera
from models.simulate.room import Furniture, camera_rays

Colour = tuple[float, float, float]
_FABRIC: Colour = (95.0, 80.0, 130.0)  # BGR
_WOOD: Colour = (60.0, 95.0, 140.0)
_DARK: Colour = (55.0, 55.0, 60.0)


def sofa(
    x0: float, y0: float, x1: float, facing: str, colour: Colour = _FABRIC
) -> tuple[Furniture, ...]:
    """A sofa from x0 to x1 (metres) with its back at y0, facing +y (``facing="+y"``) or -y:
    a 0.38 m seat 0.85 m deep, a 0.8 m back 0.2 m thick and 0.6 m arms."""
    sign = 1.0 if facing == "+y" else -1.0
    back0, back1 = sorted((y0, y0 + sign * 0.2))
    seat0, seat1 = sorted((y0, y0 + sign * 0.85))
    return (
        Furniture((x0, seat0, 0.0), (x1, seat1, 0.38), colour),
        Furniture((x0, back0, 0.38), (x1, back1, 0.8), colour),
        Furniture((x0, seat0, 0.38), (x0 + 0.18, seat1, 0.6), colour),
        Furniture((x1 - 0.18, seat0, 0.38), (x1, seat1, 0.6), colour),
    )


def table(x0: float, y0: float, x1: float, y1: float, top: float = 0.45,
          colour: Colour = _WOOD) -> tuple[Furniture, ...]:  # fmt: skip
    """A table x0..x1 × y0..y1 as one solid block up to ``top`` metres (a coffee table 0.45 m,
    a dining table or desk 0.74 m): a modesty panel or a full cloth hides what is behind it,
    which is the case that matters for the legs of someone sitting at it."""
    return (Furniture((x0, y0, 0.0), (x1, y1, top), colour),)


def chair(x: float, y: float, facing: str, colour: Colour = _DARK) -> tuple[Furniture, ...]:
    """A chair centred at (x, y): a 0.45 × 0.45 m seat block up to 0.36 m (its legs and seat
    seen as one solid), and a back 0.9 m high on the side away from ``facing`` ("+x", "-x",
    "+y", "-y")."""
    half = 0.225
    seat = Furniture((x - half, y - half, 0.0), (x + half, y + half, 0.36), colour)
    axis, sign = (0 if facing[1] == "x" else 1), (1.0 if facing[0] == "+" else -1.0)
    lo, hi = [x - half, y - half, 0.36], [x + half, y + half, 0.9]
    if sign > 0:
        hi[axis] = lo[axis] + 0.06
    else:
        lo[axis] = hi[axis] - 0.06
    back = Furniture((lo[0], lo[1], lo[2]), (hi[0], hi[1], hi[2]), colour)
    return (seat, back)


class Occluders:
    """The pieces of a scene as arrays, for the detection-side and drawing-side tests."""

    def __init__(self, pieces: Sequence[Furniture]) -> None:
        self.lo = np.array([p.lo for p in pieces], float).reshape(-1, 3)
        self.hi = np.array([p.hi for p in pieces], float).reshape(-1, 3)

    def __len__(self) -> int:
        return len(self.lo)

    def hidden(self, points: np.ndarray, cameras: Sequence[PinholeCamera]) -> np.ndarray:
        """[F, K, P, M] bool: world points [F, P, M, 3] with a piece between them and camera k."""
        f, p, m, _ = points.shape
        out = np.zeros((f, len(cameras), p, m), dtype=bool)
        if not len(self):
            return out
        centres = np.stack([c.position for c in cameras])  # [K, 3]
        direction = points[:, None] - centres[None, :, None, None]  # [F, K, P, M, 3]
        direction = np.where(np.abs(direction) < 1e-12, 1e-12, direction)
        for lo, hi in zip(self.lo, self.hi, strict=True):
            enter, leave = _slab(centres[None, :, None, None], direction, lo, hi)
            out |= (enter < leave) & (enter < 1.0) & (leave > 0.0)
        return out

    def depth_map(self, camera: PinholeCamera) -> np.ndarray | None:
        """[H, W] camera depth (m) of the nearest piece at every pixel, inf where none; None
        when the scene has no pieces."""
        if not len(self):
            return None
        rays = camera_rays(camera)  # camera-z component 1: the ray parameter is the depth
        rays = np.where(np.abs(rays) < 1e-12, 1e-12, rays)
        best = np.full(rays.shape[:2], np.inf)
        for lo, hi in zip(self.lo, self.hi, strict=True):
            enter, leave = _slab(camera.position, rays, lo, hi)
            hit = (enter <= leave) & (enter > 1e-6)
            best = np.where(hit & (enter < best), enter, best)
        return best


def _slab(origin: np.ndarray, direction: np.ndarray, lo: np.ndarray,
          hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Ray parameters where ``origin + t direction`` enters and leaves the box lo..hi."""
    t0 = (lo - origin) / direction
    t1 = (hi - origin) / direction
    return np.minimum(t0, t1).max(-1), np.maximum(t0, t1).min(-1)

"""Pinhole cameras for the synthetic scene: webcam intrinsics, look-at mounting, radial distortion.

Conventions (OpenCV): world x, y on the floor and z up (metres); camera x right, y down, z forward
along the optical axis; a world point X maps to camera coordinates ``R @ X + t`` and to pixels
``K @ (R @ X + t)`` followed by the perspective division. Radial distortion acts on normalised
image coordinates: ``(x, y) * (1 + k1 r² + k2 r⁴)`` with ``r² = x² + y²``, so the 3×4
``projection_matrix`` is exact only when k1 = k2 = 0 (the calibrated baseline gets the undistorted
matrix, as a real calibration would).

Example::

    cam = PinholeCamera.look_at((0, 0, 2.3), (5, 5, 1.0), hfov_deg=65, image_size=(640, 480))
    pixels, in_front = cam.project(np.array([[5.0, 5.0, 1.0]]))
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

NEAR = 0.05  # metres: points closer than this to the camera plane count as behind it


def intrinsics_from_fov(hfov_deg: float, image_size: tuple[int, int]) -> np.ndarray:
    """Square-pixel K with the principal point at the image centre, from the horizontal FOV."""
    width, height = image_size
    focal = (width / 2.0) / np.tan(np.radians(hfov_deg) / 2.0)
    return np.array(
        [[focal, 0.0, width / 2.0], [0.0, focal, height / 2.0], [0.0, 0.0, 1.0]], dtype=np.float64
    )


def look_at_rotation(position: np.ndarray, target: np.ndarray) -> np.ndarray:
    """World→camera rotation whose optical axis points at ``target`` with no roll (z is up)."""
    forward = np.asarray(target, float) - np.asarray(position, float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-9:
        raise ValueError("camera looks straight up or down; a look-at needs a horizontal component")
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return np.stack([right, down, forward])


def roll_rotation(degrees: float) -> np.ndarray:
    """Rotation about the camera's optical axis (rotates the image about the principal point)."""
    a = np.radians(degrees)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])


def project_points(
    points: np.ndarray,
    intrinsics: np.ndarray,
    rotation: np.ndarray,
    translation: np.ndarray,
    distortion: np.ndarray,
    with_scale: bool = False,
) -> tuple[np.ndarray, ...]:
    """Vectorised projection; camera arrays broadcast against the points' leading dimensions.

    ``points`` [..., 3]; ``intrinsics`` and ``rotation`` [..., 3, 3]; ``translation`` [..., 3];
    ``distortion`` [..., 2]. Returns pixels [..., 2] and depth [...] (camera z, metres), and with
    ``with_scale`` the local distortion magnification [...] (1 + k1 r² + k2 r⁴), which scales the
    projected size of a small sphere at the point.
    """
    cam = np.einsum("...ij,...j->...i", rotation, points) + translation
    depth = cam[..., 2]
    safe = np.where(depth > NEAR, depth, NEAR)
    normalised = cam[..., :2] / safe[..., None]
    r2 = (normalised**2).sum(-1)
    k1, k2 = distortion[..., 0], distortion[..., 1]
    magnification = 1.0 + k1 * r2 + k2 * r2 * r2
    normalised = normalised * magnification[..., None]
    fx, fy = intrinsics[..., 0, 0], intrinsics[..., 1, 1]
    cx, cy, skew = intrinsics[..., 0, 2], intrinsics[..., 1, 2], intrinsics[..., 0, 1]
    u = fx * normalised[..., 0] + skew * normalised[..., 1] + cx
    v = fy * normalised[..., 1] + cy
    if with_scale:
        return np.stack([u, v], axis=-1), depth, magnification
    return np.stack([u, v], axis=-1), depth


@dataclass(frozen=True, eq=False)  # arrays inside: identity equality, hashable
class PinholeCamera:
    """A calibrated pinhole camera: ``K`` [3,3], ``R`` [3,3], ``t`` [3], ``image_size`` (w, h)."""

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    image_size: tuple[int, int]
    distortion: tuple[float, float] = field(default=(0.0, 0.0))

    def __post_init__(self) -> None:
        object.__setattr__(self, "K", np.asarray(self.K, dtype=np.float64).reshape(3, 3))
        object.__setattr__(self, "R", np.asarray(self.R, dtype=np.float64).reshape(3, 3))
        object.__setattr__(self, "t", np.asarray(self.t, dtype=np.float64).reshape(3))
        object.__setattr__(self, "image_size", (int(self.image_size[0]), int(self.image_size[1])))
        object.__setattr__(
            self, "distortion", (float(self.distortion[0]), float(self.distortion[1]))
        )

    @classmethod
    def look_at(
        cls,
        position: tuple[float, float, float],
        target: tuple[float, float, float],
        hfov_deg: float = 65.0,
        image_size: tuple[int, int] = (640, 480),
        distortion: tuple[float, float] = (0.0, 0.0),
    ) -> PinholeCamera:
        """A camera at ``position`` looking at ``target`` (both world metres, z up)."""
        rotation = look_at_rotation(np.asarray(position, float), np.asarray(target, float))
        translation = -rotation @ np.asarray(position, float)
        return cls(
            intrinsics_from_fov(hfov_deg, image_size), rotation, translation, image_size, distortion
        )

    @property
    def projection_matrix(self) -> np.ndarray:
        """K [R | t], [3, 4] (ignores distortion)."""
        return self.K @ np.hstack([self.R, self.t[:, None]])

    @property
    def position(self) -> np.ndarray:
        """Camera centre in world coordinates."""
        return -self.R.T @ self.t

    @property
    def hfov_deg(self) -> float:
        return float(np.degrees(2 * np.arctan(self.image_size[0] / 2 / self.K[0, 0])))

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points [..., 3] → pixels [..., 2] (distorted) and in_front [...] bool."""
        pixels, depth = self.project_depth(points)
        return pixels, depth > NEAR

    def project_depth(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Like :meth:`project` but returns the camera depth (metres) instead of in_front."""
        pixels, depth = project_points(
            np.asarray(points, dtype=np.float64),
            self.K,
            self.R,
            self.t,
            np.asarray(self.distortion),
        )
        return pixels, depth

    def perturbed(self, dx: float = 0.0, dy: float = 0.0, roll_deg: float = 0.0) -> PinholeCamera:
        """The camera after a bump: image shifted by (dx, dy) pixels and rolled by ``roll_deg``.

        Realised as a real camera (principal point moved, rotation about the optical axis), so
        rendering, distortion and the projection matrix all stay consistent.
        """
        roll = roll_rotation(roll_deg)
        intrinsics = self.K.copy()
        intrinsics[0, 2] += dx
        intrinsics[1, 2] += dy
        return PinholeCamera(
            intrinsics, roll @ self.R, roll @ self.t, self.image_size, self.distortion
        )

"""What the model's decoder says about the cameras' view of the floor, for association and
tracking alike: which cameras should see a person at a floor position, and each camera's line of
sight there.

Its own module so that the tracker's noise model (``service.tracking.measurements``) and the
lone-view correction (``service.tracking.view_bias``) read the geometry without importing the
association, which sits before them in the chain.
"""

from __future__ import annotations

import numpy as np

from service.stages import Reprojecting

_STEP_M = 0.05  # finite-difference step of the line-of-sight direction


def covering_cameras(
    runtime: Reprojecting,
    world: np.ndarray,
    margin: float = 0.05,
    lying: np.ndarray | None = None,
) -> np.ndarray:
    """[N, K] bool: camera k should see a person at floor position ``world`` [N, 2], i.e. the
    decoder puts their body's mean point inside its image, ``margin`` (fraction of the image
    size) away from the border. For the tracker's ghost check (``Tracker(ghost_s=...)``).

    ``lying`` [N] bool: those rows are a body on the floor, judged by their floor pixel
    (:func:`floor_pixels`) instead. Why: a camera on the wall looks down across the room, and a
    standing person a metre from it shows their upper body while the floor at their feet is
    below the image; a body lying there is out of its view. In the simulated lounge the ghost
    check hid a fallen person's only track for 3.5 s because the camera beside the body
    "should" have seen them (``bench/results/falls.md``)."""
    world = np.asarray(world, dtype=np.float64).reshape(-1, 2)
    pixels = np.asarray(runtime.reproject(world), np.float64)
    if lying is not None and np.asarray(lying, bool).any():
        rows = np.asarray(lying, bool)
        pixels[rows] = floor_pixels(runtime, world[rows], pixels[rows])
    size = np.asarray(runtime.image_sizes, dtype=np.float64)[None]
    inside = (pixels >= margin * size) & (pixels <= (1.0 - margin) * size)
    return np.all(inside, axis=-1)


def floor_pixels(
    runtime: Reprojecting, world: np.ndarray, centres: np.ndarray | None = None
) -> np.ndarray:
    """Each camera's pixel [N, K, 2] of the floor point under a person at ``world`` [N, 2]: the
    bottom of a standing person's box there, half the height the model's set-up area expects
    (:meth:`models.mom.setup_area.CameraRegion.foot_row`, a fixed point: the height depends on
    the foot pixel) below the body's mean point that the decoder gives (``centres``,
    from ``runtime.reproject`` when not given; the box centre, ``models.mom.sampling.unit_mean``).
    A camera without a height model keeps the mean point."""
    world = np.asarray(world, dtype=np.float64).reshape(-1, 2)
    if centres is None:
        centres = np.asarray(runtime.reproject(world), np.float64)
    out = np.array(centres, dtype=np.float64, copy=True)
    area = getattr(runtime, "setup_area", None)
    if area is None or not len(out):
        return out
    for k, region in enumerate(area.cameras[: out.shape[1]]):
        if region is None:
            continue
        centre = out[:, k, 1]
        foot = region.foot_row(out[:, k, 0], centre, 0.5, start=centre)
        if foot is not None:
            out[:, k, 1] = foot
    return out


def line_of_sight(runtime: Reprojecting, camera: int, world: np.ndarray) -> np.ndarray | None:
    """Unit floor direction at ``world`` [2] along which camera ``camera``'s horizontal pixel
    of the person does not change (its line of sight), from the decoder; None if degenerate."""
    world = np.asarray(world, dtype=np.float64).reshape(2)
    probes = world + np.array([[0.0, 0.0], [_STEP_M, 0.0], [0.0, _STEP_M]])
    u = np.asarray(runtime.reproject(probes), dtype=np.float64)[:, camera, 0]
    gradient = np.array([u[1] - u[0], u[2] - u[0]])
    norm = float(np.linalg.norm(gradient))
    if not np.isfinite(norm) or norm < 1e-9:
        return None
    return np.array([-gradient[1], gradient[0]]) / norm

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


def covering_cameras(runtime: Reprojecting, world: np.ndarray, margin: float = 0.05) -> np.ndarray:
    """[N, K] bool: camera k should see a person at floor position ``world`` [N, 2], i.e. the
    decoder puts their body's mean point inside its image, ``margin`` (fraction of the image
    size) away from the border. For the tracker's ghost check (``Tracker(ghost_s=...)``)."""
    pixels = np.asarray(runtime.reproject(np.asarray(world, dtype=np.float64)), np.float64)
    size = np.asarray(runtime.image_sizes, dtype=np.float64)[None]
    inside = (pixels >= margin * size) & (pixels <= (1.0 - margin) * size)
    return np.all(inside, axis=-1)


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

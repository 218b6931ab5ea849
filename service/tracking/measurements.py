"""What the tracker learns from the localizer besides positions: noise and camera coverage.

:meth:`service.tracking.tracker.Tracker.update` takes, per association, the covariance of its floor
position (its measurement noise) and a ``coverage`` function (which cameras should see a person
standing at a floor position, for the ghost check). This module derives both from the loaded
model for the live pipeline (:mod:`service.pipeline.live`) and the offline runs
(:mod:`service.offline.stream_eval`), so they feed the tracker the same way.

Covariance policy, per association:

1. the model's own (``Association.covariance``: the floor prior's GLS covariance, see
   ``MomRuntime.covariance``), when finite;
2. otherwise a default per view class. Two or more cameras: isotropic ``MULTI_VIEW_STD_M``.
   One camera: ``SINGLE_VIEW_DEPTH_STD_M`` along that camera's line of sight on the floor and
   ``SINGLE_VIEW_ACROSS_STD_M`` across it; the line of sight comes from the model's decoder
   (``reproject``): moving along it leaves the person's horizontal pixel position unchanged, so
   it is the floor direction orthogonal to the gradient of that pixel coordinate. Where that
   direction is degenerate: ``None`` (the tracker's isotropic ``measurement_std_m``).

Why along / across: a lone box fixes the bearing well (its horizontal position) and the range
badly (box size and bottom edge). The constants are the measured single- and two-view errors
rounded up (an overconfident measurement locks the track); the floor prior's own covariance,
where a model has one, ranks rows well but is overconfident, and still beats these defaults on
the stream bench, so the defaults are only the fallback. Figures:
``bench/results/design_measurements.md`` (measurement noise defaults).

Rejected: an isotropic default for single views (the tracker's former 0.12 m): a single view
then pulls a track along its poorly known range as hard as across it, and a second camera
arriving is averaged with it instead of correcting it (``tests/service/test_measurements.py``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from service.stages import Association, Coverage, Reprojecting
from service.tracking.view_geometry import covering_cameras, line_of_sight

SINGLE_VIEW_DEPTH_STD_M = 0.6
SINGLE_VIEW_ACROSS_STD_M = 0.09
MULTI_VIEW_STD_M = 0.12


def measurement_covariances(
    associations: Sequence[Association], runtime: Reprojecting | None
) -> list[np.ndarray | None]:
    """Per association its position's covariance [2, 2] (m²), or ``None`` when unknown."""
    out: list[np.ndarray | None] = []
    for a in associations:
        own = a.covariance
        if own is not None and np.isfinite(own).all():
            out.append(np.asarray(own, dtype=np.float64))
        else:
            out.append(default_covariance(runtime, a.cameras, np.asarray(a.world, float)[:2]))
    return out


def default_covariance(
    runtime: Reprojecting | None, cameras: Sequence[int], world: np.ndarray
) -> np.ndarray | None:
    """The per-view-class default (module docstring) for a person seen by ``cameras``."""
    if len(cameras) >= 2:
        return np.eye(2) * MULTI_VIEW_STD_M**2
    if len(cameras) != 1 or runtime is None:
        return None
    along = line_of_sight(runtime, int(cameras[0]), world)
    if along is None:
        return None
    across = np.array([-along[1], along[0]])
    return SINGLE_VIEW_DEPTH_STD_M**2 * np.outer(along, along) + (
        SINGLE_VIEW_ACROSS_STD_M**2 * np.outer(across, across)
    )


def coverage_function(runtime: Reprojecting | None, delivered: Sequence[bool]) -> Coverage | None:
    """``floor positions [N, 2] (, lying [N]) -> [N, K] bool``: cameras that should see a person
    there and delivered a frame this time (a camera without a frame cannot be expected to
    report), from :func:`service.tracking.view_geometry.covering_cameras`; None without a
    model."""
    if runtime is None:
        return None
    mask = np.asarray(delivered, dtype=bool)[None]

    def coverage(world: np.ndarray, lying: np.ndarray | None = None) -> np.ndarray:
        return covering_cameras(runtime, world, lying=lying) & mask

    return coverage

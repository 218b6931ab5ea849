"""Self-healing: a bumped camera re-learns its floor map from the positions the others give.

When the camera-moved check (:mod:`service.camera_health`) flags camera ``m``, its floor map
(the floor prior's pixel → floor homographies, :mod:`models.geometry.floor_prior`) and its
decoder matrix no longer describe where it looks; every other camera still does. So, while ``m``
stays flagged, each moment where the *other* cameras localize a person alone in ``m``'s view
pairs that position with ``m``'s box (:func:`heal_samples`); once ``min_positions`` are in,
:func:`repair` first fits the bump as one image transform of the former model (the camera's
boxes mapped back into the image the model learned, :mod:`service.learning.bump`, served as
``model.json`` ``image_transforms``): a bump turns the camera, the room stays, so its image
moves by one homography and the former maps, encoder and decoder hold once the boxes are mapped
back; 3 unknowns (roll and shift) instead of 16 per map, so 120 positions (under a minute of
walking) bring indoor-2cam back to 1.02-1.04× of its pre-bump error, where the refit reached
1.18-1.31× from 200-400 (``bench/results/self_healing.md``). Only when no transform explains
the held-out positions (the camera was moved, not turned) are ``m``'s maps refitted on them
and its decoder matrix (a DLT of the floor onto the box's mean pixel). An earlier similarity
of the former maps' points was rejected (it left camera 1 of indoor-2cam at 0.27 m single-view
error where the refit reached 0.215 m): a rolled camera's boxes are the bounding boxes of a
rotated person, whose foot and centre points no similarity maps exactly; the transform now
maps whole boxes (:func:`models.mom.image_transform.boxes_to_model`), which un-boxes their
size.

Pairing a position with ``m``'s box: ``m``'s former map predicts where the person's feet
should be in its image; a bump of a few degrees moves them by tens of pixels, less than a box
height, so the nearest box within ``GATE_HEIGHTS`` box heights is taken when it is clearly the
nearest (the second nearest at least ``AMBIGUITY_RATIO`` times as far, and farther by
``AMBIGUITY_HEIGHTS`` box heights: else it could be either) and nobody else is within
``min_separation_m`` on the floor. The second box is judged against the nearest one's distance,
not against a fixed share of the box height: until 2026-12-05 any second box within 1.5 box
heights refused the moment, and in a real room whose cameras see the whole floor (CMC: boxes
370-680 px high) there always was one, so a bumped camera collected no position at all
(``bench/results/self_learning_cmc.md``).

Fitting to positions that are themselves uncertain: a map fitted straight to the references
takes their errors as if they were the camera's (a fit with error in the *given* variable is
biased towards a flatter map), and with two cameras those errors are large along the other
camera's line of sight. But each reference comes with its covariance, small across that line of
sight, and the moved camera's own box says where along it the person stood, once its map is
roughly right. So :func:`_refit` alternates ``REFINE_ROUNDS`` times: fuse each reference with
the moved camera's own single view under the current maps (inverse-covariance weights), then
refit the maps to the fused positions (errors-in-variables by alternation, as bundle adjustment
does with one camera known). Across the reference's line of sight the reference keeps the
fused position where it was; along it the moved camera's box, seen from another direction,
places it.

What a repair can reach, and the gate: the refitted map is only as good as the positions it was
fitted to. With four cameras those are multi-view positions (~0.1 m); with two, the unmoved
camera's single views, long along its line of sight (0.3-0.5 m std). The repair is checked on
held-out samples (every fifth) as ``m``'s own single-view position against the reference; the
expected spread is ``reachable_m = sqrt(single² + (1.18 reference)²)``, ``single`` being
``m``'s single-view error against the self-labels before the bump (the room's record of what
``m`` achieved) and ``reference`` the references' median std (1.18: the median distance of a 2D
Gaussian in per-axis stds). The repair is served when its held-out
error is within ``TOLERANCE`` of ``reachable_m``; the figure is stated in health either way.

A refitted model serves the floor geometry for every view (policy ``prior``): the encoder
read ``m``'s boxes as they were before the bump and cannot be refitted in seconds (a transform
keeps the model's policy: its encoder reads the boxes mapped back). The next
self-improvement run (:mod:`service.learning.improve`) retrains it on post-bump labels.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from common.errors import MomlocError
from models.geometry.dlt import fit_dlt
from models.geometry.floor_prior import FloorPrior
from models.mom.image_transform import apply, boxes_to_model, from_json
from models.mom.sampling import SamplerConfig, unit_mean
from service.learning.bump import DOFS
from service.learning.bump import fit as fit_bump
from service.learning.labels import LabelRules
from service.stages import FrameResult

GATE_HEIGHTS = 0.75
AMBIGUITY_RATIO = 3.0
AMBIGUITY_HEIGHTS = 0.5
REFINE_ROUNDS = 6
TOLERANCE = 1.25
HELD_OUT_EVERY = 5
MAX_REFERENCE_STD_M = 0.6
RAYLEIGH_MEDIAN = float(np.sqrt(2 * np.log(2)))  # median distance / per-axis std, 2D Gaussian


@dataclass
class HealSamples:
    """Pairs of a reference position (other cameras) and camera ``m``'s box; ``cov`` the
    references' covariances [2, 2] (empty: unknown, the maps are fitted to the positions as
    they are)."""

    t: list[float]
    world: list[np.ndarray]
    std: list[float]
    box: list[np.ndarray]
    cov: list[np.ndarray] = field(default_factory=list)

    @classmethod
    def empty(cls) -> HealSamples:
        return cls([], [], [], [], [])

    @property
    def n(self) -> int:
        return len(self.t)


def heal_samples(
    result: FrameResult,
    camera: int,
    rules: LabelRules,
    last: dict[int, float],
    into: HealSamples,
) -> int:
    """Add this frame set's pairs for moved ``camera`` to ``into``; how many were added."""
    runtime = result.runtime
    if runtime is None or runtime.floor_prior is None:
        return 0
    prior = runtime.floor_prior
    if prior.cameras[camera] is None:
        return 0
    boxes_m = np.asarray(result.detections[camera].boxes, np.float64).reshape(-1, 4)
    if not len(boxes_m) or not result.associations:
        return 0
    others = np.stack([np.asarray(a.boxes, np.float64) for a in result.associations])
    others[:, camera] = np.nan
    seen: np.ndarray = np.any(np.all(np.isfinite(others), axis=-1), axis=1)
    if not seen.any():
        return 0
    others = _model_frame(runtime.meta, others)  # another repaired camera's: as its maps saw
    xy, cov = prior.predict_covariance(np.where(seen[:, None, None], others, np.nan))
    std = np.sqrt(np.clip(np.linalg.eigvalsh(np.nan_to_num(cov))[:, -1], 0, None))
    feet = prior.reproject(np.nan_to_num(xy), "foot")[:, camera]
    former = _transform(runtime.meta, camera)
    if former is not None:  # a camera repaired before: where its current image shows the feet
        feet = apply(former, feet)
    box_feet = np.c_[(boxes_m[:, 0] + boxes_m[:, 2]) / 2, boxes_m[:, 3]]
    height = boxes_m[:, 3] - boxes_m[:, 1]
    by_association = {tr.association: tr for tr in result.tracks if tr.association is not None}
    added = 0
    for i in np.flatnonzero(seen & np.isfinite(xy).all(axis=1) & (std <= MAX_REFERENCE_STD_M)):
        track = by_association.get(int(i))
        if track is None or track.coasting or track.frame != result.snapshot.seq:
            continue
        if result.t_capture - last.get(track.id, -np.inf) < rules.min_interval_s:
            continue
        apart = np.delete(xy, i, axis=0)
        apart = apart[np.isfinite(apart).all(axis=1)]
        if len(apart) and np.linalg.norm(apart - xy[i], axis=1).min() < rules.min_separation_m:
            continue
        distance = np.linalg.norm(box_feet - feet[i], axis=1)
        order = np.argsort(distance)
        best = order[0]
        gate = GATE_HEIGHTS * height[best]
        if not distance[best] <= gate:
            continue
        clear = max(
            AMBIGUITY_RATIO * distance[best], distance[best] + AMBIGUITY_HEIGHTS * height[best]
        )
        if len(order) > 1 and distance[order[1]] < clear:
            continue
        last[track.id] = result.t_capture
        into.t.append(result.t_capture)
        into.world.append(xy[i])
        into.std.append(float(std[i]))
        into.box.append(boxes_m[best])
        into.cov.append(cov[i])
        added += 1
    return added


@dataclass(frozen=True)
class Repair:
    """A repaired ``model.json`` and its check; ``how``: ``"transform"`` (the former model with
    the camera's boxes mapped back, :mod:`service.learning.bump`) or ``"refit"`` (its maps
    refitted)."""

    meta: dict[str, Any]
    positions: int
    error_m: float
    reachable_m: float
    how: str = "refit"

    @property
    def passed(self) -> bool:
        return self.error_m <= TOLERANCE * self.reachable_m


def repair(meta: dict[str, Any], camera: int, samples: HealSamples, single_m: float) -> Repair:
    """``meta`` (a model.json) repaired for moved ``camera`` on the training share of
    ``samples`` and checked on the held-out share (module docstring).

    The first repair that passes its check, in order of unknowns: the bump as the camera's
    image rolled and shifted under the former model (3), as any homography (8)
    (:func:`_transform_repair`), its maps refitted (:func:`_refit_repair`, 16 per map). Fewer
    unknowns first, not the best on the held-out share: with two cameras the references are
    single views and a fifth of 100 of them cannot tell a homography that fits their noise
    from the roll and shift that is there (indoor-2cam, 80 positions: 0.17 m and 0.33 m on the
    dense room, the held-out check preferring the second). The homography is for a larger pan
    or tilt, the refit for a camera that was moved, not turned: the room then looks different
    from where it stands, which no image transform undoes. None passing: the one with the
    smallest held-out error (the caller collects more positions).
    """
    entry = (meta.get("floor_prior") or {}).get("prior")
    if not entry:
        raise MomlocError("the model has no floor geometry to repair")
    single_views = np.asarray(samples.std, np.float64)[_held(samples.n)]
    reference = float(np.median(single_views)) if len(single_views) else float("inf")
    reachable = round(float(np.hypot(single_m, RAYLEIGH_MEDIAN * reference)), 4)
    tried: list[Repair] = []
    if len(samples.cov) == samples.n:
        for dof in DOFS:
            try:
                tried.append(_transform_repair(meta, camera, samples, reachable, dof))
            except MomlocError:
                continue
            if tried[-1].passed:
                return tried[-1]
    tried.append(_refit_repair(meta, camera, samples, reachable))
    return tried[-1] if tried[-1].passed else min(tried, key=lambda r: r.error_m)


def _held(n: int) -> np.ndarray:
    return np.arange(n) % HELD_OUT_EVERY == HELD_OUT_EVERY - 1


def _model_frame(meta: dict[str, Any], boxes: np.ndarray) -> np.ndarray:
    """Boxes [B, K, 4] with each repaired camera's mapped back into the image its maps learned
    (as the runtime does, :meth:`models.mom.runtime.MomRuntime.to_model_frame`)."""
    out = np.array(boxes, dtype=np.float64, copy=True)
    for k in range(out.shape[1]):
        h = _transform(meta, k)
        if h is not None:
            out[:, k] = boxes_to_model(h, out[:, k])
    return out


def _transform(meta: dict[str, Any], camera: int) -> np.ndarray | None:
    """The camera's image transform in ``meta`` (None: none), read as the runtime reads it."""
    return from_json(meta.get("image_transforms"), int(meta["num_cameras"]))[camera]


def _transform_repair(
    meta: dict[str, Any], camera: int, samples: HealSamples, reachable: float, dof: int
) -> Repair:
    """The former model with ``camera``'s boxes mapped back by an image transform of ``dof``
    unknowns fitted on the training share (:mod:`service.learning.bump`)."""
    held = _held(samples.n)
    if (~held).sum() < 4 * dof:  # a few positions per unknown, or it fits their noise
        raise MomlocError(f"{samples.n} positions are too few for {dof} unknowns")
    prior = FloorPrior.from_json(meta["floor_prior"]["prior"])
    world = np.asarray(samples.world, np.float64)
    box = np.asarray(samples.box, np.float64)
    cov = np.asarray(samples.cov, np.float64)
    h = fit_bump(prior, camera, world[~held], cov[~held], box[~held], _transform(meta, camera), dof)
    error = _lone_error(prior, camera, world[held], boxes_to_model(h, box[held]))
    out = copy.deepcopy(meta)
    transforms = out.get("image_transforms") or [None] * int(meta["num_cameras"])
    transforms[camera] = h.tolist()
    out["image_transforms"] = transforms
    return Repair(out, samples.n, round(error, 4), reachable, "transform")


def _refit_repair(
    meta: dict[str, Any], camera: int, samples: HealSamples, reachable: float
) -> Repair:
    """``meta`` with camera's floor maps and decoder matrix refitted on the training share."""
    world = np.asarray(samples.world, np.float64)
    box = np.asarray(samples.box, np.float64)
    held = _held(samples.n)
    prior = FloorPrior.from_json(meta["floor_prior"]["prior"])
    decoder = np.asarray(meta["decoder"]["matrices"], np.float64)
    cov = np.asarray(samples.cov, np.float64) if len(samples.cov) == samples.n else None
    fixed, decoder[camera] = _refit(
        prior, camera, world[~held], None if cov is None else cov[~held], box[~held],
        decoder[camera], meta,
    )  # fmt: skip
    error = _lone_error(fixed, camera, world[held], box[held])
    out = copy.deepcopy(meta)
    out["floor_prior"] = {
        **out["floor_prior"],
        "policy": "prior",
        "weights": [1.0, 1.0, 1.0],
        "prior": fixed.to_json(),
        "reason": f"camera {camera} re-learned from {samples.n} positions after it moved",
    }
    out["decoder"] = {**out["decoder"], "matrices": decoder.tolist()}
    if out.get("image_transforms"):  # the refitted maps read the camera's boxes as they are
        out["image_transforms"][camera] = None
    return Repair(out, samples.n, round(error, 4), reachable, "refit")


def _lone_error(prior: FloorPrior, camera: int, world: np.ndarray, box: np.ndarray) -> float:
    """Median distance of the camera's own single-view positions from the references."""
    lone = np.full((len(world), prior.num_cameras, 4), np.nan)
    lone[:, camera] = box
    xy, _ = prior.predict(lone)
    distance = np.linalg.norm(xy - world, axis=1)
    return float(np.nanmedian(distance)) if np.isfinite(distance).any() else float("inf")


def _refit(
    prior: FloorPrior,
    camera: int,
    world: np.ndarray,
    cov: np.ndarray | None,
    box: np.ndarray,
    matrix: np.ndarray,
    meta: dict[str, Any],
) -> tuple[FloorPrior, np.ndarray]:
    """The camera's maps fitted afresh on the references (refined with their covariances
    ``cov``, module docstring), and its decoder matrix."""
    boxes = np.full((len(world), prior.num_cameras, 4), np.nan)
    boxes[:, camera] = box
    refitted = _with_camera(prior, camera, world, boxes)
    if cov is not None:
        reference_info = np.linalg.inv(cov + np.eye(2) * 1e-6)
        fused = world
        for _ in range(REFINE_ROUNDS):
            own, own_cov = refitted.predict_covariance(boxes)
            ok = np.isfinite(own).all(axis=1) & np.isfinite(own_cov).all(axis=(1, 2))
            own_info = np.linalg.inv(np.where(ok[:, None, None], own_cov, np.eye(2)))
            own_info = np.where(ok[:, None, None], own_info, 0.0)
            eta = reference_info @ world[..., None] + own_info @ np.nan_to_num(own)[..., None]
            fused = np.linalg.solve(reference_info + own_info, eta)[..., 0]
            refitted = _with_camera(prior, camera, fused, boxes)
        world = fused
    return refitted, _decoder_matrix(world, box, matrix, meta)


def _with_camera(
    prior: FloorPrior, camera: int, world: np.ndarray, boxes: np.ndarray
) -> FloorPrior:
    """``prior`` with ``camera``'s maps fitted on ``world`` and its ``boxes``."""
    fitted = FloorPrior.fit_arrays(world, boxes, prior.image_size, points="both")
    cameras = list(prior.cameras)
    cameras[camera] = fitted.cameras[camera]
    return FloorPrior(tuple(cameras), prior.image_size, prior.cut_inflation, prior.height_spread)


def _decoder_matrix(
    world: np.ndarray, box: np.ndarray, former: np.ndarray, meta: dict[str, Any]
) -> np.ndarray:
    """P̄_m [3, 4] from floor positions to the box's mean pixel (the decoder's target: the
    point ``unit_mean`` of the sampler; the box centre for the default sampler)."""
    fraction = unit_mean(SamplerConfig(**meta["sampler"]))
    pixel = box[:, :2] + (box[:, 2:] - box[:, :2]) * fraction
    h = fit_dlt(world, pixel, "decoder repair")
    matrix = np.zeros((3, 4))
    matrix[:, 0], matrix[:, 1], matrix[:, 3] = h[:, 0], h[:, 1], h[:, 2]
    scale = float(np.linalg.norm(former)) / max(float(np.linalg.norm(matrix)), 1e-12)
    return matrix * scale

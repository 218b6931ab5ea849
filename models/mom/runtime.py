"""MoM serving runtime: onnxruntime + numpy only (no torch), loaded from a model directory.

``localize`` builds the deterministic estimators (fixed draws from ``model.json``, see
:mod:`models.mom.sampling`) and runs the encoder once for the whole batch; the ONNX graph averages
the D draws and returns metres. ``reproject`` applies the decoder's P̄_k (stored in pixel units) so
association and camera-moved alerts need no torch either.

Example::

    runtime = MomRuntime.load("model/")
    xy = runtime.localize(boxes)                       # [B, K, 4] pixels, NaN = unseen
    err = runtime.reprojection_error(boxes, xy)        # [B, K] pixels
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from common.errors import MomlocError, shorten
from common.onnx_session import open_session
from common.row_memo import RowMemo
from models.geometry.floor_prior import FloorPrior
from models.mom import image_transform
from models.mom.prior_policy import POLICY_WEIGHTS, VIEW_CLASSES, blend, row_weights
from models.mom.sampling import InferenceSampler, SamplerConfig, draws_from_json, unit_mean
from models.mom.schema import validate_model_json
from models.mom.setup_area import SetupArea

if TYPE_CHECKING:
    from onnxruntime import InferenceSession

MODEL_FORMAT = "mom-model-v1"  # same literal as models.mom.training.export (which imports torch)
PROBE_JOINTS = 17  # COCO-17, what keypoint models read (models.detector.keypoints)


class MomRuntime:
    """A loaded model: encoder session, sampler, decoder matrices."""

    def __init__(self, meta: dict[str, Any], session: InferenceSession, model_dir: Path) -> None:
        self.meta = meta
        self.model_dir = model_dir
        self._session = session
        self.num_cameras = int(meta["num_cameras"])
        self.image_sizes = np.asarray(meta["image_sizes"], dtype=np.int32)
        self.observation = str(meta["observation"])
        self.sampler_config = SamplerConfig(**meta["sampler"])
        self._sampler = InferenceSampler(self.sampler_config, draws_from_json(meta["draws"]))
        self.decoder = np.asarray(meta["decoder"]["matrices"], dtype=np.float64)  # [K, 3, 4]
        prior = meta.get("floor_prior") or {}
        self.policy = str(prior.get("policy", "mom"))  # see models.mom.prior_policy
        if self.policy not in POLICY_WEIGHTS:
            raise ValueError(f"floor_prior: unknown policy {self.policy!r}")
        weights = prior.get("weights", POLICY_WEIGHTS[self.policy])
        if len(weights) != len(VIEW_CLASSES):
            raise ValueError(f"floor_prior: {len(weights)} weights, expected {len(VIEW_CLASSES)}")
        self.prior_weights = tuple(float(w) for w in weights)  # per VIEW_CLASSES
        self.floor_prior = FloorPrior.from_json(prior["prior"]) if prior.get("prior") else None
        if max(self.prior_weights) > 0 and self.floor_prior is None:
            raise ValueError(f"floor_prior: policy {self.policy!r} without a fitted prior")
        # a repaired camera's boxes are mapped back into the image the model learned (None: as
        # seen; models.mom.image_transform)
        self.image_transforms = image_transform.from_json(
            meta.get("image_transforms"), self.num_cameras
        )
        area = meta.get("setup_area")
        # where the model was set up (models.mom.setup_area); None for models trained before it
        self.setup_area = SetupArea.from_json(area) if area else None
        # Each row's position depends on that row alone (the serving draws are fixed), and the
        # chain localizes the same rows many times per frame set (common.row_memo).
        self._localized: RowMemo[np.ndarray] = RowMemo()
        bounds = meta.get("world_bounds")
        # the floor area the training positions cover ((xmin, ymin), (xmax, ymax)) metres, for
        # the map's default extent; None for models written before export stored it
        self.world_bounds: tuple[tuple[float, float], tuple[float, float]] | None = (
            None
            if bounds is None
            else (
                (float(bounds["xmin"]), float(bounds["ymin"])),
                (float(bounds["xmax"]), float(bounds["ymax"])),
            )
        )

    @classmethod
    def load(cls, model_dir: str | os.PathLike[str], threads: int = 1) -> MomRuntime:
        """Read ``model.json`` and ``encoder.onnx``; any problem raises :class:`MomlocError`.

        One non-spinning thread by default: serving batches are a handful of people, and the
        daemon shares a small CPU with the detector (see bench/results/encoder_speed.md).
        """
        model_dir = Path(model_dir)
        meta_path = model_dir / "model.json"
        shown = shorten(model_dir)
        # One answer whether the path is missing, a file or a directory without model.json: the
        # reload endpoint must not tell a caller which arbitrary paths exist. OSError covers
        # names the OS refuses (longer than 255 bytes, embedded NUL handled by ValueError).
        try:
            found = meta_path.is_file()
        except (OSError, ValueError):
            found = False
        if not found:
            raise MomlocError(f"{shown}: not a model directory (no model.json)")
        try:
            meta = json.loads(meta_path.read_text())
        except (OSError, ValueError) as error:
            problem = error.strerror if isinstance(error, OSError) else "not valid JSON"
            raise MomlocError(f"{shown}/model.json: unreadable ({problem})") from None
        schema = validate_model_json(meta, f"{shown}/model.json")
        onnx_path = model_dir / schema.encoder.file
        if not onnx_path.is_file():
            raise MomlocError(f"{shown}: encoder file {schema.encoder.file} is missing")
        session = open_session(onnx_path, threads, what="ONNX encoder")
        try:
            runtime = cls(meta, session, model_dir)
        except (KeyError, TypeError, ValueError) as error:
            raise MomlocError(
                shorten(f"{shown}/model.json: malformed model description ({error})", 300)
            ) from None
        runtime.self_test()
        return runtime

    def self_test(self) -> None:
        """Run the model once on its own cameras and observation; :class:`MomlocError` if it
        cannot serve them.

        Why: an ONNX file that loads is not an encoder that runs. Any graph in place of
        ``encoder.onnx`` (the detector's, another model's) used to load, pass the camera checks
        and then fail on every frame set it was given. A made-up person in the middle of every
        camera's image, seen by all cameras and by each alone (the shapes serving produces),
        goes through the encoder and the served path; the outputs must be one finite floor
        position per row. Costs a few milliseconds, once per load.
        """
        boxes, keypoints = self._probe()
        shown = f"{shorten(self.model_dir)}/{self.meta['encoder']['file']}"
        try:
            encoded = self.encode(boxes, keypoints)
            world = self.localize(boxes, keypoints)
            self.reprojection_error(boxes, world, keypoints)
        except Exception as error:  # onnxruntime's own errors: wrong inputs, shapes, types
            raise MomlocError(
                shorten(
                    f"{shown}: does not run as this model's encoder "
                    f"({self.num_cameras} cameras, {self.observation}): "
                    f"{type(error).__name__}: {error}",
                    300,
                )
            ) from None
        for name, out in (("encoder", encoded), ("model", world)):
            if np.shape(out) != (len(boxes), 2) or not np.isfinite(out).all():
                raise MomlocError(
                    f"{shown}: the {name} gives {np.shape(out)} values with NaN or infinity "
                    f"for {len(boxes)} people in view, not one floor position each"
                )

    def _probe(self) -> tuple[np.ndarray, np.ndarray | None]:
        """Boxes [K+1, K, 4] (all cameras, then each alone) of a standing person in the middle
        of each image, and keypoints [K+1, K, 17, 3] from the head to the feet down its middle."""
        k = self.num_cameras
        w, h = self.image_sizes[:, 0].astype(np.float32), self.image_sizes[:, 1].astype(np.float32)
        box = np.stack([w / 2 - h / 16, h / 3, w / 2 + h / 16, h * 2 / 3], axis=1)  # [K, 4]
        seen = np.vstack([np.ones((1, k), bool), np.eye(k, dtype=bool)])  # [K+1, K]
        boxes = np.where(seen[..., None], box[None], np.nan).astype(np.float32)
        if self.observation != "keypoints":
            return boxes, None
        joints = np.linspace(0.0, 1.0, PROBE_JOINTS, dtype=np.float32)  # top to bottom
        x = np.broadcast_to(((box[:, 0] + box[:, 2]) / 2)[:, None], (k, PROBE_JOINTS))
        y = box[:, 1:2] + joints[None] * (box[:, 3:4] - box[:, 1:2])
        keypoints = np.stack([x, y, np.ones_like(y)], axis=-1)  # [K, J, 3]
        keypoints = np.where(seen[..., None, None], keypoints[None], np.nan)
        return boxes, keypoints.astype(np.float32)

    # ------------------------------------------------------------------ checks
    def _check_boxes(self, boxes: np.ndarray) -> np.ndarray:
        boxes = np.asarray(boxes, dtype=np.float32)
        if boxes.ndim == 2:
            boxes = boxes[None]
        if boxes.ndim != 3 or boxes.shape[2] != 4:
            raise MomlocError(f"boxes: shape {boxes.shape} is not [B, K, 4]")
        if boxes.shape[1] != self.num_cameras:
            raise MomlocError(
                f"boxes have {boxes.shape[1]} cameras but the model was trained for "
                f"{self.num_cameras} ({self.model_dir})"
            )
        return boxes

    def encoder_inputs(
        self, boxes: np.ndarray, keypoints: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The exact ONNX inputs: estimators [B, D, K, E, 2] and mask [B, K]."""
        boxes, keypoints = self.to_model_frame(boxes, keypoints)
        return self._encoder_inputs(boxes, keypoints)

    def to_model_frame(
        self, boxes: np.ndarray, keypoints: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Boxes [B, K, 4] (and keypoints [B, K, J, 3]) as the model's cameras saw them when it
        learned: each repaired camera's mapped by its ``image_transforms`` entry (module
        :mod:`models.mom.image_transform`); unchanged for cameras without one."""
        boxes = self._check_boxes(boxes)
        if all(h is None for h in self.image_transforms):
            return boxes, keypoints
        boxes = boxes.copy()
        kp = None if keypoints is None else np.array(keypoints, dtype=np.float32, copy=True)
        if kp is not None and kp.ndim == 3:
            kp = kp[None]
        for k, h in enumerate(self.image_transforms):
            if h is None:
                continue
            boxes[:, k] = image_transform.boxes_to_model(h, boxes[:, k])
            if kp is not None and kp.ndim == 4:  # a wrong shape is encoder_inputs' to report
                kp[:, k] = image_transform.keypoints_to_model(h, kp[:, k])
        return boxes, kp

    def _encoder_inputs(
        self, boxes: np.ndarray, keypoints: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        if self.observation == "keypoints":
            if keypoints is None:
                raise MomlocError("this model uses keypoints: pass keypoints [B, K, J, 3]")
            keypoints = np.asarray(keypoints, dtype=np.float32)
            if keypoints.ndim == 3:
                keypoints = keypoints[None]
            if keypoints.shape[:2] != boxes.shape[:2] or keypoints.shape[-1] != 3:
                raise MomlocError(f"keypoints: shape {keypoints.shape} is not [B, K, J, 3]")
        return self._sampler(boxes, self.image_sizes, keypoints)

    # ------------------------------------------------------------------ API
    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        """Floor positions [B, 2] in metres; NaN for a row no camera sees.

        The model's policy (:mod:`models.mom.prior_policy`) weighs the floor-mark geometry against
        the encoder per row: all geometry for a model trained on marks, a blend chosen on
        validation rows for dense labels; the encoder alone where no fitted camera sees the row.
        A row the geometry puts outside the set-up area (:mod:`models.mom.setup_area`) takes the
        geometry's position whatever the policy: the encoder never saw such a row in training
        and maps it into its training area.
        """
        boxes, keypoints = self.to_model_frame(boxes, keypoints)
        if len(boxes) == 0:
            return np.zeros((0, 2), dtype=np.float32)
        kp = None if keypoints is None else np.asarray(keypoints, dtype=np.float32)
        keys = [
            row.tobytes() if kp is None else row.tobytes() + kp[i].tobytes()
            for i, row in enumerate(boxes)
        ]

        def compute(rows: list[int]) -> list[np.ndarray]:
            return list(self._localize_rows(boxes[rows], None if kp is None else kp[rows]))

        return np.stack(self._localized.rows(keys, compute)).astype(np.float32)

    def _localize_rows(self, boxes: np.ndarray, keypoints: np.ndarray | None) -> np.ndarray:
        if self.floor_prior is None or (self.setup_area is None and max(self.prior_weights) == 0):
            return self._encode(boxes, keypoints)  # no geometry to serve: not computed
        prior_keypoints = keypoints if self.observation == "keypoints" else None
        prior_xy, _ = self.floor_prior.predict(boxes, prior_keypoints)
        weight = self._served_weights(boxes, prior_xy)
        if weight.max(initial=0.0) == 0.0:
            return self._encode(boxes, keypoints)
        need = ~np.isfinite(prior_xy).all(axis=1) | (weight < 1.0)
        encoder_xy = np.full_like(prior_xy, np.nan)
        if need.any():
            encoder_xy[need] = self._encode(
                boxes[need], None if keypoints is None else np.asarray(keypoints)[need]
            )
        return blend(encoder_xy, prior_xy, weight).astype(np.float32)

    def _served_weights(self, boxes: np.ndarray, prior_xy: np.ndarray) -> np.ndarray:
        """The floor geometry's weight [B] per row: the policy's, 1 beyond the set-up area."""
        weight = row_weights(boxes, self.prior_weights)
        if self.setup_area is None:
            return weight
        beyond = np.isfinite(prior_xy).all(axis=1) & ~self.setup_area.contains(prior_xy)
        return np.where(beyond, 1.0, weight)

    def floor_views(
        self, boxes: np.ndarray, keypoints: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """Each camera's own floor estimate [B, K, 2] of the rows and its information [B, K, 2,
        2] from the floor geometry (:meth:`FloorPrior.views`); None without a fitted prior."""
        if self.floor_prior is None:
            return None
        boxes, keypoints = self.to_model_frame(boxes, keypoints)
        prior_keypoints = keypoints if self.observation == "keypoints" else None
        return self.floor_prior.views(boxes, prior_keypoints)

    def inside(self, boxes: np.ndarray, world: np.ndarray) -> np.ndarray:
        """[B] bool: the rows' positions [B, 2] lie in the set-up area and some box [B, K, 4]
        where its camera saw training boxes (:class:`~models.mom.setup_area.SetupArea`); all True
        for a model without an area."""
        boxes, _ = self.to_model_frame(boxes)
        if self.setup_area is None:
            return np.ones(len(boxes), dtype=bool)
        return self.setup_area.contains(world) & self.setup_area.boxes_in_region(boxes)

    def covariance(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        """Covariance [B, 2, 2] (m²) of :meth:`localize`'s positions; NaN where unknown.

        The floor prior's GLS covariance per row (long along a lone camera's line of sight),
        scaled for the share of the encoder in the served blend by the ratio of the encoder's to
        the prior's validation error (``model.json`` ``floor_prior.validation``; 1 when not
        measured): ``(w + (1 - w) ρ)²`` for prior weight ``w``, i.e. the two localizers' errors
        taken as fully correlated (they read the same boxes). NaN without a fitted prior or
        where it sees nothing (the tracker then uses its own default).
        """
        boxes, keypoints = self.to_model_frame(boxes, keypoints)
        if self.floor_prior is None:
            return np.full((len(boxes), 2, 2), np.nan)
        prior_keypoints = keypoints if self.observation == "keypoints" else None
        prior_xy, cov = self.floor_prior.predict_covariance(boxes, prior_keypoints)
        weight = self._served_weights(boxes, prior_xy)
        scale = weight + (1.0 - weight) * self.encoder_error_ratio
        return cov * (scale**2)[:, None, None]

    @property
    def encoder_error_ratio(self) -> float:
        """Encoder / prior mean validation error (1.0 when the training did not measure it)."""
        validation = (self.meta.get("floor_prior") or {}).get("validation") or {}
        encoder, prior = validation.get("encoder_mean_m"), validation.get("prior_mean_m")
        return float(encoder) / float(prior) if encoder and prior else 1.0

    def encode(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        """The MoM encoder's floor positions [B, 2] (the D draws averaged in the graph)."""
        return self._encode(*self.to_model_frame(boxes, keypoints))

    def _encode(self, boxes: np.ndarray, keypoints: np.ndarray | None) -> np.ndarray:
        estimators, mask = self._encoder_inputs(boxes, keypoints)
        if len(mask) == 0:
            return np.zeros((0, 2), dtype=np.float32)
        (world,) = self._session.run(None, {"estimators": estimators, "mask": mask})
        world[mask.sum(axis=1) == 0] = np.nan
        return world

    def reproject(self, world: np.ndarray) -> np.ndarray:
        """Pixels [B, K, 2] of the body's mean point for floor positions [B, 2] (decoder P̄_k),
        in each camera's current image (after its ``image_transforms`` entry)."""
        world = np.asarray(world, dtype=np.float64).reshape(-1, 2)
        # On the floor (z = 0): P (x, y, 0, 1) = P[:, :2] (x, y) + P[:, 3]. Called thousands of
        # times a second on a few points, so no homogeneous array is built.
        projected = np.einsum("kij,bj->bki", self.decoder[:, :, :2], world) + self.decoder[:, :, 3]
        denominator = projected[..., 2:]
        denominator = np.where(np.abs(denominator) < 1e-9, 1e-9, denominator)
        pixels = projected[..., :2] / denominator
        for k, h in enumerate(self.image_transforms):
            if h is not None:  # where the repaired camera now sees that point
                pixels[:, k] = image_transform.apply(h, pixels[:, k])
        return pixels.astype(np.float32)

    def observed_pixels(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        """Mean pixel per camera [B, K, 2] that the decoder predicts (NaN where unseen)."""
        boxes = self._check_boxes(boxes)
        if self.observation == "bbox":
            return boxes[..., :2] + (boxes[..., 2:] - boxes[..., :2]) * unit_mean(
                self.sampler_config
            ).astype(np.float32)
        from models.mom.sampling import keypoint_visible

        if keypoints is None:
            raise MomlocError("this model uses keypoints: pass keypoints [B, K, J, 3]")
        kp = np.asarray(keypoints, dtype=np.float32)
        vis = keypoint_visible(kp)
        total = np.where(vis[..., None], kp[..., :2], 0.0).sum(axis=-2)
        mean = total / np.maximum(vis.sum(axis=-1, keepdims=True), 1)
        return np.where(np.any(vis, axis=-1)[..., None], mean, np.nan).astype(np.float32)

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray:
        """Pixel distance [B, K] between each camera's observation and the reprojected world
        point; NaN where the camera does not see the person."""
        observed = self.observed_pixels(boxes, keypoints)
        return np.linalg.norm(self.reproject(world) - observed, axis=-1)

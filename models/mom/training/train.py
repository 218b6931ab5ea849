"""Train a MoM model on a dataset file and write the model directory.

Design decisions (ARCHITECTURE.md "measured findings" and our own measurements, see the report in
``bench/results``):

* **Split without leakage.** Each track is cut into runs of consecutive frames; whole runs go to
  validation (~15 % of rows), so no validation row has a near-duplicate neighbour frame in the
  training set except at run borders. A single-track recording still gets a validation set.
* **Fresh estimators every epoch** (the paper's "billions of pairs"), deterministic estimators for
  validation: exactly what serving computes (fixed draws, averaged).
* **Train long, stop early.** The epoch cap scales with the data (small sets get more epochs), the
  learning rate halves on plateaus and training stops when the validation error (metres) has not
  improved for a while; the best epoch's weights are kept.
* **Stable decoder.** P̄_k initialised by least squares, λ ramped over the first 10 % of epochs,
  perspective denominator clamped, gradients clipped.
* **Sizes adapt to the data**, never to a preset: widths grow with the number of cameras and rows.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import torch
from tqdm import tqdm

from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.mom.prior_policy import POLICIES, choose_policy, summary
from models.mom.sampling import (
    InferenceSampler,
    SamplerConfig,
    observation_center,
    observation_mask,
    sample_estimators,
)
from models.mom.setup_area import SetupArea
from models.mom.training.export import world_bounds, write_model_dir
from models.mom.training.torch_model import MomDecoder, MomEncoder, initial_decoder_matrix

MIN_ROWS = 50
VALIDATION_DRAWS = 4  # draws averaged for the per-epoch validation (as serving does)


@dataclass(frozen=True)
class TrainSettings:
    """Sizes and schedule; :func:`adaptive_settings` derives them from the data."""

    camera_width: int
    global_width: int
    batch_size: int
    max_epochs: int
    patience: int
    learning_rate: float = 2e-3
    weight_decay: float = 0.0
    rec_weight: float = 0.1  # λ (0 disables the decoder's pull on the encoder)
    view_dropout: float = 0.15
    grad_clip: float = 1.0
    time_budget_s: float | None = 540.0  # safety net of the adaptive schedule (not with --epochs)
    val_fraction: float = 0.15


def adaptive_settings(n_train: int, num_cameras: int, epochs: int | None = None) -> TrainSettings:
    """Sizes from the data: wider with more cameras and rows, more epochs for small sets."""
    # measured on indoor-2cam (bench/results/mom_sweep.md): 32/64 matches 64/128 and 128/256 within
    # 3 mm at a quarter of the cost; the global layer grows with the number of camera streams
    camera_width = 32
    global_width = int(np.clip(16 * num_cameras + 32, 64, 192))
    batch_size = int(np.clip(2 ** round(math.log2(max(n_train, 1) / 32)), 64, 1024))
    # a budget of ~5 million training rows (fresh estimators each), between 60 and 400 epochs:
    # 20 000 instances get up to ~300 epochs, a few minutes on one core
    max_epochs = int(np.clip(5_000_000 // max(n_train, 1), 60, 400)) if epochs is None else epochs
    patience = max(15, max_epochs // 4)  # validation error keeps creeping down for a long time
    budget = 540.0 if epochs is None else None
    return TrainSettings(
        camera_width, global_width, batch_size, max_epochs, patience, time_budget_s=budget
    )


def split_rows(data: MomDataset, val_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Train/validation rows: whole runs of consecutive frames of one track go to one side."""
    order = np.lexsort((data.frame, data.track))
    track, frame = data.track[order], data.frame[order]
    # a new run starts at a new track or every ~1/40 of a track's rows (at least 10 frames)
    run_length = max(10, data.n // 40)
    new_track = np.r_[True, track[1:] != track[:-1]]
    position = np.arange(data.n) - np.maximum.accumulate(np.where(new_track, np.arange(data.n), 0))
    run_id = np.cumsum(new_track | (position % run_length == 0)) - 1
    del frame
    runs = np.unique(run_id)
    rng = np.random.default_rng(seed)
    chosen = rng.permutation(runs)
    sizes = np.bincount(run_id)
    cumulative = np.cumsum(sizes[chosen])
    n_val_runs = max(1, int(np.searchsorted(cumulative, val_fraction * data.n)) + 1)
    n_val_runs = min(n_val_runs, len(runs) - 1)
    is_val = np.isin(run_id, chosen[:n_val_runs])
    return np.sort(order[~is_val]), np.sort(order[is_val])


def _check(data: MomDataset, observation: str) -> None:
    if observation == "keypoints" and data.keypoints is None:
        raise MomlocError("dataset has no 'keypoints': cannot train in keypoint observation mode")
    if data.n < MIN_ROWS:
        raise MomlocError(f"dataset has {data.n} rows; training needs at least {MIN_ROWS}")


class _Trainer:
    """Holds one training run's data, model and optimiser."""

    def __init__(
        self,
        data: MomDataset,
        sampler: SamplerConfig,
        decoder: bool,
        settings: TrainSettings,
        seed: int,
        train_rows: np.ndarray,
        val_rows: np.ndarray,
    ) -> None:
        self.data, self.settings, self.decoder_on = data, settings, decoder
        self.sampler = sampler
        self.rng = np.random.default_rng(seed)
        world = data.world[train_rows, :2].astype(np.float64)
        self.centre = world.mean(axis=0)
        self.scale = float(np.sqrt(((world - self.centre) ** 2).sum(axis=1).mean())) or 1.0
        kp = data.keypoints
        self.mask = observation_mask(self.sampler, data.boxes, kp)
        seen = self.mask.sum(axis=1) > 0  # a row no camera observes teaches nothing
        self.train, self.val = train_rows[seen[train_rows]], val_rows[seen[val_rows]]
        if len(self.train) == 0 or len(self.val) == 0:
            raise MomlocError("dataset: no row is observed by any camera in this observation mode")
        self.target = ((data.world[:, :2] - self.centre) / self.scale).astype(np.float32)
        self.pix = observation_center(self.sampler, data.boxes, data.image_size, kp)
        k = data.num_cameras
        self.encoder = MomEncoder(
            k, self.sampler.rows, settings.camera_width, settings.global_width
        )
        self.decoder = MomDecoder(self._initial_matrices(train_rows))
        params = [*self.encoder.parameters(), *self.decoder.parameters()]
        self.optim = torch.optim.Adam(params, lr=settings.learning_rate)
        self.plateau = torch.optim.lr_scheduler.ReduceLROnPlateau(
            self.optim, factor=0.5, patience=max(3, settings.patience // 3)
        )
        val_config = SamplerConfig(**{**sampler.to_dict(), "draws": VALIDATION_DRAWS})
        self.val_inputs = InferenceSampler(val_config)(
            data.boxes[self.val], data.image_size, None if kp is None else kp[self.val]
        )

    def _initial_matrices(self, rows: np.ndarray) -> np.ndarray:
        matrices = []
        for k in range(self.data.num_cameras):
            seen = rows[self.mask[rows, k] > 0]
            if len(seen) < 3:
                matrices.append(np.array([[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1.0]]))
                continue
            matrices.append(initial_decoder_matrix(self.target[seen], self.pix[seen, k]))
        return np.stack(matrices).astype(np.float32)

    def epoch(self, index: int) -> float:
        s = self.settings
        rows = self.rng.permutation(self.train)
        est, mask = self._sample(rows)
        mask = mask * self._view_dropout(mask)
        est_t, mask_t = torch.from_numpy(est), torch.from_numpy(mask)
        target, pix = torch.from_numpy(self.target[rows]), torch.from_numpy(self.pix[rows])
        ramp = min(1.0, (index + 1) / max(1, 0.1 * s.max_epochs))
        rec_weight = s.rec_weight * ramp
        self.encoder.train()
        total = 0.0
        for start in range(0, len(rows), s.batch_size):
            sl = slice(start, start + s.batch_size)
            pred = self.encoder(est_t[sl] * mask_t[sl, :, None, None], mask_t[sl])
            loss_loc = (pred - target[sl]).norm(dim=1).mean()
            decoded = self.decoder(pred if self.decoder_on else pred.detach())
            err = (decoded - pix[sl]).norm(dim=2) * mask_t[sl]
            loss_rec = err.sum(dim=1).mean()
            loss = loss_loc + (rec_weight if self.decoder_on else 1.0) * loss_rec
            self.optim.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(self.encoder.parameters(), s.grad_clip)
            torch.nn.utils.clip_grad_norm_(self.decoder.parameters(), s.grad_clip)
            self.optim.step()
            total += float(loss_loc.detach()) * len(target[sl])
        return total / len(rows)

    def _sample(self, rows: np.ndarray, chunk: int = 8192) -> tuple[np.ndarray, np.ndarray]:
        """Fresh estimators for ``rows``, built in chunks to bound the sampler's memory."""
        parts = []
        for start in range(0, len(rows), chunk):
            part = rows[start : start + chunk]
            kp = None if self.data.keypoints is None else self.data.keypoints[part]
            parts.append(
                sample_estimators(
                    self.sampler, self.data.boxes[part], self.data.image_size, self.rng, kp
                )
            )
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def _view_dropout(self, mask: np.ndarray) -> np.ndarray:
        """Hide visible cameras at random, always keeping at least one visible."""
        if self.data.num_cameras == 1 or self.settings.view_dropout <= 0:
            return np.ones_like(mask)
        keep = (self.rng.random(mask.shape) >= self.settings.view_dropout).astype(np.float32)
        none_left = (mask * keep).sum(axis=1) == 0
        keep[none_left] = 1.0
        return keep

    @torch.no_grad()
    def validate(self) -> np.ndarray:
        """Validation errors in metres with deterministic, draw-averaged estimators (rows some
        camera sees)."""
        est, mask = self.val_inputs
        pred = self.predict(est, mask)
        ok = mask.sum(axis=1) > 0
        truth = self.data.world[self.val, :2]
        return np.linalg.norm(pred[ok] - truth[ok], axis=1)

    @torch.no_grad()
    def predict(self, est: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """Metres [B, 2] from inference estimators [B, D, K, E, 2]."""
        self.encoder.eval()
        b, d = est.shape[:2]
        flat = torch.from_numpy(est.reshape(b * d, *est.shape[2:]))
        masks = torch.from_numpy(np.repeat(mask, d, axis=0))
        out = self.encoder(flat, masks).numpy().reshape(b, d, 2).mean(axis=1)
        return out * self.scale + self.centre

    def state(self) -> dict:
        return {
            "encoder": {k: v.clone() for k, v in self.encoder.state_dict().items()},
            "decoder": {k: v.clone() for k, v in self.decoder.state_dict().items()},
        }

    def load(self, state: dict) -> None:
        self.encoder.load_state_dict(state["encoder"])
        self.decoder.load_state_dict(state["decoder"])


def train_model(
    dataset: MomDataset,
    out_dir: str | Path,
    *,
    observation: str = "bbox",
    decoder: bool = True,
    epochs: int | None = None,
    seed: int = 0,
    progress: bool = True,
    tuning: dict | None = None,
    extra_meta: dict[str, Any] | None = None,
    on_epoch: Callable[[int, int, float, float], None] | None = None,
    policy: str = "auto",
) -> dict:
    """Train on ``dataset``, write ``out_dir`` (encoder.onnx, model.pt, model.json); metrics.

    ``policy``: which localizer the model serves, ``"auto"`` (chosen from the rows) or
    ``"prior"`` (the floor geometry: rows whose positions a model produced,
    :func:`models.mom.prior_policy.choose_policy`).

    ``tuning`` overrides TrainSettings / SamplerConfig fields (for measurements and sweeps);
    ``extra_meta`` adds top-level entries to ``model.json`` in its one write;
    ``on_epoch(epoch, max_epochs, val_error_m, val_median_m)`` after each epoch (the web set-up's
    progress): the validation mean (what early stopping watches) and median (what the set-up
    page shows: a recording's rows whose only box is a detector's false box are metres off, and
    they set the mean, not what the served model does on the floor marks).
    """
    tuning = dict(tuning or {})
    sampler_keys = set(SamplerConfig.__dataclass_fields__) - {"observation"}
    sampler = SamplerConfig(
        observation=observation, **{k: tuning.pop(k) for k in list(tuning) if k in sampler_keys}
    )
    _check(dataset, sampler.observation)
    unknown = set(tuning) - set(TrainSettings.__dataclass_fields__)
    if unknown:
        raise MomlocError(f"tuning: unknown settings {sorted(unknown)}")
    if epochs is not None and epochs < 1:
        raise MomlocError(f"--epochs {epochs}: must be at least 1")
    if policy not in POLICIES:
        raise MomlocError(f"--policy {policy}: choose one of {', '.join(POLICIES)}")
    threads = torch.get_num_threads()
    # One thread: these small MLPs gain nothing from a second one, and on a busy 2-core machine
    # two spinning threads were measured 10x slower (147 s vs 13 s for the same 15 epochs).
    torch.set_num_threads(1)
    try:
        return _train(
            dataset,
            Path(out_dir),
            sampler,
            decoder,
            epochs,
            seed,
            progress,
            tuning,
            extra_meta,
            on_epoch,
            policy,
        )
    finally:
        torch.set_num_threads(threads)


def _train(
    dataset: MomDataset,
    out_dir: Path,
    sampler: SamplerConfig,
    decoder: bool,
    epochs: int | None,
    seed: int,
    progress: bool,
    tuning: dict[str, Any],
    extra_meta: dict[str, Any] | None,
    on_epoch: Callable[[int, int, float, float], None] | None,
    policy: str,
) -> dict:
    torch.manual_seed(seed)
    started = time.monotonic()
    probe = adaptive_settings(dataset.n, dataset.num_cameras, epochs)
    train_rows, val_rows = split_rows(dataset, probe.val_fraction, seed)
    settings = adaptive_settings(len(train_rows), dataset.num_cameras, epochs)
    settings = TrainSettings(**{**asdict(settings), **tuning})
    if not decoder:
        settings = TrainSettings(**{**asdict(settings), "rec_weight": 0.0})
    trainer = _Trainer(dataset, sampler, decoder, settings, seed, train_rows, val_rows)

    best, best_epoch, best_state, history = math.inf, 0, trainer.state(), []
    stop = "max_epochs"
    bar = _progress(settings.max_epochs, progress)
    for index in range(settings.max_epochs):
        trainer.epoch(index)
        errors = trainer.validate()
        error = float(errors.mean())
        trainer.plateau.step(error)
        history.append(round(error, 5))
        if error < best:
            best, best_epoch, best_state = error, index, trainer.state()
        bar.set_postfix_str(f"val {error:.3f} m (best {best:.3f} m @ {best_epoch + 1})")
        bar.update(1)
        if on_epoch is not None:
            on_epoch(index + 1, settings.max_epochs, error, float(np.median(errors)))
        if index - best_epoch >= settings.patience:
            stop = "early_stopping"
            break
        if settings.time_budget_s and time.monotonic() - started > settings.time_budget_s:
            stop = "time_budget"
            break
    bar.close()
    trainer.load(best_state)
    metrics, val_xy = _final_metrics(trainer, dataset, val_rows)
    metrics.update(
        epochs_run=len(history),
        best_epoch=best_epoch + 1,
        stopped_by=stop,
        train_rows=len(train_rows),
        val_rows=len(val_rows),
        seconds=round(time.monotonic() - started, 1),
        val_history=history,
    )
    floor_prior, _ = choose_policy(dataset, sampler.observation, val_rows, val_xy, policy)
    write_model_dir(
        out_dir,
        encoder=trainer.encoder,
        decoder_matrices=trainer.decoder.matrices.detach().numpy().astype(np.float64),
        sampler=trainer.sampler,
        image_sizes=dataset.image_size,
        centre=trainer.centre,
        scale=trainer.scale,
        checkpoint={
            **best_state,
            "settings": asdict(settings),
            "seed": seed,
            "centre": [float(c) for c in trainer.centre],  # plain types: weights_only loads
            "scale": trainer.scale,
            "sampler": trainer.sampler.to_dict(),
        },
        metrics=metrics,
        settings={**asdict(settings), "decoder": decoder, "seed": seed},
        floor_prior=floor_prior,
        extra=extra_meta,
        world_bounds=world_bounds(dataset.world),
        setup_area=SetupArea.fit(dataset.world, dataset.boxes).to_json(),
    )
    metrics["floor_prior"] = summary(floor_prior)
    return metrics


def _final_metrics(
    trainer: _Trainer, data: MomDataset, val_rows: np.ndarray
) -> tuple[dict, np.ndarray]:
    """The encoder's validation metrics, and its positions [V, 2] (NaN for unseen rows)."""
    kp = None if data.keypoints is None else data.keypoints[val_rows]
    est, mask = InferenceSampler(trainer.sampler)(data.boxes[val_rows], data.image_size, kp)
    pred = trainer.predict(est, mask)
    ok = mask.sum(axis=1) > 0
    err = np.linalg.norm(pred[ok] - data.world[val_rows, :2][ok], axis=1)
    metrics = {
        "val_mean_m": round(float(err.mean()), 4),
        "val_median_m": round(float(np.median(err)), 4),
        "val_acc@0.3": round(float((err <= 0.3).mean() * 100), 2),
        "val_acc@0.5": round(float((err <= 0.5).mean() * 100), 2),
    }
    return metrics, np.where(ok[:, None], pred, np.nan)


def _progress(total: int, enabled: bool) -> tqdm[NoReturn]:
    return tqdm(total=total, desc="momloc train", unit="epoch", disable=not enabled, leave=True)

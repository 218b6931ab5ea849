"""A plain MLP on box coordinates: the "is MoM's sampling worth it?" control for the benchmark.

Same information as MoM + bbox (each camera's box, normalised by image size, plus a visibility
flag; zeros where unseen), same kind of train/validation split by track runs, early stopping on
validation error, but no mean estimators and no decoder. ARCHITECTURE.md's findings say such an
MLP ends within ~5 mm of MoM on real data; this measures it on the simulator. Benchmark-only
(imports torch), not part of the product.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from models.data.dataset import MomDataset


def features(data: MomDataset) -> np.ndarray:
    """[N, 5K]: per camera (xmin, ymin, xmax, ymax) mapped to [-1, 1] and a seen flag."""
    size = np.repeat(data.image_size.astype(np.float32), 2, axis=1)  # [K, 4] w h w h
    seen = data.visible()
    boxes = np.where(seen[..., None], 2 * data.boxes / size - 1, 0.0)
    return np.concatenate([boxes, seen[..., None]], axis=-1).reshape(data.n, -1).astype(np.float32)


def _split(data: MomDataset, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """Validation mask: whole runs of 64 consecutive frames of a track (no neighbour leakage)."""
    runs = data.track * 1_000_000 + data.frame // 64
    keys = np.unique(runs)
    chosen = rng.choice(keys, size=max(1, int(len(keys) * fraction)), replace=False)
    return np.isin(runs, chosen)


class BoxMlp:
    """Train with :meth:`fit`, predict floor positions [N, 2] in metres with :meth:`predict`."""

    def __init__(self, width: int = 256, seed: int = 0) -> None:
        self.width, self.seed = width, seed
        self.net: nn.Module | None = None

    def fit(self, data: MomDataset, max_epochs: int = 200, patience: int = 20) -> dict:
        torch.manual_seed(self.seed)
        rng = np.random.default_rng(self.seed)
        x = torch.from_numpy(features(data))
        world = data.world[:, :2].astype(np.float64)
        self.centre = world.mean(axis=0)
        self.scale = float(world.std()) or 1.0
        y = torch.from_numpy(((world - self.centre) / self.scale).astype(np.float32))
        val = torch.from_numpy(_split(data, 0.15, rng))
        xt, yt, xv, yv = x[~val], y[~val], x[val], y[val]
        self.net = nn.Sequential(
            nn.Linear(x.shape[1], self.width),
            nn.ReLU(),
            nn.Linear(self.width, self.width),
            nn.ReLU(),
            nn.Linear(self.width, self.width),
            nn.ReLU(),
            nn.Linear(self.width, 2),
        )
        optimiser = torch.optim.Adam(self.net.parameters(), lr=2e-3)
        batch = int(np.clip(len(xt) // 16, 128, 1024))
        best, best_epoch, best_state = np.inf, 0, None
        for epoch in range(max_epochs):
            self.net.train()
            for rows in torch.randperm(len(xt)).split(batch):
                optimiser.zero_grad()
                loss = (self.net(xt[rows]) - yt[rows]).norm(dim=1).mean()
                loss.backward()
                optimiser.step()
            self.net.eval()
            with torch.no_grad():
                error = float((self.net(xv) - yv).norm(dim=1).mean()) * self.scale
            if error < best:
                best, best_epoch = error, epoch
                best_state = {k: v.clone() for k, v in self.net.state_dict().items()}
            if epoch - best_epoch >= patience:
                break
        self.net.load_state_dict(best_state)
        return {"val_mean_m": best, "epochs_run": epoch + 1}

    def predict(self, data: MomDataset) -> np.ndarray:
        assert self.net is not None, "fit first"
        with torch.no_grad():
            out = self.net(torch.from_numpy(features(data))).numpy().astype(np.float64)
        return out * self.scale + self.centre

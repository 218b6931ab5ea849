"""The MoM autoencoder in PyTorch (training only; serving runs the exported ONNX encoder).

Encoder (paper Eq. 10): one MLP_k per camera maps its ``[E, 2]`` mean estimators to features;
features are gated by the camera's visibility mask (an unseen camera contributes exactly zero) and
concatenated with the mask itself, so the global MLP knows which views it has; the global MLP
predicts the normalised floor position. View dropout during training hides random visible cameras
so a person seen by only some cameras still gets a position.

Decoder (paper Eq. 13): one learned 3×4 matrix P̄_k per camera maps the predicted homogeneous world
point ``(x, y, 0, 1)`` to camera k's mean pixel. Targets are on the floor (z = 0), so the third
column never receives a gradient: P̄_k acts as a floor→image homography of the body's mean point.
Stabilised as ARCHITECTURE.md measured: each P̄_k starts from a least-squares (DLT) fit of the
training pairs (no calibration), and the perspective denominator is clamped away from zero.

All tensors here are in normalised units: world ``(Y - centre) / scale``, pixels ``2 p / size - 1``.
"""

from __future__ import annotations

import itertools

import numpy as np
import torch
from torch import nn

from common.errors import MomlocError
from models.geometry.dlt import fit_dlt

DENOMINATOR_FLOOR = 0.05


def mlp(sizes: list[int], last_activation: bool) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(itertools.pairwise(sizes)):
        layers.append(nn.Linear(a, b))
        if last_activation or i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class MomEncoder(nn.Module):
    """k-stream MLP: estimators [B, K, E, 2] + mask [B, K] → normalised world [B, 2]."""

    def __init__(
        self, num_cameras: int, num_estimators: int, camera_width: int, global_width: int
    ) -> None:
        super().__init__()
        self.num_cameras = num_cameras
        self.streams = nn.ModuleList(
            mlp([num_estimators * 2, camera_width, camera_width], last_activation=True)
            for _ in range(num_cameras)
        )
        self.head = mlp(
            [num_cameras * (camera_width + 1), global_width, global_width, 2],
            last_activation=False,
        )

    def forward(self, estimators: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        flat = estimators.flatten(start_dim=2)  # [B, K, 2E]
        features = [
            stream(flat[:, k]) * mask[:, k : k + 1] for k, stream in enumerate(self.streams)
        ]
        return self.head(torch.cat([*features, mask], dim=1))


class MomDecoder(nn.Module):
    """Per-camera P̄_k [K, 3, 4]: normalised world [B, 2] → normalised mean pixel [B, K, 2]."""

    def __init__(self, initial: np.ndarray) -> None:
        super().__init__()
        self.matrices = nn.Parameter(torch.as_tensor(initial, dtype=torch.float32))

    def forward(self, world: torch.Tensor) -> torch.Tensor:
        zeros, ones = torch.zeros_like(world[:, :1]), torch.ones_like(world[:, :1])
        homogeneous = torch.cat([world, zeros, ones], dim=1)  # [B, 4]
        projected = torch.einsum("kij,bj->bki", self.matrices, homogeneous)  # [B, K, 3]
        denominator = projected[..., 2:]
        sign = torch.where(denominator < 0, -1.0, 1.0)
        denominator = sign * denominator.abs().clamp_min(DENOMINATOR_FLOOR)
        return projected[..., :2] / denominator


class DrawAverage(nn.Module):
    """Export wrapper: estimators [B, D, K, E, 2] + mask [B, K] → metres [B, 2].

    Averages the encoder over the D fixed draws and undoes the world normalisation inside the
    graph, so serving makes one batched call and gets metres back.
    """

    def __init__(self, encoder: MomEncoder, centre: np.ndarray, scale: float) -> None:
        super().__init__()
        self.encoder = encoder
        self.register_buffer("centre", torch.as_tensor(centre, dtype=torch.float32))
        self.scale = float(scale)

    def forward(self, estimators: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        b, d = estimators.shape[0], estimators.shape[1]
        flat = estimators.reshape(b * d, *estimators.shape[2:])
        masks = mask.unsqueeze(1).expand(b, d, mask.shape[1]).reshape(b * d, mask.shape[1])
        world = self.encoder(flat, masks).reshape(b, d, 2).mean(dim=1)
        return world * self.scale + self.centre


def initial_decoder_matrix(world: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """A decoder's starting P̄_k: the floor → image map fitted to the training pairs, as a 3×4
    matrix acting on (x, y, 0, 1) (z column 0).

    The homography is :func:`models.geometry.dlt.fit_dlt`; with fewer than 8 pairs, points in a
    degenerate configuration, a denominator that changes sign or vanishes over the data, or a
    fit worse than the best affine map, it is that affine map (always defined). Scaled so the
    denominator is +1 on average.
    """
    affine = _fit_affine(world, pixels)
    if len(world) < 8:
        return affine
    try:
        h = fit_dlt(world, pixels, what="decoder initialisation")
    except MomlocError:
        return affine
    o = np.ones(len(world))
    denominator = world @ h[2, :2] + h[2, 2]
    if np.abs(denominator).min() < 1e-6 or np.sign(denominator).min() != np.sign(denominator).max():
        return affine
    h = h / denominator.mean()
    projected = (np.c_[world, o] @ h.T)[:, :2] / (np.c_[world, o] @ h[2])[:, None]
    if np.abs(projected - pixels).mean() > np.abs(_apply(affine, world) - pixels).mean():
        return affine
    return np.insert(h, 2, 0.0, axis=1)


def _fit_affine(world: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    design = np.c_[world, np.ones(len(world))]
    coef, *_ = np.linalg.lstsq(design, pixels, rcond=None)  # [3, 2]
    h = np.zeros((3, 3))
    h[:2] = coef.T
    h[2, 2] = 1.0
    return np.insert(h, 2, 0.0, axis=1)


def _apply(matrix: np.ndarray, world: np.ndarray) -> np.ndarray:
    homogeneous = np.c_[world, np.zeros(len(world)), np.ones(len(world))] @ matrix.T
    return homogeneous[:, :2] / homogeneous[:, 2:]

"""Which localizer a trained model uses: the learned MoM encoder, or the floor-mark geometry.

Why: the MoM encoder is an MLP. Trained on people walking all over the floor it is the most
accurate localizer we have, but trained on a handful of floor marks it cannot interpolate between
them (about 1 m off over a 10 × 10 m room with 4 marks). The floor prior
(:mod:`models.floor_prior`) is fitted from the same rows and is exact geometry between the marks
(0.17 m with 9 marks in the same room, on par with MoM trained on dense ground truth). Validation
rows cannot tell the two regimes apart, because they come from the same marks as the training rows.
So the choice is made from what the labels cover: the fraction of 0.5 m floor cells, inside the
labels' bounding box, that hold at least one label. Dense walks cover most cells; marks (and the
straight walks between them) do not.

The policy and the fitted prior are stored in ``model.json`` under ``floor_prior``; the runtime
(numpy only) applies it. With the prior policy, rows no fitted camera sees fall back to MoM.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np

from models.dataset import MomDataset
from models.errors import MomlocError
from models.floor_prior import FloorPrior

CELL_M = 0.5
DENSE_COVERAGE = 0.5  # at least half the cells labelled: the MLP only interpolates over ~0.5 m


def label_coverage(world: np.ndarray, cell_m: float = CELL_M) -> float:
    """Fraction of ``cell_m`` cells in the labels' bounding box that hold a label."""
    xy = np.asarray(world, float)[:, :2]
    lo = xy.min(axis=0)
    cells = np.floor((xy - lo) / cell_m).astype(np.int64)
    shape = cells.max(axis=0) + 1
    occupied = len(np.unique(cells[:, 0] * shape[1] + cells[:, 1]))
    return occupied / float(shape[0] * shape[1])


def prior_points(observation: str) -> str:
    """Box points for bbox models; ankles too when the model reads keypoints."""
    return "all" if observation == "keypoints" else "both"


def choose_policy(dataset: MomDataset, observation: str) -> tuple[dict, FloorPrior | None]:
    """The ``floor_prior`` entry of model.json, and the fitted prior (None: cannot be fitted)."""
    coverage = label_coverage(dataset.world)
    entry: dict = {"coverage": round(coverage, 3), "dense_coverage": DENSE_COVERAGE}
    keypoints = dataset.keypoints if observation == "keypoints" else None
    try:
        prior = FloorPrior.fit_arrays(
            dataset.world[:, :2],
            dataset.boxes,
            dataset.image_size,
            keypoints=keypoints,
            points=prior_points(observation),
        )
    except MomlocError as error:
        entry.update(policy="mom", reason=f"no floor prior: {error}", prior=None)
        return entry, None
    if coverage >= DENSE_COVERAGE:
        policy, reason = "mom", f"labels cover {coverage:.0%} of the floor: the MoM encoder"
    else:
        policy = "prior"
        reason = f"labels cover {coverage:.0%} of the floor (marks): floor-mark geometry"
    entry.update(policy=policy, reason=reason, prior=prior.to_json())
    return entry, prior


def attach_floor_prior(dataset: MomDataset, model_dir: str | Path, observation: str) -> dict:
    """Fit the prior, choose the policy, and add both to ``model_dir/model.json`` atomically."""
    path = Path(model_dir) / "model.json"
    meta = json.loads(path.read_text())
    entry, _ = choose_policy(dataset, observation)
    meta["floor_prior"] = entry
    fd, tmp = tempfile.mkstemp(prefix=".model.json.", dir=path.parent)
    with os.fdopen(fd, "w") as handle:
        json.dump(meta, handle)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)
    return {key: value for key, value in entry.items() if key != "prior"}

"""Which localizer a trained model serves: the MoM encoder, the floor-mark geometry, or a blend.

Why: the MoM encoder is an MLP. Trained on people walking all over the floor it is accurate, but
trained on a handful of floor marks it cannot interpolate between them (about 1 m off over a
10 × 10 m room with 4 marks). The floor prior (:mod:`models.geometry.floor_prior`) is fitted from
the same rows and is exact geometry between the marks (0.17 m with 9 marks in the same room).

- **Marks** (labels cover less than half of the 0.5 m floor cells inside their bounding box):
  the prior serves; validation rows cannot judge the encoder here, since they come from the same
  marks as its training rows.
- **Dense labels**: the two localizers err differently (the encoder reads the whole box, the
  prior its foot and centre points through per-camera plane maps), and their weighted mean beats
  both (indoor-2cam, dense: encoder 0.130 m, prior 0.142 m, mean of the two 0.115 m). The weight
  of the prior is chosen on the validation rows, separately for people seen by 1, 2 and 3+
  cameras, with the prior fitted on the training rows only, so the choice is not flattered.

- **Rows a model labelled** (``policy="prior"``, ``momloc train --policy prior``; the room's
  self-improvement, :mod:`service.learning.improve`): the floor marks plus self-labels, whose
  positions are the serving model's own output. No validation row can then show the encoder
  beating the geometry: the encoder learns to reproduce the serving model (its errors included)
  and the marks' rows sit on four positions it has memorized, so validation chose the encoder
  while on the room's truth the refitted geometry was the better localizer, by far for people
  seen by one camera, even for a candidate trained on the labels' true positions
  (``bench/results/self_learning_policy.md``). Such data serves the floor geometry refitted on
  all rows.

The policy, weights and the prior refitted on all rows are stored in ``model.json`` under
``floor_prior``; the runtime (numpy only) applies them. Rows no fitted camera sees use the encoder.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from common.errors import MomlocError
from models.data.dataset import MomDataset
from models.geometry.floor_prior import FloorPrior

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


VIEW_CLASSES = ("1 view", "2 views", "3+ views")  # the prior's weight is chosen per class
POLICY_WEIGHTS: dict[str, tuple[float, ...]] = {
    "mom": (0.0,) * 3,
    "prior": (1.0,) * 3,
    "blend": (0.5,) * 3,
}  # if not stored
POLICIES = ("auto", "prior")  # what a caller may ask of choose_policy
WEIGHT_GRID = np.round(np.linspace(0.0, 1.0, 11), 2)
MIN_CLASS_ROWS = 30  # fewer validation rows in a class: it takes the weight chosen on all rows


def prior_points(observation: str) -> str:
    """Box points for bbox models; ankles too when the model reads keypoints."""
    return "all" if observation == "keypoints" else "both"


def view_class(boxes: np.ndarray) -> np.ndarray:
    """Index into VIEW_CLASSES per row, from how many cameras see it (none counts as one).

    Why per class: the encoder is weakest on view combinations that training rarely showed (a
    person seen by 1–2 of 6 cameras), where the per-camera geometry holds up."""
    views = np.isfinite(boxes).all(axis=-1).sum(axis=-1)
    return np.clip(views, 1, len(VIEW_CLASSES)) - 1


def row_weights(boxes: np.ndarray, weights: Sequence[float]) -> np.ndarray:
    """The prior's weight [B] for each row, from its view class."""
    return np.asarray(weights, dtype=np.float64)[view_class(boxes)]


def blend(encoder_xy: np.ndarray, prior_xy: np.ndarray, weight: np.ndarray | float) -> np.ndarray:
    """Weighted mean of the two localizers' positions (``weight`` of the prior, per row or one
    for all); the encoder's where the prior has none."""
    w = np.broadcast_to(np.asarray(weight, dtype=np.float64), prior_xy.shape[:1])[:, None]
    encoder_part = np.where(w < 1.0, (1.0 - w) * encoder_xy, 0.0)  # not computed where w is 1
    mixed = w * prior_xy + encoder_part
    return np.where(np.isfinite(prior_xy).all(axis=1, keepdims=True), mixed, encoder_xy)


def fit_prior(dataset: MomDataset, observation: str, rows: np.ndarray | None = None) -> FloorPrior:
    """The floor prior from ``rows`` of ``dataset`` (all rows by default)."""
    keypoints = dataset.keypoints if observation == "keypoints" else None
    pick = slice(None) if rows is None else rows
    return FloorPrior.fit_arrays(
        dataset.world[pick, :2],
        dataset.boxes[pick],
        dataset.image_size,
        keypoints=None if keypoints is None else keypoints[pick],
        points=prior_points(observation),
    )


def _mean_errors(
    encoder_xy: np.ndarray, prior_xy: np.ndarray, boxes: np.ndarray, world: np.ndarray
) -> np.ndarray:
    """Mean error [rows of WEIGHT_GRID] for each prior weight, over the given rows."""
    errors = [np.linalg.norm(blend(encoder_xy, prior_xy, w) - world, axis=1) for w in WEIGHT_GRID]
    return np.nanmean(np.stack(errors), axis=1)


def choose_weights(
    encoder_xy: np.ndarray, prior_xy: np.ndarray, boxes: np.ndarray, world: np.ndarray
) -> tuple[float, ...]:
    """Prior weight per view class minimising the mean validation error."""
    world = np.asarray(world, dtype=np.float64)[:, :2]
    overall = float(WEIGHT_GRID[np.argmin(_mean_errors(encoder_xy, prior_xy, boxes, world))])
    classes = view_class(boxes)
    weights = []
    for c in range(len(VIEW_CLASSES)):
        rows = classes == c
        if rows.sum() < MIN_CLASS_ROWS:
            weights.append(overall)
            continue
        errors = _mean_errors(encoder_xy[rows], prior_xy[rows], boxes[rows], world[rows])
        weights.append(float(WEIGHT_GRID[np.argmin(errors)]))
    return tuple(weights)


def _policy_name(weights: Sequence[float]) -> str:
    if max(weights) == 0.0:
        return "mom"
    return "prior" if min(weights) == 1.0 else "blend"


def choose_policy(
    dataset: MomDataset,
    observation: str,
    val_rows: np.ndarray | None = None,
    encoder_val_xy: np.ndarray | None = None,
    policy: str = "auto",
) -> tuple[dict, FloorPrior | None]:
    """The ``floor_prior`` entry of model.json, and the fitted prior (None: cannot be fitted).

    ``val_rows`` and the encoder's positions on them (``encoder_val_xy``) let dense data choose
    its blend; without them dense data keeps the encoder. ``policy`` ``"prior"``: the floor
    geometry whatever the coverage and validation (rows a model labelled, module docstring).
    """
    if policy not in POLICIES:
        raise MomlocError(f"policy {policy!r}: choose one of {', '.join(POLICIES)}")
    coverage = label_coverage(dataset.world)
    entry: dict = {"coverage": round(coverage, 3), "dense_coverage": DENSE_COVERAGE}
    try:
        prior = fit_prior(dataset, observation)
    except MomlocError as error:
        entry.update(
            policy="mom",
            weights=list(POLICY_WEIGHTS["mom"]),
            reason=f"no floor prior: {error}",
            prior=None,
        )
        return entry, None
    if policy == "prior":
        weights = POLICY_WEIGHTS["prior"]
        reason = "positions labelled by a model (policy prior): floor geometry fitted on all rows"
    elif coverage < DENSE_COVERAGE:
        weights = POLICY_WEIGHTS["prior"]
        reason = f"labels cover {coverage:.0%} of the floor (marks): floor-mark geometry"
    elif val_rows is None or encoder_val_xy is None or len(val_rows) == 0:
        weights, reason = (
            POLICY_WEIGHTS["mom"],
            "no validation rows to weigh the floor prior: the encoder",
        )
    else:
        weights, reason, validation = _weigh_on_validation(
            dataset, observation, val_rows, np.asarray(encoder_val_xy, np.float64), coverage
        )
        entry["validation"] = validation
    entry.update(
        policy=_policy_name(weights), weights=list(weights), reason=reason, prior=prior.to_json()
    )
    return entry, prior


def _weigh_on_validation(
    dataset: MomDataset,
    observation: str,
    val_rows: np.ndarray,
    encoder_xy: np.ndarray,
    coverage: float,
) -> tuple[tuple[float, ...], str, dict[str, float]]:
    """Weights from a prior fitted on the training rows only, scored on the validation rows."""
    train_rows = np.setdiff1d(np.arange(dataset.n), val_rows)
    try:
        prior = fit_prior(dataset, observation, train_rows)
    except MomlocError as error:
        return (
            POLICY_WEIGHTS["mom"],
            f"floor prior unusable on the training rows ({error}): the encoder",
            {},
        )
    boxes = dataset.boxes[val_rows]
    keypoints = dataset.keypoints if observation == "keypoints" else None
    prior_xy, _ = prior.predict(boxes, None if keypoints is None else keypoints[val_rows])
    world = dataset.world[val_rows, :2].astype(np.float64)
    weights = choose_weights(encoder_xy, prior_xy, boxes, world)

    def mean_error(w: Sequence[float]) -> float:
        served = blend(encoder_xy, prior_xy, row_weights(boxes, w))
        return round(float(np.nanmean(np.linalg.norm(served - world, axis=1))), 4)

    validation = {
        "encoder_mean_m": mean_error(POLICY_WEIGHTS["mom"]),
        "prior_mean_m": mean_error(POLICY_WEIGHTS["prior"]),
        "served_mean_m": mean_error(weights),
    }
    possible = VIEW_CLASSES[: dataset.num_cameras]  # a 2-camera rig has no "3+ views"
    per_class = ", ".join(f"{w:.1f} ({c})" for w, c in zip(weights, possible, strict=False))
    reason = (
        f"labels cover {coverage:.0%} of the floor: prior weight {per_class}; validation "
        f"{validation['served_mean_m']:.3f} m (encoder {validation['encoder_mean_m']:.3f} m, "
        f"prior {validation['prior_mean_m']:.3f} m)"
    )
    return weights, reason, validation


def summary(entry: dict) -> dict:
    """The ``floor_prior`` entry without the fitted prior itself (for printed metrics)."""
    return {key: value for key, value in entry.items() if key != "prior"}

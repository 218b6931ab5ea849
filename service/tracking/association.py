"""Calibration-free association of person boxes across cameras, scored by the MoM model itself.

Problem: camera A sees boxes a1, a2, a3 and camera B sees b1, b2; which boxes are the same person?
Classical systems answer with calibrated epipolar geometry. We have no calibration, but the trained
MoM model carries the same information: the encoder maps a tuple of boxes (one per camera, or
"unseen") to a floor point, and the decoder matrices P̄_k map that floor point back to the mean
pixel each camera should observe. For a consistent tuple (all boxes of one person) the reprojection
lands on every box's mean point; for an inconsistent one the encoder's compromise cannot satisfy
all cameras at once (a floor point has 2 degrees of freedom, two boxes give 4 measurements).

Cost of a tuple: the reprojection error per seen camera (``MomRuntime.reprojection_error``, which
compares against the same box mean point the decoder was trained to reproduce), *normalised* to a
box ``REFERENCE_HEIGHT_PX`` (200 px) tall: ``error_px * 200 / box_height_px``. A near person's big
box carries proportionally bigger noise than a distant person's; on simulated indoor-2cam data the
normalised error separated right from wrong pairs clearly better than raw pixels
(``bench/results/tracker_tuning.md``). The cost is the root
mean square over the seen cameras; a tuple is admissible only if *every* camera's normalised error
is at most ``max_error_px`` (the parameter keeps its name: it is in pixels at the reference height).

A second, independent gate in metres: every box is also localized *alone* (the encoder supports
missing views) and two clusters are merged only if their own positions are within ``max_view_gap_m``
(2 m), or, when ``gap_sigmas`` > 0 (default 0: off), within that many standard deviations of their
gap where the model says the two positions are that uncertain. Right pairs agree within ~1.5 m in a
room, while a lone box in each camera from two different people far apart can have a small
reprojection error (the encoder's compromise point splits it between the cameras); this gate removes
those merges. But a lone view's range error grows with its distance from the camera (one pixel of
bottom edge is many centimetres of floor far away), so a fixed radius splits far people into two (a
duplicate and often a false position): on MultiviewX's 25 × 15 m plaza, where lone views 20 m from
their camera are common, 2 m was too tight. The std of the gap comes from the floor maps
(``floor_views``, below): the fused covariances ``C_P``, ``C_Q`` of the two clusters, read along the
gap's own direction ``u``, ``sqrt(u^T (C_P + C_Q) u)``, with the same overconfidence scale as the
floor χ² gate. In the real CMC room these stds are a few decimetres and the 2 m floor binds; on a
plaza they reach 1-2 m and the gate grows with them. Measured, not served: on MultiviewX (6 cameras,
a 25 × 15 m plaza) 4 std lifted the served MODA from 81 to 85 % on one trained model (flat from 4 to
6 std and with no view gap at all: the floor χ² and reprojection gates refuse the wrong pairs it
admits) and cost 3 points on another (86.7 → 83.8 %): within the spread between trainings on 10
frames; on the real CMC room it changed little (CMC2 MOTA 77.0 → 76.9 %, CMC1 58.8 → 56.9 %); on the
simulated 2-camera room of the stream gate it cost 5 points of MOTA (86.4 → 81.5 %,
``tests/service/test_stream_accuracy.py``) and the demo's sofa sitter fell below its gate, so the
default stays the fixed radius (``bench/results/real_multiviewx.md``,
``bench/results/real_cmc_chain_tuning.md``). Rejected: a larger fixed radius (a constant tuned to
one set's size: 3 m scored below 2 m as served on MultiviewX, and it would let wrong pairs through
in a room, where the 2 m already admits most of the wrong pairs' lone views); the gap's full
Mahalanobis distance instead of its std along the gap (that is the floor χ² gate again, on the
encoder's positions). A model that cannot localize one view alone (NaN) disables this gate; one
without floor maps keeps the fixed radius. Defaults (100 px at reference height, 2 m) come from the
gate sweep in ``bench/serving/association.py`` (``bench/results/association.md``); the gap's spread
against its std on real boxes and the gate's effect end to end are in
``bench/results/real_multiviewx.md``. On the served stream the view gap is what binds, and 1.75 m
scored a little better than 2 m on one simulated profile (``bench/results/tracker_tuning.md``). Not
changed: the optimum sits between two cliffs (a lone view's range error splits true pairs below 1.5
m, wrong pairs merge above 2 m) whose places depend on the detector's bottom-edge noise, so a gain
of ~2 points on one simulated profile is no reason to move a default every deployment uses.

Solver: when exactly two cameras have detections, the optimal gated bipartite assignment
(``scipy.optimize.linear_sum_assignment`` on the pairwise cost matrix, one batched model call),
where leaving a box unmatched costs half the gate, so two marginal wrong pairs never beat one good
pair plus two single-view people.
With three or more, agglomerative merging: every detection starts as its own cluster, the cheapest
admissible merge of two clusters on disjoint cameras is applied, and the merged cluster is
re-scored against the others as a *whole* tuple (one batched call per merge). A pair that looks
consistent in two views but contradicts a third camera is thereby refused, and a person missed by
one camera is still joined across the others. A greedy camera-by-camera Hungarian extension was
tried first and failed exactly there (an early wrong pair blocks the right one later).

People seen by one camera only are kept: their cluster is localized with the other views masked
(NaN), which the MoM encoder supports when trained with missing views. Clusters whose position
the model cannot produce (non-finite output) are dropped.

A model with per-camera floor geometry (``floor_views``: the floor prior's plane maps) also
gates every merge in floor space: each box is placed on the floor by its own camera's map with
its information matrix (long along that camera's line of sight, scaled by ``FLOOR_INFO_SCALE`` for
the prior's overconfidence), clusters are fused in information form, and two clusters merge only
if the Mahalanobis rise of the fused χ² is at most ``max_floor_chi2`` (25): that is small only where
the cameras' lines of sight meet, which the 2 m view gap cannot tell in a crowd. On the real CMC
room (10 people, ``bench/results/real_cmc_chain_tuning.md``) it cut mixed clusters and lifted
per-frame MODA; a tighter χ² refused true merges (more duplicates), a looser one let mixes through.

Track-driven step (``anchors``: the tracker's served tracks predicted to this frame set,
``Tracker.anchors``, handed over by ``service.pipeline.chain``): the boxes alone split one
person into two clusters whenever a box is cut or shifted in a crowd (the floor gate refuses the
merge) or the detector gives a person a second, fragment box. The tracker then saw two people and
needed a shadow merge of close tracks, which also merged real neighbours (on the real CMC room
it was the largest loss of identities with the true association). So after clustering, each
anchor takes the cluster that best continues it, and a leftover cluster whose nearest anchor
took another one is that person's fragment: folded into the main cluster (boxes of cameras it
lacks, when the whole tuple passes the reprojection gate) or dropped. The figures, the rejected
variants (the anchors claiming each camera's boxes before clustering mixed neighbours and lost
people) are in ``bench/results/real_cmc_chain_tuning.md``. Opt-in (``continuity_z2`` > 0, off:
no gain measured on the real room), the anchors' image predictions also label the boxes each
track continues in its own camera, and boxes of two tracks never join (``_BoxContinuity``).

The model's ``covariance(boxes)`` (``MomRuntime``: the floor prior's GLS covariance; NaN without
one) also gives each association the covariance of its position, which the tracker takes as that
measurement's noise (long along a lone camera's line of sight).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from common.errors import MomlocError
from models.detector.base import Detections
from service.stages import (
    Association,
    FloorViewing,
    LocalizationModel,
    TrackAnchor,
    WithCovariance,
)

DEFAULT_MAX_ERROR_PX = (
    100.0  # normalised px (half the reference height): see bench/serving/association.py
)
REFERENCE_HEIGHT_PX = 200.0  # errors are judged as if every box were this tall
MIN_HEIGHT_PX = 20.0
DEFAULT_MAX_VIEW_GAP_M = 2.0
DEFAULT_GAP_SIGMAS = 0.0  # module docstring: the view gap may grow with the positions' uncertainty
DEFAULT_MAX_FLOOR_CHI2 = 25.0  # module docstring: the real CMC room
DEFAULT_ANCHOR_CHI2 = 9.0  # module docstring: track-driven association
DEFAULT_CONTINUITY_Z2 = 0.0  # _BoxContinuity off: measured, no gain on the real room (4.0: 2 std)
CONTINUITY_MARGIN_Z2 = 4.0  # _BoxContinuity: every other pairing this much worse (odds e² ≈ 7)
FLOOR_INFO_SCALE = 3.0  # the floor prior's std is ~3x overconfident (service.tracking.measurements)
_BLOCKED = 1e9


@dataclass(frozen=True)
class _Gate:
    max_error_px: float
    max_view_gap_m: float
    max_floor_chi2: float = DEFAULT_MAX_FLOOR_CHI2
    gap_sigmas: float = DEFAULT_GAP_SIGMAS

    def admits(
        self,
        worst: np.ndarray,
        gap: np.ndarray,
        chi2: np.ndarray | None = None,
        gap_std: np.ndarray | None = None,
    ) -> np.ndarray:
        """Worst normalised error within the gate, and views that agree on the floor: a gap
        within ``max_view_gap_m`` or ``gap_sigmas`` of its std (a NaN gap or χ², from a model
        that cannot localize one view alone or has no floor geometry for a camera, does not
        veto; a NaN std leaves the fixed radius)."""
        limit = np.full(np.shape(gap), self.max_view_gap_m)
        if gap_std is not None:
            limit = np.fmax(limit, self.gap_sigmas * gap_std)
        ok = (worst <= self.max_error_px) & ~(gap > limit)
        return ok if chi2 is None else ok & ~(chi2 > self.max_floor_chi2)


class _FloorFit:
    """Each detection's floor position and information from its own camera's floor map, and
    clusters fused in information form: merging clusters P and Q costs the Mahalanobis
    distance of their fused positions, ``d^T (Λ_P^-1 + Λ_Q^-1)^-1 d`` (the rise in the fused
    χ²), which is small only where the cameras' lines of sight meet."""

    def __init__(self, detections: _Views, runtime: FloorViewing) -> None:
        self.ok = False
        rows = [{k: j} for k in range(len(detections)) for j in range(len(detections[k]))]
        if not rows:
            return
        tuples = detections.stack(rows)
        found = runtime.floor_views(tuples.boxes, tuples.keypoints)
        if found is None:
            return
        est, info = found
        self.ok = True
        self._info: dict[tuple[int, int], np.ndarray] = {}
        self._eta: dict[tuple[int, int], np.ndarray] = {}
        for row, cluster in enumerate(rows):
            ((k, j),) = cluster.items()
            self._info[(k, j)] = info[row, k] / FLOOR_INFO_SCALE**2
            self._eta[(k, j)] = self._info[(k, j)] @ est[row, k]

    def fused_place(self, cluster: dict[int, int]) -> tuple[np.ndarray, np.ndarray] | None:
        """A cluster's fused floor position [2] and covariance [2, 2] (``None`` where its
        cameras' maps do not fix a point)."""
        info, eta = self._fused(cluster)
        if not np.isfinite(info).all() or np.linalg.det(info) <= 1e-12:
            return None
        cov = np.linalg.inv(info)
        return cov @ eta, cov

    def chi2(self, pairs: Sequence[tuple[dict[int, int], dict[int, int]]]) -> np.ndarray | None:
        """Merge cost per pair of clusters (one batched solve); NaN where either side has no
        floor information (a camera without a fitted map)."""
        if not self.ok:
            return None
        if not pairs:
            return np.zeros(0)
        (cov_p, mean_p), (cov_q, mean_q), valid = self._sides(pairs)
        d = mean_p - mean_q
        out = np.einsum("bi,bi->b", d, np.linalg.solve(cov_p + cov_q, d[..., None])[..., 0])
        return np.where(valid, out, np.nan)

    def gap_std(
        self, pairs: Sequence[tuple[dict[int, int], dict[int, int]]], gaps: np.ndarray
    ) -> np.ndarray | None:
        """Std [B] (m) of each pair's gap [B, 2] between two positions with the clusters'
        fused covariances, along the gap: ``sqrt(u^T (C_P + C_Q) u)``; NaN where either side's
        maps do not fix a point (or the gap is not finite)."""
        if not self.ok:
            return None
        if not pairs:
            return np.zeros(0)
        (cov_p, _), (cov_q, _), valid = self._sides(pairs)
        gaps = np.asarray(gaps, np.float64).reshape(len(pairs), 2)
        norm = np.linalg.norm(gaps, axis=1, keepdims=True)
        u = np.where(norm > 0, gaps / np.where(norm > 0, norm, 1.0), [1.0, 0.0])
        std = np.sqrt(np.einsum("bi,bij,bj->b", u, cov_p + cov_q, u))
        return np.where(valid & np.isfinite(norm[:, 0]), std, np.nan)

    def _sides(
        self, pairs: Sequence[tuple[dict[int, int], dict[int, int]]]
    ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], np.ndarray]:
        """Both sides' fused covariance [B, 2, 2] and position [B, 2] per pair, and [B] whether
        both are fixed (identity and the information vector where not)."""
        sides = [self._fused(p) for p, _ in pairs], [self._fused(q) for _, q in pairs]
        (lp, ep), (lq, eq) = (
            (np.stack([f[0] for f in side]), np.stack([f[1] for f in side])) for side in sides
        )
        valid = (np.linalg.det(lp) > 1e-12) & (np.linalg.det(lq) > 1e-12)
        eye = np.eye(2)
        cov_p = np.linalg.inv(np.where(valid[:, None, None], lp, eye))
        cov_q = np.linalg.inv(np.where(valid[:, None, None], lq, eye))
        mean_p = np.einsum("bij,bj->bi", cov_p, ep)
        mean_q = np.einsum("bij,bj->bi", cov_q, eq)
        return (cov_p, mean_p), (cov_q, mean_q), valid

    def _fused(self, cluster: dict[int, int]) -> tuple[np.ndarray, np.ndarray]:
        info = sum((self._info[(k, j)] for k, j in cluster.items()), np.zeros((2, 2)))
        eta = sum((self._eta[(k, j)] for k, j in cluster.items()), np.zeros(2))
        return info, eta


def associate(
    detections_per_camera: Sequence[Detections | np.ndarray],
    runtime: LocalizationModel,
    max_error_px: float = DEFAULT_MAX_ERROR_PX,
    max_view_gap_m: float = DEFAULT_MAX_VIEW_GAP_M,
    max_floor_chi2: float = DEFAULT_MAX_FLOOR_CHI2,
    anchors: Sequence[TrackAnchor] = (),
    anchor_chi2: float = DEFAULT_ANCHOR_CHI2,
    gap_sigmas: float = DEFAULT_GAP_SIGMAS,
    continuity_z2: float = DEFAULT_CONTINUITY_Z2,
) -> list[Association]:
    """Group the detections of all cameras into people (see the module docstring);
    ``anchors``: the tracker's predicted tracks, whose leftover fragments are folded in;
    ``gap_sigmas`` 0: the view gap's fixed radius alone; ``continuity_z2`` > 0: boxes that
    continue two different tracks in their own images never join (:class:`_BoxContinuity`;
    off by default)."""
    num_cameras = int(runtime.num_cameras)
    if len(detections_per_camera) != num_cameras:
        raise MomlocError(
            f"association: got detections for {len(detections_per_camera)} cameras, "
            f"the model was trained for {num_cameras}"
        )
    detections = _Views.of(detections_per_camera, runtime.observation == "keypoints")
    seen_cameras = [k for k in range(num_cameras) if len(detections[k])]
    gate = _Gate(max_error_px, max_view_gap_m, max_floor_chi2, gap_sigmas)
    floor = _FloorFit(detections, runtime)
    links = _BoxContinuity(detections, anchors, continuity_z2)
    if len(seen_cameras) == 2:
        clusters = _match_two(detections, seen_cameras, runtime, gate, floor, links)
    else:
        clusters = _merge_greedy(detections, runtime, gate, floor, links)
    clusters = _absorb(clusters, detections, anchors, floor, anchor_chi2, runtime, gate, links)

    if not clusters:
        return []
    tuples = detections.stack([{k: j for k, j in enumerate(c) if j is not None} for c in clusters])
    world, errors, cost, _ = _evaluate(tuples, runtime)
    covariance = _covariance(tuples, runtime)
    out = []
    for i, cluster in enumerate(clusters):
        if not np.isfinite(world[i]).all():
            continue
        seen = [k for k in range(num_cameras) if cluster[k] is not None]
        out.append(
            Association(
                boxes=tuples.boxes[i].astype(np.float32),
                cameras=seen,
                world=world[i],
                cost=float(cost[i]),
                detection_index=list(cluster),
                errors=errors[i],
                covariance=covariance[i],
                keypoints=None if tuples.keypoints is None else tuples.keypoints[i],
            )
        )
    return out


def _match_two(
    detections: _Views,
    cameras: list[int],
    runtime: LocalizationModel,
    limits: _Gate,
    floor: _FloorFit,
    links: _BoxContinuity,
) -> list[list[int | None]]:
    """Optimal gated bipartite assignment between the only two cameras with detections."""
    a, b = cameras
    num_cameras = len(detections)
    pairs = [(i, j) for i in range(len(detections[a])) for j in range(len(detections[b]))]
    tuples = detections.stack([{a: i, b: j} for i, j in pairs])
    _, _, cost, worst = _evaluate(tuples, runtime)
    shape = (len(detections[a]), len(detections[b]))
    single = _single_view_positions(detections, runtime)
    gaps = (single[a][:, None] - single[b][None]).reshape(-1, 2)
    sides = [({a: i}, {b: j}) for i, j in pairs]
    admitted = limits.admits(
        worst, np.linalg.norm(gaps, axis=1), floor.chi2(sides), floor.gap_std(sides, gaps)
    ) & ~np.array([links.conflict(p, q) for p, q in sides], bool).reshape(-1)
    gated = np.where(admitted, cost, _BLOCKED).reshape(shape)
    gate = limits.max_error_px
    # Leaving a detection unmatched (a single-view person) costs gate / 2, so a pair is only
    # worth matching when its RMS error is below the gate, and two marginal wrong pairs never
    # beat one good pair plus two single-view people (a plain rectangular assignment would
    # maximise the number of pairs instead).
    n, m = shape
    square = np.full((n + m, m + n), _BLOCKED)
    square[:n, :m] = gated
    square[np.arange(n), m + np.arange(n)] = gate / 2
    square[n + np.arange(m), np.arange(m)] = gate / 2
    square[n:, m:] = 0.0
    rows, cols = linear_sum_assignment(square)
    keep = (rows < n) & (cols < m)
    rows, cols = rows[keep], cols[keep]
    clusters: list[list[int | None]] = []
    used_a, used_b = set(), set()
    for r, c in zip(rows, cols, strict=True):
        if gated[r, c] < _BLOCKED:
            cluster: list[int | None] = [None] * num_cameras
            cluster[a], cluster[b] = int(r), int(c)
            clusters.append(cluster)
            used_a.add(int(r))
            used_b.add(int(c))
    for k, used in ((a, used_a), (b, used_b)):
        for j in range(len(detections[k])):
            if j not in used:
                cluster = [None] * num_cameras
                cluster[k] = j
                clusters.append(cluster)
    return clusters


def _absorb(
    clusters: list[list[int | None]],
    detections: _Views,
    anchors: Sequence[TrackAnchor],
    floor: _FloorFit,
    max_chi2: float,
    runtime: LocalizationModel,
    limits: _Gate,
    links: _BoxContinuity,
) -> list[list[int | None]]:
    """Fold the fragments of tracked people into their main cluster.

    Each anchor (a tracked person's prediction) takes the cluster that best continues it (an
    optimal assignment on the Mahalanobis distance of the cluster's fused floor position to the
    prediction, both covariances, gated at ``max_chi2``). A cluster left over whose nearest
    anchor within the gate took another cluster is that person's fragment (a box the floor gate
    kept apart, a second box of theirs, a view the greedy order left alone): its boxes in the
    cameras the main cluster lacks join it when the whole tuple passes the reprojection gate
    (its boxes in cameras the main cluster has are dropped: each camera gives a person one
    box); a fragment with no camera of its own is dropped. Clusters near no anchor are left as
    they are (new people). Unchanged without anchors or floor geometry."""
    if not anchors or not floor.ok or max_chi2 <= 0 or not clusters:
        return clusters
    as_dict = [{k: j for k, j in enumerate(c) if j is not None} for c in clusters]
    fused = [floor.fused_place(c) for c in as_dict]
    xy = np.stack([np.asarray(a.xy, np.float64) for a in anchors])
    cov = np.stack([np.asarray(a.cov, np.float64) for a in anchors])
    d2 = np.full((len(anchors), len(clusters)), np.inf)
    for i, place in enumerate(fused):
        if place is not None:
            nu = place[0][None] - xy
            d2[:, i] = np.einsum("ai,aij,aj->a", nu, np.linalg.inv(cov + place[1][None]), nu)
    for i, cluster in enumerate(as_dict):
        for other in links.anchors_of(cluster):
            # a cluster continuing a track in some image belongs to that track alone
            d2[np.arange(len(anchors)) != other, i] = np.inf
    gated = np.where(d2 <= max_chi2, d2, _BLOCKED)
    rows, cols = linear_sum_assignment(gated)
    main = {int(a): int(c) for a, c in zip(rows, cols, strict=True) if gated[a, c] < _BLOCKED}
    taken = set(main.values())
    fragments = sorted(
        (float(d2[:, i].min()), i, int(d2[:, i].argmin()))
        for i in range(len(clusters))
        if i not in taken and np.isfinite(d2[:, i]).any() and d2[:, i].min() <= max_chi2
    )
    gone: set[int] = set()
    for _, i, anchor in fragments:
        if anchor not in main:
            continue
        whole = as_dict[main[anchor]]
        extra = {k: j for k, j in as_dict[i].items() if k not in whole}
        if links.anchors_of({**whole, **extra}) - {anchor}:
            continue  # boxes that continue another track in their own image: not a fragment
        if not extra:
            gone.add(i)
            continue
        merged = {**whole, **extra}
        _, _, _, worst = _evaluate(detections.stack([merged]), runtime)
        if worst[0] <= limits.max_error_px:
            as_dict[main[anchor]] = merged
            gone.add(i)
    out = []
    for i, cluster in enumerate(as_dict):
        if i in gone:
            continue
        row: list[int | None] = [None] * len(detections)
        for k, j in cluster.items():
            row[k] = j
        out.append(row)
    return out


def _merge_greedy(
    detections: _Views,
    runtime: LocalizationModel,
    limits: _Gate,
    floor: _FloorFit,
    links: _BoxContinuity,
) -> list[list[int | None]]:
    """Agglomerative merging, cheapest admissible merge first, re-scoring each merged cluster.

    Every merge is checked on the *whole* merged tuple, so a pair that looks consistent in two
    views but contradicts a third camera is refused.
    """
    num_cameras = len(detections)
    single = _single_view_positions(detections, runtime)
    clusters: dict[int, dict[int, int]] = {}
    positions: dict[int, np.ndarray] = {}
    for k, boxes in enumerate(detections.boxes):
        for j in range(len(boxes)):
            positions[len(clusters)] = single[k][j]
            clusters[len(clusters)] = {k: j}
    costs: dict[tuple[int, int], tuple[float, np.ndarray]] = {}
    ids = sorted(clusters)
    pairs = [(p, q) for i, p in enumerate(ids) for q in ids[i + 1 :]]
    _score_pairs(pairs, clusters, positions, detections, runtime, limits, floor, links, costs)
    next_id = len(clusters)
    while costs:
        (p, q), (_, position) = min(costs.items(), key=lambda item: item[1][0])
        merged = {**clusters.pop(p), **clusters.pop(q)}
        costs = {key: c for key, c in costs.items() if p not in key and q not in key}
        clusters[next_id] = merged
        positions[next_id] = position
        pairs = [(other, next_id) for other in clusters if other != next_id]
        _score_pairs(pairs, clusters, positions, detections, runtime, limits, floor, links, costs)
        next_id += 1
    out = []
    for cluster in clusters.values():
        row: list[int | None] = [None] * num_cameras
        for k, j in cluster.items():
            row[k] = j
        out.append(row)
    return out


def _score_pairs(
    pairs: list[tuple[int, int]],
    clusters: dict[int, dict[int, int]],
    positions: dict[int, np.ndarray],
    detections: _Views,
    runtime: LocalizationModel,
    limits: _Gate,
    floor: _FloorFit,
    links: _BoxContinuity,
    costs: dict[tuple[int, int], tuple[float, np.ndarray]],
) -> None:
    """Add the admissible merges of ``pairs`` (clusters on disjoint cameras, not continuing two
    different tracks) to ``costs``."""
    pairs = [
        (p, q)
        for p, q in pairs
        if not clusters[p].keys() & clusters[q].keys()
        and not links.conflict(clusters[p], clusters[q])
    ]
    if not pairs:
        return
    tuples = detections.stack([{**clusters[p], **clusters[q]} for p, q in pairs])
    world, _, cost, worst = _evaluate(tuples, runtime)
    gaps = np.array([positions[p] - positions[q] for p, q in pairs]).reshape(-1, 2)
    sides = [(clusters[p], clusters[q]) for p, q in pairs]
    ok = limits.admits(
        worst, np.linalg.norm(gaps, axis=1), floor.chi2(sides), floor.gap_std(sides, gaps)
    )
    for i, pair in enumerate(pairs):
        if ok[i]:
            costs[pair] = (float(cost[i]), world[i])


class _BoxContinuity:
    """Which tracked person each box continues in its own camera's image (appearance-free).

    Why: in a crowd the floor cannot tell neighbours apart (their boxes' floor positions agree
    within their errors: on CMC2 a mixed cluster's worst leave-one-out floor χ² has the same
    spread as a pure one's), but each camera still sees them at distinct bearings that move
    smoothly between frames. A box whose centre x lies within ``max_z2`` of a track's
    predicted centre in that camera (``TrackAnchor.image_x`` / ``image_std``: the tracker's
    image continuity memory, moved on by its image velocity), where that pairing is mutual and
    every other pairing of either side is ``CONTINUITY_MARGIN_Z2`` worse, is labelled with the
    track. Clusters holding boxes labelled with two different tracks never merge (a cannot-link
    constraint), a cluster holding a track's labelled box is the main cluster of that track only,
    and a fragment does not fold into a track's cluster where that would join another track's
    labelled box. Only a veto: an unlabelled box (a new person, two tracks at one bearing, a
    camera the track was not seen by) leaves the floor and reprojection gates to decide.

    Off by default (``continuity_z2`` 0). Measured on the real CMC room with the product's chain
    (``bench/results/real_cmc_chain_tuning.md``, 2026-12-04 evening): about a fifth of the boxes
    get a label, and CMC2's mixed clusters did not fall (15 → 15-30 FPs); CMC2 MODA 84.1 →
    83.4-85.0 %, MOTA 79.6 → 78.0-79.8 %, CMC1 MOTA 89.6 → 84.5-91.3 % over the variants tried,
    within the chain's run-to-run scatter, so the default stays the boxes alone.
    Rejected: anchors *claiming* boxes per camera before clustering (must-links from the
    floor prediction and image continuity: mixed neighbours and lost people, 2026-12-03
    evening); splitting clusters whose members disagree on the floor (the floor does not
    separate them, above)."""

    def __init__(self, detections: _Views, anchors: Sequence[TrackAnchor], max_z2: float) -> None:
        self.labels: list[np.ndarray] = [np.full(len(b), -1) for b in detections.boxes]
        if max_z2 <= 0 or not anchors:
            return
        for k, boxes in enumerate(detections.boxes):
            if not len(boxes):
                continue
            x, std = (
                np.array([_camera_value(getattr(a, name), k) for a in anchors])
                for name in ("image_x", "image_std")
            )
            centre = 0.5 * (boxes[:, 0].astype(np.float64) + boxes[:, 2])
            z2 = ((centre[None] - x[:, None]) / np.where(std > 0, std, np.nan)[:, None]) ** 2
            z2 = np.where(np.isfinite(z2), z2, np.inf)
            for j in range(len(boxes)):
                a = int(np.argmin(z2[:, j]))
                best = z2[a, j]
                if best > max_z2 or int(np.argmin(z2[a])) != j:
                    continue
                runner_up = min(
                    np.delete(z2[:, j], a).min(initial=np.inf),
                    np.delete(z2[a], j).min(initial=np.inf),
                )
                if runner_up >= best + CONTINUITY_MARGIN_Z2:
                    self.labels[k][j] = a

    def anchors_of(self, cluster: dict[int, int]) -> set[int]:
        """The tracks the cluster's boxes continue."""
        return {int(self.labels[k][j]) for k, j in cluster.items()} - {-1}

    def conflict(self, p: dict[int, int], q: dict[int, int]) -> bool:
        """Whether merging ``p`` and ``q`` would join boxes continuing two different tracks."""
        return len(self.anchors_of(p) | self.anchors_of(q)) > 1


def _camera_value(values: np.ndarray | None, camera: int) -> float:
    """``values[camera]`` of an anchor's per-camera prediction (NaN where it has none)."""
    if values is None or camera >= len(values):
        return float("nan")
    return float(values[camera])


def _single_view_positions(detections: _Views, runtime: LocalizationModel) -> list[np.ndarray]:
    """Per camera [M_k, 2]: each box localized alone (NaN if the model cannot), one call."""
    rows = [{k: j} for k in range(len(detections)) for j in range(len(detections[k]))]
    if not rows:
        return [np.zeros((0, 2)) for _ in detections.boxes]
    world = _localize(detections.stack(rows), runtime)
    out, start = [], 0
    for boxes in detections.boxes:
        out.append(world[start : start + len(boxes)])
        start += len(boxes)
    return out


def _covariance(tuples: _Tuples, runtime: WithCovariance) -> np.ndarray:
    """The model's covariance [B, 2, 2] of each tuple's position (``MomRuntime.covariance``);
    rows it cannot tell are NaN."""
    return np.asarray(runtime.covariance(tuples.boxes, tuples.keypoints), dtype=np.float64)


@dataclass(frozen=True)
class _Tuples:
    """Candidate tuples as the model reads them: boxes [B, K, 4] and, for a keypoint model,
    keypoints [B, K, J, 3] (NaN where a camera has no detection in the tuple)."""

    boxes: np.ndarray
    keypoints: np.ndarray | None

    def __len__(self) -> int:
        return len(self.boxes)


class _Views:
    """Per camera detections: ``views[k]`` are camera k's boxes [M_k, 4] (and, for keypoint
    models, ``keypoints[k]`` [M_k, J, 3])."""

    def __init__(self, boxes: list[np.ndarray], keypoints: list[np.ndarray] | None) -> None:
        self.boxes, self.keypoints = boxes, keypoints

    @classmethod
    def of(cls, detections: Sequence[Detections | np.ndarray], with_keypoints: bool) -> _Views:
        boxes, keypoints = [], []
        for camera, found in enumerate(detections):
            raw = found.boxes if isinstance(found, Detections) else found
            boxes.append(_as_boxes(raw, camera))
            points = found.keypoints if isinstance(found, Detections) else None
            if with_keypoints and points is None and len(boxes[-1]):
                raise MomlocError(
                    f"association: the model reads keypoints, camera {camera}'s detections "
                    "carry none (a keypoint model needs a detector with keypoints)"
                )
            keypoints.append(points)
        if not with_keypoints:
            return cls(boxes, None)
        joints = next((p.shape[1] for p in keypoints if p is not None and p.ndim == 3), 17)
        return cls(
            boxes,
            [
                np.zeros((0, joints, 3), np.float32)
                if p is None
                else np.asarray(p, np.float32).reshape(len(b), joints, 3)
                for b, p in zip(boxes, keypoints, strict=True)
            ],
        )

    def __len__(self) -> int:
        return len(self.boxes)

    def __getitem__(self, camera: int) -> np.ndarray:
        return self.boxes[camera]

    def stack(self, clusters: Sequence[dict[int, int]]) -> _Tuples:
        """The tuples of ``clusters`` (``{camera: detection index}`` each), NaN elsewhere."""
        boxes = np.full((len(clusters), len(self.boxes), 4), np.nan, dtype=np.float32)
        keypoints = None
        if self.keypoints is not None:
            joints = self.keypoints[0].shape[1]
            shape = (len(clusters), len(self.boxes), joints, 3)
            keypoints = np.full(shape, np.nan, dtype=np.float32)
        for row, cluster in enumerate(clusters):
            for k, j in cluster.items():
                boxes[row, k] = self.boxes[k][j]
                if keypoints is not None and self.keypoints is not None:
                    keypoints[row, k] = self.keypoints[k][j]
        return _Tuples(boxes, keypoints)


def _as_boxes(detections: np.ndarray, camera: int) -> np.ndarray:
    boxes = np.asarray(detections, dtype=np.float32)
    if boxes.size == 0:
        return np.zeros((0, 4), dtype=np.float32)
    if boxes.ndim != 2 or boxes.shape[1] != 4:
        raise MomlocError(f"association: camera {camera} boxes must be [M, 4], got {boxes.shape}")
    return boxes


def _localize(tuples: _Tuples, runtime: LocalizationModel) -> np.ndarray:
    """World [B, 2] (float64) of each tuple; keypoints only go to a keypoint model."""
    if tuples.keypoints is None:
        world = runtime.localize(tuples.boxes)
    else:
        world = runtime.localize(tuples.boxes, tuples.keypoints)
    return np.asarray(world, dtype=np.float64).reshape(len(tuples), 2)


def _evaluate(
    tuples: _Tuples, runtime: LocalizationModel
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """World [B, 2], raw errors [B, K] px, and the RMS and worst *normalised* error per tuple.

    Normalised error: pixels scaled to a ``REFERENCE_HEIGHT_PX``-tall box, so a distant person
    (small box, small pixel errors) and a near one (large box, large errors from the same box
    noise) are judged alike. Non-computable tuples get ``inf``.
    """
    world = _localize(tuples, runtime)
    if tuples.keypoints is None:
        errors = runtime.reprojection_error(tuples.boxes, world)
    else:
        errors = runtime.reprojection_error(tuples.boxes, world, tuples.keypoints)
    errors = np.asarray(errors, dtype=np.float64)
    boxes = tuples.boxes
    seen = np.isfinite(boxes).all(axis=2)
    height = np.maximum(np.nan_to_num(boxes[..., 3] - boxes[..., 1]), MIN_HEIGHT_PX)
    scaled = np.where(seen, errors * (REFERENCE_HEIGHT_PX / height), 0.0)
    bad = ~np.isfinite(scaled).all(axis=1) | ~np.isfinite(world).all(axis=1) | ~seen.any(axis=1)
    scaled = np.where(np.isfinite(scaled), scaled, 0.0)
    rms = np.sqrt((scaled**2).sum(axis=1) / np.maximum(seen.sum(axis=1), 1))
    worst = scaled.max(axis=1)
    rms[bad] = np.inf
    worst[bad] = np.inf
    return world, errors, rms, worst

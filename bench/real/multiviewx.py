"""MultiviewX images end to end: the shipped detector on rendered 1080p images, the daemon's
association and a calibration-free MoM model, scored on the floor as MVDet is (MODA/MODP at
0.5 m) → bench/results/real_multiviewx.md.

MultiviewX (``../shared/data/multiviewx``: 10 frames × 6 cameras, 1920×1080, a 25 × 15 m
annotated playground, 20-22 annotated people per frame, more walking beyond it) is the only
set here with images, so it is the only one that
tests the whole product: pixels → ``models.detector`` (NanoDet with the daemon's default
settings, ``max_shrink`` included) → :func:`service.tracking.association.associate` → MoM →
the tracker (:class:`service.pipeline.chain.Chain`, the daemon's chain, at the data's 2 fps):
scored as served (tracks) and per frame before tracking (associations), as MVDet is scored.

The model is set up the way a user would, without calibration: a set-up recording labelled with
floor positions. Here the recording is simulated on the same camera geometry — a
:class:`~models.simulate.SceneConfig` whose cameras are the MultiviewX calibration
(:class:`bench.real.data.CalibratedSpec`, read from ``--data`` at run time), people walking the
whole playground, boxes with the simulator's detector profile — and trained with
``models.mom.training.train.train_model``. The calibration shapes the simulated recording only; the
served chain never sees it.

Where MODA falls short, oracle bounds on the real boxes say why: the detector's recall against
the true people projected through the calibration (:func:`bench.real.chain.match_people`), the
share of people no camera's box belongs to (a miss for any chain on these boxes), and MODA with
the true association (the same model on the boxes grouped by true person) and with a calibrated
foot point (:func:`bench.real.chain.foot_point`) on that association.

Usage::

    python -m bench.real.multiviewx [--data ../shared/data] [--frames 600] [--people 20]
                                    [--train-seconds 240] [--compare-shrink 2]
                                    [--out bench/results/real_multiviewx.md]
"""

from __future__ import annotations

import argparse
import functools
import tempfile
import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.real.chain import (
    FN_CAUSES,
    FP_CAUSES,
    MATCH_GATE,
    breakdown,
    floor_points,
    foot_point,
    match_people,
    positions,
    projected_people,
    serve,
    train_runtime,
    true_tuples,
)
from bench.real.data import (
    DEFAULT_DATA,
    CalibratedSpec,
    Calibration,
    FloorGrid,
    FramePositions,
    data_folder,
    load_calibrations,
    load_positions,
)
from bench.real.scoring import GATE_M, DetectionScore
from bench.report import RESULTS, command_line, machine_line, markdown_table
from models.detector.base import Detections
from models.mom.runtime import MomRuntime
from models.simulate import SceneConfig
from service.stages import AssociateStage
from service.tracking.association import (
    DEFAULT_MAX_VIEW_GAP_M,
    FLOOR_INFO_SCALE,
    associate,
)

CAMERAS = tuple(f"Camera{k}" for k in range(1, 7))
IMAGE_SIZE = (1920, 1080)
# the annotated playground (MultiviewX's README: 25 × 15 m; no label has y > 15 m)
FLOOR_M = (25.0, 15.0)
GRID = FloorGrid((0.0, 0.0), 0.025, 1000)
CITATION = (
    "MultiviewX (github.com/hou-yz/MultiviewX commit 420ef26, demo subset of 10 frames; "
    'Y. Hou, L. Zheng, S. Gould, "Multiview Detection with Feature Perspective '
    'Transformation", ECCV 2020)'
)
COLUMNS = ("chain", "MODA % ↑", "MODP % ↑", "precision %", "recall %", "matched mean m",
           "TP / FP / FN")  # fmt: skip
FRAME_COLUMNS = ("annotation frame", "people", "boxes (6 cameras)", "MODA %", "precision %",
                 "recall %", "matched mean m")  # fmt: skip
FPS = 2.0  # MultiviewX's frames: 2 fps (Wildtrack's layout)
STREAM_FROM = 2  # tracks scored from the 3rd frame: a lone-view track is served after 1 s
INPUT_COLUMNS = ("detector", "person-views found %", "boxes of a true person % (boxes)",
                 "MODA % true association", "MODA % per frame", "MODA % 2+ cameras",
                 "MODA % served tracks")  # fmt: skip
NOBODY_KINDS = (
    "foot point off the playground (people beyond it)",
    "on the playground, in the image column of people with a box (second box, fragment)",
    "on the playground, in the column of a person without a box (cut by an occluder)",
    "on the playground, in nobody's column",
)
# the view gap scaled by its std (``gap_sigmas``), measured though not served: it costs the
# simulated stream gate (tests/service/test_stream_accuracy.py) 5 points of MOTA
SCALED_GAPS = (3.0, 4.0)
MVDET_MODA = 83.9  # MVDet on MultiviewX's test split, calibrated, trained on its full split


def _log(message: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {message}", flush=True)


def scene_config(calibrations: Sequence[Calibration], people: int, fps: float) -> SceneConfig:
    """The simulated set-up: MultiviewX's cameras over its annotated 25 × 15 m playground (a
    user sets up where people are to be served; MultiviewX labels nobody beyond y = 15 m, and
    people walk there, in view: set up on 25 × 16 m, the model served them as false positives)."""
    cameras = tuple(CalibratedSpec.of(c) for c in calibrations)
    return SceneConfig("multiviewx", FLOOR_M, cameras, people=people, fps=fps, outdoor=True)


def image_sets(folder: Path) -> list[list[Path]]:
    """Per frame the six camera images (``Image_subsets/C<k>/NNNN.jpg``), frames in name order."""
    names = sorted(p.name for p in (folder / "Image_subsets" / "C1").glob("*.jpg"))
    return [[folder / "Image_subsets" / f"C{k}" / n for k in range(1, 7)] for n in names]


def detect_all(
    paths: list[list[Path]], max_shrink: float | None = None
) -> tuple[list[list[Detections]], str]:
    """Every frame set through the detector the daemon builds by default (one thread), or with
    another ``max_shrink`` (how far a large frame may shrink into the network input)."""
    import cv2

    from models.detector import create_detector
    from models.detector.nanodet import NanoDetSettings

    defaults = NanoDetSettings()
    options = {} if max_shrink is None else {"max_shrink": max_shrink}
    detector = create_detector(
        defaults.kind, score_threshold=defaults.score_threshold, threads=1, **options
    )
    out = []
    for frame in paths:
        images = [cv2.imread(str(p), cv2.IMREAD_COLOR) for p in frame]
        if any(image is None for image in images):
            raise SystemExit(f"cannot read one of {[str(p) for p in frame]}")
        out.append(detector.detect([np.asarray(image) for image in images]))
    return out, detector.describe()


def inside_floor(xy: np.ndarray) -> np.ndarray:
    return (xy[:, 0] >= 0) & (xy[:, 0] <= FLOOR_M[0]) & (xy[:, 1] >= 0) & (xy[:, 1] <= FLOOR_M[1])


def chain_scores(
    detections: Sequence[Sequence[Detections]],
    truth_frames: Sequence[FramePositions],
    runtime: MomRuntime,
    associate: AssociateStage | None = None,
) -> dict[str, dict[str, float]]:
    """The daemon's chain (``associate``: another association stage) over the frames: its
    served tracks from frame ``STREAM_FROM`` on (``tracked``) and its associations before
    tracking, each frame alone (``frame``)."""
    from service.pipeline.chain import Chain, gate_to_area
    from service.tracking.tracker import RECOMMENDED, Tracker

    chain = Chain(Tracker(fps_hint=FPS, **RECOMMENDED), associate=associate)
    tracked, frame = DetectionScore(), DetectionScore()
    for index, (dets, truth) in enumerate(zip(detections, truth_frames, strict=True)):
        _, tracks = chain(index / FPS, dets, runtime, [True] * len(dets), index)
        if index >= STREAM_FROM:
            tracked.add(np.array([[t.x, t.y] for t in tracks]).reshape(-1, 2), truth.xy)
        found = gate_to_area(
            chain.associate(list(dets), runtime, max_error_px=chain.max_error_px), runtime, "drop"
        )
        frame.add(positions(found), truth.xy)
    return {"tracked": tracked.result(), "frame": frame.result()}


def people_boxes(
    detections: Sequence[Sequence[Detections]],
    truth_frames: Sequence[FramePositions],
    calibrations: Sequence[Calibration],
) -> list[list[Detections]]:
    """Each frame's boxes that belong to an annotated person (:func:`match_people`): the input
    of a perfect box filter (an oracle)."""
    out = []
    for dets, truth in zip(detections, truth_frames, strict=True):
        kept = []
        for d, c in zip(dets, calibrations, strict=True):
            mine = match_people(d.boxes, c, truth.xy) >= 0
            kept.append(Detections(d.boxes[mine], d.scores[mine], None))
        out.append(kept)
    return out


def nobody_boxes(
    detections: Sequence[Sequence[Detections]],
    truth_frames: Sequence[FramePositions],
    calibrations: Sequence[Calibration],
) -> Counter[str]:
    """What the boxes of no annotated person are, by their calibrated foot point: off the
    playground (people beyond it), or on it in the image column of a person who has a box
    (a second box or a fragment of them), of one who has none there (a box cut by an occluder,
    its bottom edge not at the feet), or of nobody (``NOBODY_KINDS``)."""
    kinds: Counter[str] = Counter()
    for dets, truth in zip(detections, truth_frames, strict=True):
        for d, c in zip(dets, calibrations, strict=True):
            owner = match_people(d.boxes, c, truth.xy)
            foot, height, seen = projected_people(c, truth.xy)
            on_floor = inside_floor(floor_points(d.boxes, c))
            for i in np.flatnonzero(owner < 0):
                if not on_floor[i]:
                    kinds[NOBODY_KINDS[0]] += 1
                    continue
                centre = (d.boxes[i, 0] + d.boxes[i, 2]) / 2
                across = np.where(seen, np.abs(centre - foot[:, 0]) / np.maximum(height, 1), np.inf)
                near = np.flatnonzero(across <= MATCH_GATE)
                if not len(near):
                    kinds[NOBODY_KINDS[3]] += 1
                else:
                    unboxed = ~np.isin(near, owner).all()
                    kinds[NOBODY_KINDS[2] if unboxed else NOBODY_KINDS[1]] += 1
    return kinds


def view_gaps(
    detections: Sequence[Sequence[Detections]],
    truth_frames: Sequence[FramePositions],
    calibrations: Sequence[Calibration],
    runtime: MomRuntime,
) -> np.ndarray:
    """Per pair of boxes of annotated people in two cameras of a frame [N, 3]: the gap (m)
    between their lone-view positions, its std along the gap from the floor maps (what the
    association's view gap gate reads: ``sqrt(u^T (C_a + C_b) u)``, covariances scaled by
    ``FLOOR_INFO_SCALE``) and 1 for two boxes of one person, 0 of two people."""
    rows = []
    for dets, truth in zip(detections, truth_frames, strict=True):
        owner = np.concatenate(
            [match_people(d.boxes, c, truth.xy) for d, c in zip(dets, calibrations, strict=True)]
        )
        camera = np.concatenate([np.full(len(d.boxes), k) for k, d in enumerate(dets)])
        alone = np.full((len(owner), len(dets), 4), np.nan, np.float32)
        alone[np.arange(len(owner)), camera] = np.concatenate([d.boxes for d in dets])
        xy = np.asarray(runtime.localize(alone), np.float64)
        views = runtime.floor_views(alone)
        if views is None:
            return np.zeros((0, 3))
        info = views[1][np.arange(len(owner)), camera] / FLOOR_INFO_SCALE**2
        cov = np.linalg.pinv(info)
        for a, b in zip(*np.triu_indices(len(owner), 1), strict=True):
            if camera[a] == camera[b] or owner[a] < 0 or owner[b] < 0:
                continue
            gap = xy[a] - xy[b]
            u = gap / max(float(np.linalg.norm(gap)), 1e-9)
            std = float(np.sqrt(u @ (cov[a] + cov[b]) @ u))
            rows.append((float(np.linalg.norm(gap)), std, float(owner[a] == owner[b])))
    return np.array(rows, np.float64).reshape(-1, 3)


def score_frames(
    detections: Sequence[Sequence[Detections]],
    truth_frames: Sequence[FramePositions],
    calibrations: Sequence[Calibration],
    runtime: MomRuntime,
    variants: bool = False,
) -> dict[str, Any]:
    """The served chain and the oracle bounds over all frames (see the module docstring);
    ``variants``: also the former fixed view gap and the boxes of annotated people only."""
    served, served_in, served_multi = DetectionScore(), DetectionScore(), DetectionScore()
    gated, gated_multi = DetectionScore(), DetectionScore()
    oracle, foot = DetectionScore(), DetectionScore()
    fp: Counter[str] = Counter()
    fn: Counter[str] = Counter()
    fp_views: Counter[str] = Counter()
    per_frame = []
    views = found_views = people = found_people = boxes_total = boxes_matched = 0
    for dets, truth in zip(detections, truth_frames, strict=True):
        xy = truth.xy
        found = serve(dets, runtime)
        where = positions(found)
        frame = DetectionScore()
        frame.add(where, xy)
        rows, matched = served.add(where, xy)
        served_in.add(where[inside_floor(where)], xy)
        served_multi.add(where[[len(a.cameras) >= 2 for a in found]], xy)
        kept = []
        for d, c in zip(dets, calibrations, strict=True):
            on_floor = inside_floor(floor_points(d.boxes, c))
            kept.append(Detections(d.boxes[on_floor], d.scores[on_floor], None))
        on_floor_found = serve(kept, runtime)
        gated.add(positions(on_floor_found), xy)
        gated_multi.add(positions([a for a in on_floor_found if len(a.cameras) >= 2]), xy)
        per_frame.append((truth.frame, len(xy), sum(len(d.boxes) for d in dets), frame.result()))
        labels = [match_people(d.boxes, c, xy) for d, c in zip(dets, calibrations, strict=True)]
        causes = breakdown(found, labels, rows, matched, len(xy))
        for total, counts in zip((fp, fn, fp_views), causes, strict=True):
            total.update(counts)
        for lab, cal in zip(labels, calibrations, strict=True):
            seen = projected_people(cal, xy)[2]
            views += int(seen.sum())
            found_views += int(np.isin(np.flatnonzero(seen), lab).sum())
            boxes_total += len(lab)
            boxes_matched += int((lab >= 0).sum())
        tuples, who = true_tuples([d.boxes for d in dets], labels, len(xy))
        people += len(xy)
        found_people += len(who)
        # the true association: the model on each person's boxes, scored against everyone
        oracle.add(runtime.localize(tuples.astype(np.float32)) if len(who) else tuples[:, 0], xy)
        foot.add(foot_point(tuples, calibrations) if len(who) else tuples[:, 0], xy)
    out: dict[str, Any] = {}
    if variants:
        for sigmas in SCALED_GAPS:
            scaled = functools.partial(associate, gap_sigmas=sigmas)
            out[f"gap_{sigmas:g}"] = chain_scores(detections, truth_frames, runtime, scaled)
        boxed = people_boxes(detections, truth_frames, calibrations)
        out["boxed"] = chain_scores(boxed, truth_frames, runtime)
        out["nobody"] = nobody_boxes(detections, truth_frames, calibrations)
        out["gaps"] = view_gaps(detections, truth_frames, calibrations, runtime)
    return out | {
        "served": served.result(),
        "served_inside": served_in.result(),
        "served_multi": served_multi.result(),
        "tracked": chain_scores(detections, truth_frames, runtime)["tracked"],
        "gated": gated.result(),
        "gated_multi": gated_multi.result(),
        "oracle": oracle.result(),
        "foot": foot.result(),
        "fp": fp,
        "fn": fn,
        "fp_views": fp_views,
        "per_frame": per_frame,
        "view_recall": 100.0 * found_views / max(views, 1),
        "views": views,
        "box_precision": 100.0 * boxes_matched / max(boxes_total, 1),
        "boxes": boxes_total,
        "people_found": 100.0 * found_people / max(people, 1),
        "people": people,
    }


def _f(value: float, digits: int = 1) -> str:
    return "–" if not np.isfinite(value) else f"{value:.{digits}f}"


def _score_cells(m: dict[str, float]) -> list[str]:
    return [_f(m["moda"]), _f(m["modp"]), _f(m["precision"]), _f(m["recall"]), _f(m["mean"], 3),
            f"{m['tp']:.0f} / {m['fp']:.0f} / {m['fn']:.0f}"]  # fmt: skip


def gap_section(gaps: np.ndarray) -> list[str]:
    """The view gap gate on real boxes: how far apart the lone views of one person and of two
    people land, against the std the gate reads (:func:`view_gaps`)."""
    if not len(gaps):
        return []
    gap, std, same = gaps.T
    one, two = same > 0, same == 0
    gates = {f"fixed {DEFAULT_MAX_VIEW_GAP_M:g} m (served)": gap <= DEFAULT_MAX_VIEW_GAP_M}
    for sigmas in SCALED_GAPS:
        radius = np.maximum(DEFAULT_MAX_VIEW_GAP_M, sigmas * std)
        gates[f"{DEFAULT_MAX_VIEW_GAP_M:g} m or {sigmas:g} std of the gap"] = gap <= radius
    rows = []
    for name, ok in gates.items():
        rows.append([name, _f(100 * ok[one].mean()), _f(100 * ok[two].mean())])
    bins = []
    for lo, hi in ((0.0, 0.6), (0.6, 1.0), (1.0, 2.0), (2.0, np.inf)):
        sel = one & (std >= lo) & (std < hi)
        if sel.any():
            bins.append([f"{lo:g}–{hi:g}", int(sel.sum()), _f(float(np.median(gap[sel])), 2),
                         _f(float(np.percentile(gap[sel], 95)), 2),
                         _f(100 * float((gap[sel] > DEFAULT_MAX_VIEW_GAP_M).mean()))])  # fmt: skip
    ratio = np.percentile(gap[one] / std[one], [50, 95, 99])
    return [
        "## The view gap gate on the real boxes",
        "",
        f"Every pair of boxes of annotated people in two cameras of a frame ({int(one.sum())} of "
        f"one person, {int(two.sum())} of two): each box localized alone by the served model, "
        "the gap between the two positions, and its std along the gap from the floor maps "
        f"(×{FLOOR_INFO_SCALE:g} for their overconfidence, `bench.real.multiviewx.view_gaps`). "
        "A lone view's range error grows with its distance from the camera, and so does the "
        "std: the gap of one person's two views, by std (m):",
        "",
        markdown_table(
            [
                "std of the gap m",
                "pairs of one person",
                "gap median m",
                "gap p95 m",
                f"gap > {DEFAULT_MAX_VIEW_GAP_M:g} m %",
            ],
            bins,
        ),
        "",
        f"Gap / std for one person's pairs: median {ratio[0]:.2f}, p95 {ratio[1]:.2f}, p99 "
        f"{ratio[2]:.2f}. The view gap gate alone (the reprojection and floor χ² gates act "
        "too):",
        "",
        markdown_table(
            ["view gap gate", "pairs of one person kept %", "pairs of two people admitted %"], rows
        ),
        "",
    ]


def report(result: dict, other: dict, header: str, command: str) -> str:
    """The markdown: what was run, the headline table, the detector input, the error breakdown,
    per frame. ``other``: the same scoring on the boxes of a detector with a larger input."""
    rows = []
    names = {
        "tracked": f"**product as the daemon serves it** (NanoDet → association → MoM → "
        f"tracker), served tracks, frames {STREAM_FROM + 1}–{len(result['per_frame'])}",
        "served": "product per frame: the associations before tracking (all frames)",
        "served_inside": f"the same, positions inside the {FLOOR_M[0]:g} × {FLOOR_M[1]:g} m "
        "playground",
        "served_multi": "the same, positions fused from 2+ cameras only",
        "gated": "associations of the boxes whose calibrated foot point is on the playground "
        "(oracle validity gate)",
        "gated_multi": "the same, positions fused from 2+ cameras only",
        "oracle": "true association + the same MoM model (oracle)",
        "foot": "true association + calibrated foot point (P known)",
    }
    for key, name in names.items():
        rows.append([name, *_score_cells(result[key])])
    extra = {
        **{
            f"gap_{g:g}": f"the same chain, view gap 2 m or {g:g} std of the gap (not served)"
            for g in SCALED_GAPS
        },
        "boxed": "the chain on the boxes of annotated people only (oracle box filter)",
    }
    for key, name in extra.items():
        if key in result:
            for part, label in (("tracked", "served tracks"), ("frame", "per frame")):
                rows.append([f"{name}: {label}", *_score_cells(result[key][part])])
    rows.append(["MVDet (calibrated, trained on MultiviewX's full training split)",
                 f"{MVDET_MODA:.1f}", "", "", "", "", ""])  # fmt: skip
    fp, fn, views = result["fp"], result["fn"], result["fp_views"]
    causes = [[f"FP: {c}", fp.get(c, 0)] for c in FP_CAUSES]
    causes += [[f"FP fused from {v} camera(s)", views.get(v, 0)] for v in ("1", "2", "3+")]
    causes += [[f"FN: {c}", fn.get(c, 0)] for c in FN_CAUSES]
    per_frame = [
        [f, n, b, _f(m["moda"]), _f(m["precision"]), _f(m["recall"]), _f(m["mean"], 3)]
        for f, n, b, m in result["per_frame"]
    ]
    inputs = [
        [
            r["detector"],
            _f(r["view_recall"]),
            f"{_f(r['box_precision'])} ({r['boxes']})",
            _f(r["oracle"]["moda"]),
            _f(r["served"]["moda"]),
            _f(r["served_multi"]["moda"]),
            _f(r["tracked"]["moda"]),
        ]
        for r in (result, other)
    ]
    s, o, t, m = result["served"], result["oracle"], result["tracked"], result["served_multi"]
    reading = (
        f"As the daemon serves it (its tracks), the product reaches MODA {_f(t['moda'])} % "
        f"(precision {_f(t['precision'])} %, recall {_f(t['recall'])} %; target ≥ 85 %, MVDet "
        f"{MVDET_MODA} %) from the third frame on, once a lone-view track can be confirmed "
        f"(1 s); its associations before tracking score {_f(s['moda'])} % per frame, "
        f"{_f(m['moda'])} % when only positions fused from 2+ cameras count (what the "
        "tracker's single-view confirmation and ghost check approach over time). With the true "
        f"association the same model reaches {_f(o['moda'])} % (recall {_f(o['recall'])} %, "
        f"mean {_f(o['mean'], 3)} m). The gap to it is the boxes of nobody: the same chain on "
        "the boxes of annotated people only reaches "
        f"{_f(result['boxed']['tracked']['moda'])} % as served and "
        f"{_f(result['boxed']['frame']['moda'])} % per frame (oracle box filter), so "
        "associating real people's boxes is not what is lost; the boxes of no annotated person "
        "(below: most of them people beyond the playground, which the set-up area gate "
        "drops, then second boxes and fragments of boxed people, whose bottom edge is not at "
        "the feet) become lone-view positions or mix with a neighbour. The view gap gate "
        "(third section) is a fixed 2 m as served; scaled with each position's own "
        "uncertainty (`gap_sigmas`, which joins far people's lone views), on the same model: "
        "at 3 std "
        f"{_f(result['gap_3']['tracked']['moda'])} % as served "
        f"({_f(result['gap_3']['frame']['moda'])} % per frame), at 4 std "
        f"{_f(result['gap_4']['tracked']['moda'])} % "
        f"({_f(result['gap_4']['frame']['moda'])} %), against {_f(t['moda'])} % "
        f"({_f(s['moda'])} %) at 2 m (8 frames of 20-22 people: one person-frame is 0.6 "
        "points; on another training of the model, 80.9 % at 2 m and 85.0 % at 4 std: the "
        "gate's effect is within the spread between trainings); not served, as it costs the "
        "simulated room's stream gate 5 points of MOTA "
        "(`bench/results/real_cmc_chain_tuning.md`). "
        "The shipped detector finds "
        f"{_f(result['view_recall'])} % of the person-views (a box whose bottom centre lies "
        f"within {MATCH_GATE:g} projected heights of the true floor point) and "
        f"{_f(result['people_found'])} % of the people have a box in some camera: recall is "
        "not what limits MODA here (second table). People walk beyond the annotated "
        f"playground, in view: set up on the {FLOOR_M[0]:g} × {FLOOR_M[1]:g} m playground the "
        "chain's set-up area gate drops them (set up on 25 × 16 m, the model served those at "
        "y 15-16 m as false positives)."
    )
    return "\n".join(
        [
            "# MultiviewX images end to end (real rendered images, shipped detector)",
            "",
            f"Generated by `{command}`. {machine_line()}",
            "",
            f"Data: {CITATION}. {header}",
            "",
            "**Reading.** " + reading,
            "",
            markdown_table(COLUMNS, rows),
            "",
            f"Hungarian matching per frame on the floor, {GATE_M} m gate; MODA = 1 − (FP + FN) / "
            "GT, MODP = mean(1 − d / 0.5 m) over the matches (MVDet's definitions). Ground truth: "
            "every annotated person in the frame.",
            "",
            "## Where the product's errors come from",
            "",
            "Each served position left unmatched (FP) and each person left unmatched (FN), by "
            "the true person of each box (`bench.real.chain.breakdown`; a box belongs to the "
            "person whose projected floor point is within 0.3 projected heights of its bottom "
            "centre, one to one).",
            "",
            markdown_table(["cause", "count"], causes),
            "",
            "What the boxes of nobody are (`bench.real.multiviewx.nobody_boxes`; a box of "
            "nobody has no annotated person within 0.3 projected heights of its bottom centre):",
            "",
            markdown_table(
                ["box of nobody", "count"],
                [[k, result.get("nobody", Counter()).get(k, 0)] for k in NOBODY_KINDS],
            ),
            "",
            *gap_section(result.get("gaps", np.zeros((0, 3)))),
            "## Detector input",
            "",
            "The same scoring on the boxes of the daemon's default detector and of one with a "
            "larger input for 1920×1080 frames (`max_shrink`, "
            "`bench/results/highres_recall.md`): person-views found, share of boxes that "
            "belong to an annotated person, and MODA with the true association, per frame and "
            "as served.",
            "",
            markdown_table(INPUT_COLUMNS, inputs),
            "",
            "## Per frame (associations before tracking)",
            "",
            markdown_table(FRAME_COLUMNS, per_frame),
            "",
        ]
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--frames", type=int, default=600, help="simulated set-up frames")
    parser.add_argument("--people", type=int, default=20, help="walkers in the set-up scene")
    parser.add_argument("--fps", type=float, default=2.0, help="set-up scene frame rate")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--train-seconds", type=float, default=240.0)
    parser.add_argument(
        "--compare-shrink", type=float, default=2.0, help="max_shrink of the compared detector"
    )
    parser.add_argument("--out", type=Path, default=RESULTS / "real_multiviewx.md")
    args = parser.parse_args(argv)
    folder = data_folder(args.data, "multiviewx")
    if folder is None:
        return 0
    from models.simulate import simulate

    truth_frames = load_positions(folder, GRID)
    floor_xy = np.concatenate([p.xy for p in truth_frames])
    floor = np.c_[floor_xy, np.zeros(len(floor_xy))]
    calibrations = [
        c.facing(floor) for c in load_calibrations(folder, list(CAMERAS), "intrinsic", IMAGE_SIZE)
    ]
    paths = image_sets(folder)
    if len(paths) != len(truth_frames):
        raise SystemExit(f"{folder}: {len(paths)} image sets but {len(truth_frames)} annotations")
    _log(f"detecting {len(paths)} frame sets")
    detections, detector = detect_all(paths)
    larger, larger_detector = detect_all(paths, args.compare_shrink)
    config = scene_config(calibrations, args.people, args.fps)
    setup = simulate(config, args.frames, seed=args.seed).dataset
    _log(f"simulated set-up: {setup.summary()}")
    with tempfile.TemporaryDirectory(prefix="momloc-mvx-") as tmp:
        started = time.monotonic()
        runtime, epochs = train_runtime(setup, Path(tmp) / "model", args.train_seconds, args.seed)
        trained = time.monotonic() - started
        _log(f"trained in {trained:.0f} s, policy {runtime.policy}")
        result = score_frames(detections, truth_frames, calibrations, runtime, variants=True)
        other = score_frames(larger, truth_frames, calibrations, runtime)
    result["detector"] = f"{detector} (default)"
    other["detector"] = larger_detector
    header = (
        f"Images: {len(paths)} frame sets × {len(CAMERAS)} cameras {IMAGE_SIZE[0]}×"
        f"{IMAGE_SIZE[1]} (image `NNNN.jpg` of every camera ↔ the NNNN-th annotation file in name "
        "order; MultiviewX's first 10 frames, 2 fps (people walk 0.6 m between frames), "
        "which MVDet trains on: no MultiviewX data trains "
        f"the model here), detector: {detector} (the daemon's default settings, one thread). "
        "Model: MoM + "
        f"bbox, `models.mom.training.train.train_model` defaults with a {args.train_seconds:g} s "
        f"budget "
        f"({trained:.0f} s used, {epochs} epochs), served policy `{runtime.policy}`, trained "
        "on a simulated set-up "
        f"recording: `models.simulate` on the MultiviewX cameras (calibration read from the data "
        f"at run time; the served chain never sees it), {args.people} walkers over the whole "
        f"{FLOOR_M[0]:g} × {FLOOR_M[1]:g} m playground, {args.frames} frames at {args.fps:g} "
        f"fps, seed {args.seed}, detector "
        f"profile `{setup_profile(config)}` ({setup.n} rows)."
    )
    text = report(result, other, header, command_line("bench.real.multiviewx", argv))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)
    return 0


def setup_profile(config: SceneConfig) -> str:
    """The detector profile's name the set-up scene used."""
    profile = config.detector_profile
    return profile if isinstance(profile, str) else str(getattr(profile, "name", profile))


if __name__ == "__main__":
    raise SystemExit(main())

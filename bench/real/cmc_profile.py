"""The real room's evidence as profile rows: the ``cmc`` profile and the CMC edge source.

``bench.real.cmc_detector`` measured the CMC room's real Faster R-CNN boxes against the true people
(Ong et al., IEEE TPAMI 2020) and, with the same code, the simulated ``cmc-room`` seen by an
exact detector. A profile describes the detector's error against the *tight body box* the
simulator draws, so every edge figure here is real minus geometry (:func:`detector_edges`): the
bias less the geometric bias, the robust spread with the geometric spread taken out in
quadrature. Called by ``bench.detector.profiles``, which writes the profiles and the record.

What CMC cannot show is said, not guessed silently (:data:`CMC_ASSUMED`): nobody in CMC is cut
by the image border (truncation misses are assumed as for the other profiles), 2 z_c is not a
person's stature (the top edge's bias is not measurable, only its spread), and the detector's
scale error cannot be told from its edge errors (the shared 0.05 of the other profiles is
assumed and taken out of each edge's own spread).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from models.simulate.profile import FORMAT, parse_profile

CMC_MEASUREMENTS = (
    Path(__file__).resolve().parents[1] / "results" / "cmc_detector_measurements.json"
)
CMC_DETECTOR = (
    "Faster R-CNN ResNet-50 (TF model zoo, COCO, 2018-01-28), person class, score >= 0.3: "
    "the CMC authors' boxes"
)
CMC_ASSUMED: dict[str, Any] = {
    "zero_recall_px": 20.0,
    "scale_sigma": 0.05,
    "truncation_extra": 0.3,
    "miss_correlation_s": 0.5,
    "fp_persistence_s": 1.0,
    "top_bias": 0.0,
}


def load(path: Path = CMC_MEASUREMENTS) -> dict[str, Any] | None:
    """The measurement file of ``bench.real.cmc_detector``, or None when it was never run."""
    return json.loads(path.read_text()) if path.is_file() else None


def detector_edges(data: dict[str, Any], edge: str) -> list[tuple[float, float, float, float, int]]:
    """(low, high, bias, sigma, n) per height bin: real minus the exact simulated geometry."""
    geometry = {(b["low"], b["high"]): b for b in data["geometry"]["edges"][edge]}
    out = []
    for b in data["real"]["edges"][edge]:
        g = geometry.get((b["low"], b["high"]))
        if g is None:
            continue
        sigma = math.sqrt(max(b["sigma"] ** 2 - g["sigma"] ** 2, 0.0))
        out.append((b["low"], b["high"], b["bias"] - g["bias"], sigma, b["n"]))
    return out


def _variance(block: dict[str, Any], edge: str) -> float:
    """The edge's robust variance pooled over the height bins (weighted by people)."""
    bins = block["edges"][edge]
    return sum(b["sigma"] ** 2 * b["n"] for b in bins) / sum(b["n"] for b in bins)


def pooled_sigma(data: dict[str, Any], edge: str) -> float:
    """The detector's own spread of ``edge`` over all heights: real less geometry."""
    return math.sqrt(max(_variance(data["real"], edge) - _variance(data["geometry"], edge), 0.0))


def edge_correlation_s(data: dict[str, Any]) -> float:
    """The detector's own bottom-edge correlation time: the real lag-1 covariance less the
    geometric one (gait), over the detector's own variance, at the data's frame rate."""
    real, geom = _variance(data["real"], "bottom"), _variance(data["geometry"], "bottom")
    own = real - geom
    rho = (data["real"]["bottom_lag1"] * real - data["geometry"]["bottom_lag1"] * geom) / own
    return round(-1.0 / (4.0 * math.log(min(max(rho, 1e-3), 0.999))), 2)


def own_sigma(total: float, scale_sigma: float) -> float:
    """An edge's own sigma so that with the shared scale error its total is ``total``."""
    return round(math.sqrt(max(total**2 - (scale_sigma / 2) ** 2, 0.0)), 4)


def extra_miss(bins: list[dict[str, float]], free: float) -> tuple[list[float], list[float]]:
    """Occlusion table: extra miss 1 - recall / free recall at each bin's middle."""
    xs, ys = [0.0], [0.0]
    for b in bins:
        xs.append(round((b["low"] + min(b["high"], 1.0)) / 2, 3))
        ys.append(round(min(max(1 - b["recall"] / free, 0.0), 1.0), 3))
    return [*xs, 1.0], [*ys, ys[-1]]


def cmc_profile(
    data: dict[str, Any], keypoints: tuple[dict[str, Any], str], shared: dict[str, Any]
) -> tuple[dict[str, Any], list[list[str]]]:
    """The ``cmc`` profile from the measurement ``data`` and its record rows; ``keypoints`` is
    the keypoint block and its note (the MediaPipe measurement), ``shared`` the keys every
    profile has in common (reference height, minimum height, occlusion shrink)."""
    a, real = CMC_ASSUMED, data["real"]
    run = data["machine"].split("run ")[-1].rstrip(".")
    where = f"bench/results/cmc_detector_measurements.json ({run})"
    label = f"CMC real room, {where}"
    bottom, top = detector_edges(data, "bottom"), detector_edges(data, "top_person")
    nodes = [x for b in bottom for x in (b[0], b[1])]
    # The box centre's column moves by the mean of the two side errors: sigma_side = √2 sigma_c.
    # Pooled over heights: per bin, the real and the simulated arm swing differ by more than
    # the detector's own spread.
    side = round(math.sqrt(2) * pooled_sigma(data, "centre"), 4)
    # Misses by size where nothing else interferes: CMC1 (3 people, almost no occlusion); the
    # crowd's misses come from the occlusion table, calibrated on CMC2 through the simulator.
    recall = data["per_sequence"]["CMC1"]["recall_by_height"]
    # Flat pieces per bin (a step at the shared edge), falling to recall 0 below the lowest.
    miss_x = [a["zero_recall_px"]] + [x for b in recall for x in (b["low"], b["high"])]
    miss_y = [1.0] + [round(1 - b["recall"], 4) for b in recall for _ in (0, 1)]
    calibrated = data.get("calibrated")
    if calibrated is not None:
        occ_x, occ_y = calibrated["fraction"], calibrated["probability"]
    else:
        crowd = data["per_sequence"]["CMC2"]
        occ_x, occ_y = extra_miss(crowd["recall_by_occlusion"], crowd["recall_free"])
    # False boxes: CMC1's boxes of nobody with a foot point in the area or off the floor, less
    # those the exact simulated set-up recording makes of pairing alone (outside people cut by
    # the image's bottom edge, boxes shrunk by occlusion failing the IoU gate).
    cameras = 4
    false = (
        data["per_sequence"]["CMC1"]["unmatched"]["false_per_frame"]
        - data["geometry_setup"]["unmatched"]["false_per_frame"]
    )
    false_rate = round(max(false, 0.0) / cameras, 3)
    fp_heights = real["unmatched"]["false_height_px"]
    fp_rows = real["unmatched"]["false_bottom_rows"]
    correlation = edge_correlation_s(data)
    rows = [
        ["cmc", "bottom edge bias / sigma", label + " minus geometry", _edges(bottom)],
        ["cmc", "top edge sigma (per-person offset out)", label + " minus geometry", _edges(top)],
        ["cmc", "side edge sigma (√2 × centre, pooled)", label + " minus geometry", f"{side}"],
        ["cmc", "edge correlation time", label, f"{correlation} s (lag-1 real "
         f"{real['bottom_lag1']:.2f}, geometry {data['geometry']['bottom_lag1']:.2f})"],
        ["cmc", "recall by height", label, ", ".join(
            f"{b['low']}-{b['high']} px {b['recall']:.2f} (n={b['n']})" for b in recall)],
        ["cmc", "extra miss by occlusion", label + (" (CMC2, calibrated through the simulator)"
         if calibrated is not None else " (CMC2)"), ", ".join(
            f"{x:.2f}: {y:.2f}" for x, y in zip(occ_x, occ_y, strict=True))],
        ["cmc", "false positives / camera and frame", label + " (CMC1: foot point in the area "
         "or off the floor, less the exact simulation's pairing artefacts)", f"{false_rate:.3f}"],
    ]  # fmt: skip
    note = (
        f"{label}: Faster R-CNN boxes against the true people projected with P, minus the "
        "exact simulated cmc-room's geometry (bench/real/cmc_detector.py, "
        "bench/real/cmc_profile.py). "
        f"Assumed: recall 0 at {a['zero_recall_px']:g} px, scale sigma {a['scale_sigma']}, "
        f"truncation extra miss {a['truncation_extra']} (nobody truncated in CMC), top bias "
        f"{a['top_bias']} (2 z_c is not stature), miss correlation {a['miss_correlation_s']} s, "
        f"false-positive lifetime {a['fp_persistence_s']} s, aspects and hotspots; "
        f"{keypoints[1]}"
    )
    profile = {
        "format": FORMAT,
        "name": "cmc",
        "detector": CMC_DETECTOR,
        "source": note,
        **shared,
        "keypoints": keypoints[0],
        "miss": {
            "height_px": [round(x, 1) for x in miss_x],
            "probability": miss_y,
            "occlusion": {"fraction": occ_x, "probability": occ_y},
            "truncation": {
                "fraction": [0, 0.1, 0.4, 0.7, 1],
                "probability": [0, 0, a["truncation_extra"], 1, 1],
            },
            "correlation_s": a["miss_correlation_s"],
        },
        "edges": {
            "height_px": nodes,
            "bottom_bias": [round(b[2], 4) for b in bottom for _ in (0, 1)],
            "bottom_sigma": [own_sigma(b[3], a["scale_sigma"]) for b in bottom for _ in (0, 1)],
            "top_bias": [a["top_bias"]] * len(nodes),
            "top_sigma": [own_sigma(t[3], a["scale_sigma"]) for t in top for _ in (0, 1)],
            "side_sigma": [side] * len(nodes),
            "scale_sigma": a["scale_sigma"],
            "scale_clip": 0.3,
            "correlation_s": correlation,
        },
        "false_positives": {
            "per_frame": false_rate,
            "persistence_s": a["fp_persistence_s"],
            "height_px": [round(v, 1) for v in fp_heights],
            "aspect": [0.3, 0.6],
            "hotspots": 3,
            "hotspot_share": 0.6,
            "bottom": [round(v, 3) for v in fp_rows],
            "jitter": 0.02,
        },
    }
    parse_profile(profile, where="cmc")
    return profile, rows


def _edges(bins: list[tuple[float, float, float, float, int]]) -> str:
    return ", ".join(f"{b[0]:g}-{b[1]:g} px {b[2]:+.3f} / {b[3]:.3f} (n={b[4]})" for b in bins)

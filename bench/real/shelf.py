"""Shelf: real OpenPose keypoints against true 3D joints, next to the keypoint noise the
simulator's profile assumes → bench/results/real_shelf.md and real_shelf.json.

Shelf (``../shared/data/shelf``: 5 calibrated 1032×776 cameras, 301 frames, up to 4 people
working at a shelf) holds real OpenPose BODY25 detections (joints not grouped into people) and
the true 3D skeletons (15 joints). The simulator draws keypoints as the true projected joint plus
``N(0, sigma · h + pixels)`` px, no pose at all with a probability by box height, and whole joint
groups going wild at a rate (:mod:`models.simulate.noise`, the profile's ``keypoints`` block,
calibrated on MediaPipe by ``bench/keypoints/keypoint_noise.py``). This bench measures the same
quantities on a real detector with true joints, which vtest (no true joints) could not give.

Method. Every true joint is projected with the calibration into every camera where it is in
front and inside the image; ``h`` is the person's projected height there (the vertical extent of
the projected joints, head top to ankles: the box height up to the feet's and hair's margins).
Per camera, frame and BODY25 joint type, the detected candidates are matched one to one to the
people's projected joints (Hungarian on distance / h, gate ``GATE_H`` = 0.5 h). Then per joint:

- **miss**: no candidate within the gate; **no pose**: a person-view with no joint matched;
- **gross**: matched but more than ``GROSS_H`` (0.15 h) off; per joint group (the simulator's
  torso = shoulders and hips, limbs = elbows, wrists, knees, ankles), the share of person-views
  where any joint of the group is gross (the simulator draws one event per group);
- **noise** of the rest: bias (median signed residual) and robust spread (1.4826 · MAD per axis,
  pooled), in px and as a fraction of h; ``sigma`` and ``pixels`` fitted (non-negative least
  squares) to the spread per height bin, as the profile's model has it.

Caveats: Shelf's "neck" (bottom of the head) is not OpenPose's neck (between the shoulders), and
its hips are the annotators' joint centres, so a bias there is partly a definition offset, not
noise (both listed, neither in the groups). Matching joint by joint without grouping can pair a
person's missed joint with a neighbour's within the gate: people at the shelf stand close, which
makes the miss rate a lower bound and can add to the gross rate.

Usage::

    python -m bench.real.shelf [--data ../shared/data] [--out bench/results/real_shelf.md]
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment, nnls

from bench.real.data import DEFAULT_DATA, data_folder
from bench.real.shelf_data import (
    SHELF_NAMES,
    SHELF_TO_BODY25,
    TOP_HEAD,
    load_cameras,
    load_detections,
    load_truth,
)
from bench.report import RESULTS, command_line, machine_line, markdown_table, strict_json

GATE_H = 0.5
GROSS_H = 0.15
GROUPS = {"torso": (2, 3, 8, 9), "limbs": (0, 1, 4, 5, 6, 7, 10, 11)}  # Shelf joint indices
HEIGHT_BINS = (0.0, 200.0, 300.0, 400.0, 1e9)
CITATION = (
    'Shelf (V. Belagiannis et al., "3D Pictorial Structures for Multiple Human Pose '
    'Estimation", CVPR 2014) with the OpenPose BODY25 detections and file formats of Y. Zhang '
    'et al., "4D Association Graph for Realtime Multi-person Motion Capture Using Multiple Video '
    'Cameras", CVPR 2020 (github.com/zhangyux15/4d_association commit 6dd8093)'
)


def robust_sigma(values: np.ndarray) -> float:
    """1.4826 · median absolute deviation: a normal's sigma that a few wild values do not set."""
    values = np.asarray(values, float)
    if not values.size:
        return float("nan")
    return float(1.4826 * np.median(np.abs(values - np.median(values))))


def match_joint(truth_px: np.ndarray, heights: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """[P] index of the candidate [n, 3] matched to each projected joint [P, 2] (-1: none within
    ``GATE_H`` of the person's height), one to one."""
    out = np.full(len(truth_px), -1, np.int64)
    ok = np.isfinite(truth_px).all(axis=1)
    if not len(candidates) or not ok.any():
        return out
    dist = np.linalg.norm(truth_px[:, None] - candidates[None, :, :2], axis=2)
    cost = np.where(ok[:, None], dist / heights[:, None], np.inf)
    cost = np.where(cost <= GATE_H, cost, 1e6)
    rows, cols = linear_sum_assignment(cost)
    keep = cost[rows, cols] <= GATE_H
    out[rows[keep]] = cols[keep]
    return out


def measure(folder: Path) -> dict[str, Any]:
    """Residuals of every true joint-view: per joint arrays of (h, dx, dy) or a miss."""
    cameras = load_cameras(folder)
    truth = load_truth(folder / "gt_shelf15_3d.txt")
    detections = [
        load_detections(folder / "detection_openpose_body25" / f"{k}.txt", c.image_size)
        for k, c in enumerate(cameras)
    ]
    joints = sorted(SHELF_TO_BODY25)
    records: list[
        tuple[int, int, float, float, float]
    ] = []  # view id, joint, h, dx, dy (NaN: miss)
    views = 0
    for k, cam in enumerate(cameras):
        w, h_img = cam.image_size
        for f, people in enumerate(truth):
            if not len(people.ids):
                continue
            px, depth = cam.project(people.joints)  # [P, 15, 2], [P, 15]
            inside = (depth > 0.1) & (px[..., 0] >= 0) & (px[..., 0] < w)
            inside &= (px[..., 1] >= 0) & (px[..., 1] < h_img) & people.valid
            ys = np.where(people.valid & (depth > 0.1), px[..., 1], np.nan)
            height = np.nanmax(ys, axis=1) - np.nanmin(ys, axis=1)
            in_view = inside[:, TOP_HEAD] | inside.any(axis=1)
            for p in np.flatnonzero(in_view & (height > 20)):
                views += 1
                view_id = views
                for s in joints:
                    if not inside[p, s]:
                        continue
                    cand = detections[k][f][SHELF_TO_BODY25[s]]
                    target = np.full((len(people.ids), 2), np.nan)
                    target[p] = px[p, s]
                    # match all people at once so a neighbour keeps their own candidate
                    others = inside[:, s]
                    target[others] = px[others, s]
                    match = match_joint(target, np.maximum(height, 20.0), cand)
                    j = match[p]
                    if j < 0:
                        records.append((view_id, s, float(height[p]), np.nan, np.nan))
                    else:
                        d = cand[j, :2] - px[p, s]
                        records.append((view_id, s, float(height[p]), float(d[0]), float(d[1])))
    return {"records": np.array(records, float), "views": views}


def summarise(records: np.ndarray, views: int) -> dict[str, Any]:
    """The figures of the module docstring from the per-joint records."""
    view, joint, h, dx, dy = records.T
    found = np.isfinite(dx)
    err = np.hypot(dx, dy) / h
    gross = found & (err > GROSS_H)
    inlier = found & ~gross
    per_joint = {}
    for s in sorted(SHELF_TO_BODY25):
        m = joint == s
        per_joint[SHELF_NAMES[s]] = {
            "n": int(m.sum()),
            "miss": float(np.mean(~found[m])),
            "gross": float(gross[m].sum() / max(found[m].sum(), 1)),
            "bias_x_h": float(np.median(dx[m & inlier] / h[m & inlier])),
            "bias_y_h": float(np.median(dy[m & inlier] / h[m & inlier])),
            "sigma_px": robust_sigma(np.r_[dx[m & inlier], dy[m & inlier]]),
            "sigma_h": robust_sigma(np.r_[(dx / h)[m & inlier], (dy / h)[m & inlier]]),
        }
    grouped = np.zeros(len(records), bool)
    for members in GROUPS.values():
        grouped |= np.isin(joint, members)
    groups = {}
    for name, members in GROUPS.items():
        m = np.isin(joint, members)
        views_with = np.unique(view[m & found])
        wild = np.unique(view[m & gross])
        resid = np.r_[dx[m & inlier] - np.median(dx[m & inlier]),
                      dy[m & inlier] - np.median(dy[m & inlier])]  # fmt: skip
        groups[name] = {
            "joint_views": int(m.sum()),
            "miss": float(np.mean(~found[m])),
            "gross_joint": float(gross[m].sum() / max(found[m].sum(), 1)),
            "gross_group": float(len(wild) / max(len(views_with), 1)),
            "sigma_px": robust_sigma(resid),
        }
    fit_rows, bins = [], []
    for lo, hi in itertools.pairwise(HEIGHT_BINS):
        m = grouped & inlier & (h >= lo) & (h < hi)
        if m.sum() < 30:
            continue
        sig = robust_sigma(np.r_[dx[m] - np.median(dx[m]), dy[m] - np.median(dy[m])])
        bins.append({"h_px": float(np.median(h[m])), "n": int(m.sum()), "sigma_px": sig})
        fit_rows.append((float(np.median(h[m])), sig))
    coef = nnls(np.array([[hh, 1.0] for hh, _ in fit_rows]), np.array([s for _, s in fit_rows]))[0]
    matched_views = np.unique(view[found])
    return {
        "person_views": views,
        "no_pose": 1.0 - len(matched_views) / max(views, 1),
        "height_px_median": float(np.median(h)),
        "groups": groups,
        "joints": per_joint,
        "bins": bins,
        "fit": {"sigma": float(coef[0]), "pixels": float(coef[1])},
    }


def profile_figures(name: str, height_px: float, image_height: float) -> dict[str, Any]:
    """What profile ``name`` assumes at Shelf's median person height."""
    from models.simulate.profile import KEYPOINT_GROUPS, load_profile

    profile = load_profile(name)
    kp = profile.keypoints
    ref = float(profile.reference_height(np.array([height_px]), np.array([image_height]))[0])
    return {
        "name": name,
        "sigma": kp.sigma,
        "pixels": kp.pixels,
        "noise_px_at_median_h": kp.sigma * height_px + kp.pixels,
        "no_pose_at_median_h": float(kp.miss(np.array([ref]))[0]) if kp.misses else 0.0,
        "gross": {group: kp.gross[joints[0]] for group, joints in KEYPOINT_GROUPS.items()},
    }


def _pct(value: float) -> str:
    return f"{100.0 * value:.1f} %"


def report(measured: dict[str, Any], profile: dict[str, Any], command: str) -> str:
    """The markdown: the comparison with the profile, per group, per height, per joint."""
    fit, groups = measured["fit"], measured["groups"]
    compare = [
        ["noise model sigma · h + pixels: sigma", f"{fit['sigma']:.4f}", f"{profile['sigma']:g}"],
        ["noise model: pixels", f"{fit['pixels']:.2f}", f"{profile['pixels']:g}"],
        [
            f"noise at the median height ({measured['height_px_median']:.0f} px), px",
            f"{fit['sigma'] * measured['height_px_median'] + fit['pixels']:.1f}",
            f"{profile['noise_px_at_median_h']:.1f}",
        ],
        [
            "no pose in a person-view",
            _pct(measured["no_pose"]),
            _pct(profile["no_pose_at_median_h"]),
        ],
        [
            "gross, torso group (per person-view)",
            _pct(groups["torso"]["gross_group"]),
            _pct(profile["gross"]["torso"]),
        ],
        [
            "gross, limbs group (per person-view)",
            _pct(groups["limbs"]["gross_group"]),
            _pct(profile["gross"]["limbs"]),
        ],
        [
            "joint missed (torso / limbs)",
            f"{_pct(groups['torso']['miss'])} / {_pct(groups['limbs']['miss'])}",
            "only through no pose, occlusion and the image border",
        ],
    ]
    by_group = [
        [name, g["joint_views"], _pct(g["miss"]), _pct(g["gross_joint"]), _pct(g["gross_group"]),
         f"{g['sigma_px']:.1f}"]
        for name, g in groups.items()
    ]  # fmt: skip
    by_height = [[f"{b['h_px']:.0f}", b["n"], f"{b['sigma_px']:.1f}"] for b in measured["bins"]]
    by_joint = [
        [name, j["n"], _pct(j["miss"]), _pct(j["gross"]), f"{j['bias_x_h']:+.3f}",
         f"{j['bias_y_h']:+.3f}", f"{j['sigma_px']:.1f}", f"{j['sigma_h']:.4f}"]
        for name, j in measured["joints"].items()
    ]  # fmt: skip
    return "\n".join(
        [
            "# Shelf: real OpenPose keypoints against true 3D joints",
            "",
            f"Generated by `{command}`. {machine_line()}",
            "",
            f"Data: {CITATION}. {measured['person_views']} person-views (5 cameras, 301 "
            f"frames); median projected person height {measured['height_px_median']:.0f} px "
            f"at 1032×776. Method, gate ({GATE_H} h) and gross threshold ({GROSS_H} h): "
            "`bench/real/shelf.py`'s docstring. Figures also in `real_shelf.json`.",
            "",
            f"## Measured vs the simulator's `{profile['name']}` profile (keypoints block)",
            "",
            markdown_table(["quantity", "Shelf, OpenPose (measured)", "profile"], compare),
            "",
            "The profile's keypoints were calibrated on MediaPipe Pose (the product's keypoint "
            "path) on vtest without true joints; OpenPose is another estimator, so a gap is "
            "evidence about the real-keypoint regime, not a defect of either.",
            "",
            "## By joint group",
            "",
            markdown_table(
                [
                    "group",
                    "joint-views",
                    "missed",
                    "gross (per joint)",
                    "gross (per person-view)",
                    "robust sigma px",
                ],
                by_group,
            ),
            "",
            "## Noise by projected height (torso and limbs, inliers)",
            "",
            markdown_table(["median h px", "joint residuals", "robust sigma px"], by_height),
            "",
            "## By joint",
            "",
            markdown_table(
                [
                    "joint",
                    "views",
                    "missed",
                    "gross",
                    "bias x / h",
                    "bias y / h",
                    "sigma px",
                    "sigma / h",
                ],
                by_joint,
            ),
            "",
        ]
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--profile", default="nanodet", help="simulator profile to compare with")
    parser.add_argument("--out", type=Path, default=RESULTS / "real_shelf.md")
    args = parser.parse_args(argv)
    folder = data_folder(args.data, "shelf")
    if folder is None:
        return 0
    raw = measure(folder)
    measured = summarise(raw["records"], raw["views"])
    image_height = float(load_cameras(folder)[0].image_size[1])
    profile = profile_figures(args.profile, measured["height_px_median"], image_height)
    text = report(measured, profile, command_line("bench.real.shelf", argv))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    payload = {"data": CITATION, "measured": measured, "profile": profile}
    args.out.with_suffix(".json").write_text(
        json.dumps(strict_json(payload, 5), indent=1, sort_keys=True) + "\n"
    )
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

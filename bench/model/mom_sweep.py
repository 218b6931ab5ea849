"""Design sweep for the MoM model: which sizes, sampler and λ the defaults use, and why.

Run ``python -m bench.model.mom_sweep [--quick]``: trains each variant on the simulator's
indoor-2cam preset (train seed 1, held-out test seed 2, the adaptive schedule with early stopping)
and writes
``bench/results/mom_sweep.md``, one row per variant as it finishes. Test error is split by the
number of cameras that see the person: single-view rows (depth from one camera) dominate the mean.
``--presets`` then appends a table of the same defaults on other scenes (1, 3, 6 cameras,
1920×1080, 80 % of views hidden).
"""

from __future__ import annotations

import datetime as dt
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parents[1] / "results" / "mom_sweep.md"

VARIANTS: list[tuple[str, dict]] = [
    ("default (extent rows, uniform points, adaptive widths, λ=0.1)", {}),
    ("paper input only (no extent rows)", {"tuning": {"extent": False}}),
    ("body-shaped points", {"tuning": {"distribution": "body"}}),
    ("narrow: camera 32, global 64", {"tuning": {"camera_width": 32, "global_width": 64}}),
    ("wide: camera 128, global 256", {"tuning": {"camera_width": 128, "global_width": 256}}),
    ("no decoder (λ = 0)", {"decoder": False}),
    ("strong decoder (λ = 1)", {"tuning": {"rec_weight": 1.0}}),
    ("no view dropout", {"tuning": {"view_dropout": 0.0}}),
]


def evaluate(model_dir: Path, test) -> dict:
    from models.mom.runtime import MomRuntime

    runtime = MomRuntime.load(model_dir)
    world = runtime.localize(test.boxes, test.keypoints)
    error = np.linalg.norm(world - test.world[:, :2], axis=1)
    views = test.visible().sum(axis=1)
    out = {"mean": np.nanmean(error), "acc": np.nanmean(error <= 0.3) * 100}
    out["mean2"] = np.nanmean(error[views >= 2])
    out["acc2"] = np.nanmean(error[views >= 2] <= 0.3) * 100
    out["mean1"] = np.nanmean(error[views == 1]) if (views == 1).any() else float("nan")
    return out


def drop_views(data, fraction: float, seed: int):
    """The same dataset with ``fraction`` of the visible (row, camera) views hidden (NaN)."""
    from models.data.dataset import MomDataset

    rng = np.random.default_rng(seed)
    boxes = data.boxes.copy()
    hide = data.visible() & (rng.random(data.visible().shape) < fraction)
    boxes[hide] = np.nan
    keypoints = None if data.keypoints is None else data.keypoints.copy()
    if keypoints is not None:
        keypoints[hide] = np.nan
    keep = np.isfinite(boxes).all(axis=2).any(axis=1)
    return MomDataset(
        data.world[keep],
        boxes[keep],
        data.frame[keep],
        data.track[keep],
        data.image_size,
        None if keypoints is None else keypoints[keep],
    )


def presets_table(frames: int) -> list[str]:
    """Defaults, untouched, on other camera counts, resolutions and missing-view rates."""
    from models.mom.training.train import train_model
    from models.simulate import simulate

    lines = [
        "",
        "## Same defaults on other scenes (no per-preset tuning)",
        "",
        "| scene | cameras | image | train rows | missing views | train s | mean | Acc@0.3 % "
        "| mean 2+ views |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    cases = [("single-cam", 0.0), ("office-3cam", 0.0), ("outdoor-6cam", 0.0), ("indoor-4cam", 0.8)]
    for preset, hidden in cases:
        train = simulate(preset, frames=frames, seed=1).dataset
        test = simulate(preset, frames=max(300, frames // 3), seed=2).dataset
        if hidden:
            train, test = drop_views(train, hidden, 1), drop_views(test, hidden, 2)
        out = Path(tempfile.mkdtemp(prefix="mom-preset-"))
        started = time.monotonic()
        train_model(train, out, progress=False, seed=0)
        seconds = time.monotonic() - started
        r = evaluate(out, test)
        w, h = train.image_size[0]
        missing = 1 - train.visible().mean()
        lines.append(
            f"| {preset} | {train.num_cameras} | {w}×{h} | {train.n} | {missing:.0%} | "
            f"{seconds:.0f} | {r['mean']:.3f} | {r['acc']:.1f} | {r['mean2']:.3f} |"
        )
        print(lines[-1], flush=True)
    return lines


def main(argv: list[str] | None = None) -> int:
    from models.mom.training.train import train_model
    from models.simulate import simulate

    argv = sys.argv[1:] if argv is None else argv
    frames = 600 if "--quick" in argv else 3000
    if "--presets" in argv:  # append the cross-scene table to the existing results
        lines = presets_table(frames // 3)
        RESULTS.write_text(RESULTS.read_text() + "\n".join(lines) + "\n")
        return 0
    train = simulate("indoor-2cam", frames=frames, seed=1).dataset
    test = simulate("indoor-2cam", frames=max(300, frames // 3), seed=2).dataset
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    lines = [
        "# MoM design sweep (indoor-2cam)",
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} cores (shared), date "
        f"{dt.datetime.now(dt.UTC):%Y-%m-%d %H:%M} UTC. Train: {train.summary()}. "
        f"Test (other seed): {test.n} rows. Errors in metres on the test set; "
        "'2+ views' / '1 view' split by how many cameras see the person.",
        "",
        "| variant | epochs (best) | train s | mean | Acc@0.3 % | mean 2+ views | Acc@0.3 2+ "
        "| mean 1 view |",
        "|---|---|---|---|---|---|---|---|",
    ]
    RESULTS.write_text("\n".join(lines) + "\n")
    for name, options in VARIANTS:
        out = Path(tempfile.mkdtemp(prefix="mom-sweep-"))
        started = time.monotonic()
        metrics = train_model(train, out, progress=False, seed=0, **options)
        seconds = time.monotonic() - started
        r = evaluate(out, test)
        row = (
            f"| {name} | {metrics['epochs_run']} ({metrics['best_epoch']}) | {seconds:.0f} | "
            f"{r['mean']:.3f} | {r['acc']:.1f} | {r['mean2']:.3f} | {r['acc2']:.1f} | "
            f"{r['mean1']:.3f} |"
        )
        lines.append(row)
        RESULTS.write_text("\n".join(lines) + "\n")
        print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

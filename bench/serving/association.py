"""Association and tracking benchmark on synthetic scenes (writes bench/results/association.md).

For 1-5 people in a preset scene, every frame's noisy simulated detections (misses, occlusion,
truncation, jitter) are shuffled per camera and associated with
:func:`service.tracking.association.associate` using a real trained MoM model. Reported:

* **all correct**: frames in which every output groups exactly one person's detections and every
  detected person is output once (a person seen by one camera must come out alone);
* **pairs correct**: fraction of cross-camera detection pairs classified right (same / different);
* localisation error of the associated positions (matched to the truth, 1 m gate) against the
  error of localising the *true* tuples with the same model, and the share of people missed;
* tracking on top (``service.tracking.tracker.Tracker``): id switches per 100 person-seconds and the
  share of person-frames covered by a track within 0.5 m;
* time per ``associate`` call.

Usage::

    python -m bench.serving.association [--model DIR] [--preset indoor-2cam] [--frames 600]
    [--quick]

Without ``--model`` a model is trained on a separate simulated recording (another seed) and cached
in the system temp directory (``momloc-bench-cache``).
"""

from __future__ import annotations

import argparse
import itertools
import os
import platform
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from bench.report import write_report
from models.mom.runtime import MomRuntime
from models.simulate import Scene, get_config
from service.stages import Origin
from service.tracking.association import DEFAULT_MAX_ERROR_PX, DEFAULT_MAX_VIEW_GAP_M, associate
from service.tracking.tracker import Tracker

RESULTS = Path(__file__).resolve().parents[1] / "results"


def train_cached(preset: str, frames: int, epochs: int) -> Path:
    from models.mom.training.train import train_model
    from models.simulate import simulate

    out = Path(tempfile.gettempdir()) / "momloc-bench-cache" / f"assoc-{preset}-{frames}f-{epochs}e"
    if not (out / "model.json").is_file():
        data = simulate(preset, frames=frames, seed=1000).dataset
        train_model(data, out, epochs=epochs, seed=0, progress=True)
    return out


def frame_detections(boxes: np.ndarray, rng: np.random.Generator):
    """Shuffled per-camera detections and their true owners."""
    detections, owners = [], []
    for k in range(boxes.shape[1]):
        people = np.flatnonzero(np.isfinite(boxes[:, k]).all(axis=1))
        people = people[rng.permutation(len(people))]
        detections.append(boxes[people, k].astype(np.float32).reshape(-1, 4))
        owners.append(people.tolist())
    return detections, owners


def judge(result, owners, boxes) -> tuple[bool, int, int]:
    """(all correct, correct cross-camera pairs, total pairs) for one frame."""
    label = {}
    for n, a in enumerate(result):
        for k, j in enumerate(a.detection_index):
            if j is not None:
                label[(k, j)] = n
    keys = sorted(label)
    total = right = 0
    for (k1, j1), (k2, j2) in itertools.combinations(keys, 2):
        if k1 == k2:
            continue
        total += 1
        right += (label[(k1, j1)] == label[(k2, j2)]) == (owners[k1][j1] == owners[k2][j2])
    visible = np.isfinite(boxes).all(axis=2)
    groups = sorted(
        tuple(sorted((k, j) for k, j in enumerate(a.detection_index) if j is not None))
        for a in result
    )
    truth = []
    for p in range(len(boxes)):
        cams = np.flatnonzero(visible[p])
        if len(cams):
            truth.append(tuple(sorted((int(k), owners[k].index(p)) for k in cams)))
    return groups == sorted(truth), right, total


def match_errors(pred: np.ndarray, truth: np.ndarray, gate: float = 1.0):
    """Errors of predictions matched one-to-one to the truth within ``gate``; misses count."""
    if not len(truth):
        return np.zeros(0), 0
    if not len(pred):
        return np.zeros(0), len(truth)
    dist = np.linalg.norm(pred[:, None] - truth[None], axis=2)
    rows, cols = linear_sum_assignment(dist)
    ok = dist[rows, cols] <= gate
    return dist[rows, cols][ok], len(truth) - int(ok.sum())


def run_scene(
    runtime,
    preset: str,
    people: int,
    frames: int,
    seeds: list[int],
    max_error: float = DEFAULT_MAX_ERROR_PX,
    max_gap: float = DEFAULT_MAX_VIEW_GAP_M,
) -> dict:
    """All metrics for ``people`` walkers, pooled over one scene per seed."""
    n = dict.fromkeys(
        ("correct", "pairs_right", "pairs_total", "frames", "misses", "misses_true", "truth"), 0
    )
    n.update(switches=0, reentries=0, covered=0, person_frames=0)
    err_assoc, err_true, seconds = [], [], []
    fps = 1.0
    for seed in seeds:
        scene = Scene(get_config(preset, people=people), seed=seed)
        fps = scene.fps
        rng = np.random.default_rng(seed)
        tracker = Tracker(fps_hint=scene.fps)
        last_match: dict[int, tuple[int, int]] = {}  # person -> (track id, frame)
        for i in range(frames):
            obs = scene.observe(i)
            boxes = obs.boxes
            seen = np.isfinite(boxes).all(axis=2).any(axis=1)
            detections, owners = frame_detections(boxes, rng)
            started = time.perf_counter()
            result = associate(detections, runtime, max_error, max_gap)
            seconds.append(time.perf_counter() - started)
            pred = np.array([a.world for a in result]).reshape(-1, 2)
            if seen.any():
                n["frames"] += 1
                ok, right, total = judge(result, owners, boxes)
                n["correct"] += ok
                n["pairs_right"] += right
                n["pairs_total"] += total
                errors, missed = match_errors(pred, obs.world[seen])
                err_assoc.extend(errors)
                n["misses"] += missed
                n["truth"] += int(seen.sum())
                errors, missed = match_errors(runtime.localize(boxes[seen]), obs.world[seen])
                err_true.extend(errors)
                n["misses_true"] += missed
            origins = [Origin(cameras=tuple(a.cameras), cost=a.cost) for a in result]
            tracks = tracker.update(i / scene.fps, pred, origins)
            n["person_frames"] += int(seen.sum())
            if not tracks or not seen.any():
                continue
            pos = np.array([[t.x, t.y] for t in tracks])
            gt = np.flatnonzero(seen)
            dist = np.linalg.norm(obs.world[gt][:, None] - pos[None], axis=2)
            for r, c in zip(*linear_sum_assignment(dist), strict=True):
                if dist[r, c] > 0.5:
                    continue
                n["covered"] += 1
                person, tid = int(gt[r]), tracks[c].id
                if person in last_match and last_match[person][0] != tid:
                    # A new id after the person was lost longer than the tracker keeps tracks
                    # (walked out of every view) is a re-entry, not a tracking failure.
                    gap = (i - last_match[person][1]) / scene.fps
                    n["reentries" if gap > tracker.max_missing_s else "switches"] += 1
                last_match[person] = (tid, i)
    err_assoc, err_true = np.array(err_assoc), np.array(err_true)
    person_seconds = n["person_frames"] / fps
    return {
        "people": people,
        "frames": n["frames"],
        "all_correct": 100.0 * n["correct"] / max(n["frames"], 1),
        "pairs_correct": 100.0 * n["pairs_right"] / max(n["pairs_total"], 1),
        "err_assoc_mean": float(err_assoc.mean()) if len(err_assoc) else float("nan"),
        "err_assoc_median": float(np.median(err_assoc)) if len(err_assoc) else float("nan"),
        "err_true_mean": float(err_true.mean()),
        "err_true_median": float(np.median(err_true)),
        "missed": 100.0 * n["misses"] / max(n["truth"], 1),
        "missed_true": 100.0 * n["misses_true"] / max(n["truth"], 1),
        "switches_per_100s": 100.0 * n["switches"] / max(person_seconds, 1e-9),
        "switches": n["switches"],
        "reentries": n["reentries"],
        "covered": 100.0 * n["covered"] / max(n["person_frames"], 1),
        "ms": 1000.0 * float(np.median(seconds)),
        "ms_p95": 1000.0 * float(np.percentile(seconds, 95)),
    }


TABLE_HEAD = (
    "| people | frames | all correct % | pairs correct % | error assoc. mean / median (m) "
    "| missed % | error true assoc. mean / median (m) | missed true assoc. % "
    "| id switches (per 100 person-s) | re-entries "
    "| tracked within 0.5 m % | associate ms (median / p95) |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|---|\n"
)

NOTES = (
    "*all correct*: every detected person's boxes grouped exactly (single-view people alone). "
    "*pairs correct*: cross-camera detection pairs rightly put together or apart. "
    "*error assoc.*: positions from association matched one-to-one to the truth (1 m gate; "
    "*missed* = detected people without a prediction within 1 m). *true assoc.*: the same "
    "model on the true box tuples, scored the same way. Tracking: `Tracker` defaults fed "
    "with the associated positions; an id switch is a change of the track id matched (within "
    "0.5 m) to a true person while that person had been matched within the last "
    "`max_missing_s` (1.5 s); a change after a longer absence (the person left every view) is "
    "counted as a *re-entry*. Timing is wall clock on a shared machine (p95 includes "
    "scheduling noise).\n"
)


def section(preset: str, rows: list[dict], args, model_dir: Path, meta: dict) -> str:
    fps = get_config(preset).fps
    body = "".join(
        f"| {r['people']} | {r['frames']} | {r['all_correct']:.1f} | {r['pairs_correct']:.2f} "
        f"| {r['err_assoc_mean']:.3f} / {r['err_assoc_median']:.3f} "
        f"| {r['missed']:.1f} | {r['err_true_mean']:.3f} / {r['err_true_median']:.3f} "
        f"| {r['missed_true']:.1f} "
        f"| {r['switches']} ({r['switches_per_100s']:.2f}) | {r['reentries']} | {r['covered']:.1f} "
        f"| {r['ms']:.1f} / {r['ms_p95']:.1f} |\n"
        for r in rows
    )
    metrics = meta.get("metrics", {})
    return (
        f"## `{preset}`\n\n"
        f"{get_config(preset).num_cameras} cameras at {fps:g} fps, {args.frames} frames per scene, "
        f"scenes seeded {', '.join(map(str, args.seeds))} pooled per row. Model: "
        f"`{model_dir.name}` (validation mean error {metrics.get('val_mean_m', float('nan'))} m, "
        "trained on a different simulated recording).\n\n" + TABLE_HEAD + body + "\n"
    )


def sweep(runtime, preset: str, args, people: int = 3) -> str:
    """All-correct % for 3 people over a grid of the two gates (how the defaults were chosen)."""
    errors, gaps = (40.0, 60.0, 100.0, 150.0), (1.5, 2.0, 3.0, float("inf"))
    lines = [
        f"### Gate sweep: {people} people, all-correct % (rows: reprojection gate px at "
        "200 px box height; columns: view-gap gate m)\n",
        "| gate | " + " | ".join(f"{g:g} m" for g in gaps) + " |",
        "|---|" + "---|" * len(gaps),
    ]
    for e in errors:
        cells = []
        for g in gaps:
            row = run_scene(runtime, preset, people, args.frames, args.seeds, e, g)
            cells.append(f"{row['all_correct']:.1f}")
            print("sweep", e, g, cells[-1], flush=True)
        lines.append(f"| {e:g} px | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", type=Path, help="trained model directory (one preset only)")
    parser.add_argument("--presets", nargs="+", default=["indoor-2cam", "indoor-4cam"])
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--seeds", type=int, nargs="+", default=[7, 8, 9])
    parser.add_argument("--people", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--max-error", type=float, default=DEFAULT_MAX_ERROR_PX)
    parser.add_argument("--max-gap", type=float, default=DEFAULT_MAX_VIEW_GAP_M)
    parser.add_argument("--train-frames", type=int, default=3000)
    parser.add_argument("--epochs", type=int, default=150)
    parser.add_argument("--no-sweep", action="store_true", help="skip the gate sweep")
    parser.add_argument("--out", type=Path, default=RESULTS / "association.md")
    parser.add_argument("--quick", action="store_true", help="200 frames, small model")
    args = parser.parse_args(argv)
    if args.quick:
        args.frames, args.train_frames, args.epochs = 200, 800, 40
    if args.model and len(args.presets) != 1:
        parser.error("--model needs exactly one --presets entry")
    sections = []
    for preset in args.presets:
        model_dir = args.model or train_cached(preset, args.train_frames, args.epochs)
        runtime = MomRuntime.load(model_dir)
        rows = []
        for people in args.people:
            row = run_scene(
                runtime, preset, people, args.frames, args.seeds, args.max_error, args.max_gap
            )
            print(preset, row, flush=True)
            rows.append(row)
        sections.append(section(preset, rows, args, Path(model_dir), runtime.meta))
        if preset == args.presets[0] and not args.no_sweep:
            sections.append(sweep(runtime, preset, args))
    text = (
        "# Association and tracking benchmark\n\n"
        f"Generated by `python -m bench.serving.association` on "
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, "
        f"{platform.machine()} {platform.processor() or ''} ({platform.system()}, "
        f"{os.cpu_count()} cores shared), Python {platform.python_version()}. Noisy simulated "
        "detections (misses, occlusion, truncation, jitter) shuffled per camera, association "
        f"gates {args.max_error:g} px (at a 200 px box height) and {args.max_gap:g} m.\n\n"
        + "\n".join(sections)
        + "\n"
        + NOTES
    )
    return write_report(args.out, text)


if __name__ == "__main__":
    raise SystemExit(main())

"""Accuracy benchmark: MoM against the calibrated baseline, decoder ablation, robustness curves.

``python -m bench.model.model_accuracy [--quick | --tables] [--profile NAME]`` writes
``bench/results/model_accuracy.md`` (with ``--quick``: ``model_accuracy_quick.md``, with
``--tables``: ``model_accuracy_tables.md``; with a ``--profile`` other than the default, the
profile's name is appended, e.g. ``model_accuracy_ideal.md``, then the ``--presets`` asked for,
e.g. ``model_accuracy_tables_outdoor-6cam.md``) and PNG plots next to it.

Every recording is simulated with the detector profile ``--profile`` (default: the shipped
detector's, ``models.simulate.DEFAULT_PROFILE``; ``ideal`` is the former kind noise). ``--tables``
measures what the localization tables (``bench/results/model_accuracy_tables.md``) show and
nothing else: Table 1 with one training
seed, MoM + bbox on every preset, MoM + keypoints on indoor-2cam, the calibrated baselines; no
decoder ablation, no plain MLP, no curves.

Protocol (the paper's Table 1, Table 2, Fig. 5 and Fig. 6 on the synthetic presets):

* For each preset, train on one simulated recording and test on another one with a different
  seed: the same cameras, *unseen walks* (other paths, other people's heights and noise).
* MoM rows use ``models.mom.training.train.train_model`` with its defaults (adaptive sizes and
  schedule, early stopping), exactly what ``momloc train`` does; evaluation is
  ``models.mom.evaluate`` (the code of
  ``momloc eval``): the served localizer, which blends the MoM encoder with the floor-mark
  geometry fitted on the same rows (``models.mom.prior_policy``); the "encoder alone" rows are the
  paper's model by itself. The decoder ablation repeats training with several seeds (mean ± std)
  and compares encoders alone: the decoder regularises the encoder only.
* "Plain MLP on box coordinates" (``bench.model.mlp_baseline``): the same boxes without mean
  estimators or decoder, trained to early stopping; the control for MoM's sampling.
* Baselines (``models.geometry.calibrated_baseline``) use the simulator's true 3×4 matrices, or
  matrices re-estimated by DLT from a simulated chessboard session per camera (``ChessboardSetup``
  defaults: 36 points, 1 px corner noise, 5 mm / 1° placement error), repeated over several sessions
  (mean ± std). The true matrices ignore the lens distortion, as a DLT calibration does. A row the
  baseline cannot localize gets the training set's mean position (counted in the notes).
* Fig. 5: every camera bumped by ``n`` pixels in a random direction (``simulate(...,
  perturbation=...)`` on the test walks, i.e. at test time only; the model is not retrained).
* Fig. 6: Gaussian noise of ``n`` px (std per coordinate) added to every test keypoint.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.report import RESULTS, machine_line, markdown_table, mean_std, plot_curves
from models.data.dataset import MomDataset
from models.data.metrics import METRIC_KEYS
from models.geometry import calibrated_baseline as baseline
from models.mom.evaluate import evaluate, score

ENCODER_ALONE = ", encoder alone"
COLUMNS = ("Mean ↓", "Median ↓", "Std ↓", "ATE ↓", "RPE ↓", "@0.2 ↑", "@0.3 ↑", "@0.4 ↑", "@0.5 ↑")
CURVE_PRESET = "indoor-2cam"


@dataclass(frozen=True)
class Plan:
    """Sizes of one benchmark run (rows are approximate: frames = rows / people)."""

    presets: tuple[str, ...] = ("indoor-2cam", "indoor-4cam", "outdoor-6cam")
    train_rows: int = 6000
    test_rows: int = 2000
    epochs: int | None = None  # None: train_model's adaptive schedule
    decoder_seeds: tuple[int, ...] = (0, 1, 2)  # on CURVE_PRESET; other presets use the first
    calibration_sessions: int = 5
    offsets: tuple[int, ...] = (*range(0, 20, 2), 19)
    noises: tuple[int, ...] = (*range(0, 20, 2), 19)
    directions: int = 2  # random bump directions averaged per offset
    ablation: bool = True  # no-decoder models, plain MLP, keypoints on every preset, curves


FULL = Plan()
QUICK = Plan(
    train_rows=2500,
    test_rows=900,
    epochs=12,
    decoder_seeds=(0, 1),
    calibration_sessions=2,
    offsets=(0, 6, 12, 19),
    noises=(0, 6, 12, 19),
    directions=1,
)


def _log(message: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {message}", file=sys.stderr, flush=True)


def _frames(preset: str, rows: int) -> int:
    from models.simulate import PRESETS

    return max(64, math.ceil(rows / PRESETS[preset].people))


def _fill(pred: np.ndarray, fallback: np.ndarray) -> tuple[np.ndarray, int]:
    bad = ~np.isfinite(pred).all(axis=1)
    pred = pred.copy()
    pred[bad] = fallback
    return pred, int(bad.sum())


@dataclass
class PresetRun:
    """Everything measured on one preset."""

    preset: str
    train: MomDataset
    test: MomDataset
    test_seed: int
    test_frames: int
    rows: dict[str, list[dict]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    runtimes: dict[str, object] = field(default_factory=dict)
    projections: np.ndarray | None = None


def _train(run: PresetRun, work: Path, plan: Plan, name: str, **options) -> dict:
    from models.mom.runtime import MomRuntime
    from models.mom.training.train import train_model

    out = work / f"{run.preset}-{name}-{options.get('seed', 0)}"
    started = time.monotonic()
    info = train_model(run.train, out, epochs=plan.epochs, progress=False, **options)
    seconds = time.monotonic() - started
    runtime = MomRuntime.load(out)
    metrics = evaluate(runtime, run.test, name=f"{run.preset} test").metrics
    _log(
        f"{run.preset} {name} seed {options.get('seed', 0)}: {seconds:.0f} s, "
        f"{info['epochs_run']} epochs, test mean {metrics['mean']:.3f} m, "
        f"acc@0.3 {metrics['acc@0.3']:.1f} %"
    )
    run.rows.setdefault(name, []).append({**metrics, "seconds": seconds, **info})
    run.runtimes.setdefault(name, runtime)
    if runtime.policy != "mom":  # what the paper's model alone gives, next to what is served
        keypoints = run.test.keypoints if runtime.observation == "keypoints" else None
        alone = score(runtime.encode(run.test.boxes, keypoints), run.test).metrics
        row = {**alone, "seconds": seconds, **info}
        run.rows.setdefault(f"{name}{ENCODER_ALONE}", []).append(row)
    return metrics


def _plain_mlp(run: PresetRun, plan: Plan, seed: int) -> None:
    from bench.model.mlp_baseline import BoxMlp

    started = time.monotonic()
    mlp = BoxMlp(seed=seed)
    info = mlp.fit(run.train, max_epochs=plan.epochs or 200)
    metrics = score(mlp.predict(run.test), run.test).metrics
    seconds = time.monotonic() - started
    _log(f"{run.preset} plain MLP: {seconds:.0f} s, test mean {metrics['mean']:.3f} m")
    run.rows["Plain MLP on box coordinates"] = [{**metrics, "seconds": seconds, **info}]


def _baselines(run: PresetRun, scene, plan: Plan) -> None:
    test, fallback = run.test, run.train.world[:, :2].mean(axis=0)
    sizes = test.image_size
    for method, label in (("triangulate", "triangulation"), ("foot", "foot point")):
        pred, failed = _fill(
            baseline.localize(test.boxes, run.projections, method=method, image_size=sizes),
            fallback,
        )
        run.rows[f"Calibrated {label}, true matrices"] = [score(pred, test).metrics]
        if failed:
            run.notes.append(f"{label}, true matrices: {failed} rows not localized")
    rng = np.random.default_rng(7)
    seen = run.train.visible()
    for session in range(plan.calibration_sessions):
        estimated = np.stack(
            [
                baseline.chessboard_calibration(
                    run.projections[k],
                    camera.image_size,
                    run.train.world[seen[:, k], :2],
                    rng,
                    observe=lambda points, camera=camera: camera.project(points)[0],
                )
                for k, camera in enumerate(scene.cameras)
            ]
        )
        for method, label in (("triangulate", "triangulation"), ("foot", "foot point")):
            raw = baseline.localize(test.boxes, estimated, method=method, image_size=sizes)
            pred, failed = _fill(raw, fallback)
            name = f"Calibrated {label}, chessboard calibration"
            run.rows.setdefault(name, []).append(score(pred, test).metrics)
            if failed:
                run.notes.append(f"{label}, chessboard session {session}: {failed} rows filled")


def run_preset(preset: str, index: int, plan: Plan, work: Path, profile: str) -> PresetRun:
    from models.simulate import simulate

    train_frames = _frames(preset, plan.train_rows)
    test_frames = _frames(preset, plan.test_rows)
    train_sim = simulate(preset, frames=train_frames, seed=100 + index, detector_profile=profile)
    test_sim = simulate(preset, frames=test_frames, seed=200 + index, detector_profile=profile)
    run = PresetRun(preset, train_sim.dataset, test_sim.dataset, 200 + index, test_frames)
    run.projections = test_sim.projections
    _log(f"{preset}: train {run.train.summary()}; test {run.test.summary()}")
    seeds = plan.decoder_seeds if preset == CURVE_PRESET else plan.decoder_seeds[:1]
    for seed in seeds:
        _train(run, work, plan, "MoM + bbox", seed=seed)
        if plan.ablation:
            _train(run, work, plan, "MoM + bbox, no decoder", seed=seed, decoder=False)
    if plan.ablation or preset == CURVE_PRESET:
        _train(run, work, plan, "MoM + keypoints", seed=seeds[0], observation="keypoints")
    if plan.ablation:
        _plain_mlp(run, plan, seeds[0])
    _baselines(run, test_sim.scene, plan)
    return run


def offset_curve(run: PresetRun, plan: Plan, profile: str) -> dict[str, list[float]]:
    """Acc@0.3 against a test-time camera bump of n px (random direction per camera)."""
    from models.simulate import Perturbation, simulate

    rng = np.random.default_rng(11)
    fallback = run.train.world[:, :2].mean(axis=0)
    curves: dict[str, list[float]] = {
        "MoM + bbox": [],
        "MoM + keypoints": [],
        "Calibrated triangulation (true matrices)": [],
    }
    # one random direction per camera and repeat, kept for every magnitude: the curve then
    # varies the size of the bump only
    directions = rng.uniform(0, 2 * np.pi, (plan.directions, run.test.num_cameras))
    for offset in plan.offsets:
        acc: dict[str, list[float]] = {name: [] for name in curves}
        for angles in directions:
            bumps = [
                Perturbation(camera=k, dx=offset * np.cos(a), dy=offset * np.sin(a))
                for k, a in enumerate(angles)
            ]
            bumped = simulate(
                run.preset,
                frames=run.test_frames,
                seed=run.test_seed,
                perturbation=bumps,
                detector_profile=profile,
            ).dataset
            acc["MoM + bbox"].append(evaluate(run.runtimes["MoM + bbox"], bumped).metrics)
            acc["MoM + keypoints"].append(evaluate(run.runtimes["MoM + keypoints"], bumped).metrics)
            pred, _ = _fill(
                baseline.localize(bumped.boxes, run.projections, image_size=bumped.image_size),
                fallback,
            )
            acc["Calibrated triangulation (true matrices)"].append(score(pred, bumped).metrics)
        for name, values in acc.items():
            curves[name].append(float(np.mean([m["acc@0.3"] for m in values])))
        _log(f"offset {offset} px: " + ", ".join(f"{k} {v[-1]:.1f}" for k, v in curves.items()))
    return curves


def noise_curve(run: PresetRun, plan: Plan) -> dict[str, list[float]]:
    """Acc@t of MoM + keypoints against Gaussian keypoint noise of n px at test time."""
    rng = np.random.default_rng(13)
    runtime = run.runtimes["MoM + keypoints"]
    curves: dict[str, list[float]] = {f"Acc@{t} m": [] for t in (0.2, 0.3, 0.4, 0.5)}
    for noise in plan.noises:
        arrays = run.test.arrays()
        keypoints = arrays["keypoints"].copy()
        keypoints[..., :2] += rng.normal(0, noise, keypoints[..., :2].shape).astype(np.float32)
        arrays["keypoints"] = keypoints
        metrics = evaluate(runtime, MomDataset(**arrays)).metrics
        for t in (0.2, 0.3, 0.4, 0.5):
            curves[f"Acc@{t} m"].append(metrics[f"acc@{t}"])
        _log(f"keypoint noise {noise} px: acc@0.3 {metrics['acc@0.3']:.1f} %")
    return curves


def _cells(values: list[dict]) -> list[str]:
    out = []
    for key in METRIC_KEYS[1:]:
        digits = 2 if key.startswith("acc@") else 3
        out.append(mean_std([v[key] for v in values], digits))
    return out


def preset_section(run: PresetRun) -> str:
    rows = [[name, str(len(values)), *_cells(values)] for name, values in run.rows.items()]
    text = [
        f"### {run.preset}",
        "",
        f"Train: {run.train.summary()}.  ",
        f"Test (unseen walks): {run.test.summary()}.",
        "",
        markdown_table(("Method", "runs", *COLUMNS), rows),
    ]
    mom = [r for name, values in run.rows.items() if name.startswith("MoM") for r in values]
    if mom:
        seconds = [r["seconds"] for r in mom]
        epochs = [r["epochs_run"] for r in mom]
        text.append(
            f"\nMoM training: {min(seconds):.0f}-{max(seconds):.0f} s per model (wall clock), "
            f"{min(epochs)}-{max(epochs)} epochs run (cap or early stopping)."
        )
    text += [f"- note: {note}" for note in run.notes]
    return "\n".join(text)


def decoder_section(run: PresetRun) -> str:
    header = ("Decoder", "seed", "Mean ↓", "@0.2 ↑", "@0.3 ↑", "@0.4 ↑", "@0.5 ↑")
    rows = []
    for name, label in (("MoM + bbox", "with"), ("MoM + bbox, no decoder", "without")):
        values = run.rows.get(name + ENCODER_ALONE, run.rows[name])
        for seed, m in enumerate(values):
            rows.append(
                [label, str(seed), f"{m['mean']:.3f}"]
                + [f"{m[f'acc@{t}']:.2f}" for t in (0.2, 0.3, 0.4, 0.5)]
            )
        rows.append(
            [f"**{label}**", "mean ± std", mean_std([m["mean"] for m in values], 3)]
            + [mean_std([m[f"acc@{t}"] for m in values], 2) for t in (0.2, 0.3, 0.4, 0.5)]
        )
    return markdown_table(header, rows)


def curve_table(x: tuple[int, ...], curves: dict[str, list[float]], xlabel: str) -> str:
    rows = [[name, *(f"{v:.1f}" for v in values)] for name, values in curves.items()]
    return markdown_table((xlabel, *(str(v) for v in x)), rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small smoke run (a few minutes)")
    parser.add_argument(
        "--tables", action="store_true", help="the localization tables only (one seed)"
    )
    parser.add_argument("--presets", nargs="+", help="subset of presets")
    parser.add_argument(
        "--profile", default=None, help="detector profile of every recording (default: shipped)"
    )
    args = parser.parse_args(argv)
    from models.simulate import DEFAULT_PROFILE, load_profile

    profile = args.profile or DEFAULT_PROFILE
    source = load_profile(profile).source
    plan = QUICK if args.quick else FULL
    if args.tables:
        plan = dataclasses.replace(plan, decoder_seeds=plan.decoder_seeds[:1], ablation=False)
    presets = tuple(args.presets) if args.presets else plan.presets
    suffix = ("_quick" if args.quick else "") + ("_tables" if args.tables else "")
    suffix += "" if profile == DEFAULT_PROFILE else f"_{Path(profile).stem}"
    suffix += f"_{'_'.join(args.presets)}" if args.presets else ""
    started, load_start = time.monotonic(), os.getloadavg()[0]
    runs: list[PresetRun] = []
    with tempfile.TemporaryDirectory(prefix="momloc-bench-") as work:
        for index, preset in enumerate(presets):
            runs.append(run_preset(preset, index, plan, Path(work), profile))
        curve_run = next((r for r in runs if r.preset == CURVE_PRESET), runs[0])
        if plan.ablation:
            offsets = offset_curve(curve_run, plan, profile)
            noises = noise_curve(curve_run, plan)
    minutes = (time.monotonic() - started) / 60
    RESULTS.mkdir(parents=True, exist_ok=True)
    command = f"python -m bench.model.model_accuracy{' --quick' if args.quick else ''}"
    command += " --tables" if args.tables else ""
    command += f" --profile {args.profile}" if args.profile else ""
    command += f" --presets {' '.join(args.presets)}" if args.presets else ""
    header = [
        "# Model accuracy: MoM vs. calibrated baseline"
        + (" (quick run)" if args.quick else " (tables)" if args.tables else ""),
        "",
        machine_line() + f" Whole script: {minutes:.1f} min wall clock (1-min load average "
        f"{load_start:.1f} at start, {os.getloadavg()[0]:.1f} at end: the 2 cores were shared).",
        "",
        f"Command: `{command}`. Detector profile: `{profile}` ({source}). "
        f"Plan: ~{plan.train_rows} train rows, ~{plan.test_rows} test rows per preset, "
        f"epochs {'adaptive (train_model defaults)' if plan.epochs is None else plan.epochs}, "
        f"decoder seeds {list(plan.decoder_seeds)} on {CURVE_PRESET}, "
        f"{plan.calibration_sessions} chessboard sessions. Errors in metres, accuracies in %; "
        "`a ± b` is mean ± std over runs. Protocol: see the docstring of "
        "`bench/model/model_accuracy.py`.",
        "",
        "## Table 1: localization on unseen walks",
        "",
        *(preset_section(run) + "\n" for run in runs),
    ]
    if not plan.ablation:
        out = RESULTS / f"model_accuracy{suffix}.md"
        out.write_text("\n".join(header))
        _log(f"wrote {out} ({minutes:.1f} min)")
        return 0
    offset_png = plot_curves(
        RESULTS / f"model_accuracy_offset{suffix}.png",
        plan.offsets,
        offsets,
        xlabel="camera offset (px, every camera, test time only)",
        ylabel="Acc@0.3 m (%)",
        title=f"Camera perturbation ({curve_run.preset})",
    )
    noise_png = plot_curves(
        RESULTS / f"model_accuracy_keypoint_noise{suffix}.png",
        plan.noises,
        noises,
        xlabel="keypoint noise (px, std per coordinate, test time only)",
        ylabel="accuracy (%)",
        title=f"MoM + keypoints under keypoint noise ({curve_run.preset})",
    )
    text = [
        *header,
        f"## Table 2: decoder ablation ({curve_run.preset}, several seeds, encoders alone)",
        "",
        decoder_section(curve_run),
        "",
        "## Fig. 5: camera perturbation (Acc@0.3 m, %)",
        "",
        f"![camera offset]({offset_png.name})",
        "",
        curve_table(plan.offsets, offsets, "offset (px)"),
        "",
        "## Fig. 6: keypoint noise (MoM + keypoints, %)",
        "",
        f"![keypoint noise]({noise_png.name})",
        "",
        curve_table(plan.noises, noises, "noise (px)"),
        "",
    ]
    out = RESULTS / f"model_accuracy{suffix}.md"
    out.write_text("\n".join(text))
    _log(f"wrote {out} ({minutes:.1f} min)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

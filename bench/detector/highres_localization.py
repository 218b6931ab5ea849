"""High-resolution cameras end to end: what NanoDet's ``max_shrink`` buys in *localization*
(writes bench/results/highres_localization.md).

``bench/results/highres_recall.md`` measures the detector alone; this bench follows its boxes
through the MoM model, as a user with 1080p cameras gets it. For preset ``outdoor-6cam`` (six
1920×1080 cameras, the preset's own fps) and the shipped NanoDet with ``max_shrink`` None (fixed
320×256 input) and 3 (640×384 on 1080p), one onnxruntime thread each:

1. a training and a test set of *drawn frames through the real detector*, labelled with the
   simulator's truth (:func:`models.simulate.detector_view.detector_dataset`, as
   ``tools/make_demo_model.py`` builds the demo model): every ``--every``-th frame of a training
   scene and of a test scene with another seed (unseen walks). A detection matching nobody is
   dropped; a person a camera's detector misses is a missing view there; a person no camera
   found has no row;
2. a MoM model trained on each training set with ``models.mom.training.train.train_model`` defaults
   (what
   ``momloc train`` does; ``bench.model.model_accuracy``'s training helper), evaluated on the test
   set of the same setting with ``models.mom.evaluate`` (the code of ``momloc eval``): the served
   localizer;
3. per setting: person-instances in the test frames' view (simulator truth: the reference box of
   :func:`~models.simulate.detector_view.camera_truth` in at least one camera), the share found by
   at least one camera's detector and by how many cameras, the served model's errors on the found
   rows, and Acc@0.5 over *all* instances in view, an instance nobody found counting as a miss:
   the figure that combines the detector's recall and the model's accuracy.

Usage::

    python -m bench.detector.highres_localization [--train-frames 1600] [--test-frames 800] [--every
    2]
                                         [--out bench/results/highres_localization.md]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.report import RESULTS, command_line, machine_line, markdown_table

PRESET = "outdoor-6cam"
SETTINGS: tuple[float | None, ...] = (None, 3.0)
TRAIN_SEED, TEST_SEED = 100, 200
TRAIN_FRAMES, TEST_FRAMES, EVERY = 1600, 800, 2
THRESHOLD = 0.5  # metres: the all-instances accuracy
NAME = "MoM + bbox"


def _log(message: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {message}", file=sys.stderr, flush=True)


def in_view(scene, frames: range) -> np.ndarray:
    """Per person-instance in view of at least one camera (simulator truth, counted as
    :func:`~models.simulate.detector_view.detector_dataset` matches): how many cameras see it.
    One entry per (frame, person) in view, frames in order, people by track."""
    from models.simulate.detector_view import camera_truth

    sizes = [camera.image_size for camera in scene.cameras]
    counts = []
    for f in frames:
        obs = scene.observe(f)
        hips = obs.joints[:, 11:13].mean(1)
        seen = np.zeros(len(obs.track), int)
        for k in range(scene.num_cameras):
            depth = scene.cameras[k].project_depth(hips)[1]
            seen += camera_truth(obs.true_boxes[:, k], depth, sizes[k]).seen
        counts.append(seen[seen > 0])
    return np.concatenate(counts)


def camera_shares(cameras: np.ndarray, total: int) -> dict[str, float]:
    """Percent of ``total`` instances found (or seen) by exactly 1, exactly 2 and 3+ cameras;
    ``cameras`` holds one count per found instance (zeros are not found)."""
    cameras = np.asarray(cameras)
    return {
        "1": 100.0 * np.sum(cameras == 1) / total,
        "2": 100.0 * np.sum(cameras == 2) / total,
        "3+": 100.0 * np.sum(cameras >= 3) / total,
    }


def all_instances_accuracy(errors: np.ndarray, total: int, threshold: float = THRESHOLD) -> float:
    """Percent of ``total`` person-instances in view localized within ``threshold`` metres.

    ``errors`` [N] holds the error of each *found* instance (NaN: the model gave no position);
    the ``total - N`` instances nobody found, and NaN errors, count as misses."""
    errors = np.asarray(errors, float)
    if total < 1 or errors.size > total:
        raise ValueError(f"{errors.size} found instances out of {total} in view")
    return 100.0 * float(np.sum(np.nan_to_num(errors, nan=np.inf) < threshold)) / total


@dataclass(frozen=True)
class SettingResult:
    """One detector setting: what the detector found on the test frames and how well the
    model trained on its training frames localizes it.

    ``cameras`` [N] how many cameras found each found test instance, ``errors`` [N] the served
    model's error in metres (NaN: no position), ``metrics`` ``models.mom.evaluate``'s dict on the
    found rows, ``in_view`` test instances in view, ``truth_cameras`` [in_view] cameras that see
    each one (simulator truth)."""

    setting: str
    detector: str
    in_view: int
    truth_cameras: np.ndarray
    cameras: np.ndarray
    errors: np.ndarray
    metrics: dict[str, float]
    train_rows: int
    epochs: int
    data_seconds: float
    train_seconds: float

    @property
    def localized(self) -> float:
        """Percent of the instances in view that at least one camera's detector found."""
        return 100.0 * len(self.cameras) / self.in_view

    @property
    def all_accuracy(self) -> float:
        return all_instances_accuracy(self.errors, self.in_view)


def setting_name(shrink: float | None, input_size: tuple[int, int]) -> str:
    """How an operator sets it, with the network input it gives on the preset's frames."""
    size = f"{input_size[0]}x{input_size[1]}"
    return f"fixed {size}" if shrink is None else f"max_shrink {shrink:g} ({size})"


def _pct(value: float) -> str:
    return f"{value:.1f} %"


def reading(results: Sequence[SettingResult]) -> str:
    """The paragraph under the header, computed from the numbers."""
    parts = []
    for r in results:
        shares = camera_shares(r.cameras, r.in_view)
        parts.append(
            f"{r.setting} finds {_pct(r.localized)} of the {r.in_view} person-instances in view "
            f"(by 1 / 2 / 3+ cameras: {shares['1']:.1f} / {shares['2']:.1f} / "
            f"{shares['3+']:.1f} %); on those the served model is off by {r.metrics['mean']:.3f} m "
            f"on average (median {r.metrics['median']:.3f} m, Acc@0.5 "
            f"{_pct(r.metrics['acc@0.5'])}), so {_pct(r.all_accuracy)} of all instances in view "
            f"are placed within {THRESHOLD} m"
        )
    text = "; ".join(parts) + "."
    if len(results) >= 2:
        base, other = results[0], results[-1]
        d_all = other.all_accuracy - base.all_accuracy
        d_found = other.localized - base.localized
        d_acc = other.metrics["acc@0.5"] - base.metrics["acc@0.5"]
        d_mean = other.metrics["mean"] - base.metrics["mean"]
        d_multi = (
            camera_shares(other.cameras, other.in_view)["3+"]
            - camera_shares(base.cameras, base.in_view)["3+"]
        )
        verb = "raises" if d_all > 0 else "lowers" if d_all < 0 else "leaves"
        text += (
            f" Against {base.setting}, {other.setting} {verb} Acc@0.5 over all instances in view "
            f"by {abs(d_all):.1f} points: {d_found:+.1f} points localized, {d_multi:+.1f} points "
            f"found by 3+ cameras, {d_acc:+.1f} points Acc@0.5 and {d_mean:+.3f} m mean error on "
            "the found rows."
        )
        if d_found > 0 and d_acc < 0:
            text += (
                " The extra instances it finds are partly harder ones (fewer or worse views), "
                "which pulls the found-rows accuracy down while the all-instances figure counts "
                "them as gained."
            )
    return text


def report(results: Sequence[SettingResult], command: str, header: str) -> str:
    """The markdown: title, what was run, machine, command, reading, tables."""
    truth = results[0]
    truth_shares = camera_shares(truth.truth_cameras, truth.in_view)
    rows = [
        [
            "simulator truth (in view)",
            truth.in_view,
            _pct(100.0),
            *(f"{truth_shares[k]:.1f}" for k in ("1", "2", "3+")),
            "",
            "",
            "",
            "",
            "",
        ]
    ]
    for r in results:
        shares = camera_shares(r.cameras, r.in_view)
        rows.append(
            [
                r.setting,
                r.in_view,
                _pct(r.localized),
                *(f"{shares[k]:.1f}" for k in ("1", "2", "3+")),
                f"{r.metrics['mean']:.3f}",
                f"{r.metrics['median']:.3f}",
                f"{r.metrics['acc@0.3']:.1f}",
                f"{r.metrics['acc@0.5']:.1f}",
                f"**{r.all_accuracy:.1f}**",
            ]
        )
    columns = (
        "detector setting",
        "person-instances in view",
        "instances localized",
        "by 1 camera %",
        "by 2 cameras %",
        "by 3+ cameras %",
        "mean m ↓ (found)",
        "median m ↓ (found)",
        "Acc@0.3 % ↑ (found)",
        "Acc@0.5 % ↑ (found)",
        "Acc@0.5 % over all in view ↑",
    )
    runs = [
        [
            r.setting,
            r.detector,
            r.train_rows,
            r.epochs,
            f"{r.data_seconds:.0f}",
            f"{r.train_seconds:.0f}",
        ]
        for r in results
    ]
    return "\n".join(
        [
            "# High-resolution cameras end to end: localization through NanoDet's max_shrink",
            "",
            f"Generated by `{command}`. {machine_line()} {header}",
            "",
            "**Reading.** " + reading(results),
            "",
            markdown_table(columns, rows),
            "",
            '"found": the test rows at least one camera\'s detector found (what `momloc eval` '
            'scores); "by n cameras" is a share of all instances in view (the three add up to '
            '"instances localized"); the truth row gives how many cameras see each instance. '
            '"Acc@0.5 over all in view" counts an instance nobody found as a miss.',
            "",
            "## Runs",
            "",
            markdown_table(
                ("setting", "detector", "training rows", "epochs", "data s", "training s"), runs
            ),
            "",
        ]
    )


def run_setting(
    shrink: float | None,
    train_scene,
    test_scene,
    train_frames: range,
    test_frames: range,
    truth_cameras: np.ndarray,
    work: Path,
) -> SettingResult:
    """Both data sets through one detector setting, one model trained and evaluated."""
    from bench.model.model_accuracy import Plan, PresetRun, _train
    from models.detector import create_detector
    from models.detector.nanodet import NanoDetDetector
    from models.detector.preprocessing import input_for_frame
    from models.mom.evaluate import evaluate
    from models.simulate.detector_view import detector_dataset

    detector = create_detector("nanodet", max_shrink=shrink, threads=1)
    assert isinstance(detector, NanoDetDetector)
    width, height = test_scene.cameras[0].image_size
    frame_size = (int(width), int(height))
    setting = setting_name(shrink, input_for_frame(detector.input_size, frame_size, shrink))
    started = time.monotonic()
    _log(f"{setting}: drawing and detecting {len(train_frames)} training frame sets")
    train = detector_dataset(train_scene, train_frames, detector, progress=True)
    _log(f"{setting}: {len(test_frames)} test frame sets")
    test = detector_dataset(test_scene, test_frames, detector, progress=True)
    data_seconds = time.monotonic() - started
    _log(f"{setting}: train {train.summary()}; test {test.summary()} ({data_seconds:.0f} s)")
    run = PresetRun(PRESET, train, test, TEST_SEED, len(test_frames))
    tag = "fixed" if shrink is None else f"shrink{shrink:g}"
    _train(run, work / tag, Plan(epochs=None), NAME, seed=0)
    result = evaluate(run.runtimes[NAME], test, name=f"{PRESET} test")
    errors = np.linalg.norm(result.predictions - test.world[:, :2], axis=1)
    info = run.rows[NAME][0]
    return SettingResult(
        setting=setting,
        detector=detector.describe(),
        in_view=len(truth_cameras),
        truth_cameras=truth_cameras,
        cameras=test.visible().sum(1),
        errors=errors,
        metrics=result.metrics,
        train_rows=train.n,
        epochs=int(info["epochs_run"]),
        data_seconds=data_seconds,
        train_seconds=float(info["seconds"]),
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--train-frames", type=int, default=TRAIN_FRAMES,
                        help="training scene frames to draw from")  # fmt: skip
    parser.add_argument("--test-frames", type=int, default=TEST_FRAMES,
                        help="test scene frames to draw from")  # fmt: skip
    parser.add_argument("--every", type=int, default=EVERY, help="use every n-th frame")
    parser.add_argument("--out", type=Path, default=RESULTS / "highres_localization.md")
    args = parser.parse_args(argv)
    from models.simulate import Scene, get_config

    config = get_config(PRESET)
    train_scene, test_scene = Scene(config, TRAIN_SEED), Scene(config, TEST_SEED)
    train_frames = range(0, args.train_frames, args.every)
    test_frames = range(0, args.test_frames, args.every)
    truth_cameras = in_view(test_scene, test_frames)
    _log(f"test: {len(truth_cameras)} person-instances in view in {len(test_frames)} frame sets")
    results = []
    with tempfile.TemporaryDirectory(prefix="momloc-highres-") as tmp:
        for shrink in SETTINGS:
            results.append(
                run_setting(
                    shrink,
                    train_scene,
                    test_scene,
                    train_frames,
                    test_frames,
                    truth_cameras,
                    Path(tmp),
                )
            )
    width, height = config.cameras[0].image_size
    header = (
        f"Preset `{PRESET}` ({config.num_cameras} cameras {width}×{height}, {config.people} "
        f"people, {config.fps:g} fps): training scene seed {TRAIN_SEED}, frames 0–"
        f"{args.train_frames - 1}, one in {args.every} ({len(train_frames)} frame sets), test "
        f"scene seed {TEST_SEED} (unseen walks), frames 0–{args.test_frames - 1}, one in "
        f"{args.every} ({len(test_frames)} frame sets). Every frame drawn by `models.simulate` "
        "and sent through the shipped NanoDet (default score threshold, one onnxruntime thread) "
        "with max_shrink "
        + ", ".join("None" if s is None else f"{s:g}" for s in SETTINGS)
        + "; detections labelled with the simulator's truth (one-to-one, IoU ≥ 0.5, "
        "`models.simulate.detector_view.detector_dataset`). One MoM + bbox model per setting, "
        "trained with `models.mom.training.train.train_model` defaults (seed 0) on that setting's "
        "training "
        "rows and evaluated with `models.mom.evaluate` (the served localizer) on its test rows."
    )
    command = command_line("bench.detector.highres_localization", argv)
    text = report(results, command, header)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Choose the detector by measurement: recall by person height, precision, edge errors, speed.

Run with ``make bench-detector`` or ``python -m bench.detector.accuracy [--quick]
[--model KIND=PATH ...]``. Every detector kind in the registry (``available_detectors()``) that
can be built without a user file is measured — a kind the lead registers later shows up here by
itself; kinds that need a file (``yolov8``) run when ``--model yolov8=/path/to/model.onnx`` names
one. Variants of a kind (other options, e.g. NanoDet's input size) run with ``--variant
KIND:OPTION=VALUE`` (by default NanoDet at 416×320 and 256×192 besides its default). Writes
``bench/results/detector_accuracy.md`` (tables, machine, date), ``detector_recall_by_height.png``
and ``detector_profile_measurements.json`` (per-height miss rates and edge errors for the
simulator's detector-noise profiles; ``_quick`` names with ``--quick``).

Method, decided once:

- Detectors are built at the lowest reported score threshold (0.3) and their detections are
  filtered for 0.4 and 0.5 afterwards, so one inference serves all three thresholds. Frames go
  in pairs, one batched call per pair, as the daemon sends two cameras.
- Data: :mod:`bench.detector.data` (hand-checked vtest frames, simulator renders, pasted
  scikit-image photographs); metrics: :mod:`bench.detector.metrics`.
- Speed: a pair of real 640×480 frames (two vtest frames), preprocessing and decoding included
  (``detect()`` end to end), 1 and 2 onnxruntime threads. All configurations run interleaved
  round-robin so a neighbour's load hits each alike; reported as median and p90 of wall and CPU
  milliseconds (``time.process_time``, all threads) and as a ratio to SSDLite *in the same run* —
  the machine is shared, so absolute figures are upper bounds and only the ratios compare.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from bench.detector.data import (
    PHOTO_LABELS,
    VTEST_LABELS,
    Sample,
    load_labels,
    photo_samples,
    simulator_samples,
    vtest_samples,
)
from bench.detector.metrics import Evaluation, evaluate
from common.errors import MomlocError
from models.detector import PersonDetector, available_detectors, create_detector

SCORE_THRESHOLDS = (0.3, 0.4, 0.5)
IOU_THRESHOLDS = (0.5, 0.3)
REFERENCE = "ssdlite"
# Input sizes issue 11 asks about for NanoDet (measured only when the kind is registered).
DEFAULT_VARIANTS = ("nanodet:input_size=416,320", "nanodet:input_size=256,192")


@dataclass
class DetectorRun:
    """One detector kind: its description, raw detections per data set, and timings."""

    kind: str
    describe: str
    detections: dict[str, list[tuple[object, np.ndarray, np.ndarray]]] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    timing: dict[int, dict[str, list[float]]] = field(default_factory=dict)

    def evaluation(self, dataset: str, score: float, iou: float) -> Evaluation:
        return evaluate(self.detections[dataset], score, iou)


def build(
    kind: str, threads: int, model_paths: dict[str, str], extra: dict[str, object] | None = None
) -> PersonDetector:
    """A detector of ``kind`` at the lowest threshold; raises MomlocError when it needs a file."""
    options: dict[str, object] = {"threads": threads, "score_threshold": min(SCORE_THRESHOLDS)}
    options.update(extra or {})
    if kind in model_paths:
        options["model_path"] = model_paths[kind]
    try:
        return create_detector(kind, **options)
    except MomlocError as error:
        if "bad option" not in str(error):
            raise
    # A kind without some of these options (a future plugin): build with what it takes.
    for drop in ("score_threshold", "threads"):
        options.pop(drop)
        try:
            return create_detector(kind, **options)
        except MomlocError as error:
            if "bad option" not in str(error):
                raise
    raise MomlocError(f"detector {kind!r}: cannot be built with the benchmark's options")


def detect_all(detector: PersonDetector, samples: Sequence[Sample]) -> list[tuple]:
    """``(truth, boxes, scores)`` per sample, frames batched in pairs."""
    out = []
    for start in range(0, len(samples), 2):
        pair = samples[start : start + 2]
        for sample, found in zip(pair, detector.detect([s.image for s in pair]), strict=True):
            out.append((sample.truth, np.asarray(found.boxes), np.asarray(found.scores)))
    return out


def measure_speed(
    detectors: dict[tuple[str, int], PersonDetector], frames: list[np.ndarray], repeats: int
) -> dict[tuple[str, int], dict[str, list[float]]]:
    """Wall and CPU ms per ``detect(frames)`` call, all configurations interleaved."""
    times: dict[tuple[str, int], dict[str, list[float]]] = {
        key: {"wall": [], "cpu": []} for key in detectors
    }
    for detector in detectors.values():  # warm-up beyond the load-time one
        detector.detect(frames)
    for _ in range(repeats):
        for key, detector in detectors.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            detector.detect(frames)
            times[key]["wall"].append((time.perf_counter() - start) * 1000)
            times[key]["cpu"].append((time.process_time() - start_cpu) * 1000)
    return times


def speed_summary(runs: dict[str, DetectorRun]) -> list[dict[str, object]]:
    """Median/p90 wall and CPU per (kind, threads), with ratios to SSDLite at the same threads."""
    rows = []
    for threads in (1, 2):
        ref = runs.get(REFERENCE)
        ref_t = ref.timing.get(threads) if ref else None
        for kind, run in runs.items():
            t = run.timing.get(threads)
            if not t:
                continue
            row: dict[str, object] = {"detector": kind, "threads": threads}
            for key in ("wall", "cpu"):
                row[f"{key}_median"] = statistics.median(t[key])
                row[f"{key}_p90"] = float(np.percentile(t[key], 90))
                if ref_t:
                    row[f"{key}_ratio"] = row[f"{key}_median"] / statistics.median(ref_t[key])
            rows.append(row)
    return rows


def parse_models(values: Sequence[str]) -> dict[str, str]:
    paths = {}
    for value in values:
        kind, sep, path = value.partition("=")
        if not sep or not kind or not path:
            raise MomlocError(f"--model {value!r}: expected KIND=PATH")
        paths[kind] = path
    return paths


def parse_variant(value: str) -> tuple[str, str, dict[str, object]]:
    """``"nanodet:input_size=416,320"`` → (label ``"nanodet 416x320"``, kind, options)."""
    kind, sep, assignment = value.partition(":")
    key, eq, raw = assignment.partition("=")
    if not sep or not eq or not kind or not key:
        raise MomlocError(f"--variant {value!r}: expected KIND:OPTION=VALUE")
    parts = [p.strip() for p in raw.split(",")]

    def number(text: str) -> object:
        for cast in (int, float):
            try:
                return cast(text)
            except ValueError:
                pass
        return {"true": True, "false": False}.get(text.lower(), text)

    parsed = tuple(number(p) for p in parts) if len(parts) > 1 else number(parts[0])
    shown = "x".join(parts) if key == "input_size" else f"{key}={raw}"
    return f"{kind} {shown}", kind, {key: parsed}


def main(argv: list[str] | None = None) -> int:
    from bench.detector import report as detector_report

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer frames and repeats (smoke)")
    parser.add_argument(
        "--model", action="append", default=[], metavar="KIND=PATH", help="model file for a kind"
    )
    parser.add_argument(
        "--variant", action="append", default=None, metavar="KIND:OPTION=VALUE",
        help=f"also measure a kind with other options (default: {' '.join(DEFAULT_VARIANTS)})",
    )  # fmt: skip
    parser.add_argument("--no-variants", action="store_true", help="only each kind's defaults")
    parser.add_argument("--repeats", type=int, default=None, help="timing repeats per config")
    parser.add_argument("--kinds", nargs="*", default=None, help="only these kinds")
    args = parser.parse_args(argv)
    try:
        model_paths = parse_models(args.model)
        variants = (
            [] if args.no_variants else [parse_variant(v) for v in args.variant or DEFAULT_VARIANTS]
        )
    except MomlocError as error:
        parser.error(str(error))
    repeats = args.repeats or (8 if args.quick else 40)
    load = os.getloadavg()

    started = time.perf_counter()
    vtest_doc = load_labels(VTEST_LABELS)
    datasets: dict[str, list[Sample]] = {
        "vtest": vtest_samples(vtest_doc),
        "simulator": list(
            simulator_samples(
                frames_per_scene=2 if args.quick else 6, seeds=(1,) if args.quick else (1, 2)
            )
        ),
        "photos": photo_samples(load_labels(PHOTO_LABELS)),
    }
    print(f"data ready in {time.perf_counter() - started:.0f} s: "
          + ", ".join(f"{k} {len(v)} frames" for k, v in datasets.items()), flush=True)  # fmt: skip

    runs: dict[str, DetectorRun] = {}
    skipped: dict[str, str] = {}
    timed: dict[tuple[str, int], PersonDetector] = {}
    kinds = args.kinds or available_detectors()
    configs = [(kind, kind, {}) for kind in kinds]
    configs += [v for v in variants if v[1] in kinds and v[1] in available_detectors()]
    for label, kind, extra in configs:
        try:
            detector = build(kind, 1, model_paths, extra)
            timed[(label, 1)] = detector
            timed[(label, 2)] = build(kind, 2, model_paths, extra)
        except MomlocError as error:
            skipped[label] = str(error)
            print(f"skip {label}: {error}", flush=True)
            continue
        run = runs[label] = DetectorRun(label, detector.describe())
        for name, samples in datasets.items():
            start = time.perf_counter()
            run.detections[name] = detect_all(detector, samples)
            run.seconds[name] = time.perf_counter() - start
        print(f"{label}: detections done ({run.describe})", flush=True)

    pair = [s.image for s in datasets["vtest"][10:12]]
    for (label, threads), samples in measure_speed(timed, pair, repeats).items():
        runs[label].timing[threads] = samples

    counts = {k: len(v) for k, v in datasets.items()}
    report = detector_report.Report(
        runs=runs,
        skipped=skipped,
        frames=counts,
        vtest_counts=vtest_doc["counts"],
        speed=speed_summary(runs),
        repeats=repeats,
        load=load,
        quick=args.quick,
        argv=argv if argv is not None else [],
    )
    for path in report.write():
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

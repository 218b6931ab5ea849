"""Choose NanoDet's inference engine by measurement: CPU and wall time per pair, and accuracy.

Run with ``make bench-detector`` or ``python -m bench.detector.runtimes [--quick]``; writes
``bench/results/detector_runtimes.md``. Every engine of :mod:`models.detector.runtimes` (runtime
and precision) whose runtime is installed runs the shipped NanoDet at its default input (320×256,
the same graph: ncnn's files are converted, the INT8 model quantized, from the ONNX file), and
the levers that were tried and not shipped run beside them:

- a **smaller input** (288×224) with the default engine;
- **candidates** given as ``--candidate LABEL=RUNTIME:PATH`` (e.g. onnxruntime's INT8 graph that
  ``tools/quantize_nanodet.py --onnxruntime-candidate`` writes);

on

- **speed**: a pair of real 640×480 frames (two vtest frames) per ``detect()`` call,
  preprocessing and decoding included, at 1 and 2 threads; all configurations interleaved
  round-robin so a neighbour's load hits each alike, reported as medians and as a ratio to
  onnxruntime FP32 *in the same run* (the machine is shared: only the ratios compare);
- **accuracy**: the hand-checked ``vtest.avi`` boxes (``bench/data/vtest_people.json``), frames
  in pairs as the daemon sends two cameras; recall, precision and the bottom-edge error at the
  shipped score threshold. A configuration must keep recall within 1 point of onnxruntime
  FP32's to be eligible as the default (``models.detector.runtimes.PREFERRED``).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import statistics
import time

import numpy as np

from bench.detector.accuracy import detect_all, measure_speed
from bench.detector.data import VTEST_LABELS, load_labels, vtest_samples
from bench.detector.metrics import evaluate
from bench.report import command_line, machine_line, markdown_table, write_result
from models.detector import PersonDetector, create_detector
from models.detector.runtimes import PREFERRED, installed

REFERENCE = "onnxruntime fp32"
SMALLER_INPUT = (288, 224)
SCORES = (0.3, 0.4, 0.5)
SHIPPED_SCORE = 0.4
IOU = 0.5
MAX_RECALL_LOSS = 0.01


def version(runtime: str) -> str:
    try:
        return importlib.metadata.version(runtime)
    except importlib.metadata.PackageNotFoundError:
        return "?"


def accuracy_rows(
    detections: dict[str, list[tuple]],
) -> tuple[list[list[object]], dict[str, float]]:
    rows, recall_at_shipped = [], {}
    reference = {s: evaluate(detections[REFERENCE], s, IOU).recall()[0] for s in SCORES}
    for runtime, found in detections.items():
        for score in SCORES:
            result = evaluate(found, score, IOU)
            recall, people = result.recall()
            bottom = result.edge_stats("bottom")
            if score == SHIPPED_SCORE:
                recall_at_shipped[runtime] = recall
            rows.append(
                [
                    runtime,
                    score,
                    f"{recall:.3f}",
                    f"{100 * (recall - reference[score]):+.1f}",
                    f"{result.precision:.3f}",
                    f"{result.fp_per_frame:.2f}",
                    f"{bottom['median_abs']:.3f} / {bottom['bias']:+.3f}",
                    people,
                ]
            )
    return rows, recall_at_shipped


def speed_rows(
    times: dict[tuple[str, int], dict[str, list[float]]], labels: list[str]
) -> list[list[object]]:
    rows: list[list[object]] = []
    for threads in (1, 2):
        ref = times.get((REFERENCE, threads))
        for runtime in labels:
            t = times.get((runtime, threads))
            if t is None or ref is None:
                continue
            wall, cpu = statistics.median(t["wall"]), statistics.median(t["cpu"])
            rows.append(
                [
                    runtime,
                    threads,
                    f"{wall:.1f}",
                    f"{np.percentile(t['wall'], 90):.1f}",
                    f"{cpu:.1f}",
                    f"{wall / statistics.median(ref['wall']):.2f}",
                    f"{cpu / statistics.median(ref['cpu']):.2f}",
                ]
            )
    return rows


def configurations(candidates: list[str]) -> dict[str, dict[str, object]]:
    """Label → ``create_detector`` options: the installed engines, the smaller input with the
    first of them (the default) and the ``--candidate`` models."""
    engines = [e for e in PREFERRED if installed(e.runtime)]
    configs: dict[str, dict[str, object]] = {
        f"{e.runtime} {e.precision}": {"runtime": e.runtime, "precision": e.precision}
        for e in engines
    }
    width, height = SMALLER_INPUT
    configs[f"{engines[0].runtime} {engines[0].precision} {width}x{height}"] = {
        "runtime": engines[0].runtime,
        "precision": engines[0].precision,
        "input_size": SMALLER_INPUT,
    }
    for candidate in candidates:
        label, _, target = candidate.partition("=")
        runtime, _, path = target.partition(":")
        if not (label and runtime and path):
            raise SystemExit(f"--candidate {candidate!r}: expected LABEL=RUNTIME:PATH")
        configs[label] = {"runtime": runtime, "model_path": path}
    return configs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer timing repeats (smoke run)")
    parser.add_argument("--repeats", type=int, default=None, help="timing repeats per config")
    parser.add_argument(
        "--candidate",
        action="append",
        default=[],
        help="LABEL=RUNTIME:PATH, an unshipped model measured beside the engines (repeatable)",
    )
    args = parser.parse_args(argv)
    repeats = args.repeats or (8 if args.quick else 30)
    load = os.getloadavg()

    samples = vtest_samples(load_labels(VTEST_LABELS))
    configs = configurations(args.candidate)
    missing = sorted({e.runtime for e in PREFERRED if not installed(e.runtime)})
    timed: dict[tuple[str, int], PersonDetector] = {}
    detections: dict[str, list[tuple]] = {}
    for label, options in configs.items():
        for threads in (1, 2):
            timed[(label, threads)] = create_detector(
                "nanodet", threads=threads, score_threshold=min(SCORES), **options
            )
        detections[label] = detect_all(timed[(label, 1)], samples)
        print(f"{label}: detections done", flush=True)
    pair = [s.image for s in samples[10:12]]
    started = time.perf_counter()
    times = measure_speed(timed, pair, repeats)
    seconds = time.perf_counter() - started

    accuracy, recall = accuracy_rows(detections)
    speed = speed_rows(times, list(configs))
    eligible = [c for c in configs if recall[c] >= recall[REFERENCE] - MAX_RECALL_LOSS]
    verdicts = []
    default = next(f"{e.runtime} {e.precision}" for e in PREFERRED if installed(e.runtime))
    for threads in (1, 2):
        cpu = {c: statistics.median(times[(c, threads)]["cpu"]) for c in configs}
        fastest = min(eligible, key=cpu.__getitem__)
        verdicts.append(
            f"- {threads} thread(s): **{fastest}** uses the least CPU among the configurations "
            f"that keep recall within {100 * MAX_RECALL_LOSS:.0f} point of onnxruntime FP32's; "
            f"`runtime: auto` takes **{default}** here"
            + (
                "."
                if fastest == default
                else f", {cpu[default] / cpu[fastest]:.2f}x the CPU of {fastest} in this run."
            )
        )
        reference_cpu = statistics.median(times[(REFERENCE, threads)]["cpu"])
        verdicts.append(
            f"  {default}: {cpu[default]:.1f} CPU-ms per pair, {cpu[default] / reference_cpu:.2f}x "
            f"onnxruntime FP32's {reference_cpu:.1f} (target ≤ 25 CPU-ms: "
            f"{'met' if cpu[default] <= 25 else 'not met'} in this run, at the load above)."
        )
    ineligible = [c for c in configs if c not in eligible]
    if ineligible:
        verdicts.append(
            f"- Not eligible (recall more than {100 * MAX_RECALL_LOSS:.0f} point below "
            f"onnxruntime FP32's): {', '.join(ineligible)}."
        )
    verdict = "\n".join(verdicts)
    present = sorted({e.runtime for e in PREFERRED if installed(e.runtime)})
    versions = ", ".join(f"{r} {version(r)}" for r in present)
    not_run = f" Not installed, not measured: {', '.join(missing)}." if missing else ""
    text = f"""# NanoDet under each inference runtime

{machine_line()} {versions}.{not_run}
Load average at start {load[0]:.1f} (1 min), {load[1]:.1f} (5 min): the machine is shared by
several sessions, so absolute times are upper bounds and only the ratios within this run
compare. Produced by `{command_line("bench.detector.runtimes", argv)}`.

Eligible configurations and the default (`models.detector.runtimes.PREFERRED`; the daemon's
scheduled detector runs one thread):

{verdict}

## Speed: a pair of 640×480 frames, one `detect()` call, 320×256 input unless named

{repeats} interleaved rounds after warm-up ({seconds:.0f} s); "CPU" is the CPU time of this process
per call, all threads (the figure that decides how often a busy 2-core machine can detect);
ratios are to onnxruntime FP32 at the same thread count. ncnn runs the two frames one after the
other (it has no batch); onnxruntime and OpenVINO run them as one batch of 2.

{
        markdown_table(
            [
                "configuration",
                "threads",
                "wall median ms",
                "wall p90 ms",
                "CPU median ms",
                "wall ratio",
                "CPU ratio",
            ],
            speed,
        )
    }

## Accuracy on the hand-checked vtest.avi boxes

{len(samples)} frames resized to 640×480 (people 18–122 px tall), IoU ≥ {IOU}; "Δ recall" in
points against onnxruntime FP32 at the same score threshold (the shipped threshold is
{SHIPPED_SCORE}); bottom error: median |error| / median signed error of matched boxes fully in
view, as a fraction of the true height (about ±0.02 is label noise here).

{
        markdown_table(
            [
                "configuration",
                "score",
                "recall",
                "Δ recall (points)",
                "precision",
                "FP/frame",
                "bottom err",
                "people",
            ],
            accuracy,
        )
    }
"""
    write_result("detector_runtimes_quick.md" if args.quick else "detector_runtimes.md", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

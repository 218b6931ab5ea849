"""Small people: what recovers people below ~150 px, and at what CPU cost (writes
bench/results/small_people.md).

Candidates, all with the shipped NanoDet on the hand-checked vtest frames (scaled to 640×480, as
``bench.detector.accuracy`` does; people there are 40–130 px tall, the far half of a webcam's
room):

- **larger input** for the whole frame (256×192 … 512×384);
- **a top band** at a higher scale: the far half of the room is the top half of the frame, so the
  upper rows get a second pass at 1.6× the full pass's scale;
- **windows around known people** (:class:`models.detector.windows.WindowRefiner`): the people
  found in the previous frames (as the image-space tracker carries them) are looked at again in
  small windows at ~``target`` px. Run recurrently over the ``history`` frames before each
  annotated frame, so a person found once is kept, as in the live pipeline.

Reported per candidate: recall at IoU ≥ 0.5 by true height, precision, the bottom edge's median
error (fraction of box height), CPU-ms per frame (one onnxruntime thread, ``time.process_time``:
the CPU budget, robust to other load), and recall gained per CPU-ms over the default.

Usage::

    python -m bench.detector.small_people [--history 4] [--out bench/results/small_people.md]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path

import cv2
import numpy as np

from bench.detector.data import (
    FRAME_SIZE,
    VTEST_LABELS,
    ensure_vtest,
    load_labels,
    truth_from_rows,
)
from bench.detector.metrics import Truth, evaluate
from bench.report import write_report
from models.detector import Detections, create_detector
from models.detector.nanodet import NanoDetDetector
from models.detector.preprocessing import nms
from models.detector.windows import WindowRefiner

RESULTS = Path(__file__).resolve().parents[1] / "results"
BANDS = (("<100", 0.0, 100.0), ("100-200", 100.0, 200.0), ("80-300", 80.0, 300.0))
# One frame set's step: the frame and the boxes the previous step found (the tracker's priors).
Strategy = Callable[[np.ndarray, np.ndarray], Detections]


def sequences(history: int) -> list[tuple[Truth, list[np.ndarray]]]:
    """Per annotated frame: its truth and the ``history`` frames before it, then itself."""
    doc = load_labels(VTEST_LABELS)
    path = ensure_vtest(doc)
    wanted = {int(k): rows for k, rows in doc["frames"].items()}
    scale = FRAME_SIZE[0] / doc["video"]["width"]
    capture = cv2.VideoCapture(str(path))
    frames: list[np.ndarray] = []
    out = []
    index = 0
    while index <= max(wanted):
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(cv2.resize(frame, FRAME_SIZE, interpolation=cv2.INTER_AREA))
        frames = frames[-(history + 1) :]
        if index in wanted:
            out.append((truth_from_rows(wanted[index]).scaled(scale), list(frames)))
        index += 1
    capture.release()
    return out


def full(detector: NanoDetDetector) -> Strategy:
    return lambda frame, _priors: detector.detect([frame])[0]


def band(detector: NanoDetDetector, band_size: tuple[int, int], rows: float) -> Strategy:
    """Full pass plus the top ``rows`` of the frame at ``band_size``; boxes merged by NMS."""
    band_detector = detector.resized(band_size)

    def run(frame: np.ndarray, _priors: np.ndarray) -> Detections:
        whole = detector.detect([frame])[0]
        top = band_detector.detect([frame[: int(frame.shape[0] * rows)]])[0]
        boxes = np.vstack([top.boxes, whole.boxes])
        scores = np.concatenate([top.scores, whole.scores])
        keep = nms(boxes, scores, detector.iou_threshold)
        return Detections(boxes[keep], scores[keep])

    return run


def windows(detector: NanoDetDetector, refiner: WindowRefiner) -> Strategy:
    """Full pass plus windows around the previous step's boxes."""
    return lambda frame, priors: refiner([frame], detector.detect([frame]), [priors])[0]


def measure(
    name: str, strategy: Strategy, data: Sequence[tuple[Truth, list[np.ndarray]]]
) -> dict[str, object]:
    """Run ``strategy`` recurrently over each annotated frame's history; score the last step and
    time it alone (the steady-state cost of one frame)."""
    triples, costs = [], []
    for truth, frames in data:
        priors = np.zeros((0, 4), np.float32)
        for image in frames[:-1]:
            priors = strategy(image, priors).boxes
        begin = time.process_time()
        found = strategy(frames[-1], priors)
        costs.append(time.process_time() - begin)
        triples.append((truth, found.boxes, found.scores))
    result = evaluate(triples, score_threshold=0.0, iou_threshold=0.5)
    row: dict[str, object] = {"name": name, "precision": result.precision}
    for label, low, high in BANDS:
        row[label] = result.recall(low, high)
    row["bottom"] = result.edge_stats("bottom")["median_abs"]
    row["cpu_ms"] = float(np.median(costs)) * 1e3
    return row


def candidates() -> list[tuple[str, Strategy]]:
    base = create_detector("nanodet", threads=1, score_threshold=0.4)
    assert isinstance(base, NanoDetDetector)
    out: list[tuple[str, Strategy]] = []
    for size in ((256, 192), (320, 256), (416, 320), (512, 384)):
        out.append((f"full {size[0]}x{size[1]}", full(base.resized(size))))
    out.append(("full 320x256 + top half at 512x192", band(base, (512, 192), 0.5)))
    for size in ((96, 160), (128, 192)):
        for max_height in (100.0, 150.0):
            refiner = WindowRefiner(base.resized(size), max_height=max_height, max_windows=6)
            name = f"full 320x256 + windows {size[0]}x{size[1]} below {max_height:.0f} px"
            out.append((name, windows(base, refiner)))
    return out


def report(rows: list[dict[str, object]], history: int, frames: int) -> str:
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    cores = len(os.sched_getaffinity(0))
    machine = f"{platform.machine()} ({platform.system()}, {cores} cores shared)"
    base = next(r for r in rows if r["name"] == "full 320x256")
    lines = [
        "# Small people: recall gained per CPU-ms",
        "",
        f"Generated by `python -m bench.detector.small_people` on {stamp}, {machine}. NanoDet "
        f"(shipped), "
        f"score ≥ 0.4, on the {frames} hand-checked vtest frames scaled to 640×480 "
        "(`bench/data/vtest_people.json`); recall at IoU ≥ 0.5 by true box height (count in "
        f"brackets); windows are carried over the {history} frames before each annotated frame. "
        "CPU-ms per frame on one onnxruntime thread (process time, steady state).",
        "",
        "| candidate | recall <100 px | recall 100-200 px | recall 80-300 px | precision "
        "| bottom edge median abs | CPU-ms / frame | recall <100 gained per extra CPU-ms |",
        "|---|---|---|---|---|---|---|---|",
    ]
    base_recall, base_cost = base["<100"][0], base["cpu_ms"]
    for row in rows:
        cells = [str(row["name"])]
        for label, _, _ in BANDS:
            value, count = row[label]
            cells.append(f"{value:.2f} ({count})")
        extra_ms = row["cpu_ms"] - base_cost
        gain = (row["<100"][0] - base_recall) / extra_ms * 100 if extra_ms > 1 else None
        gained = "—" if gain is None else f"{gain:+.2f} pt"
        cells += [
            f"{row['precision']:.2f}",
            f"{row['bottom']:.3f}",
            f"{row['cpu_ms']:.1f}",
            gained,
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--history", type=int, default=4)
    parser.add_argument("--out", type=Path, default=RESULTS / "small_people.md")
    args = parser.parse_args(argv)
    data = sequences(args.history)
    rows = [measure(name, strategy, data) for name, strategy in candidates()]
    text = report(rows, args.history, len(data))
    return write_report(args.out, text)


if __name__ == "__main__":
    raise SystemExit(main())

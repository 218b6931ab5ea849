"""High-resolution cameras: what NanoDet's ``max_shrink`` buys in recall, and at what CPU cost
(writes bench/results/highres_recall.md).

A fixed 320×256 input squeezes a 1920×1080 frame by 6 in x and 4.2 in y, so a person 150 px
tall arrives 36 px tall and much thinner than the network was trained on. ``max_shrink`` grows
the input with the frame (:func:`models.detector.preprocessing.input_for_frame`). Measured for
``max_shrink`` None (fixed 320×256), 4, 3 and 2, score ≥ 0.4, IoU ≥ 0.5:

- **real video at high resolution**: the hand-checked vtest frames (640×480) rebuilt as
  1280×720 and 1920×1080 frames — resized to the frame's height (INTER_LINEAR, aspect kept) and
  centred on grey, as a 4:3 picture in a 16:9 camera frame — with the 640×480 frames themselves as
  the reference. The people and their labels stay those a person checked by hand; only the
  pixel count changes. "Under 100 px" is in 640×480 terms (true height × 480 / frame height), so
  the band holds the same people at every size;
- **drawn high-resolution frames**: :mod:`models.simulate` preset ``outdoor-6cam`` (six
  1920×1080 cameras), recall by true height;
- **CPU**: ms per frame on one thread of the default engine (``time.process_time``: the machine
  is shared, process time is the budget and robust to other load), all settings interleaved
  frame by frame, and as a ratio to the fixed input on the 640×480 frames of the same run.

Usage::

    python -m bench.detector.highres_recall [--out bench/results/highres_recall.md]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from bench.detector.data import FRAME_SIZE, Sample, scene_samples, vtest_samples
from bench.detector.metrics import HEIGHT_BANDS, Evaluation, Truth, evaluate
from bench.report import command_line, machine_line
from models.detector import create_detector
from models.detector.nanodet import NanoDetDetector
from models.detector.preprocessing import PAD_VALUE, input_for_frame

RESULTS = Path(__file__).resolve().parents[1] / "results"
SETTINGS: tuple[float | None, ...] = (None, 4.0, 3.0, 2.0)
VTEST_SIZES = (FRAME_SIZE, (1280, 720), (1920, 1080))
SCORE, IOU = 0.4, 0.5
SMALL = 100.0  # px in 640×480 terms: the far people a webcam must still find
DRAWN_PRESET, DRAWN_SEEDS, DRAWN_FRAMES = "outdoor-6cam", (1, 2), (0, 60, 120, 180)
DRAWN_BANDS = ("<100", "100-200", ">200")


@dataclass(frozen=True)
class Row:
    """One data set at one frame size under one ``max_shrink``: the pooled matching result,
    the height below which a person counts as small (frame pixels), and median CPU-ms."""

    data: str
    frame_size: tuple[int, int]
    max_shrink: float | None
    input_size: tuple[int, int]
    result: Evaluation
    small_below: float
    cpu_ms: float

    @property
    def setting(self) -> str:
        """The row's name as an operator would set it (``max_shrink`` None shows its input)."""
        if self.max_shrink is None:
            return f"fixed {self.input_size[0]}x{self.input_size[1]}"
        return f"max_shrink {self.max_shrink:g}"


def rebuilt(sample: Sample, size: tuple[int, int]) -> Sample:
    """``sample`` as a camera of ``size`` (width, height) would deliver it: the picture scaled
    to fit (aspect kept, INTER_LINEAR as a camera's upscaler), centred on grey (114, the
    detector's own padding value, so the border adds no edges), boxes moved with the pixels."""
    height, width = sample.image.shape[:2]
    scale = min(size[0] / width, size[1] / height)
    new_w, new_h = round(width * scale), round(height * scale)
    left, top = (size[0] - new_w) // 2, (size[1] - new_h) // 2
    canvas = np.full((size[1], size[0], 3), PAD_VALUE, np.uint8)
    canvas[top : top + new_h, left : left + new_w] = cv2.resize(
        sample.image, (new_w, new_h), interpolation=cv2.INTER_LINEAR
    )
    factor = np.array([new_w / width, new_h / height] * 2)
    boxes = sample.truth.boxes * factor + [left, top, left, top]
    truth = Truth(boxes, sample.truth.occluded, sample.truth.truncated, sample.truth.ignore)
    return Sample(f"{sample.name}@{size[0]}x{size[1]}", canvas, truth)


def drawn_samples() -> Iterator[Sample]:
    """Every camera of the outdoor preset at a few frames and seeds."""
    from models.simulate import Scene, get_config

    for seed in DRAWN_SEEDS:
        scene = Scene(get_config(DRAWN_PRESET), seed)
        yield from scene_samples(scene, DRAWN_FRAMES, f"{DRAWN_PRESET}/s{seed}")


def detectors() -> dict[float | None, NanoDetDetector]:
    """The shipped NanoDet per setting, one thread each of the default engine (runtime auto;
    CPU per frame = budget)."""
    out = {}
    for shrink in SETTINGS:
        detector = create_detector("nanodet", max_shrink=shrink, threads=1, score_threshold=SCORE)
        assert isinstance(detector, NanoDetDetector)
        out[shrink] = detector
    return out


def measure(
    data: str,
    samples: Iterable[Sample],
    models: dict[float | None, NanoDetDetector],
    small_below: float,
) -> list[Row]:
    """Every setting on every frame (interleaved frame by frame, so a neighbour's load hits
    each alike); one row per setting with the pooled result and the median CPU-ms per frame.
    All ``samples`` share one frame size."""
    triples: dict[float | None, list[tuple[Truth, np.ndarray, np.ndarray]]] = {
        s: [] for s in models
    }
    costs: dict[float | None, list[float]] = {s: [] for s in models}
    frame_size = (0, 0)
    for sample in samples:
        frame_size = (sample.image.shape[1], sample.image.shape[0])
        for shrink, detector in models.items():
            begin = time.process_time()
            found = detector.detect([sample.image])[0]
            costs[shrink].append(time.process_time() - begin)
            triples[shrink].append((sample.truth, found.boxes, found.scores))
    return [
        Row(
            data,
            frame_size,
            shrink,
            input_for_frame(detector.input_size, frame_size, shrink),
            evaluate(triples[shrink], SCORE, IOU),
            small_below,
            float(np.median(costs[shrink])) * 1e3,
        )
        for shrink, detector in models.items()
    ]


def cell(value: tuple[float, int]) -> str:
    """A recall with its number of people, so a band of 11 people is not read like one of 300."""
    return f"{value[0]:.2f} ({value[1]})"


def reference(rows: Sequence[Row]) -> Row:
    """The CPU yardstick: the fixed input on the smallest vtest frames (a webcam's 640×480)."""
    vtest = [r for r in rows if r.data == "vtest" and r.max_shrink is None]
    return min(vtest, key=lambda r: r.frame_size[1])


def reading(rows: Sequence[Row]) -> str:
    """The paragraph under the header: per data set, at its largest frame, each setting's
    recall, small-people recall, precision and CPU against the fixed input."""
    ref = reference(rows)
    sentences = []
    for data, what in (("vtest", "The hand-checked video"), ("drawn", "The drawn outdoor frames")):
        top = max(r.frame_size[1] for r in rows if r.data == data)
        group = [r for r in rows if r.data == data and r.frame_size[1] == top]
        parts = []
        for r in group:
            shown = "" if r.max_shrink is None else f" ({r.input_size[0]}x{r.input_size[1]})"
            parts.append(
                f"{r.setting}{shown} finds {r.result.recall()[0]:.2f} (under 100 px "
                f"{r.result.recall(0, r.small_below)[0]:.2f}) at precision "
                f"{r.result.precision:.2f} for {r.cpu_ms / ref.cpu_ms:.1f}× the CPU"
            )
        most = max(r.result.recall()[0] for r in group)
        best = " and ".join(r.setting for r in group if r.result.recall()[0] == most)
        precise = max(group, key=lambda r: r.result.precision)
        people = group[0].result.recall()[1]
        small = group[0].result.recall(0, group[0].small_below)[1]
        sentences.append(
            f"{what} at {group[0].frame_size[0]}x{top} ({people} people, {small} under 100 px): "
            + "; ".join(parts)
            + f". Most people found with {best}, highest precision with {precise.setting}."
        )
    webcam = {r.input_size for r in rows if r.data == "vtest" and r.frame_size == ref.frame_size}
    if len(webcam) == 1:
        sentences.append(
            f"At {ref.frame_size[0]}x{ref.frame_size[1]} every setting keeps the "
            f"{ref.input_size[0]}x{ref.input_size[1]} input, so webcams are unchanged."
        )
    return " ".join(sentences)


def report(rows: Sequence[Row], counts: dict[str, int], command: str, engine: str) -> str:
    """The markdown: header (what, machine, date, command), the reading, and one table per data
    set with CPU per frame beside the recall it buys."""
    ref = reference(rows)
    cpu = lambda r: f"{r.cpu_ms:.1f} | {r.cpu_ms / ref.cpu_ms:.2f}"  # noqa: E731
    lines = [
        "# High-resolution cameras: NanoDet's max_shrink",
        "",
        f"Generated by `{command}`. {machine_line()} NanoDet (shipped, "
        f"{ref.input_size[0]}x{ref.input_size[1]} base input) with max_shrink "
        + ", ".join("None (fixed)" if s is None else f"{s:g}" for s in SETTINGS)
        + f"; score ≥ {SCORE}, recall and precision at IoU ≥ {IOU}, people counted in brackets. "
        f"Video: the {counts['vtest']} hand-checked vtest frames (`bench/data/vtest_people.json`, "
        "640×480) rebuilt as 16:9 frames (scaled to the frame height, INTER_LINEAR, centred on "
        "grey 114); under 100 px is in 640×480 terms (true height × 480 / frame height). "
        f"Drawn: `{DRAWN_PRESET}` seeds {', '.join(map(str, DRAWN_SEEDS))}, frames "
        f"{', '.join(map(str, DRAWN_FRAMES))}, every camera ({counts['drawn']} frames, "
        "1920×1080), heights in frame pixels. CPU-ms: median per frame on one "
        f"{engine} thread (`time.process_time`, settings interleaved), and as a ratio to the "
        "fixed input "
        f"on {ref.frame_size[0]}x{ref.frame_size[1]} frames in this run.",
        "",
        "**Reading.** " + reading(rows),
        "",
        "## Hand-checked video at three frame sizes",
        "",
        "| frame | setting | network input | recall | recall <100 px (640×480 terms) "
        "| precision | false boxes / frame | CPU-ms / frame | CPU × fixed @ 640×480 |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r.data == "vtest":
            lines.append(
                f"| {r.frame_size[0]}x{r.frame_size[1]} | {r.setting} | "
                f"{r.input_size[0]}x{r.input_size[1]} | {cell(r.result.recall())} | "
                f"{cell(r.result.recall(0, r.small_below))} | {r.result.precision:.2f} | "
                f"{r.result.fp_per_frame:.2f} | {cpu(r)} |"
            )
    lines += [
        "",
        "## Drawn outdoor frames (1920×1080)",
        "",
        "| setting | network input | "
        + " | ".join(f"recall {b} px" for b in DRAWN_BANDS)
        + " | recall | precision | false boxes / frame | CPU-ms / frame | CPU × fixed @ 640×480 |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r.data == "drawn":
            bands = " | ".join(cell(r.result.recall(*HEIGHT_BANDS[b])) for b in DRAWN_BANDS)
            lines.append(
                f"| {r.setting} | {r.input_size[0]}x{r.input_size[1]} | {bands} | "
                f"{cell(r.result.recall())} | {r.result.precision:.2f} | "
                f"{r.result.fp_per_frame:.2f} | {cpu(r)} |"
            )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=RESULTS / "highres_recall.md")
    args = parser.parse_args(argv)
    models = detectors()
    video = vtest_samples()
    rows: list[Row] = []
    for size in VTEST_SIZES:
        frames = (rebuilt(s, size) for s in video)
        rows += measure("vtest", frames, models, SMALL * size[1] / FRAME_SIZE[1])
        print(f"vtest {size[0]}x{size[1]} done", flush=True)
    rows += measure("drawn", drawn_samples(), models, SMALL)
    counts = {"vtest": len(video), "drawn": rows[-1].result.frames}
    command = command_line("bench.detector.highres_recall", argv)
    graph = next(iter(models.values())).graph
    text = report(rows, counts, command, f"{graph.runtime} {graph.precision}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""How the shipped detectors see the simulator's drawn people → bench/results/render_recall.md.

For each preset (indoor-2cam, indoor-4cam, living-room, office-3cam; seed 2, every ``step``-th of
``frames`` frames) every camera's frame is rendered and run through NanoDet (the default, score
0.4) and SSDLite (score 0.4). People are counted as ``models.simulate.detector_view`` defines:
recall at IoU >= 0.5 on *clear* people (>= 90 % in the image, < 20 % covered by nearer people's
boxes) by reference box height, plus recall on every person in view, precision (a detection
matching no person at IoU >= 0.5 is false), and the matched boxes' bottom-edge error
(detected - true, in % of the true height: what the demo model has to learn).

Render cost: ms per 640×480 frame (background cached, as in the demo), wall and CPU.

Run: ``python -m bench.detector.render_recall [--frames 1200 --step 15] [--label NAME]``;
``--label`` names the renderer version in the output file (``render_recall_<label>.md``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench.report import RESULTS, machine_line, markdown_table
from models.simulate import PRESETS, Scene
from models.simulate.detector_view import camera_truth, match

PRESET_NAMES = ("indoor-2cam", "indoor-4cam", "living-room", "office-3cam")
BINS = ((0, 100, "< 100 px"), (100, 200, "100-200 px"), (200, 10_000, "> 200 px"))


def mid_hip_depth(scene: Scene, obs, camera: int) -> np.ndarray:
    hips = obs.joints[:, 11:13].mean(1)
    return scene.cameras[camera].project_depth(hips)[1]


def collect(detectors: dict, frames: range, seed: int = 2) -> tuple[dict, list]:
    """Per detector rows (preset, height, clear, found, bottom error %, score); render timings."""
    rows: dict[str, list] = {name: [] for name in detectors}
    extra = {name: [0, 0] for name in detectors}  # detections, false
    timing = []
    for preset in PRESET_NAMES:
        scene = Scene(PRESETS[preset], seed=seed)
        for k in range(scene.num_cameras):
            scene.render(0, k)  # backgrounds cached, as in a running demo
        wall = cpu = 0.0
        count = 0
        for f in frames:
            obs = scene.observe(f)
            w0, c0 = time.perf_counter(), time.process_time()
            images = [scene.render(f, k) for k in range(scene.num_cameras)]
            wall += time.perf_counter() - w0
            cpu += time.process_time() - c0
            count += len(images)
            truths = [
                camera_truth(obs.true_boxes[:, k], mid_hip_depth(scene, obs, k),
                             scene.cameras[k].image_size)
                for k in range(scene.num_cameras)
            ]  # fmt: skip
            for name, detector in detectors.items():
                for truth, found in zip(truths, detector.detect(images), strict=True):
                    hit = match(truth.boxes, found.boxes)
                    extra[name][0] += len(found)
                    extra[name][1] += len(found) - int((hit >= 0).sum())
                    for p in np.flatnonzero(truth.seen):
                        height = truth.heights[p]
                        if hit[p] >= 0:
                            box = found.boxes[hit[p]]
                            bottom = 100 * (box[3] - truth.boxes[p, 3]) / height
                            score = float(found.scores[hit[p]])
                        else:
                            bottom, score = np.nan, np.nan
                        rows[name].append(
                            (preset, height, bool(truth.clear[p]), hit[p] >= 0, bottom, score)
                        )
        timing.append([preset, scene.config.people, f"{1000 * wall / count:.1f}",
                       f"{1000 * cpu / count:.1f}"])  # fmt: skip
    for name in detectors:
        rows[name].append(("_counts", *extra[name]))
    return rows, timing


def tables(rows: dict) -> list[str]:
    out = []
    header = ["detector", "preset", *[label for *_, label in BINS], "all clear", "all in view",
              "precision"]  # fmt: skip
    recall_rows, geometry_rows = [], []
    for name, data in rows.items():
        counts = data[-1]
        people = data[:-1]
        for preset in (*PRESET_NAMES, "all"):
            sel = [r for r in people if preset == "all" or r[0] == preset]
            if not sel:
                continue
            h = np.array([r[1] for r in sel])
            clear = np.array([r[2] for r in sel])
            found = np.array([r[3] for r in sel])
            cells = []
            for lo, hi, _ in BINS:
                s = clear & (h >= lo) & (h < hi)
                cells.append(f"{found[s].mean():.0%} ({s.sum()})" if s.any() else "-")
            cells.append(f"{found[clear].mean():.0%} ({clear.sum()})")
            cells.append(f"{found.mean():.0%} ({len(found)})")
            precision = "-"
            if preset == "all":
                detections, false = counts[1], counts[2]
                precision = f"{1 - false / max(detections, 1):.2f}"
            recall_rows.append([name, preset, *cells, precision])
        h = np.array([r[1] for r in people])
        bottom = np.array([r[4] for r in people])
        for lo, hi, label in BINS:
            s = (h >= lo) & (h < hi) & np.isfinite(bottom)
            if s.any():
                geometry_rows.append([name, label, s.sum(), f"{np.median(bottom[s]):+.1f}",
                                      f"{np.median(np.abs(bottom[s])):.1f}"])  # fmt: skip
    out.append(markdown_table(header, recall_rows))
    out.append(
        "Bottom edge of matched boxes, detected - true, in % of the true height:\n\n"
        + markdown_table(
            ["detector", "height", "matched", "median", "median |error|"], geometry_rows
        )
    )
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1200)
    parser.add_argument("--step", type=int, default=15)
    parser.add_argument("--label", default="")
    args = parser.parse_args(argv)
    from models.detector import create_detector

    detectors = {
        "nanodet": create_detector("nanodet", score_threshold=0.4, threads=2),
        "ssdlite": create_detector("ssdlite", score_threshold=0.4, threads=2),
    }
    rows, timing = collect(detectors, range(0, args.frames, args.step))
    label = f" ({args.label})" if args.label else ""
    text = "\n\n".join([
        f"# Detectors on the simulator's drawn people{label}",
        machine_line(),
        f"Presets {', '.join(PRESET_NAMES)}, seed 2, every {args.step}th of {args.frames} frames. "
        "Recall at IoU ≥ 0.5 on clear people (≥ 90 % in the image, < 20 % covered by nearer "
        "people's boxes) by true box height, cell = recall (people); 'all in view' counts "
        "truncated and occluded people too. Score threshold 0.4 for both.",
        *tables(rows),
        "Render cost per 640×480 frame (background cached):\n\n"
        + markdown_table(["preset", "people", "wall ms", "CPU ms"], timing),
    ]) + "\n"  # fmt: skip
    RESULTS.mkdir(parents=True, exist_ok=True)
    suffix = f"_{args.label}" if args.label else ""
    (RESULTS / f"render_recall{suffix}.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()

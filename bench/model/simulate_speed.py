"""Simulator speed and how the shipped detector sees rendered frames → bench/results/simulate.md.

Measures (wall clock and CPU time, since the bench box is shared):
- ``simulate`` of 2000 frames for indoor-2cam (3 people) and outdoor-6cam (8 people);
- ``Scene.render`` per frame at 640×480 and 1920×1080 (background cached, as in a live demo);
- SSDLite recall on rendered frames: people fully inside the image and not overlapping anyone,
  matched at IoU ≥ 0.5, by true box height, with the median score and box-height ratio.

Run: ``python -m bench.model.simulate_speed`` (about a minute on 2 cores).
"""

from __future__ import annotations

import time

import numpy as np

from bench.report import RESULTS, machine_line, markdown_table
from models.simulate import PRESETS, Scene, simulate


def _timed(fn, repeat: int = 1) -> tuple[float, float]:
    """(wall, cpu) seconds per call."""
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - wall) / repeat, (time.process_time() - cpu) / repeat


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ix = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    iy = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    inter = np.clip(ix, 0, None) * np.clip(iy, 0, None)
    area = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        return inter / (area[:, None] + area_b[None] - inter)


def detector_rows(frames: range) -> list[list[object]]:
    from models.detector import create_detector

    detector = create_detector("ssdlite", score_threshold=0.3)
    rows = []
    for name in ("indoor-2cam", "indoor-4cam", "office-3cam", "living-room"):
        scene = Scene(PRESETS[name], seed=2)
        for f in frames:
            obs = scene.observe(f)
            images = [scene.render(f, k) for k in range(scene.num_cameras)]
            for k, found in enumerate(detector.detect(images)):
                size = np.array(scene.cameras[k].image_size * 2, float)
                true = obs.true_boxes[:, k]
                ok = np.isfinite(true).all(-1)
                ok &= (true[:, :2] > 0).all(-1) & (true[:, 2:] < size[2:]).all(-1)
                filled = np.nan_to_num(true, nan=-9.0)
                overlap = _iou(filled, filled)
                np.fill_diagonal(overlap, 0)
                ok &= np.nan_to_num(overlap).max(1) < 0.05
                for p in np.nonzero(ok)[0]:
                    height = true[p, 3] - true[p, 1]
                    if len(found.boxes):
                        match = _iou(true[p : p + 1], found.boxes)[0]
                        j = int(match.argmax())
                        box = found.boxes[j]
                        ratio = (box[3] - box[1]) / height
                        rows.append((height, match[j], found.scores[j], ratio))
                    else:
                        rows.append((height, 0.0, 0.0, np.nan))
    table = []
    data = np.array(rows)
    for lo, hi in ((0, 80), (80, 120), (120, 220), (220, 2000)):
        sel = (data[:, 0] >= lo) & (data[:, 0] < hi)
        hit = sel & (data[:, 1] >= 0.5)
        if sel.any():
            table.append([
                f"{lo}-{hi} px" if hi < 2000 else f"≥ {lo} px", int(sel.sum()),
                f"{hit.sum() / sel.sum():.0%}",
                f"{np.median(data[hit, 2]):.2f}" if hit.any() else "-",
                f"{np.median(data[hit, 3]):.2f}" if hit.any() else "-",
            ])  # fmt: skip
    return table


def main() -> None:
    speed = []
    for name in ("indoor-2cam", "outdoor-6cam"):
        wall, cpu = _timed(lambda name=name: simulate(name, 2000, seed=0))
        config = PRESETS[name]
        speed.append([f"simulate {name}, 2000 frames × {config.people} people", f"{wall:.2f} s",
                      f"{cpu:.2f} s"])  # fmt: skip
    for name in ("indoor-2cam", "outdoor-6cam"):
        scene = Scene(PRESETS[name], seed=0)
        scene.render(0, 0)  # background cached once per camera
        w, h = scene.cameras[0].image_size
        counter = iter(range(1, 10_000))
        wall, cpu = _timed(lambda scene=scene, c=counter: scene.render(next(c), 0), repeat=100)
        speed.append([f"render {name} {w}×{h}, {scene.config.people} people",
                      f"{wall * 1000:.1f} ms", f"{cpu * 1000:.1f} ms"])  # fmt: skip
    detection = detector_rows(range(0, 1200, 20))
    text = "\n\n".join([
        "# Synthetic scene simulator: speed and detector view",
        machine_line(),
        markdown_table(["task", "wall", "CPU"], speed),
        "SSDLite (shipped, score ≥ 0.3) on rendered frames of indoor-2cam, indoor-4cam, "
        "office-3cam and living-room (seed 2, every 20th of 1200 frames): people fully in view "
        "and not overlapping anyone; found = a detection with IoU ≥ 0.5 to the true box.",
        markdown_table(["true box height", "people", "found", "median score",
                        "detected / true height"], detection),
    ]) + "\n"  # fmt: skip
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "simulate.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()

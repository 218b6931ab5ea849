"""Shelf streamed: people standing and bending at a shelf, served by the daemon's chain from real
keypoint boxes → bench/results/real_shelf_stream.md.

Shelf (``../shared/data/shelf``) has real OpenPose joints but no person boxes and no grouping of
joints into people. Each person's box in each camera is built from *their* OpenPose joints: the
joints matched to the person's projected true joints (:func:`bench.real.shelf.match_joint`, 0.5 h
gate), at least ``MIN_JOINTS`` of them, their extent widened to the body (head top above the
neck, soles below the ankles, ``PAD``). The grouping uses the truth (an oracle a pose estimator's
own grouping would replace), the boxes' noise, misses and bends are OpenPose's.

The set-up is the first ``--train-fraction`` of the frames (dense: every person-instance, labels
the true pelvis floor point), trained with ``models.mom.training.train.train_model``; the rest is
streamed through the daemon's pipeline (:func:`bench.real.stream.stream_chain`) at ``--fps``. Shelf
does not state its frame rate: 25 fps is assumed (the tracker's time rules depend on it). People
there barely walk (0.4-1.3 m spread each), so this measures served error, id stability and the
jitter of people standing and bending, not walking coverage.

Usage::

    python -m bench.real.shelf_stream [--data ../shared/data] [--fps 25]
                                      [--out bench/results/real_shelf_stream.md]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bench.real.chain import train_runtime
from bench.real.data import DEFAULT_DATA, Calibration, data_folder
from bench.real.scoring import DetectionScore
from bench.real.shelf import CITATION, match_joint
from bench.real.shelf_data import (
    PELVIS,
    SHELF_TO_BODY25,
    Skeletons,
    load_cameras,
    load_detections,
    load_truth,
)
from bench.real.stream import stream_chain
from bench.report import RESULTS, command_line, machine_line, markdown_table
from models.data.dataset import MomDataset
from models.detector.base import Detections

MIN_JOINTS = 5
PAD = (0.12, 0.25, 0.12, 0.05)  # left, top, right, bottom, in units of the joints' height


def person_boxes(
    cameras: Sequence[Calibration], truth: Sequence[Skeletons], detections: list
) -> list[np.ndarray]:
    """Per frame [P, K, 4]: each true person's box from their own OpenPose joints (NaN: fewer
    than ``MIN_JOINTS`` matched in that camera)."""
    out = []
    for f, people in enumerate(truth):
        boxes = np.full((len(people.ids), len(cameras), 4), np.nan)
        for k, cam in enumerate(cameras):
            if not len(people.ids):
                continue
            px, depth = cam.project(people.joints)
            ok = people.valid & (depth > 0.1)
            ys = np.where(ok, px[..., 1], np.nan)
            with np.errstate(invalid="ignore"):
                height = np.nan_to_num(np.nanmax(ys, axis=1) - np.nanmin(ys, axis=1))
            found = np.full((len(people.ids), 15, 2), np.nan)
            for s, j in SHELF_TO_BODY25.items():
                cand = detections[k][f][j]
                target = np.where(ok[:, s, None], px[:, s], np.nan)
                match = match_joint(target, np.maximum(height, 20.0), cand)
                found[match >= 0, s] = cand[match[match >= 0], :2]
            for p in range(len(people.ids)):
                pts = found[p][np.isfinite(found[p]).all(axis=1)]
                if len(pts) < MIN_JOINTS:
                    continue
                lo, hi = pts.min(axis=0), pts.max(axis=0)
                h = max(hi[1] - lo[1], 1.0)
                box = [
                    lo[0] - PAD[0] * h,
                    lo[1] - PAD[1] * h,
                    hi[0] + PAD[2] * h,
                    hi[1] + PAD[3] * h,
                ]
                w, hh = cam.image_size
                boxes[p, k] = np.clip(box, [0, 0, 0, 0], [w - 1, hh - 1, w - 1, hh - 1])
        out.append(boxes)
    return out


def rows(truth: Sequence[Skeletons], boxes: Sequence[np.ndarray], frames: range,
         sizes: np.ndarray, seen_only: bool) -> MomDataset:  # fmt: skip
    """Dataset v1 of ``frames``: world = pelvis floor point, track = person id."""
    world, box, frame, track = [], [], [], []
    for f in frames:
        people, b = truth[f], boxes[f]
        keep = people.valid[:, PELVIS]
        if seen_only:
            keep &= np.isfinite(b).all(axis=2).any(axis=1)
        world.append(people.joints[keep, PELVIS, :2])
        box.append(b[keep])
        frame.append(np.full(int(keep.sum()), f, np.int64))
        track.append(people.ids[keep])
    return MomDataset(
        np.concatenate(world).astype(np.float32),
        np.concatenate(box).reshape(-1, len(sizes), 4).astype(np.float32),
        np.concatenate(frame),
        np.concatenate(track),
        sizes,
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--fps", type=float, default=25.0, help="assumed frame rate")
    parser.add_argument("--train-fraction", type=float, default=0.6)
    parser.add_argument("--train-seconds", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=RESULTS / "real_shelf_stream.md")
    args = parser.parse_args(argv)
    folder = data_folder(args.data, "shelf")
    if folder is None:
        return 0
    cameras = load_cameras(folder)
    truth = load_truth(folder / "gt_shelf15_3d.txt")
    detections = [
        load_detections(folder / "detection_openpose_body25" / f"{k}.txt", c.image_size)
        for k, c in enumerate(cameras)
    ]
    boxes = person_boxes(cameras, truth, detections)
    sizes = np.array([c.image_size for c in cameras], np.int32)
    split = round(args.train_fraction * len(truth))
    train = rows(truth, boxes, range(split), sizes, seen_only=True)
    test_frames = range(split, len(truth))
    served_truth = rows(truth, boxes, test_frames, sizes, seen_only=False)
    rng = np.random.default_rng([args.seed, 13])

    def report(f: int) -> list[Detections]:
        out = []
        for k in range(len(cameras)):
            b = boxes[f][:, k]
            b = b[np.isfinite(b).all(axis=1)][
                rng.permutation(int(np.isfinite(b).all(axis=1).sum()))
            ]
            out.append(Detections(b.astype(np.float32), np.ones(len(b), np.float32), None))
        return out

    def annotated(f: int) -> np.ndarray:
        return truth[f].joints[truth[f].valid[:, PELVIS], PELVIS, :2]

    with tempfile.TemporaryDirectory(prefix="momloc-shelf-") as tmp:
        started = time.monotonic()
        runtime, epochs = train_runtime(train, Path(tmp) / "model", args.train_seconds, args.seed)
        trained = time.monotonic() - started
        stream, frame = stream_chain(
            list(test_frames), args.fps, report, annotated, runtime, Path(tmp), served_truth
        )
    oracle = DetectionScore()
    for f in test_frames:
        seen = np.isfinite(boxes[f]).all(axis=2).any(axis=1) & truth[f].valid[:, PELVIS]
        tuples = boxes[f][seen].astype(np.float32)
        oracle.add(runtime.localize(tuples) if len(tuples) else np.zeros((0, 2)), annotated(f))
    o = oracle.result()
    near = np.linalg.norm(served_truth.world[:, None] - train.world[None], axis=2).min(axis=1)
    covered = 100.0 * float(np.mean(near <= 0.3))
    boxed = np.mean([np.isfinite(b).all(axis=2).any(axis=1).mean() for b in boxes if len(b)])
    table = [
        [
            train.n,
            f"{trained:.0f} ({epochs})",
            runtime.policy,
            f"{frame['moda']:.1f}",
            f"{frame['precision']:.1f} / {frame['recall']:.1f}",
            f"{frame['mean']:.3f}",
            f"{o['moda']:.1f} ({o['mean']:.3f})",
            f"**{stream['mota']:.1f}**",
            stream["id_switches"],
            f"{stream['mean']:.3f}",
            f"{stream['acc@0.3']:.1f}",
            f"{100 * stream['jitter_m']:.1f}" if stream.get("jitter_m") is not None else "–",
        ]
    ]
    header = ["training rows", "training s (epochs)", "served policy", "MODA % (per frame)",
              "precision / recall % (per frame)", "matched mean m (per frame)",
              "MODA % (mean m) true association", "streamed MOTA %", "id switches",
              "streamed mean m", "Acc@0.3 %", "standing jitter cm RMS"]  # fmt: skip
    text = "\n".join(
        [
            "# Shelf streamed: standing and bending at a shelf, real keypoint boxes",
            "",
            f"Generated by `{command_line('bench.real.shelf_stream', argv)}`. {machine_line()}",
            "",
            f"Data: {CITATION}. Boxes from each person's own OpenPose joints (grouped by the "
            f"truth, see `bench/real/shelf_stream.py`); {100 * boxed:.1f} % of the person-"
            f"instances have a box in at least one camera. Set-up: frames 0–{split - 1} "
            f"(dense, pelvis floor point as label), served: frames {split}–{len(truth) - 1} "
            f"through the daemon's pipeline at an assumed {args.fps:g} fps; per frame: the "
            "association's positions, Hungarian at 0.5 m against every annotated person; "
            "streamed: `momloc track --truth` scoring against every annotated person. "
            f"{covered:.1f} % of the served person-instances stand within 0.3 m of a set-up "
            "label (people work at other spots of the shelf later on).",
            "",
            markdown_table(header, table),
            "",
        ]
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

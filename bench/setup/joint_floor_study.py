"""Self-labels' positions as served against refitted jointly (writes bench/results/joint_floor.md).

``python -m bench.setup.joint_floor_study [--seeds 21 22] [--minutes 2 5 10]``

The floor geometry a self-improvement run trains (`models/geometry/floor_prior.py` refitted on
the floor marks plus the self-labels) with the labels' positions as the 4-mark model served
them, and with the positions of the joint floor fit (`models/geometry/joint_floor.py`, what
`service.learning.training_set.aligned` hands the training); against geometries fitted on the
4 marks, on 9 marks, and on a dense recording's true positions. indoor-2cam, detector profile
nanodet; the marks as in `bench/setup/self_learning.py` (the set-up plan, 20 s per mark), the
labels collected by the daemon's listener while the 4-mark model serves 3 people walking
(`bench/setup/room_run.py`); per-frame error on the same dense test room (simulate seed 12,
true association). The geometry alone, no encoder and no gate: what the labels' positions do
to the fit. The last two columns are the rows an improvement run trains on: the half of the
labels the gate does not hold out, refitted jointly, each label kept with a chance that falls
with the covariance the serving model gave its position (until 2026-12-06) or, for those the
joint fit placed, whole (`service/learning/training_set.py`). Code:
`bench/setup/joint_floor_study.py`.

Part 2: Whether it holds for other set-ups, where the 4-mark geometry is good or poor: 4-mark
recordings of other simulated feeds (seeds 11, the one above, and 1-3; 6 or 20 s per mark),
each with the same 2000 two-view moments of one walk (simulate seed 5, 3 people) as labels, at
the positions that recording's 4-mark geometry gives them; every column the per-frame mean on
the test room. (A bundle adjustment by alternation, re-fusing the labels with the refitted
geometry, made the geometry worse on two such set-ups: `self_learning_policy.md`.)
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.report import RESULTS, machine_line, markdown_table
from bench.setup.room_run import RoomRun
from bench.setup.self_learning import DENSE_SEED, PRESET, TEST_SEED, train
from bench.setup.setup_stream import collect_marks
from models.data.dataset import MomDataset
from models.geometry.floor_prior import FloorPrior
from models.geometry.joint_floor import fit_joint_floor
from models.simulate import simulate
from service.learning.gate import held_out
from service.learning.training_set import aligned, training_set
from service.offline.stream_eval import scene_config

PROFILE = "nanodet"
WALK_SEED, WALK_FRAMES, WALK_LABELS = 5, 3000, 2000


def per_frame(prior: FloorPrior, test: MomDataset) -> float:
    xy, _ = prior.predict(test.boxes)
    error = np.linalg.norm(xy - test.world[:, :2], axis=1)
    return float(np.mean(error[np.isfinite(error)]))


def refit(marks: MomDataset, world: np.ndarray, boxes: np.ndarray) -> FloorPrior:
    """The floor geometry of the marks plus labels at ``world`` (their ``boxes`` after the
    marks' rows)."""
    rows_world = np.concatenate([marks.world[:, :2], world])
    return FloorPrior.fit_arrays(rows_world, boxes, marks.image_size)


def rooms(
    seeds: list[int], minutes: list[float], test: MomDataset, work: Path
) -> tuple[list[list[object]], list[list[object]]]:
    """Part 1: the labels the daemon collects in the room bench's rooms; and the references."""
    rows: list[list[object]] = []
    marks = collect_marks("2x2", 20.0, PROFILE, work / "marks4.npz")
    nine = collect_marks("3x3", 20.0, PROFILE, work / "marks9.npz")
    dense = simulate(PRESET, 3000, DENSE_SEED, detector_profile=PROFILE).dataset
    references = [
        [name, f"{per_frame(FloorPrior.fit(data), test):.4f}"]
        for name, data in (("4 marks", marks), ("9 marks", nine), ("dense, true positions", dense))
    ]
    start = train(marks, work / "start", 30.0)
    for seed in seeds:
        (work / f"room-{seed}").mkdir()
        room = RoomRun(scene_config(PRESET, 3, PROFILE), seed, start, work / f"room-{seed}")
        for minute in minutes:
            room.advance(int(minute * 60 * room.scene.fps) - room.frame)
            store = room.labeler.store
            labels = None if store is None else store.load()
            if labels is None:
                raise SystemExit(f"seed {seed}: no self-labels after {minute:g} min")
            began = time.perf_counter()
            joint = fit_joint_floor(
                marks.world, marks.boxes, labels.world, labels.boxes, marks.image_size
            )
            seconds = time.perf_counter() - began
            boxes = np.concatenate([marks.boxes, labels.boxes])
            served, jointly = (
                per_frame(refit(marks, world, boxes), test) for world in (labels.world, joint.world)
            )
            taught, placed, _ = aligned(marks, labels.subset(~held_out(labels)))
            thinned, whole = (
                per_frame(FloorPrior.fit(training_set(marks, taught, placed=p)), test)
                for p in (None, placed)
            )
            rows.append([
                f"seed {seed}, {minute:g} min", labels.n, joint.moments, f"{served:.4f}",
                f"{jointly:.4f}", f"{thinned:.4f}", f"{whole:.4f}", f"{seconds:.1f}",
            ])  # fmt: skip
            print(rows[-1], flush=True)
    return references, rows


def recordings(feeds: list[int], test: MomDataset, work: Path) -> list[list[object]]:
    """Part 2: other floor-mark recordings (feed seeds, 6 or 20 s per mark), each with the same
    walk's two-view moments as labels at the positions its 4-mark geometry gives them."""
    walk = simulate(PRESET, WALK_FRAMES, WALK_SEED, detector_profile=PROFILE).dataset
    two = np.flatnonzero(np.isfinite(walk.boxes).all(axis=-1).sum(axis=1) >= 2)
    pick = np.random.default_rng(0).choice(two, min(WALK_LABELS, len(two)), replace=False)
    boxes, truth = walk.boxes[pick], walk.world[pick, :2]
    rows: list[list[object]] = []
    for feed_seed in feeds:
        for seconds in (6.0, 20.0):
            path = work / f"marks-{feed_seed}-{seconds:g}.npz"
            marks = collect_marks("2x2", seconds, PROFILE, path, seed=feed_seed)
            start = FloorPrior.fit(marks)
            served, _ = start.predict(boxes)
            ok = np.isfinite(served).all(axis=1)
            joint = fit_joint_floor(marks.world, marks.boxes, served[ok], boxes[ok],
                                    marks.image_size)  # fmt: skip
            rows_boxes = np.concatenate([marks.boxes, boxes[ok]])
            rows.append([
                f"feed {feed_seed}, {seconds:g} s per mark", f"{per_frame(start, test):.4f}",
                *(f"{per_frame(refit(marks, world, rows_boxes), test):.4f}"
                  for world in (served[ok], joint.world, truth[ok])),
            ])  # fmt: skip
            print(rows[-1], flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[21, 22])
    parser.add_argument("--minutes", type=float, nargs="+", default=[2.0, 5.0, 10.0])
    parser.add_argument("--feeds", type=int, nargs="+", default=[11, 1, 2, 3])
    parser.add_argument("--out", type=Path, default=RESULTS / "joint_floor.md")
    args = parser.parse_args()
    test = simulate(PRESET, 900, TEST_SEED, detector_profile=PROFILE).dataset
    with tempfile.TemporaryDirectory() as tmp:
        references, rows = rooms(args.seeds, args.minutes, test, Path(tmp))
        other = recordings(args.feeds, test, Path(tmp))
    table = markdown_table(
        ("4 marks + self-labels of", "self-labels", "moments in the joint fit",
         "positions as served: per-frame mean m", "refitted jointly: per-frame mean m",
         "training half, thinned by served covariance m", "training half, placed labels whole m",
         "joint fit s"),
        rows,
    )  # fmt: skip
    other_table = markdown_table(
        ("4-mark recording", "4 marks alone m", "positions as served m", "refitted jointly m",
         "true positions m"),
        other,
    )  # fmt: skip
    intro, part2 = __doc__.split(chr(10) + chr(10), 2)[2].split("Part 2: ")
    reference_table = markdown_table(("geometry fitted on", "per-frame mean m"), references)
    args.out.write_text(
        "# Self-labels: positions as served against refitted jointly\n\n"
        f"{machine_line()}\n\n{intro}\n{reference_table}\n\n{table}\n\n"
        f"## Other floor-mark recordings\n\n{part2}\n{other_table}\n"
    )
    print(args.out)


if __name__ == "__main__":
    main()

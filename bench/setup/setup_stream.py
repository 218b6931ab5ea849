"""Streamed accuracy of a model made by the set-up flow (writes bench/results/setup_stream.md).

Issue 14's second target: a room set up with 9 floor marks × 20 s, then scored on what clients
receive over the *whole* room, not only on the marks. Protocol: the indoor-2cam scene with the
detector ``--profile``; one simulated person follows the ``momloc collect`` plan (the same
collector, keep rule and feed the web set-up uses, :mod:`service.setup.collector`), the
recording trains a model with ``momloc train``'s defaults
(:func:`models.mom.training.train.train_model`), and that model serves the stream bench's chain
(:func:`service.offline.stream_eval.run_stream`: association, tracking, CLEAR-MOT at 0.5 m) on
people walking everywhere in the room (other seeds).

Usage::

    python -m bench.setup.setup_stream [--grid 3x3] [--seconds 20] [--profile nanodet] [--people 1
    3]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from bench.report import RESULTS, machine_line
from bench.serving.stream_accuracy import HEAD, combine, row
from models.data.dataset import MomDataset
from models.mom.runtime import MomRuntime
from models.mom.training.train import train_model
from models.simulate import get_config
from service.offline.stream_eval import run_stream, scene_config
from service.setup.collector import DatasetAppender, collect, plan_steps
from service.setup.feeds import SyntheticFeed
from service.setup.marks import grid_marks

PRESET = "indoor-2cam"
COLLECT_SEED = 11


def collect_marks(
    grid: str,
    seconds: float,
    profile: str | None,
    out: Path,
    preset: str = PRESET,
    seed: int = COLLECT_SEED,
) -> MomDataset:
    """The set-up recording: one simulated person standing on each mark of ``grid`` (the
    simulated feed's ``seed``)."""
    room = get_config(preset).room
    marks = grid_marks(grid, f"{room[0]}x{room[1]}")
    feed = SyntheticFeed(preset, seed, detector_profile=profile)
    steps = plan_steps(marks, seconds, start=(room[0] / 2, room[1] / 2))
    feed.prepare(steps)
    collect(feed, steps, DatasetAppender(out, feed.image_sizes))
    return MomDataset.load(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", default="3x3")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--profile", default="nanodet")
    parser.add_argument("--people", type=int, nargs="+", default=[1, 3])
    parser.add_argument("--seeds", type=int, nargs="+", default=[7, 8])
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--out", type=Path, default=RESULTS / "setup_stream.md")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        data = collect_marks(args.grid, args.seconds, args.profile, Path(tmp) / "setup.npz")
        model_dir = Path(tmp) / "model"
        train_model(data, model_dir, seed=0, progress=False)
        runtime = MomRuntime.load(model_dir)
        rows = []
        for people in args.people:
            config = scene_config(PRESET, people, args.profile)
            runs = [run_stream(runtime, config, seed, args.frames) for seed in args.seeds]
            scores = {gate: combine([r[gate] for r in runs]) for gate in (0.5, 1.0)}
            rows.append(row(PRESET, people, "set-up model", scores))
            print(rows[-1], end="", flush=True)
    text = (
        "# Streamed accuracy of a set-up model\n\n"
        f"{machine_line()}\n\n"
        f"Model: `momloc train` defaults on a `momloc collect` recording of {args.grid} marks × "
        f"{args.seconds:g} s (indoor-2cam, seed {COLLECT_SEED}, {data.n} rows, detector profile "
        f"`{args.profile}`); policy `{runtime.policy}`. Stream: {args.frames} frames × seeds "
        f"{', '.join(map(str, args.seeds))} of people walking everywhere in the room, scored as "
        "in `bench/results/stream_accuracy.md` (columns there).\n\n"
        f"{HEAD}{''.join(rows)}"
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(args.out)


if __name__ == "__main__":
    main()

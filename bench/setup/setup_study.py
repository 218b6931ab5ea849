"""Calibration-free setup study: accuracy over the whole room versus the floor marks recorded.

``python -m bench.setup.setup_study [--quick]`` writes ``bench/results/setup_study.md``.

Protocol: the indoor-2cam scene (10 × 10 m, two 640×480 webcams). A simulated person follows the
``momloc collect`` plan (go to each mark, countdown, sway and turn in place while recording) on
grids of 4, 6, 9 and 16 marks, for several seconds per mark, optionally walking between marks
(walk mode). Each collection trains a model with ``momloc train``'s defaults, with and without the
decoder, and is scored on a *dense* test recording of people walking everywhere in the same room
(``simulate``, other seed): that is what a user gets over the whole floor, not only on the marks.
The reference is a model trained on dense ground truth of the same room (``simulate``, a third
seed), what an expensive motion-capture labelling would give.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.report import RESULTS, machine_line, markdown_table
from models.data.dataset import MomDataset
from models.mom.evaluate import evaluate, score
from models.mom.runtime import MomRuntime
from models.mom.training.train import train_model
from models.simulate import get_config, simulate
from service.setup.collector import DatasetAppender, collect, plan_steps
from service.setup.feeds import SyntheticFeed
from service.setup.marks import grid_marks

PRESET = "indoor-2cam"
COLLECT_SEED, TEST_SEED, DENSE_SEED = 11, 12, 13


@dataclass(frozen=True)
class Case:
    grid: str
    seconds: float
    walk: bool = False

    @property
    def label(self) -> str:
        marks = int(np.prod([int(v) for v in self.grid.split("x")]))
        return f"{marks} marks ({self.grid}), {self.seconds:g} s" + (
            " + walks" if self.walk else ""
        )


FULL_CASES = (
    Case("2x2", 20),
    Case("2x3", 20),
    Case("3x3", 10),
    Case("3x3", 20),
    Case("3x3", 20, walk=True),
    Case("4x4", 20),
)
QUICK_CASES = (Case("2x2", 10), Case("3x3", 10))


def collect_marks(case: Case, out: Path) -> MomDataset:
    room = get_config(PRESET).room
    marks = grid_marks(case.grid, f"{room[0]}x{room[1]}")
    feed = SyntheticFeed(PRESET, COLLECT_SEED)
    steps = plan_steps(marks, case.seconds, start=(room[0] / 2, room[1] / 2), walk=case.walk)
    feed.prepare(steps)
    collect(feed, steps, DatasetAppender(out, feed.image_sizes))
    return MomDataset.load(out)


def train_and_score(data: MomDataset, test: MomDataset, decoder: bool, work: Path) -> dict:
    """The model as served (its localizer policy) and its MoM encoder alone."""
    out = work / f"model-{time.monotonic_ns()}"
    started = time.monotonic()
    train_model(data, out, decoder=decoder, progress=False)
    runtime = MomRuntime.load(out)
    metrics = evaluate(runtime, test).metrics
    encoder = score(runtime.encode(test.boxes), test).metrics
    return {
        **metrics,
        "encoder_mean": encoder["mean"],
        "encoder_acc@0.3": encoder["acc@0.3"],
        "policy": runtime.policy,
        "train_s": time.monotonic() - started,
    }


def run(quick: bool) -> Path:
    cases = QUICK_CASES if quick else FULL_CASES
    test = simulate(PRESET, frames=600 if quick else 2000, seed=TEST_SEED).dataset
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        dense = simulate(PRESET, frames=1500 if quick else 4000, seed=DENSE_SEED).dataset
        reference = train_and_score(dense, test, True, work)
        rows.append(("dense ground truth", dense.n, "yes", reference))
        print(f"dense reference: mean {reference['mean']:.3f} m", flush=True)
        for case in cases:
            data = collect_marks(case, work / f"{case.grid}-{case.seconds}-{case.walk}.npz")
            for decoder in (True, False):
                result = train_and_score(data, test, decoder, work)
                rows.append((case.label, data.n, "yes" if decoder else "no", result))
                print(f"{case.label} decoder={decoder}: mean {result['mean']:.3f} m", flush=True)

    table = markdown_table(
        ("Training data", "rows", "decoder", "localizer", "mean (m)", "vs dense", "median",
         "Acc@0.3 %", "Acc@0.5 %", "encoder alone: mean", "Acc@0.3 %", "train s"),
        [
            (label, n, dec, r["policy"], f"{r['mean']:.3f}",
             f"{r['mean'] / reference['mean']:.2f}×",
             f"{r['median']:.3f}", f"{r['acc@0.3']:.1f}", f"{r['acc@0.5']:.1f}",
             f"{r['encoder_mean']:.3f}", f"{r['encoder_acc@0.3']:.1f}", f"{r['train_s']:.0f}")
            for label, n, dec, r in rows
        ],
    )  # fmt: skip
    name = "setup_study_quick.md" if quick else "setup_study.md"
    path = RESULTS / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        "# Calibration-free setup study (indoor-2cam)\n\n"
        f"{machine_line()}\n\n"
        f"Test: dense walks of {test.n} person instances over the whole 10 × 10 m room "
        f"(simulate seed {TEST_SEED}); marks collected with seed {COLLECT_SEED}, the dense "
        f"reference trained on seed {DENSE_SEED}. 'vs dense' is the mean error ratio. "
        "'localizer' is what the trained model serves with (models/mom/prior_policy.py: floor-mark "
        "geometry for mark data, the MoM encoder for dense labels); 'encoder alone' is the MoM "
        "encoder of the same model, where the decoder's effect shows.\n\n"
        f"{table}\n"
    )
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two small cases, for a smoke run")
    print(run(parser.parse_args().quick))


if __name__ == "__main__":
    main()

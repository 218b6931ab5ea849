"""The room that learns, measured (writes bench/results/self_learning.md).

``python -m bench.setup.self_learning [--quick] [--minutes 2 5 10] [--no-baselines]
[--preset indoor-4cam]``

(a) **Self-improvement** (``--preset``, default indoor-2cam: bench/results/self_learning.md,
others self_learning_<preset>.md; detector ``--profile``, default nanodet): a model set up
on 4 floor marks (2 × 2, one simulated person following the ``momloc collect`` plan) serves a
room where 3 people walk; the self-label listener (:mod:`service.learning.listener`) collects
while it serves, and after 2, 5 and 10 simulated minutes one self-improvement run
(:class:`service.learning.improve.Improver`: the real ``momloc train`` child and the gate)
decides whether its candidate replaces the model in service. Scored on a dense test room
(other seed): per-frame (every person instance localized from its true boxes, ``momloc eval``)
and streamed (the chain and tracker, matched mean at 0.5 m), against models trained on 9 marks
and on dense ground truth of the same room.

(b) **Self-healing** (see :mod:`bench.setup.self_healing`).

Never worse: every gate decision is also judged against the truth (the candidate's and the
served model's per-frame error on the dense test room): a served candidate must not be worse.
``--never-worse N`` runs N more seeded rooms (one decision each after ``--minutes``, shorter
training: the point is the gate, not the best model) and writes
bench/results/self_learning_never_worse.md.
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bench.report import RESULTS, machine_line, markdown_table
from bench.setup.room_run import RoomRun
from bench.setup.setup_stream import collect_marks
from models.data.dataset import MomDataset
from models.mom.evaluate import evaluate
from models.mom.runtime import MomRuntime
from models.mom.training.train import train_model
from models.simulate import simulate
from service.learning.gate import Check, compare, held_out
from service.learning.improve import ImproveOptions, Improver
from service.learning.labels import BEYOND_TRACK, LabelBatch
from service.offline.stream_eval import run_stream, scene_config
from service.stages import LocalizationModel

PRESET = "indoor-2cam"
TEST_SEED, DENSE_SEED, STREAM_SEED = 12, 13, 7
TRAIN_BUDGET_S = 90.0
NEVER_WORSE_BUDGET_S = 30.0
NEVER_WORSE_SEEDS = 100  # the never-worse rooms are seeds 101, 102, ...


def train(data: MomDataset, out: Path, budget_s: float = TRAIN_BUDGET_S) -> MomRuntime:
    train_model(data, out, progress=False, tuning={"time_budget_s": budget_s})
    return MomRuntime.load(out)


class Judge:
    """Per-frame and streamed error of a model on the dense test room (cached per model)."""

    def __init__(
        self, profile: str, test_frames: int, stream_frames: int, preset: str = PRESET
    ) -> None:
        self.test = simulate(preset, test_frames, TEST_SEED, detector_profile=profile).dataset
        self.config = scene_config(preset, 3, profile)
        self.stream_frames = stream_frames

    def per_frame(self, model: LocalizationModel) -> float:
        return float(evaluate(model, self.test).metrics["mean"])  # type: ignore[arg-type]

    def streamed(self, model: LocalizationModel) -> dict[str, float]:
        m = run_stream(model, self.config, STREAM_SEED, self.stream_frames)[0.5]
        return {"mean": m["mean"], "recall": m["recall"], "mota": m["mota"]}

    def row(self, name: str, model: LocalizationModel, extra: str = "") -> list[str]:
        s = self.streamed(model)
        return [
            name,
            getattr(model, "policy", "?"),
            f"{self.per_frame(model):.3f}",
            f"{s['mean']:.3f}",
            f"{s['recall']:.1f}",
            f"{s['mota']:.1f}",
            extra,
        ]


def improvement_run(
    seed: int,
    marks: Path,
    work: Path,
    judge: Judge,
    minutes: list[float],
    budget_s: float = TRAIN_BUDGET_S,
    streamed: bool = True,
    trained: Path | None = None,
    rows: list[list[str]] | None = None,
    decisions: list[dict[str, Any]] | None = None,
    save: Callable[[], None] = lambda: None,
    keep: Path | None = None,
) -> tuple[list[list[str]], list[dict[str, Any]]]:
    """One room: 4-mark model (``trained``: a copy of that one), people walk, an improvement
    run at each of ``minutes``; appends to ``rows`` and ``decisions`` and calls ``save`` after
    each (a long run keeps what it measured so far). ``keep``: a folder that gets each run's
    candidate, self-labels and decision (:func:`rejudge` reads it)."""
    data_dir = work / f"room-{seed}"
    data_dir.mkdir()
    shutil.copyfile(marks, data_dir / "marks.npz")
    if trained is None:
        start = train(MomDataset.load(marks), data_dir / "model", budget_s)
    else:
        shutil.copytree(trained, data_dir / "model")
        start = MomRuntime.load(data_dir / "model")
    room = RoomRun(judge.config, seed, start, data_dir)
    options = ImproveOptions(nice_by=10, time_budget_s=budget_s)
    kept = None if keep is None else keep / f"seed-{seed}"

    def load(path: Path) -> MomRuntime:
        if kept is not None:
            shutil.rmtree(kept / "candidate", ignore_errors=True)
            shutil.copytree(path, kept / "candidate")
        return MomRuntime.load(path)

    improver = Improver(
        data_dir, room.labeler, room, marks=data_dir / "marks.npz", options=options, load=load
    )
    rows = [] if rows is None else rows
    decisions = [] if decisions is None else decisions
    if streamed:
        rows.append(judge.row(f"seed {seed}: 4 marks, start", start))
        save()
    for minute in minutes:
        target = int(minute * 60 * room.scene.fps)
        started = time.monotonic()
        room.advance(target - room.frame)
        walked = time.monotonic() - started
        current = room.runtime
        if kept is not None and room.labeler.store is not None:
            kept.mkdir(parents=True, exist_ok=True)
            stored = room.labeler.store.load()
            if stored is not None:
                np.savez(kept / "labels.npz", allow_pickle=False, **stored.arrays())
        verdict = improver.run()
        print(f"seed {seed} {minute:g} min: {room.labeler.stats()}", flush=True)
        if verdict is None:
            raise RuntimeError(f"improvement failed: {improver.status()}")
        candidate = improver.candidate
        assert candidate is not None
        truth = {"current": judge.per_frame(current), "candidate": judge.per_frame(candidate)}
        decisions.append({"seed": seed, "minute": minute, "serve": verdict.serve, **truth})
        if kept is not None:
            (kept / "decision.json").write_text(json.dumps(decisions[-1]))
        store = room.labeler.store
        stored = store.load() if store is not None else None
        labels = 0 if stored is None else stored.n
        beyond = 0 if stored is None else int((stored.track == BEYOND_TRACK).sum())
        served = "new model" if verdict.serve else "kept"
        print(f"seed {seed} {minute:g} min ({walked:.0f} s): {labels} labels; {verdict.reason}")
        if streamed:
            rows.append(
                judge.row(
                    f"seed {seed}: + {minute:g} min walking ({labels} labels, {beyond} beyond "
                    "the set-up area)",
                    room.runtime,
                    f"{served}: {verdict.reason.split(': ', 1)[-1]}",
                )
            )
        save()
    return rows, decisions


def gate_table(decisions: list[dict[str, Any]]) -> str:
    """Every gate decision against the truth, and how many served candidates were worse (with
    :func:`rejudge`'s decisions: also the gate of the run and both checks' differences)."""
    worse = [d for d in decisions if d["serve"] and d["candidate"] > d["current"]]
    rejudged = bool(decisions) and "then" in decisions[0]
    header = ["seed", "minute", "served"]
    header += ["served then", "marks mm", "views mm"] if rejudged else []
    header += ["in service: per-frame m", "candidate: per-frame m"]
    rows = []
    for d in decisions:
        row = [d["seed"], f"{d['minute']:g}", "yes" if d["serve"] else "no"]
        if rejudged:
            marks, views = d["verdict"].marks, d["verdict"].labels
            row += ["yes" if d["then"] else "no", _difference(marks), _difference(views)]
        rows.append([*row, f"{d['current']:.3f}", f"{d['candidate']:.3f}"])
    return (
        f"{markdown_table(header, rows)}\n\n"
        f"Served candidates worse than the model they replaced (per-frame, truth): {len(worse)} "
        f"of {sum(d['serve'] for d in decisions)} served, {len(decisions)} decisions.\n"
    )


def _difference(check: Check | None) -> str:
    """A paired check's difference and standard error in millimetres."""
    if check is None:
        return ""
    return f"{check.difference_m * 1000:+.1f} ± {check.se_m * 1000:.1f}"


def never_worse(args: argparse.Namespace) -> Path:
    """``--never-worse N``: N seeded rooms, one gate decision each (module docstring)."""
    judge = Judge(args.profile, 300, 0)
    decisions: list[dict[str, Any]] = []
    seeds = [NEVER_WORSE_SEEDS + i + 1 for i in range(args.never_worse)]
    path = RESULTS / "self_learning_never_worse.md"

    def save() -> None:
        path.write_text(
            "# The room that learns: the gate never serves a worse model\n\n"
            f"{machine_line()}\n\n"
            f"indoor-2cam, detector profile `{args.profile}`; a model set up on 4 floor marks "
            f"× {args.seconds:g} s serves {len(seeds)} rooms of 3 people walking (seeds "
            f"{seeds[0]}–{seeds[-1]}; {len(decisions)} done); after {args.minutes[0]:g} minutes "
            f"one self-improvement run (training capped at {NEVER_WORSE_BUDGET_S:g} s) and its "
            "gate decision, judged against the truth: per-frame error on a dense test room "
            f"(simulate seed {TEST_SEED}, {judge.test.n} person instances). Code: "
            f"`bench/setup/self_learning.py --never-worse`.\n\n{gate_table(decisions)}"
        )

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        marks4 = work / "marks4.npz"
        collect_marks("2x2", args.seconds, args.profile, marks4)
        trained = work / "start"
        train(MomDataset.load(marks4), trained, NEVER_WORSE_BUDGET_S)
        if args.keep is not None:
            args.keep.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(marks4, args.keep / "marks4.npz")
            shutil.copytree(trained, args.keep / "start", dirs_exist_ok=True)
        for seed in seeds:
            improvement_run(
                seed, marks4, work, judge, args.minutes[:1], NEVER_WORSE_BUDGET_S,
                streamed=False, trained=trained,
                decisions=decisions, save=save, keep=args.keep,
            )  # fmt: skip
            shutil.rmtree(work / f"room-{seed}", ignore_errors=True)
    return path


def rejudge(args: argparse.Namespace) -> Path:
    """``--rejudge DIR``: the rooms a ``--never-worse N --keep DIR`` run kept, judged again by
    the gate as it is now. The same candidates (training is not repeated), so the gate of that
    run and this one are compared decision by decision."""
    folder = args.rejudge
    marks = MomDataset.load(folder / "marks4.npz")
    start = MomRuntime.load(folder / "start")  # in service at each room's one decision
    decisions: list[dict[str, Any]] = []
    rooms = sorted(folder.glob("seed-*"), key=lambda p: int(p.name.split("-", 1)[1]))
    for room in rooms:
        if not (room / "decision.json").is_file():
            continue  # a room the run did not finish
        then = json.loads((room / "decision.json").read_text())
        labels = LabelBatch.from_arrays(dict(np.load(room / "labels.npz")))
        candidate = MomRuntime.load(room / "candidate")
        verdict = compare(start, candidate, marks, labels.subset(held_out(labels)))
        decisions.append(
            {**then, "then": then["serve"], "serve": verdict.serve, "verdict": verdict}
        )
        print(f"seed {then['seed']}: {verdict.reason}", flush=True)
    path = RESULTS / "self_learning_never_worse.md"
    seeds = [d["seed"] for d in decisions]
    worse_then = [d for d in decisions if d["then"] and d["candidate"] > d["current"]]
    path.write_text(
        "# The room that learns: the gate never serves a worse model\n\n"
        f"{machine_line()}\n\n"
        f"indoor-2cam, detector profile `{args.profile}`; a model set up on 4 floor marks "
        f"serves {len(decisions)} rooms of 3 people walking (seeds {seeds[0]}–{seeds[-1]}); "
        f"after {decisions[0]['minute']:g} minutes one self-improvement run (training capped at "
        f"{NEVER_WORSE_BUDGET_S:g} s), its candidate judged by the gate and against the truth: "
        f"per-frame error on a dense test room (simulate seed {TEST_SEED}). The rooms were run "
        f"once with `--never-worse {len(decisions)} --keep DIR` (column *served then*: the gate "
        "of that run) and re-judged by the gate as it is now (`--rejudge DIR`: the same "
        "candidates; column *served*). Paired differences, candidate minus model in service, "
        "with their clustered standard error: *marks* on the floor-mark rows, *views* the "
        "leave-one-camera-out distance on the held-out self-labels "
        "(:mod:`service.learning.gate`). Code: `bench/setup/self_learning.py`.\n\n"
        f"{gate_table(decisions)}"
        f"By the gate of that run: {len(worse_then)} of "
        f"{sum(d['then'] for d in decisions)} served candidates were worse against the truth.\n"
    )
    return path


def run(args: argparse.Namespace) -> Path:
    if args.rejudge is not None:
        return rejudge(args)
    if args.never_worse:
        return never_worse(args)
    quick = args.quick
    seeds = args.seeds[:1] if quick else args.seeds
    judge = Judge(args.profile, 300 if quick else 900, 300 if quick else 600, args.preset)
    rows: list[list[str]] = []
    decisions: list[dict[str, Any]] = []
    path = RESULTS / (
        "self_learning.md" if args.preset == PRESET else f"self_learning_{args.preset}.md"
    )
    baselines = (
        "The 9-mark and dense-label models were not retrained in this run (`--no-baselines`): "
        "see the run before it for theirs.\n\n"
        if args.no_baselines
        else ""
    )

    def save() -> None:
        table = markdown_table(
            ("model", "policy", "per-frame mean m", "streamed mean m", "recall %", "MOTA %",
             "gate"),
            rows,
        )  # fmt: skip
        path.write_text(
            "# The room that learns: self-improvement from people walking\n\n"
            f"{machine_line()}\n\n"
            f"{args.preset}, detector profile `{args.profile}`; floor marks × {args.seconds:g} s "
            f"collected by the set-up plan; 3 people walk (seeds {', '.join(map(str, seeds))}); "
            f"each training run capped at {args.budget:g} s. Per-frame: dense test room "
            f"(simulate seed {TEST_SEED}, {judge.test.n} person instances, true association); "
            f"streamed: the daemon's chain on {judge.stream_frames} frames of 3 people (seed "
            f"{STREAM_SEED}), matched mean at 0.5 m. Code: `bench/setup/self_learning.py`.\n\n"
            f"{baselines}{table}\n\n"
            "## Never worse: every gate decision against the truth\n\n"
            f"{gate_table(decisions)}"
        )

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        marks4 = work / "marks4.npz"
        collect_marks("2x2", args.seconds, args.profile, marks4, args.preset)
        if not args.no_baselines:
            nine = collect_marks("3x3", args.seconds, args.profile, work / "marks9.npz",
                                 args.preset)  # fmt: skip
            frames = 600 if quick else 3000
            dense = simulate(args.preset, frames, DENSE_SEED, detector_profile=args.profile)
            rows.append(judge.row("9 marks", train(nine, work / "nine", args.budget)))
            dense_model = train(dense.dataset, work / "dense", args.budget)
            rows.append(judge.row("dense labels", dense_model))
            save()
        for seed in seeds:
            improvement_run(
                seed, marks4, work, judge, args.minutes, args.budget,
                rows=rows, decisions=decisions, save=save,
            )  # fmt: skip
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one seed, a smaller test room")
    parser.add_argument("--no-baselines", action="store_true", help="no 9-mark/dense models")
    parser.add_argument("--budget", type=float, default=TRAIN_BUDGET_S, help="s per training")
    parser.add_argument("--profile", default="nanodet")
    parser.add_argument("--preset", default=PRESET, help="the simulated room (not --never-worse)")
    parser.add_argument("--seconds", type=float, default=20.0, help="per floor mark")
    parser.add_argument("--seeds", type=int, nargs="+", default=[21, 22])
    parser.add_argument("--minutes", type=float, nargs="+", default=[2.0, 5.0, 10.0])
    parser.add_argument("--never-worse", type=int, default=0, metavar="N", help="N gate rooms")
    parser.add_argument("--keep", type=Path, help="--never-worse: keep candidates and labels here")
    parser.add_argument("--rejudge", type=Path, help="judge the rooms --keep kept again")
    print(run(parser.parse_args()))


if __name__ == "__main__":
    main()

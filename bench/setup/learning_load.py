"""Background self-improvement against the camera rate (writes bench/results/self_learning_load.md).

``python -m bench.setup.learning_load [--seconds 40] [--rounds 4]``

The room's self-improvement (:mod:`service.learning.improve`) trains in a ``momloc train`` child
at ``nice`` + ``learning.nice_by`` while the daemon serves. The target: the daemon never drops
below 0.95 × the camera rate because of it. One run measures the daemon's pipeline (the realtime
bench's: two 640x480 cameras replayed at 30 fps, shipped demo model, association, tracking, hub;
:func:`bench.serving.realtime.run_pipeline`) in interleaved slices, alternately with the training
child running and with it stopped (``SIGSTOP``/``SIGCONT`` on the one child, so both halves see
the same process, the same machine load and no start-up in between), for two detection stages:
the simulator's boxes at no cost (the pipeline alone) and the shipped detector with the default
scheduling (the demo's daemon). The ratio is fps with training / fps without, in the same run.

The child trains on a simulated room (the indoor-2cam preset with the nanodet profile: a
recording of the size an improvement run trains on) with the improver's own spawn
(:func:`service.setup.training.spawn_train`) and priority; its CPU use during the slices is
measured from ``/proc`` so the table shows it was busy.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import tempfile
import threading
import time
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from bench.report import RESULTS, machine_line, markdown_table
from bench.serving.realtime import (
    ClipRig,
    ReplayedBoxes,
    drawn_clips,
    make_detector,
    run_pipeline,
    scheduled,
    simulated_boxes,
    summary,
)
from models.simulate import simulate
from service.learning.improve import ImproveOptions
from service.setup.training import drain, spawn_train

PRESET = "indoor-2cam"
TRAIN_ROWS_FRAMES = 1500  # about the rows of 4 marks plus a few minutes of self-labels
CHILD_BUDGET_S = 3600.0  # never ends on its own within the run
CAMERA_FPS = 30.0


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` (all its threads), from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class TrainingChild:
    """One ``momloc train`` child, as the improver starts it, stopped between the slices that
    measure it."""

    def __init__(self, recording: Path, staging: Path, nice_by: int) -> None:
        budget = ["--time-budget", f"{CHILD_BUDGET_S:g}"]
        self.process = spawn_train(recording, staging, budget, nice_by=nice_by)
        self.errors: deque[str] = deque(maxlen=20)
        self.epochs = 0
        self._first_epoch = threading.Event()
        threading.Thread(target=self._follow, daemon=True).start()
        threading.Thread(target=drain, args=(self.process.stderr, self.errors), daemon=True).start()

    def _follow(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            if line.strip():
                self.epochs += 1
                self._first_epoch.set()

    def wait_training(self, timeout_s: float = 600.0) -> None:
        """Until the first epoch is done (torch imported, rows loaded: it is training)."""
        if not self._first_epoch.wait(timeout_s) or self.process.poll() is not None:
            raise SystemExit(f"training child did not start: {list(self.errors)[-3:]}")
        self.pause()

    def pause(self) -> None:
        os.kill(self.process.pid, signal.SIGSTOP)

    @contextmanager
    def running(self) -> Iterator[dict[str, float]]:
        """Resumed for the block; yields a dict that gets its CPU seconds and wall time."""
        used: dict[str, float] = {}
        cpu0, wall0 = cpu_seconds(self.process.pid), time.monotonic()
        os.kill(self.process.pid, signal.SIGCONT)
        try:
            yield used
        finally:
            self.pause()
            if self.process.poll() is not None:
                raise SystemExit(f"training child ended during the run: {list(self.errors)[-3:]}")
            used["cpu"] = cpu_seconds(self.process.pid) - cpu0
            used["wall"] = time.monotonic() - wall0

    def close(self) -> None:
        os.kill(self.process.pid, signal.SIGCONT)
        self.process.terminate()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()


def measure(
    stages: dict[str, Any], clips: list, child: TrainingChild, seconds: float, rounds: int
) -> list[list[Any]]:
    """Per stage: every round one slice without and one with the child running."""
    raw: dict[tuple[str, bool], list[dict[str, Any]]] = {}
    child_cpu = {name: [0.0, 0.0] for name in stages}
    for _ in range(rounds):
        for name, stage in stages.items():
            raw.setdefault((name, False), []).append(
                run_pipeline(ClipRig(clips, CAMERA_FPS), stage, seconds / rounds)
            )
            with child.running() as used:
                raw.setdefault((name, True), []).append(
                    run_pipeline(ClipRig(clips, CAMERA_FPS), stage, seconds / rounds)
                )
            child_cpu[name][0] += used["cpu"]
            child_cpu[name][1] += used["wall"]
            print(name, raw[(name, False)][-1]["frames"], raw[(name, True)][-1]["frames"])
    rows = []
    for name in stages:
        without, with_training = summary(raw[(name, False)]), summary(raw[(name, True)])
        cpu, wall = child_cpu[name]
        rows.append(
            [
                name,
                f"{without['fps']:.1f}",
                f"{with_training['fps']:.1f}",
                f"{with_training['fps'] / without['fps']:.3f}",
                f"{with_training['fps'] / CAMERA_FPS:.3f}",
                f"{without['p95']:.1f}",
                f"{with_training['p95']:.1f}",
                f"{cpu / wall:.2f}",
            ]
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=40.0, help="measured s per row and half")
    parser.add_argument("--rounds", type=int, default=4, help="interleaved slices per row")
    parser.add_argument("--clip", type=int, default=150, help="frames per replayed clip")
    parser.add_argument("--out", type=Path, default=RESULTS / "self_learning_load.md")
    args = parser.parse_args(argv)
    nice_by = ImproveOptions().nice_by
    load_before = os.getloadavg()
    clips, scene = drawn_clips(args.clip)
    stages = {
        "simulated boxes (the pipeline alone)": ReplayedBoxes(simulated_boxes(scene, args.clip)),
        "shipped detector, default scheduling": scheduled(make_detector(1)),
    }
    with tempfile.TemporaryDirectory() as tmp:
        rows_path = Path(tmp) / "rows.npz"
        simulate(PRESET, TRAIN_ROWS_FRAMES, 5, detector_profile="nanodet").dataset.save(rows_path)
        child = TrainingChild(rows_path, Path(tmp) / "candidate", nice_by)
        try:
            child.wait_training()
            rows = measure(stages, clips, child, args.seconds, args.rounds)
            epochs = child.epochs
        finally:
            child.close()
    load_after = os.getloadavg()
    table = markdown_table(
        (
            "detection",
            "fps without training",
            "fps with training",
            "ratio",
            "fps / camera rate",
            "p95 ms without",
            "p95 ms with",
            "training child CPU cores",
        ),
        rows,
    )
    args.out.write_text(
        "# The room that learns: background training against the camera rate\n\n"
        f"{machine_line()} Load average {load_before[0]:.1f} at the start, "
        f"{load_after[0]:.1f} at the end (other jobs share the machine).\n\n"
        f"Two 640x480 cameras replayed at {CAMERA_FPS:g} fps through the daemon's pipeline "
        "(shipped demo model, association, tracking, hub); the self-improvement's `momloc train` "
        f"child at `nice` +{nice_by} (the `learning.nice_by` default) on {TRAIN_ROWS_FRAMES} "
        f"simulated frames of {PRESET}; {args.seconds:g} s measured per row with and "
        f"{args.seconds:g} s without the child, in {args.rounds} interleaved slices each (the "
        f"child stopped between them; {epochs} epochs trained in all). Ratio: fps with "
        "training / fps without, same run. Target: >= 0.95 × the camera rate. Code: "
        "`bench/setup/learning_load.py`.\n\n"
        f"{table}\n"
    )
    print(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

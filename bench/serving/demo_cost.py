"""CPU cost per frame set of `momloc demo`'s frame path, in lock-step (writes
bench/results/demo_cost.md).

The demo draws its two cameras, detects people in them and runs the chain, all in one process on
the machine's cores; when their sum per frame set passes ~33 ms of CPU per core, the published
rate falls below the cameras' 30 fps. The live figures (``/v1/health``) move with the machine's
load; these are CPU seconds of one thread per frame set, so a busy machine adds noise, not bias.

Measured on the demo scene (``demo-lounge``: 3 walkers and one person on the sofa, furniture)
with the demo's settings, frames stamped at the scene's 30 fps (no wall clock):

- **draw**: both cameras' frames (``SyntheticRig.produce``);
- **detect**: the shipped detector's default back-end on both frames (``every_frame``);
- **chain**: association, lone-view correction, tracking and posture on the detector's boxes,
  with and without :mod:`common.row_memo` (without: each row is localized and mapped on every
  call, as before 2026-12-03), in the same run, with identical snapshots checked.

    python -m bench.serving.demo_cost [--frames 150]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from collections.abc import Callable, Sequence
from typing import Any

from bench.report import command_line, machine_line, markdown_table, write_result
from capture.rig import FrameSet


def _scene_time(frame_set: FrameSet, index: int, fps: float) -> FrameSet:
    """The frame set stamped at its scene time (deterministic tracking, no wall clock)."""
    frames = [
        None if f is None else dataclasses.replace(f, timestamp=1e9 + index / fps)
        for f in frame_set.frames
    ]
    return dataclasses.replace(frame_set, frames=frames)


def _without_memo() -> Callable[[], None]:
    """Make every RowMemo compute all its rows (the chain before the memo); returns the undo."""
    from common.row_memo import RowMemo

    remembered = RowMemo.rows

    def every_row(self: Any, keys: Sequence[bytes], compute: Callable[[list[int]], Any]) -> Any:
        return list(compute(list(range(len(keys)))))

    RowMemo.rows = every_row  # type: ignore[method-assign]

    def undo() -> None:
        RowMemo.rows = remembered  # type: ignore[method-assign]

    return undo


def measure(frames: int, warm: int = 30) -> dict[str, float]:
    """Per-frame-set CPU ms of drawing, detecting and the chain (memo on and off)."""
    os.environ["MOMLOC_DETECTION__SCHEDULE"] = "every_frame"
    os.environ["MOMLOC_LEARNING__ENABLED"] = "false"
    from service.daemon import build_daemon
    from service.demo import DEMO_FPS, demo_settings

    pipeline = build_daemon(demo_settings(port=1)).pipeline
    rig = pipeline.rig
    draw = detect = 0.0
    drawn, detected = [], []
    for i in range(warm + frames):
        t0 = time.thread_time()
        frame_set = _scene_time(rig.produce(i), i, DEMO_FPS)  # type: ignore[attr-defined]
        drawing = time.thread_time() - t0
        t1 = time.process_time()  # the detector's own threads count too
        boxes = pipeline.detect(frame_set)
        detecting = time.process_time() - t1
        if i >= warm:
            draw, detect = draw + drawing, detect + detecting
        drawn.append(frame_set)
        detected.append(list(boxes))
    chain: dict[str, float] = {}
    served: dict[str, list[Any]] = {}
    for label in ("with row memo", "without"):
        undo = _without_memo() if label == "without" else (lambda: None)
        try:
            fresh = build_daemon(demo_settings(port=1)).pipeline
            fresh.detect = _replay(detected)  # type: ignore[assignment]
            spent, people = 0.0, []
            for i, frame_set in enumerate(drawn):
                t0 = time.thread_time()
                snapshot = fresh.process(frame_set)
                if i >= warm:
                    spent += time.thread_time() - t0
                people.append([(p["id"], p["x"], p["y"]) for p in snapshot.people])
        finally:
            undo()
        chain[label], served[label] = spent / frames * 1e3, people
    if served["with row memo"] != served["without"]:
        raise SystemExit("the row memo changed the served positions")
    return {"draw": draw / frames * 1e3, "detect": detect / frames * 1e3, **chain}


def _replay(detected: list[list[Any]]) -> Callable[[FrameSet], list[Any]]:
    """A detect stage that returns the boxes found for each frame set, in order."""
    calls = iter(detected)
    return lambda frame_set: next(calls)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=150, help="frame sets measured")
    args = parser.parse_args(argv)
    ms = measure(args.frames)
    rows = [
        ["draw both cameras", f"{ms['draw']:.1f}"],
        ["detect both frames (default back-end)", f"{ms['detect']:.1f}"],
        ["chain, with the row memo", f"{ms['with row memo']:.1f}"],
        ["chain, without (every row on every call)", f"{ms['without']:.1f}"],
    ]
    text = "\n\n".join(
        [
            "# CPU per frame set of the demo's frame path",
            f"`{command_line('bench.serving.demo_cost', argv)}` — {machine_line()} "
            f"{args.frames} frame sets of `demo-lounge` after 30 warm-up ones, CPU ms of one "
            "thread per frame set (detection: of the process, with its back-end's threads); the "
            "machine's load adds noise, not bias.",
            markdown_table(["stage", "CPU ms per frame set"], rows),
            f"The row memo cuts the chain's CPU by {1 - ms['with row memo'] / ms['without']:.0%}"
            " with identical snapshots (checked in the run).",
        ]
    )
    write_result("demo_cost.md", text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

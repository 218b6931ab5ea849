"""The shape of the code a newcomer meets: how far one frame set travels, folder sizes, the
largest function. Re-run it before and after a restructuring (figures: bench/results/code_shape.md).

Static (``ast``, no imports of the project):

- modules per folder of ``service/``, ``models/`` and ``bench/`` (``__init__.py`` not counted);
- the largest function in ``service/`` (lines from ``def`` to its last line, nested functions
  counted inside their parent: a factory of nested routes is one long function to read).

Dynamic (``--trace``): the embedded demo's daemon (drawn frames through the shipped detector,
the default detection schedule) processes frame sets fed by hand with scene timestamps, under
``sys.setprofile`` on the pipeline thread and ``threading.setprofile`` on the detector's:

- *files crossed*: the project's source files (``service/ models/ capture/ common/``) whose code
  runs while one frame set is processed, union over the measured frame sets;
- *returns to the pipeline*: how many calls made by ``service/pipeline/live.py`` into another
  project file return to it per frame set (median over the frame sets): each is a hand-over a
  reader follows back to the pipeline.

Usage: ``python tools/code_shape.py [--trace] [--frames N]`` prints a markdown table.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import statistics
import sys
import threading
from collections import Counter
from pathlib import Path
from types import FrameType
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
PROJECT = ("service", "models", "capture", "common")
PIPELINE = ROOT / "service" / "pipeline" / "live.py"


def modules_per_folder(top: str) -> dict[str, int]:
    """``folder -> number of modules`` under ``top`` (``__init__.py`` left out)."""
    counts: Counter[str] = Counter()
    for path in sorted((ROOT / top).rglob("*.py")):
        if path.name != "__init__.py" and ".venv" not in path.parts:
            counts[str(path.parent.relative_to(ROOT))] += 1
    return dict(sorted(counts.items()))


def largest_function(top: str) -> tuple[int, str]:
    """``(lines, "file:name")`` of the longest function or method under ``top``."""
    best = (0, "")
    for path in sorted((ROOT / top).rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > best[0]:
                    best = (lines, f"{path.relative_to(ROOT)}:{node.name}")
    return best


def _project_file(filename: str) -> str | None:
    try:
        relative = Path(filename).resolve().relative_to(ROOT)
    except ValueError:
        return None
    return str(relative) if relative.parts and relative.parts[0] in PROJECT else None


def trace_frame_sets(frames: int = 20, warmup: int = 10) -> tuple[set[str], list[int]]:
    """Files crossed and returns to the pipeline per frame set (module docstring)."""
    from capture.rig import FrameSet
    from service.daemon import build_daemon
    from service.demo import demo_settings

    files: set[str] = set()
    returns: list[int] = []
    count = [0]
    measuring = threading.Event()
    pipeline_file = str(PIPELINE)

    def profile(frame: FrameType, event: str, arg: Any) -> None:
        if not measuring.is_set():
            return
        name = _project_file(frame.f_code.co_filename)
        if name is None:
            return
        files.add(name)
        caller = frame.f_back
        if (
            event == "return"
            and frame.f_code.co_filename != pipeline_file
            and caller is not None
            and caller.f_code.co_filename == pipeline_file
        ):
            count[0] += 1

    threading.setprofile(profile)  # before the daemon starts its threads (the detector's)
    daemon = build_daemon(demo_settings(detections="rendered"))
    pipeline, rig = daemon.pipeline, daemon.pipeline.rig
    try:
        for i in range(warmup + frames):
            produced = rig.produce(i).frames  # type: ignore[attr-defined]
            stamped = [
                None if f is None else dataclasses.replace(f, timestamp=1e6 + i / 30.0)
                for f in produced
            ]
            if i < warmup:
                pipeline.process(FrameSet(stamped, 0.0))
                continue
            count[0] = 0
            measuring.set()
            sys.setprofile(profile)
            try:
                pipeline.process(FrameSet(stamped, 0.0))
            finally:
                sys.setprofile(None)
                measuring.clear()
            returns.append(count[0])
    finally:
        threading.setprofile(None)  # type: ignore[arg-type]
        pipeline.stop()
    return files, returns


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--trace", action="store_true", help="also trace frame sets (demo)")
    parser.add_argument("--frames", type=int, default=20, help="frame sets traced")
    args = parser.parse_args(argv)
    print("| measure | value |\n|---|---|")
    if args.trace:
        files, returns = trace_frame_sets(args.frames)
        print(f"| files one frame set crosses | {len(files)} |")
        median = statistics.median(returns)
        print(f"| returns to service/pipeline/live.py per frame set | {median:g} |")
    for top in ("service", "models", "bench"):
        counts = modules_per_folder(top)
        listed = ", ".join(f"{k.removeprefix(top + '/') or top}/ {v}" for k, v in counts.items())
        print(f"| modules in {top}/ ({sum(counts.values())}) | {listed} |")
    lines, where = largest_function("service")
    print(f"| largest function in service/ | {lines} lines ({where}) |")
    if args.trace:
        print("\nFiles crossed:", ", ".join(sorted(files)))
    return 0


if __name__ == "__main__":
    sys.exit(main())

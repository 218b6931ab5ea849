"""Shared pieces of the benchmark reports: machine description, Markdown tables, PNG curves.

Every result file states the machine (core count, CPU model) and the date, because numbers from a
2-core shared box and from a workstation are not comparable. Plots use matplotlib's Agg backend:
no display is needed and nothing is shown.
"""

from __future__ import annotations

import math
import os
import platform
import shlex
import sys
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_line() -> str:
    """One Markdown line: date (UTC), cores, CPU model, Python and numpy versions."""
    now = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return (
        f"Machine: {cores} cores ({cpu_model()}), Python {platform.python_version()}, "
        f"numpy {np.__version__}; run {now}."
    )


def command_line(module: str, argv: Sequence[str] | None) -> str:
    """The command that ran a bench, as one would type it again (``argv`` None: the process's
    own arguments, as ``argparse`` reads them)."""
    given = sys.argv[1:] if argv is None else list(argv)
    return shlex.join(["python", "-m", module, *given])


def strict_json(value: Any, digits: int | None = None) -> Any:
    """``value`` for ``json.dumps`` as strict JSON: NaN and infinite floats as None, floats
    rounded to ``digits`` when given, through dicts, lists and tuples."""
    if isinstance(value, float):
        if not math.isfinite(value):
            return None
        return value if digits is None else round(value, digits)
    if isinstance(value, dict):
        return {k: strict_json(v, digits) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [strict_json(v, digits) for v in value]
    return value


def write_result(name: str, text: str) -> Path:
    """Write ``bench/results/<name>``, print the text and where it went; returns the path."""
    out = RESULTS / name
    write_report(out, text)
    return out


def write_report(path: Path, text: str) -> int:
    """Write a bench's report to ``path`` (its folder made), print it and where it went; 0,
    the bench's exit status."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    print(text)
    print(f"wrote {path}")
    return 0


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A GitHub Markdown table; the first column left-aligned, the others right-aligned."""
    lines = [
        "| " + " | ".join(header) + " |",
        "|" + "|".join([":---"] + ["---:"] * (len(header) - 1)) + "|",
    ]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def mean_std(values: Sequence[float], digits: int) -> str:
    """``mean ± std`` over seeds (population std), or the single value."""
    values = np.asarray(values, dtype=float)
    if values.size == 1:
        return f"{values[0]:.{digits}f}"
    return f"{values.mean():.{digits}f} ± {values.std():.{digits}f}"


def plot_curves(
    path: Path,
    x: Sequence[float],
    curves: dict[str, Sequence[float]],
    *,
    xlabel: str,
    ylabel: str,
    title: str,
    bands: dict[str, Sequence[float]] | None = None,
) -> Path:
    """Line plot of named curves over ``x`` (optional ± bands), saved as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
    for name, ys in curves.items():
        (line,) = ax.plot(x, ys, marker="o", markersize=3, label=name)
        if bands and name in bands:
            lo = np.asarray(ys) - np.asarray(bands[name])
            hi = np.asarray(ys) + np.asarray(bands[name])
            ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.15)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path

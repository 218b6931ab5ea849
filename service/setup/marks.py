"""Floor marks: the only ground truth a calibration-free setup needs.

A user tapes a few marks on the floor and types their coordinates (a YAML marks file), or lays out
a regular grid. The floor frame of every position the daemon reports is the frame of these marks.

Marks file (YAML)::

    marks:
      - {name: A1, x: 0.5, y: 0.5}
      - {name: A2, x: 2.5, y: 0.5}

A grid of R x C marks over a W x D room puts one mark at the centre of each cell, named by row
letter and column number (A1, A2, ..., B1, ...), row by row so a person walks a short path.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import yaml

from models.atomic import atomic_write_text
from models.errors import MomlocError


@dataclass(frozen=True)
class FloorMark:
    name: str
    x: float
    y: float


def load_marks(path: str | Path) -> list[FloorMark]:
    """Read a marks YAML file; each problem is one MomlocError line naming the entry."""
    path = Path(path)
    try:
        document = yaml.safe_load(path.read_text())
    except OSError as error:
        raise MomlocError(f"marks file {path}: {error.strerror}") from None
    except yaml.YAMLError as error:
        raise MomlocError(f"marks file {path}: not valid YAML ({error})") from None
    entries = document.get("marks") if isinstance(document, dict) else document
    if not isinstance(entries, list) or not entries:
        raise MomlocError(f"marks file {path}: expected a non-empty list under 'marks'")
    marks = []
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict) or not {"x", "y"} <= set(entry):
            raise MomlocError(f"marks file {path}: entry {i} needs x and y (metres)")
        try:
            x, y = float(entry["x"]), float(entry["y"])
        except (TypeError, ValueError):
            raise MomlocError(f"marks file {path}: entry {i} has a non-numeric x or y") from None
        if not (math.isfinite(x) and math.isfinite(y)):
            raise MomlocError(f"marks file {path}: entry {i} has a non-finite x or y")
        marks.append(FloorMark(str(entry.get("name", f"M{i + 1}")), x, y))
    names = [mark.name for mark in marks]
    duplicates = sorted({name for name in names if names.count(name) > 1})
    if duplicates:
        raise MomlocError(f"marks file {path}: duplicate mark name '{duplicates[0]}'")
    return marks


def save_marks(marks: list[FloorMark], path: str | Path) -> None:
    entries = [{"name": m.name, "x": m.x, "y": m.y} for m in marks]
    atomic_write_text(path, yaml.safe_dump({"marks": entries}, sort_keys=False))


def _parse_pair(text: str, what: str) -> tuple[float, float]:
    match = re.fullmatch(r"\s*([0-9.]+)\s*[xX×]\s*([0-9.]+)\s*", text)
    if not match:
        raise MomlocError(f"{what} '{text}': expected AxB, e.g. 3x3")
    a, b = float(match.group(1)), float(match.group(2))
    if a <= 0 or b <= 0:
        raise MomlocError(f"{what} '{text}': both numbers must be positive")
    return a, b


def grid_marks(grid: str, room: str) -> list[FloorMark]:
    """R x C marks at the cell centres of a W x D metre room (``grid_marks("3x3", "4x5")``)."""
    rows_f, cols_f = _parse_pair(grid, "grid")
    if rows_f != int(rows_f) or cols_f != int(cols_f) or rows_f > 26:
        raise MomlocError(f"grid '{grid}': rows and columns must be whole numbers, rows <= 26")
    width, depth = _parse_pair(room, "room")
    rows, cols = int(rows_f), int(cols_f)
    marks = []
    for r in range(rows):
        y = (r + 0.5) * depth / rows
        columns = range(cols) if r % 2 == 0 else reversed(range(cols))  # walk a snake path
        for c in columns:
            marks.append(FloorMark(f"{chr(65 + r)}{c + 1}", (c + 0.5) * width / cols, y))
    return marks

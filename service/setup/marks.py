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

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from common.atomic import atomic_write_text
from common.errors import MomlocError, shorten
from service.settings import read_yaml

MAX_MARKS = 400  # a few hundred marks is already hours of recording; more is a mistake
MAX_COORD_M = 1000.0  # metres from the origin: any room, and far from overflow
MAX_ROOM_M = 1000.0


@dataclass(frozen=True)
class FloorMark:
    name: str
    x: float
    y: float


Coordinate = Annotated[
    float,
    Field(
        strict=True,
        allow_inf_nan=False,
        ge=-MAX_COORD_M,
        le=MAX_COORD_M,
        description="Floor coordinate in metres (a number, finite, within ±1000).",
    ),
]


class MarkIn(BaseModel):
    """One floor mark as typed by the user: the same rules for the web and for marks files."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(min_length=1, max_length=40, description="Mark label, e.g. B2.")
    x: Coordinate
    y: Coordinate


def check_names(marks: list[FloorMark], origin: str) -> list[FloorMark]:
    """Refuse too many marks and duplicate names (one linear pass)."""
    if len(marks) > MAX_MARKS:
        raise MomlocError(f"{origin}: {len(marks)} marks, at most {MAX_MARKS}")
    seen: set[str] = set()
    for mark in marks:
        if mark.name in seen:
            raise MomlocError(f"{origin}: duplicate mark name '{shorten(mark.name, 40)}'")
        seen.add(mark.name)
    return marks


def marks_from_entries(entries: list[MarkIn], origin: str) -> list[FloorMark]:
    """Validated web entries as floor marks (names unique, count bounded)."""
    return check_names([FloorMark(e.name, e.x, e.y) for e in entries], origin)


def load_marks(path: str | Path) -> list[FloorMark]:
    """Read a marks YAML file; each problem is one MomlocError line naming the entry."""
    path = Path(path)
    document = read_yaml(path, "marks file")
    entries = document.get("marks") if isinstance(document, dict) else document
    if not isinstance(entries, list) or not entries:
        raise MomlocError(f"marks file {path}: expected a non-empty list under 'marks'")
    if len(entries) > MAX_MARKS:
        raise MomlocError(f"marks file {path}: {len(entries)} marks, at most {MAX_MARKS}")
    marks = []
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict) or not {"x", "y"} <= set(entry):
            raise MomlocError(f"marks file {path}: entry {i} needs x and y (metres)")
        entry = {**entry, "name": str(entry.get("name", f"M{i + 1}"))}
        try:
            mark = MarkIn.model_validate(entry)
        except ValidationError as error:
            first = error.errors()[0]
            field = ".".join(str(part) for part in first["loc"])
            label = shorten(entry["name"], 40)
            raise MomlocError(
                f"marks file {path}: entry {i} ({label}): {field}: {_plain(first)}"
            ) from None
        marks.append(FloorMark(mark.name, mark.x, mark.y))
    return check_names(marks, f"marks file {path}")


def _plain(item: Any) -> str:
    """Pydantic's message in the words a marks file user needs."""
    if item["type"] in ("float_type", "float_parsing"):
        return "must be a number (metres)"
    if item["type"] == "finite_number":
        return "must be a finite number"
    return str(item["msg"])


def save_marks(marks: list[FloorMark], path: str | Path) -> None:
    entries = [{"name": m.name, "x": m.x, "y": m.y} for m in marks]
    atomic_write_text(path, yaml.safe_dump({"marks": entries}, sort_keys=False))


_NUMBER = r"([0-9]{1,6}(?:\.[0-9]{1,6})?)"
_PAIR = re.compile(rf"\s*{_NUMBER}\s*[xX×]\s*{_NUMBER}\s*")


def _parse_pair(text: str, what: str) -> tuple[float, float]:
    """``AxB`` with plain decimal numbers only (``...x4`` or ``1e9x4`` are refused)."""
    match = _PAIR.fullmatch(text)
    if not match:
        raise MomlocError(f"{what} '{shorten(text, 40)}': expected AxB, e.g. 3x3")
    a, b = float(match.group(1)), float(match.group(2))
    if a <= 0 or b <= 0:
        raise MomlocError(f"{what} '{text}': both numbers must be positive")
    return a, b


def grid_marks(grid: str, room: str) -> list[FloorMark]:
    """R x C marks at the cell centres of a W x D metre room (``grid_marks("3x3", "4x5")``)."""
    rows_f, cols_f = _parse_pair(grid, "grid")
    if rows_f != int(rows_f) or cols_f != int(cols_f) or rows_f > 26:
        raise MomlocError(f"grid '{grid}': rows and columns must be whole numbers, rows <= 26")
    if rows_f * cols_f > MAX_MARKS:
        raise MomlocError(f"grid '{grid}': {int(rows_f * cols_f)} marks, at most {MAX_MARKS}")
    width, depth = _parse_pair(room, "room")
    if width > MAX_ROOM_M or depth > MAX_ROOM_M:
        raise MomlocError(f"room '{room}': at most {MAX_ROOM_M:.0f} m a side")
    rows, cols = int(rows_f), int(cols_f)
    marks = []
    for r in range(rows):
        y = (r + 0.5) * depth / rows
        columns = range(cols) if r % 2 == 0 else reversed(range(cols))  # walk a snake path
        for c in columns:
            marks.append(FloorMark(f"{chr(65 + r)}{c + 1}", (c + 0.5) * width / cols, y))
    return marks

"""The check's statistic, shared by the live check (:mod:`service.setup.verify`) and its offline
twin (``momloc eval --served``, :mod:`service.offline.served_marks`), so both give one number for
the same frames.

Per served snapshot, the person nearest to the mark counts (someone else in the room is
further away); a mark's error is the median of those distances (a moment of a wrong association
does not dominate); the summary is the median over the marks someone was served at, and says
how many had nobody.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable
from typing import Any

import numpy as np

from service.snapshot import Person


def nearest_error(people: Iterable[Person], x: float, y: float) -> float | None:
    """Distance from (x, y) to the nearest served person, None when nobody is served."""
    distances = [math.dist((p["x"], p["y"]), (x, y)) for p in people]
    return min(distances) if distances else None


def mark_error(errors: list[float]) -> float | None:
    """A mark's error: the median of its snapshots' nearest distances (None: nobody served)."""
    return round(float(np.median(errors)), 3) if errors else None


def summarise(marks: list[dict[str, Any]]) -> dict[str, Any]:
    """Median and mean error over the marks that were measured, and the line the page shows."""
    errors = [m["error_m"] for m in marks if m["error_m"] is not None]
    missing = len(marks) - len(errors)
    if not errors:
        return {
            "median_m": None,
            "mean_m": None,
            "marks": 0,
            "unmeasured": missing,
            "time": time.time(),
            "per_mark": marks,
            "text": f"nobody was seen on any of the {len(marks)} marks",
        }
    # The line shows the stored figure, so the page, model.json and health never disagree.
    median = round(float(np.median(errors)), 3)
    text = f"median {median:.2f} m over {len(errors)} mark{'s' if len(errors) > 1 else ''}"
    if missing:
        text += f" ({missing} not measured: nobody seen)"
    return {
        "median_m": median,
        "mean_m": round(float(np.mean(errors)), 3),
        "marks": len(errors),
        "unmeasured": missing,
        "time": time.time(),
        "per_mark": marks,
        "text": text,
    }

"""Remembered results of a row-wise batch function, for the chain's repeated small batches.

Per frame set the chain asks the localizer about the same boxes many times, in different
groupings: every candidate cluster of the association, the lone views, the tracker's measurement
covariance. Each row's result depends on that row alone, and a small batch costs its numpy and
onnxruntime call overheads rather than its rows, so computing each distinct row once removes
most of that work (``bench/results/demo_cost.md``). Rejected: passing one frame set's views
down the chain, which would couple every stage's signature to the others' needs.

Bounded by clearing when full (a few seconds of frames), not by LRU order: the rows of a live
scene change every frame, so old rows are never asked for again. Dictionary get/set are atomic
under the GIL, so a second thread (the learning gate scoring a served model) may share it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

Result = TypeVar("Result")


class RowMemo(Generic[Result]):
    """``rows(keys, compute)``: the result per key, ``compute`` called on the unknown keys only."""

    def __init__(self, capacity: int = 4096) -> None:
        self.capacity = capacity
        self._known: dict[bytes, Result] = {}

    def rows(
        self, keys: Sequence[bytes], compute: Callable[[list[int]], Sequence[Result]]
    ) -> list[Result]:
        """Results for ``keys``; ``compute(indices)`` returns those of ``keys[i]`` for the
        indices not remembered, in that order."""
        if len(self._known) > self.capacity:
            self._known.clear()
        found = [self._known.get(key) for key in keys]
        missing = [i for i, result in enumerate(found) if result is None]
        if missing:
            for i, result in zip(missing, compute(missing), strict=True):
                found[i] = self._known[keys[i]] = result
        return [result for result in found if result is not None]  # every one, now

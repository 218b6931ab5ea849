"""A yes/no verdict with hysteresis in time, shared by the camera-moved checks.

A bump is only reported when the evidence has held for ``hold_s`` seconds, and cleared only when
the opposite evidence has held as long: one bad frame, a passing occlusion or a person in front of
the lens never flips the verdict.
"""

from __future__ import annotations


class HeldFlag:
    """Turns on after its condition held ``hold_s`` seconds, off after its negation did."""

    def __init__(self, hold_s: float) -> None:
        self.hold_s = hold_s
        self.value = False
        self._since: float | None = None  # when the evidence started disagreeing with value

    def update(self, t: float, condition: bool) -> bool:
        if condition == self.value:
            self._since = None
        elif self._since is None:
            self._since = t
        if self._since is not None and t - self._since >= self.hold_s:
            self.value, self._since = condition, None
        return self.value

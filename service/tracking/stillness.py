"""Whether a tracked person is *still*, judged from where they were measured, and where.

A person sitting or standing still is the one a detector loses for seconds, so the tracker holds
a still person's track through misses (``hold_still_s`` in :mod:`service.tracking.tracker`). This
module decides who is still and at which *place* the track is held.

Why the measured positions and a median: the former rule asked the *filtered* track to stay
within 0.3 m for 5 s. Through the daemon's chain that failed for a seated person (issue 27,
``bench/results/still_presence_chain.md``): when one camera misses them the other's lone view
puts them 0.3-0.5 m off, a detector fragment of their body during a dropout is localized 0.5 m
off, and each such frame pulled the filter beyond the radius and restarted the clock; the next
dropout then ended the track like a walker's. A person is now still when, over the last
``window_s`` of their measurements (spanning at least ``after_s``), a share of at least ``share``
lies within ``radius_m`` of the measurements' coordinate-wise median: a few frames of lone views
or fragments do not change a median nor the share, a walker's measurements spread along their
path (at 0.5 m/s a 10 s window spans 5 m, of which 1 m is within 0.5 m of the median). The
median is the still *place*: an unseen still track is served there (not where its filter coasts
with the velocity the last odd measurements gave it) and a reappearing detection near it takes
the id again. Rejected: a wider radius or a shorter wait on the filtered track (both measured
in the results file: neither holds the sitter).

The place is that median only until two cameras say where in it the person is now: with at
least ``settled_fixes`` two-camera fixes in the last ``settled_s``, their median (when within
the radius of the window's) is the place. A window's median lags a person who shifts their
stance by up to the radius, and a still track one camera loses is held at the place: in the
lounge's falls a person stood 0.5 m from the median of their window, the second camera lost
them, their track snapped back to the median, and their fall's lone views, read as a body on
the floor, landed 0.6 m from the track, too far to be theirs (a fall missed; with this, two
falls of the ten seed sets gained, ``bench/results/falls.md``). Lone views do not move the place
this way: their range is poorly known.

A person who walks off has *left* the place once the median of their measurements of the last
``recent_s`` lies beyond ``leave_m`` (the tracker's still gate) from it, although the window's
median stays there for seconds more. Without this, a person who stood on a mark, walked 3.5 m
and was then missed for a second (a stalled pipeline, a dropout) was held back at the mark they
had left and served there for the whole hold, while they themselves became a new track beyond
the gate: the set-up check failed a fresh-clone CI run this way. A median of the recent
measurements, not the last one: a mispaired view 2 m off just before a dropout must not end a
sitter's stillness. The median of the recent fixes of two cameras or more (at least two of
them) beyond ``leave_seen_m`` (the still radius) is enough: such fixes are where the person is,
and a lone view among them does not undo that. A person who had stood still walked 0.95 m, seen
by both cameras, and crouched; unseen a moment, their track was held back at the place they had
left (within the gate), the crouch became a new track, and a false box read lying on the held
phantom fired a fall (``bench/results/falls.md``). Lone views keep the wide bound: their range
is poorly known.

Leaving takes two two-camera fixes beyond the radius; once left, one keeps the person away.
Without that a person who had stood still walked 1.15 m off, seen by both cameras, and
squatted; after a second unseen, one two-camera fix 0.83 m from the place (within ``leave_m``,
and one fix was too few for the two-camera bound) made the old place theirs again, the track
was held back there, and a pair of boxes read lying beside it fired a false fall
(``bench/results/falls.md``). Rejected, both measured there: forgetting the measurements at the
place once the person has left (a body on the floor, whose two-camera fixes swing half a metre
off for a few frames, then needed a fresh ``after_s`` to be still again, and the lounge's lying
person's posture was right 80 % of the time instead of 94 %), and holding a person who left
away until all their recent measurements, lone views too, are back within the radius (two
falls of seed set 1401 were lost: the track held where the faller had lain before, no longer
taken back there by lone views, changed which track took the body of their next fall nearby).
The place a person left is kept (:attr:`StillMemory.left`) until the window's median lies
elsewhere; the tracker uses it to give the id back to a person who reappears there
(:mod:`service.tracking.tracker`).

Times are the measurements' timestamps (no clock); the rule is in seconds and metres, so it
means the same at any frame rate.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class StillRule:
    """The still rule's settings (module docstring)."""

    after_s: float = 5.0  # the measurements judged must span this long
    window_s: float = 10.0  # measurements older than this (before the latest) are forgotten
    radius_m: float = 0.5  # around the median
    share: float = 0.6  # of the window's measurements within ``radius_m``
    leave_m: float = 1.0  # the recent measurements' median this far from the place: left it
    recent_s: float = 0.5  # the measurements of this last span are the recent ones
    leave_seen_m: float = 0.5  # ... or those of them two cameras or more gave this far
    settled_s: float = 2.0  # the place: the median of the two-camera fixes of this last span
    settled_fixes: int = 3  # ... when there are at least this many, within ``radius_m``

    def __post_init__(self) -> None:
        if not (0.0 < self.share <= 1.0 and self.radius_m > 0 and self.window_s >= self.after_s):
            raise ValueError("still rule: need 0 < share <= 1, radius_m > 0, window_s >= after_s")
        if not (self.leave_m > 0 and self.leave_seen_m > 0 and self.recent_s >= 0):
            raise ValueError("still rule: need leave_m, leave_seen_m > 0 and recent_s >= 0")


@dataclass
class StillMemory:
    """One track's measured positions over the last ``window_s`` and its still place."""

    times: deque[float] = field(default_factory=deque)
    points: deque[tuple[float, float]] = field(default_factory=deque)
    views: deque[int] = field(default_factory=deque)  # how many cameras gave each point
    place: np.ndarray | None = None  # the still place when last judged; None: not still
    left: np.ndarray | None = None  # the place the person was last judged to have left

    def remember(self, t: float, z: np.ndarray, rule: StillRule, views: int = 1) -> None:
        """Add the measurement ``z`` [2] of time ``t``, from ``views`` cameras, and judge
        again (sets :attr:`place`)."""
        self.times.append(float(t))
        self.points.append((float(z[0]), float(z[1])))
        self.views.append(int(views))
        while self.times and t - self.times[0] > rule.window_s + 1e-9:
            self.times.popleft()
            self.points.popleft()
            self.views.popleft()
        self.place = self._judge(rule)

    def _judge(self, rule: StillRule) -> np.ndarray | None:
        points = np.asarray(self.points)
        median = np.median(points, axis=0)
        if self.left is not None and np.linalg.norm(median - self.left) > rule.radius_m:
            self.left = None  # most of the window is elsewhere: that place is history
        if self.times[-1] - self.times[0] < rule.after_s - 1e-9:
            return None
        near = np.linalg.norm(points - median, axis=1) <= rule.radius_m
        if near.mean() < rule.share:
            return None
        times, views = np.asarray(self.times), np.asarray(self.views)
        is_recent = times >= times[-1] - rule.recent_s - 1e-9
        recent = points[is_recent]
        seen = recent[views[is_recent] >= 2]  # fixes of two cameras or more
        left = np.linalg.norm(np.median(recent, axis=0) - median) > rule.leave_m
        # two fixes to leave (one mispaired fix must not end a sitter's stillness), one to
        # stay away once left (module docstring)
        if len(seen) >= (2 if self.left is None else 1):
            left = left or np.linalg.norm(np.median(seen, axis=0) - median) > rule.leave_seen_m
        self.left = median if left else None
        if left:
            return None
        # the place: where two cameras put the person in the last seconds (module docstring)
        settled = (times >= times[-1] - rule.settled_s - 1e-9) & (views >= 2)
        if settled.sum() < rule.settled_fixes:
            return median
        here = np.median(points[settled], axis=0)
        return here if np.linalg.norm(here - median) <= rule.radius_m else median

"""Fixed-lag smoothing of a tracked stream for offline ``momloc track``.

Live, a position must be served when its frame arrives, so it rests on the past only. Offline,
nothing is waiting: each snapshot can be written once the frames ``half_window_s`` after it have
been tracked, and every person's position then comes from a window centred on its time. Per id
the smoother fits a straight line (position and velocity, least squares) to that id's served
positions within ``± half_window_s`` and reports the line at the snapshot's time: a constant
walk passes through unchanged (no lag is added: the window is symmetric), a standing person's
frame-to-frame shake is averaged over the window, and a jump when a camera comes or goes is
spread over it. Fewer than ``MIN_SAMPLES`` samples of an id in its window leave the position as
tracked. Velocities are the fitted slope. Ids, confidences and cameras are untouched.

Why ± 0.5 s and a straight line (figures: ``bench/results/tracking_filters.md``): on the stream
benchmark's served tracks it lowered the standing jitter and the matched error and raised MOTA
without adding lag (the lag left is the live filter's own), and a frame-count sweep of the same
fit gave ± 0.5 s the best mean error and Acc@0.3. Rejected: a quadratic fit (it follows the
jumps it should spread). A standing person's shake is dominated by a few large steps (see
:mod:`service.tracking.motion`), which a window spreads but cannot remove.
An RTS pass over the IMM's own states was not built: the tracker keeps no state history and its
two-model mixture makes the backward pass model-specific; the window fit needs only the output.

Example::

    smoother = FixedLagSmoother(0.5)
    for frame, snapshot in stream:
        for ready in smoother.push(frame, snapshot):
            write(*ready)
    for ready in smoother.flush():
        write(*ready)
"""

from __future__ import annotations

from collections import deque

import numpy as np

from service.snapshot import Snapshot

MIN_SAMPLES = 3
DEFAULT_HALF_WINDOW_S = 0.5


class FixedLagSmoother:
    """Buffers snapshots for ``half_window_s`` and releases them smoothed (module docstring)."""

    def __init__(self, half_window_s: float = DEFAULT_HALF_WINDOW_S) -> None:
        if not half_window_s > 0:
            raise ValueError(f"half_window_s {half_window_s}: must be positive")
        self.half_window_s = float(half_window_s)
        self._buffer: deque[tuple[int, Snapshot]] = deque()
        self._released = 0  # index in the buffer of the next snapshot to release

    def push(self, frame: int, snapshot: Snapshot) -> list[tuple[int, Snapshot]]:
        """Add the newest snapshot; returns the (frame, smoothed snapshot) pairs now complete."""
        self._buffer.append((frame, snapshot))
        ready = []
        while (
            self._released < len(self._buffer)
            and snapshot.t - self._buffer[self._released][1].t >= self.half_window_s
        ):
            ready.append(self._smoothed(self._released))
            self._released += 1
        self._trim()
        return ready

    def flush(self) -> list[tuple[int, Snapshot]]:
        """The snapshots still held (end of the stream: their windows are cut short)."""
        ready = [self._smoothed(i) for i in range(self._released, len(self._buffer))]
        self._buffer.clear()
        self._released = 0
        return ready

    def _trim(self) -> None:
        """Drop snapshots no window still needs (older than the oldest unreleased one's)."""
        if self._released >= len(self._buffer):
            oldest = self._buffer[-1][1].t
        else:
            oldest = self._buffer[self._released][1].t
        while self._released > 0 and oldest - self._buffer[0][1].t > self.half_window_s:
            self._buffer.popleft()
            self._released -= 1

    def _smoothed(self, index: int) -> tuple[int, Snapshot]:
        frame, snapshot = self._buffer[index]
        people = []
        for person in snapshot.people:
            ts, xy = self._samples(int(person["id"]), snapshot.t)
            if len(ts) < MIN_SAMPLES:
                people.append(person)
                continue
            design = np.stack([np.ones_like(ts), ts - snapshot.t], axis=1)
            (x, y), (vx, vy) = np.linalg.lstsq(design, xy, rcond=None)[0]
            people.append(
                {
                    **person,
                    "x": round(float(x), 4),
                    "y": round(float(y), 4),
                    "vx": round(float(vx), 4),
                    "vy": round(float(vy), 4),
                }
            )
        return frame, Snapshot.build(snapshot.seq, snapshot.t, people)

    def _samples(self, track_id: int, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Times [S] and positions [S, 2] of ``track_id`` within the window around ``t``."""
        ts, xy = [], []
        for _, s in self._buffer:
            if abs(s.t - t) > self.half_window_s + 1e-9:
                continue
            for p in s.people:
                if int(p["id"]) == track_id:
                    ts.append(s.t)
                    xy.append((float(p["x"]), float(p["y"])))
        return np.asarray(ts, dtype=np.float64), np.asarray(xy, dtype=np.float64).reshape(-1, 2)

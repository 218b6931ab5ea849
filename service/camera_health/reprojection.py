"""Camera-moved alert from the decoder's reprojection error.

The MoM decoder maps each predicted floor position back to every camera's mean pixel through its
learned matrix P̄_k. While the cameras stay where they were during collection, that reprojection
error stays at its usual level. When a camera is bumped, the encoder's input from that camera shifts
while P̄_k does not, so its error rises and stays high. The monitor therefore compares a rolling
median of each camera's error with a baseline (given by the model, or learned during the first
seconds of running) and raises an alert only when the median has stayed above
``max(ratio * baseline, baseline + margin_px)`` for ``hold_s`` seconds: a single bad frame, a
passing occlusion or one badly detected person does not trip it.

This signal alone cannot see every bump nor say which camera moved (with two cameras a sideways
shift is absorbed into the position, and both cameras share a rise), so :func:`combine` merges it
with the image check of ``service.camera_health.image_shift``: the image decides which camera moved
whenever it has a reference, and the reprojection error is the fallback (and catches what images
miss).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from service.camera_health.held_flag import HeldFlag
from service.camera_health.image_shift import CameraShiftState

WHAT_TO_DO = (
    "re-collect the floor marks (momloc collect, or the /setup page) and retrain (momloc train)"
)


@dataclass(frozen=True)
class CameraAlignment:
    """One camera's state as shown in ``/v1/health`` and on the map."""

    camera: int
    error_px: float | None
    baseline_px: float | None
    moved: bool
    message: str | None


class CameraMotionMonitor:
    """Rolling reprojection-error watch for K cameras (feed it every processed frame set)."""

    def __init__(
        self,
        num_cameras: int,
        baseline_px: Sequence[float] | None = None,
        *,
        window_s: float = 5.0,
        hold_s: float = 3.0,
        warmup_s: float = 10.0,
        ratio: float = 2.5,
        margin_px: float = 6.0,
    ) -> None:
        self.window_s, self.hold_s, self.warmup_s = window_s, hold_s, warmup_s
        self.ratio, self.margin_px = ratio, margin_px
        # (t, error) per camera
        self._samples: list[deque[tuple[float, float]]] = [deque() for _ in range(num_cameras)]
        self._warmup: list[list[float]] = [[] for _ in range(num_cameras)]
        self._baseline: list[float | None] = (
            list(baseline_px) if baseline_px is not None else [None] * num_cameras
        )
        self._moved = [HeldFlag(hold_s) for _ in range(num_cameras)]
        self._start: float | None = None
        # the pipeline thread updates while /v1/health reads: one lock, or a read can meet a
        # deque being trimmed ("deque mutated during iteration", a 500 on /v1/health)
        self._lock = threading.Lock()

    def update(self, t: float, errors: np.ndarray) -> None:
        """Add one frame set's errors, shape [P, K] in pixels (NaN where a camera saw nobody)."""
        with self._lock:
            self._update(t, errors)

    def _update(self, t: float, errors: np.ndarray) -> None:
        if self._start is None:
            self._start = t
        errors = np.asarray(errors, dtype=float).reshape(-1, len(self._samples))
        for k, samples in enumerate(self._samples):
            seen = errors[:, k][np.isfinite(errors[:, k])]
            if seen.size:
                value = float(np.median(seen))
                samples.append((t, value))
                if self._baseline[k] is None and t - self._start < self.warmup_s:
                    self._warmup[k].append(value)
            while samples and samples[0][0] < t - self.window_s:
                samples.popleft()
            if self._baseline[k] is None and t - self._start >= self.warmup_s and self._warmup[k]:
                self._baseline[k] = float(np.median(self._warmup[k]))
            self._update_state(k, t)

    def _threshold(self, k: int) -> float | None:
        base = self._baseline[k]
        return None if base is None else max(self.ratio * base, base + self.margin_px)

    def _update_state(self, k: int, t: float) -> None:
        current, threshold = self._current(k), self._threshold(k)
        if current is None or threshold is None:
            return
        self._moved[k].update(t, current > threshold)

    def _current(self, k: int) -> float | None:
        samples = self._samples[k]
        return float(np.median([e for _, e in samples])) if samples else None

    def status(self) -> list[CameraAlignment]:
        with self._lock:
            return self._status()

    def _status(self) -> list[CameraAlignment]:
        out = []
        for k in range(len(self._samples)):
            message = None
            if self._moved[k].value:
                message = (
                    f"camera {k} looks moved: reprojection error {self._current(k):.1f} px vs "
                    f"{self._baseline[k]:.1f} px usual; {WHAT_TO_DO}"
                )
            out.append(
                CameraAlignment(
                    k, self._current(k), self._baseline[k], self._moved[k].value, message
                )
            )
        return out


@dataclass(frozen=True)
class CameraMoved:
    """Both camera-moved signals for one camera, and the verdict shown in health and on the map."""

    camera: int
    moved: bool
    shift: CameraShiftState
    reprojection: CameraAlignment
    message: str | None


def combine(
    reprojection: Sequence[CameraAlignment],
    shift: Sequence[CameraShiftState],
    names: Sequence[str] | None = None,
) -> list[CameraMoved]:
    """Per camera: moved if its image shifted, or if its reprojection error stays high.

    Attribution: a reprojection alarm on camera k is dropped when the image check has a
    reference for k, sees k steady, and sees another camera moved: the shared rise is that other
    camera's (with two cameras both errors rise when either is bumped).
    """
    image_moved = {s.camera for s in shift if s.moved}
    out = []
    for r, s in zip(reprojection, shift, strict=True):
        k = r.camera
        name = f"camera {k}" if names is None or k >= len(names) else f"camera {k} ({names[k]})"
        explained = s.reference == "ready" and not s.moved and bool(image_moved - {k})
        by_error = r.moved and not explained
        message = None
        if s.moved:
            message = (
                f"{name} was moved: its view is {s.shift_px or 0.0:.0f} px off the reference "
                f"taken at start; {WHAT_TO_DO}"
            )
        elif by_error:
            seen = " (the image check sees no shift)" if s.reference == "ready" else ""
            message = (
                f"{name} looks moved: reprojection error {r.error_px or 0.0:.1f} px vs "
                f"{r.baseline_px or 0.0:.1f} px usual{seen}; {WHAT_TO_DO}"
            )
        out.append(CameraMoved(k, s.moved or by_error, s, r, message))
    return out

"""Camera-moved check from the images themselves: is this camera still looking where it was?

Why an image check
------------------
The decoder's reprojection error (``service.camera_health.reprojection``) cannot see every bump:
with two cameras, two horizontal bearings triangulate a floor point exactly, so a sideways shift of
one camera is absorbed into the predicted position and no error rises; and when the error does rise,
both cameras share it, so it cannot say which one moved. The static background of each camera
says both, and needs no calibration.

How (measured, see ``bench/serving/camera_shift.py``)
---------------------------------------------
- **Reference**: the per-pixel median of ``reference_frames`` downscaled grayscale frames taken
  ``reference_spacing_s`` apart after start (or after :meth:`CameraShiftMonitor.reset`, e.g. on a
  model reload), so people walking through vanish from it. Corners (``goodFeaturesToTrack``) are
  picked on that median once. If one of those frames does not line up with the median (the camera
  was bumped while collecting), collection starts again from the newest frame.
- **Check** (about once a second): pyramidal Lucas-Kanade tracks the reference corners into the
  current frame; a RANSAC fit of a rigid motion (rotation + translation: a bump neither zooms nor
  shears) keeps the corners on the static background and drops those occluded by people.
  ``shift_px`` is the largest displacement of the four image corners under that motion, in
  full-resolution pixels, so a roll about the centre counts as much as a slide.
- Global phase correlation was tried first and rejected: the simulated rooms (like many real
  ones) are plain walls and a tiled floor, so walking people dominate the correlation and gave
  10–150 px false shifts; the corner tracker stayed within 0.1 px on the same frames.
- **Alert**: ``moved`` once ``shift_px`` has stayed above ``threshold_px`` for ``hold_s``; cleared
  once it has stayed below for ``hold_s`` (the camera was put back). An estimate with too few
  inliers is "no estimate" and changes nothing.

Cost: ~1–2 ms per camera per check at 320 px wide; :class:`ShiftWorker` runs checks on a small
thread with a latest-frame slot so the pipeline thread only copies a reference to the images.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from service.camera_health.held_flag import HeldFlag

WORK_WIDTH = 320  # analysis width in pixels; 160 left too few corners in plain rooms


@dataclass(frozen=True)
class ShiftEstimate:
    """One camera's motion against its reference, in full-resolution pixels."""

    shift_px: float  # largest image-corner displacement
    dx: float
    dy: float
    roll_deg: float
    confidence: float  # RANSAC inlier fraction of the tracked corners
    inliers: int


@dataclass(frozen=True)
class CameraShiftState:
    """What ``/v1/health`` shows per camera: the reference state and the latest estimate."""

    camera: int
    reference: str  # "collecting", "ready" or "no texture"
    shift_px: float | None
    confidence: float | None
    moved: bool
    checked_at: float | None


def to_gray(image: np.ndarray, width: int = WORK_WIDTH) -> tuple[np.ndarray, float]:
    """Downscaled uint8 grayscale and the factor back to full-resolution pixels."""
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    scale = max(1.0, gray.shape[1] / width)
    if scale > 1.0:
        size = (round(gray.shape[1] / scale), round(gray.shape[0] / scale))
        gray = cv2.resize(gray, size, interpolation=cv2.INTER_AREA)
    return gray, scale


def rigid_ransac(
    src: np.ndarray, dst: np.ndarray, threshold: float, *, hypotheses: int = 200, seed: int = 0
) -> tuple[np.ndarray, np.ndarray] | None:
    """Rotation + translation mapping ``src`` [N,2] to ``dst`` with RANSAC; (2x3, inliers)."""
    n = len(src)
    if n < 3:
        return None
    rng = np.random.default_rng(seed)
    i, j = rng.integers(0, n, (2, hypotheses))
    i, j = i[i != j], j[i != j]
    a, b = src[j] - src[i], dst[j] - dst[i]
    angle = np.arctan2(b[:, 1], b[:, 0]) - np.arctan2(a[:, 1], a[:, 0])
    cos, sin = np.cos(angle), np.sin(angle)
    rot = np.stack([np.stack([cos, -sin], -1), np.stack([sin, cos], -1)], -2)  # [H,2,2]
    trans = dst[i] - np.einsum("hab,hb->ha", rot, src[i])
    pred = np.einsum("hab,nb->hna", rot, src) + trans[:, None]
    inliers = np.linalg.norm(pred - dst[None], axis=-1) < threshold
    best = int(np.argmax(inliers.sum(1))) if len(rot) else None
    if best is None or inliers[best].sum() < 3:
        return None
    keep = inliers[best]
    return _kabsch(src[keep], dst[keep]), keep


def _kabsch(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Least-squares rigid 2x3 motion (refit on the inliers)."""
    cs, cd = src.mean(0), dst.mean(0)
    u, _, vt = np.linalg.svd((src - cs).T @ (dst - cd))
    rot = (u @ vt).T
    if np.linalg.det(rot) < 0:
        vt[-1] *= -1
        rot = (u @ vt).T
    return np.hstack([rot, (cd - rot @ cs)[:, None]])


class ShiftReference:
    """A camera's background median and the corners tracked against it."""

    def __init__(self, frames: Sequence[np.ndarray], scale: float, max_corners: int = 200) -> None:
        self.gray = np.median(np.stack(frames), axis=0).astype(np.uint8)
        self.scale = scale
        h, w = self.gray.shape
        corners = cv2.goodFeaturesToTrack(self.gray, max_corners, 0.01, 6)
        self.corners = np.zeros((0, 1, 2), np.float32) if corners is None else corners
        self.frame_corners = np.array([[0, 0], [w, 0], [0, h], [w, h]], np.float64)

    @property
    def usable(self) -> bool:
        return len(self.corners) >= 8

    def estimate(self, gray: np.ndarray, min_inliers: int = 6) -> ShiftEstimate | None:
        """Motion of ``gray`` (same size as the reference) against it, or None if unsure."""
        if not self.usable or gray.shape != self.gray.shape:
            return None
        tracked, status, _ = cv2.calcOpticalFlowPyrLK(
            self.gray, gray, self.corners, np.empty_like(self.corners), winSize=(15, 15), maxLevel=3
        )
        ok = status.ravel() == 1
        fit = rigid_ransac(self.corners[ok, 0].astype(float), tracked[ok, 0].astype(float), 1.5)
        if fit is None:
            return None
        motion, keep = fit
        if keep.sum() < min_inliers:
            return None
        moved = self.frame_corners @ motion[:, :2].T + motion[:, 2]
        shift = float(np.linalg.norm(moved - self.frame_corners, axis=1).max()) * self.scale
        return ShiftEstimate(
            shift_px=shift,
            dx=float(motion[0, 2]) * self.scale,
            dy=float(motion[1, 2]) * self.scale,
            roll_deg=float(np.degrees(np.arctan2(motion[1, 0], motion[0, 0]))),
            confidence=float(keep.sum()) / len(self.corners),
            inliers=int(keep.sum()),
        )


class CameraShiftMonitor:
    """Per-camera background reference and shift alert; feed it frames with :meth:`offer`."""

    def __init__(
        self,
        num_cameras: int,
        *,
        threshold_px: float = 6.0,
        hold_s: float = 3.0,
        interval_s: float = 1.0,
        reference_frames: int = 5,
        reference_spacing_s: float = 1.0,
        width: int = WORK_WIDTH,
    ) -> None:
        self.num_cameras = num_cameras
        self.threshold_px, self.hold_s, self.interval_s = threshold_px, hold_s, interval_s
        self.reference_frames, self.reference_spacing_s = reference_frames, reference_spacing_s
        self.width = width
        self.check_ms: list[float] = []  # per camera per check, for the bench
        self._lock = threading.Lock()
        self.reset()

    def reset(self) -> None:
        """Forget the references (a model reload, or the user says the cameras are fine now)."""
        with self._lock:
            k = self.num_cameras
            self._collected: list[list[np.ndarray]] = [[] for _ in range(k)]
            self._collected_at: list[float | None] = [None] * k
            self._reference: list[ShiftReference | None] = [None] * k
            self._estimate: list[ShiftEstimate | None] = [None] * k
            self._checked_at: list[float | None] = [None] * k
            self._moved = [HeldFlag(self.hold_s) for _ in range(k)]
            self._last_offer: float | None = None

    def due(self, t: float) -> bool:
        """Whether a frame set taken at ``t`` should be checked (at most one per ``interval_s``,
        except while references are being collected at ``reference_spacing_s``)."""
        last = self._last_offer
        if last is None:
            return True
        building = any(r is None for r in self._reference)
        spacing = min(self.interval_s, self.reference_spacing_s) if building else self.interval_s
        return t - last >= spacing

    def offer(self, t: float, images: Sequence[np.ndarray | None]) -> bool:
        """Check ``images`` (one per camera, None without pixels) if due; True if checked."""
        if not any(image is not None for image in images) or not self.due(t):
            return False
        self._last_offer = t
        for k, image in enumerate(images[: self.num_cameras]):
            if image is not None:
                self._check(k, t, image)
        return True

    def _check(self, k: int, t: float, image: np.ndarray) -> None:
        start = time.perf_counter()
        gray, scale = to_gray(image, self.width)
        with self._lock:
            reference = self._reference[k]
            if reference is None or reference.gray.shape != gray.shape:
                self._collect(k, t, gray, scale)
                return
        estimate = reference.estimate(gray)
        with self._lock:
            if self._reference[k] is not reference:  # reset meanwhile
                return
            self.check_ms = [*self.check_ms[-999:], (time.perf_counter() - start) * 1e3]
            self._checked_at[k] = t
            self._estimate[k] = estimate
            if estimate is not None:
                self._moved[k].update(t, estimate.shift_px > self.threshold_px)

    def _collect(self, k: int, t: float, gray: np.ndarray, scale: float) -> None:
        frames = self._collected[k]
        if frames and frames[-1].shape != gray.shape:
            frames.clear()  # the camera changed resolution: start over
        last = self._collected_at[k]
        if last is not None and t - last < self.reference_spacing_s * 0.999 and frames:
            return
        frames.append(gray)
        self._collected_at[k] = t
        if len(frames) >= self.reference_frames:
            reference = ShiftReference(frames, scale)
            if self._consistent(reference, frames):
                self._reference[k] = reference
                self._collected[k] = []
            else:  # bumped while collecting: a blend of two views; start again from now
                self._collected[k] = frames[-1:]

    def _consistent(self, reference: ShiftReference, frames: Sequence[np.ndarray]) -> bool:
        """Every frame of the median that can be matched agrees with it (no bump during
        collection). A frame without an estimate (a person in front of the lens) says nothing."""
        if not reference.usable:
            return True  # nothing to check against; reported as "no texture"
        estimates = [e for e in map(reference.estimate, frames) if e is not None]
        matched_enough = 2 * len(estimates) >= len(frames)
        return matched_enough and all(e.shift_px <= self.threshold_px / 2 for e in estimates)

    def status(self) -> list[CameraShiftState]:
        with self._lock:
            out = []
            for k in range(self.num_cameras):
                reference, estimate = self._reference[k], self._estimate[k]
                state = "collecting" if reference is None else "ready"
                if reference is not None and not reference.usable:
                    state = "no texture"
                out.append(
                    CameraShiftState(
                        camera=k,
                        reference=state,
                        shift_px=None if estimate is None else estimate.shift_px,
                        confidence=None if estimate is None else estimate.confidence,
                        moved=self._moved[k].value,
                        checked_at=self._checked_at[k],
                    )
                )
            return out


class ShiftWorker:
    """Runs a monitor's checks on a small thread: the caller only drops frames in a slot.

    ``threaded=False`` checks inline (tests, benchmarks: results are then deterministic).
    """

    def __init__(self, monitor: CameraShiftMonitor, *, threaded: bool = True) -> None:
        self.monitor, self.threaded = monitor, threaded
        self._slot: tuple[float, list[np.ndarray | None]] | None = None
        self._wake = threading.Condition()
        self._thread: threading.Thread | None = None
        self._stop = False

    def submit(self, t: float, images: Sequence[np.ndarray | None]) -> None:
        """Hand over the newest frames; cheap when no check is due (the usual case)."""
        if not any(image is not None for image in images) or not self.monitor.due(t):
            return
        if not self.threaded:
            self.monitor.offer(t, images)
            return
        with self._wake:
            self._slot = (t, list(images))  # an unprocessed older set is simply replaced
            if self._thread is None or not self._thread.is_alive():
                self._stop = False
                self._thread = threading.Thread(target=self._run, name="camera-shift", daemon=True)
                self._thread.start()
            self._wake.notify()

    def _run(self) -> None:
        while True:
            with self._wake:
                self._wake.wait_for(lambda: self._slot is not None or self._stop)
                if self._stop:
                    return
                slot, self._slot = self._slot, None
            if slot is not None:  # a frame set was waiting (the wait ends for it or for stop)
                self.monitor.offer(*slot)

    def stop(self) -> None:
        with self._wake:
            self._stop = True
            self._wake.notify()
        if self._thread is not None:
            self._thread.join(timeout=2)
            self._thread = None

"""Carry person boxes between detections: image-space tracking per camera.

Why: the detector costs more than a 33 ms frame slot on 2 cores
(``bench/results/detector_speed.md``), so :mod:`service.detection.schedule` runs it on some frame
sets only, in the background. Every frame set in between still needs boxes, and when a detection
arrives it describes a frame that is already 1-3 frames old. :class:`BoxCarrier` keeps
one small track per box of one camera and answers both needs:

- :meth:`BoxCarrier.advance` moves every box to the newest frame: a constant-velocity Kalman
  filter on ``(cx, cy, w, h)`` predicts it, and, when an image is given, sparse pyramidal
  Lucas-Kanade optical flow (``cv2.calcOpticalFlowPyrLK``) on a grid of points inside each box
  measures the actual image motion (median shift and scale, forward-backward checked) and
  corrects the filter.
- :meth:`BoxCarrier.correct` folds in detections of an *older* frame (time ``t``): each track's
  box at ``t`` is kept in a short history, detections are matched to those boxes (Hungarian on
  1 - IoU), and the offset seen at ``t`` is applied to the track's current box as a Kalman
  measurement, so the motion measured since ``t`` is kept. New people start a track at the
  detected box, moved to the newest frame by one flow call from the frame of ``t`` when it is
  still in the small grey-image ring.

Every box carries its **age**: seconds since a detector last found it (0 = found in this very
frame). Boxes older than ``max_age_s`` or missed by ``max_misses`` detections in a row expire,
so a person who left does not linger as a ghost.

Measured choices (``bench/serving/realtime.py``; figures in ``bench/results/box_carrier.md``):
the filter alone keeps carried boxes much closer to the detector's own boxes than holding them
still, and flow helps where people stop, turn and cross (real video) and keeps more boxes on
their person, so flow is on by default but the scheduler drops it while it costs more than its
budget (``service.detection.schedule``). Trusting flow more than a detection was worse on the
video: legs and background points make its shifts noisy. Rejected: re-running the detector on
crops around known people (these graphs take a fixed input, so each crop costs a full call),
and dense flow (Farneback: many times the time of sparse LK).

Example::

    carrier = BoxCarrier()
    carrier.correct(t0, boxes, scores)          # detector found boxes in the frame of t0
    carried = carrier.advance(t1, image_t1)     # boxes moved to the frame of t1, with ages
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from models.detector.base import Detections

_F_DIM = 8  # state: cx, cy, w, h and their rates (px, px/s)


@dataclass(frozen=True, eq=False)
class CarriedDetections(Detections):
    """:class:`Detections` with one added field: ``age`` [M] float32, seconds since the detector
    last found each box (0: found in this frame; > 0: carried by image-space tracking)."""

    age: np.ndarray | None = None

    @staticmethod
    def empty() -> CarriedDetections:
        return CarriedDetections(
            np.zeros((0, 4), np.float32), np.zeros((0,), np.float32), None, np.zeros(0, np.float32)
        )


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU matrix [len(a), len(b)] of xmin, ymin, xmax, ymax boxes."""
    a, b = np.asarray(a, float).reshape(-1, 4), np.asarray(b, float).reshape(-1, 4)
    lo = np.maximum(a[:, None, :2], b[None, :, :2])
    hi = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=2)
    area_a = np.prod(a[:, 2:] - a[:, :2], axis=1)
    area_b = np.prod(b[:, 2:] - b[:, :2], axis=1)
    return inter / np.maximum(area_a[:, None] + area_b[None, :] - inter, 1e-9)


def _to_state(box: np.ndarray) -> np.ndarray:
    x0, y0, x1, y1 = (float(v) for v in box)
    return np.array([(x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0])


def _to_box(z: np.ndarray) -> np.ndarray:
    cx, cy, w, h = z[:4]
    return np.array([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], np.float32)


@dataclass
class _Track:
    x: np.ndarray  # [8] state
    p: np.ndarray  # [8, 8] covariance
    t: float  # time of the state
    found: float  # time the detector last found it
    score: float
    keypoints: np.ndarray | None  # [17, 3], x/y relative to the box (0..1)
    misses: int = 0
    history: deque[tuple[float, np.ndarray]] = field(default_factory=lambda: deque(maxlen=48))

    @property
    def box(self) -> np.ndarray:
        return _to_box(self.x)

    def box_at(self, t: float) -> np.ndarray:
        """The box this track had at time ``t`` (history, else back-extrapolated)."""
        for when, box in reversed(self.history):
            if abs(when - t) < 1e-6:
                return box
        return _to_box(self.x[:4] + self.x[4:] * (t - self.t))


class BoxCarrier:
    """Image-space tracks of one camera's person boxes (see the module docstring).

    Noise is relative to box height, so near and far people behave alike: ``accel`` is the
    white-noise acceleration (box heights/s^2), ``det_noise`` and ``flow_noise`` the measurement
    standard deviations (fraction of box height).
    """

    def __init__(
        self,
        *,
        flow: bool = True,
        max_age_s: float = 0.5,
        max_misses: int = 2,
        match_iou: float = 0.2,
        accel: float = 1.5,
        det_noise: float = 0.03,
        flow_noise: float = 0.03,
        grid: tuple[int, int] = (3, 5),
        region: tuple[float, float, float, float] = (0.2, 0.8, 0.1, 0.9),
        levels: int = 2,
        ring: int = 8,
    ) -> None:
        self.flow, self.max_age_s, self.max_misses = flow, float(max_age_s), int(max_misses)
        self.match_iou, self.accel = float(match_iou), float(accel)
        self.det_noise, self.flow_noise = float(det_noise), float(flow_noise)
        self.grid, self.levels, self.region = grid, int(levels), region
        self.tracks: list[_Track] = []
        self.time: float | None = None
        self._grey: deque[tuple[float, np.ndarray]] = deque(maxlen=ring)
        self._size: tuple[int, int] | None = None  # (w, h) of the last image

    # -- public ----------------------------------------------------------------------------------

    def advance(self, t: float, image: np.ndarray | None = None) -> CarriedDetections:
        """Move every box to time ``t`` (the newest frame; its BGR image enables flow)."""
        grey = self._remember(t, image)
        previous = self._grey[-2][1] if grey is not None and len(self._grey) >= 2 else None
        for track in self.tracks:
            self._predict(track, t)
        if self.flow and grey is not None and previous is not None and self.tracks:
            before = self._grey[-2][0]
            origins = [tr.box_at(before) for tr in self.tracks]
            dt = max(t - before, 1e-3)
            for track, box, z in zip(
                self.tracks, origins, self._flow(previous, grey, origins), strict=True
            ):
                if z is not None:  # flow measures the motion: position and rate both
                    rate = (z - _to_state(box)) / dt
                    self._update(track, np.r_[z, rate], self.flow_noise, rate_noise=1.0 / dt)
        self.time = t
        for track in self.tracks:
            track.history.append((t, track.box))
        self._expire(t)
        return self.current()

    def correct(
        self,
        t: float,
        boxes: np.ndarray,
        scores: np.ndarray | None = None,
        keypoints: np.ndarray | None = None,
    ) -> None:
        """Fold in what the detector found in the frame of time ``t`` (may be older than now)."""
        boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
        scores = np.ones(len(boxes)) if scores is None else np.asarray(scores, float)
        now = t if self.time is None else max(self.time, t)
        judged = [tr for tr in self.tracks if tr.history and tr.history[0][0] <= t + 1e-6]
        matches: list[tuple[int, int]] = []
        if judged and len(boxes):
            iou = box_iou(np.array([tr.box_at(t) for tr in judged]), boxes)
            rows, cols = linear_sum_assignment(-iou)
            matches = [
                (int(r), int(c))
                for r, c in zip(rows, cols, strict=True)
                if iou[r, c] >= self.match_iou
            ]
        matched_tracks = {r for r, _ in matches}
        matched_boxes = {c for _, c in matches}
        for r, c in matches:
            track = judged[r]
            before = track.x[:4].copy()
            offset = _to_state(boxes[c]) - _to_state(track.box_at(t))
            self._update(track, track.x[:4] + offset, self.det_noise)
            track.found, track.score, track.misses = max(track.found, t), float(scores[c]), 0
            track.keypoints = _relative(keypoints, c, boxes[c])
            # later history moves with the correction, so a detection of a frame between t and
            # now is not applied on top of this one
            delta = _to_box(track.x[:4] - before) - _to_box(np.zeros(4))
            track.history = deque(
                ((w, b + delta) if w >= t - 1e-6 else (w, b) for w, b in track.history),
                maxlen=track.history.maxlen,
            )
        for r, track in enumerate(judged):
            if r not in matched_tracks:
                track.misses += 1
        fresh = [c for c in range(len(boxes)) if c not in matched_boxes]
        moved = self._catch_up(t, [boxes[c] for c in fresh])
        for c, box in zip(fresh, moved, strict=True):
            self.tracks.append(self._spawn(box, now, t, float(scores[c]), keypoints, c, boxes[c]))
        self._expire(now)

    def current(self) -> CarriedDetections:
        """The tracks' boxes at the last :meth:`advance` time, highest score first."""
        if not self.tracks:
            return CarriedDetections.empty()
        now = self.time if self.time is not None else max(tr.t for tr in self.tracks)
        order = sorted(range(len(self.tracks)), key=lambda i: -self.tracks[i].score)
        tracks = [self.tracks[i] for i in order]
        boxes = np.stack([tr.box for tr in tracks]).astype(np.float32)
        if self._size is not None:
            w, h = self._size
            boxes = np.clip(boxes, 0, [w, h, w, h]).astype(np.float32)
        keypoints = None
        if any(tr.keypoints is not None for tr in tracks):
            keypoints = np.stack(
                [_absolute(tr.keypoints, b) for tr, b in zip(tracks, boxes, strict=True)]
            )
        return CarriedDetections(
            boxes,
            np.array([tr.score for tr in tracks], np.float32),
            keypoints,
            np.array([max(0.0, now - tr.found) for tr in tracks], np.float32),
        )

    def reset(self) -> None:
        self.tracks, self.time = [], None
        self._grey.clear()

    # -- Kalman filter ---------------------------------------------------------------------------

    def _predict(self, track: _Track, t: float) -> None:
        dt = t - track.t
        if dt <= 0:
            return
        f = np.eye(_F_DIM)
        f[:4, 4:] = np.eye(4) * dt
        q_scale = (self.accel * max(track.x[3], 10.0)) ** 2
        g = np.concatenate([np.full(4, dt * dt / 2), np.full(4, dt)])
        q = np.outer(g, g) * np.kron(np.ones((2, 2)), np.eye(4)) * q_scale
        q[[2, 3, 6, 7], [2, 3, 6, 7]] *= 0.25  # sizes change slower than positions move
        track.x, track.p, track.t = f @ track.x, f @ track.p @ f.T + q, t

    def _update(
        self, track: _Track, z: np.ndarray, noise: float, rate_noise: float | None = None
    ) -> None:
        """Kalman update with ``z`` = box state (4) or box state and rates (8); ``rate_noise``
        scales the rates' standard deviation (per second) from the position's."""
        rows = 4 if rate_noise is None else 8
        h = np.eye(_F_DIM)[:rows]
        sigma = noise * max(track.x[3], 10.0)
        r = np.eye(rows) * sigma**2
        if rate_noise is not None:
            r[4:, 4:] *= rate_noise**2
        s = h @ track.p @ h.T + r
        k = track.p @ h.T @ np.linalg.inv(s)
        track.x = track.x + k @ (np.asarray(z[:rows], float) - h @ track.x)
        track.p = (np.eye(_F_DIM) - k @ h) @ track.p
        track.x[2:4] = np.maximum(track.x[2:4], 2.0)

    def _spawn(
        self,
        box: np.ndarray,
        now: float,
        t: float,
        score: float,
        keypoints: np.ndarray | None,
        index: int,
        detected: np.ndarray,
    ) -> _Track:
        p = np.diag([1.0, 1.0, 1.0, 1.0, 4.0, 4.0, 1.0, 1.0]) * (self.det_noise * 200) ** 2
        p[4:, 4:] = np.eye(4) * (1.0 * max(float(box[3] - box[1]), 10.0)) ** 2
        track = _Track(np.r_[_to_state(box), np.zeros(4)], p, now, t, score, None)
        track.keypoints = _relative(keypoints, index, detected)
        if now > t:
            track.history.append((t, np.asarray(detected, np.float32)))
        track.history.append((now, track.box))
        return track

    def _expire(self, now: float) -> None:
        keep = []
        for tr in self.tracks:
            x0, y0, x1, y1 = tr.box
            gone = self._size is not None and (
                x1 <= 0 or y1 <= 0 or x0 >= self._size[0] or y0 >= self._size[1]
            )
            if now - tr.found <= self.max_age_s and tr.misses <= self.max_misses and not gone:
                keep.append(tr)
        self.tracks = keep

    # -- optical flow ----------------------------------------------------------------------------

    def _remember(self, t: float, image: np.ndarray | None) -> np.ndarray | None:
        if image is None:
            return None
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        self._size = (int(grey.shape[1]), int(grey.shape[0]))
        if not self.flow:
            return grey
        if self._grey and self._grey[-1][1].shape != grey.shape:
            self._grey.clear()
        self._grey.append((t, grey))
        return grey

    def _catch_up(self, t: float, boxes: Sequence[np.ndarray]) -> list[np.ndarray]:
        """New boxes found in the frame of ``t``, moved to the newest grey frame by flow."""
        boxes = [np.asarray(b, np.float64) for b in boxes]
        if not (self.flow and boxes and self._grey) or abs(self._grey[-1][0] - t) < 1e-6:
            return boxes
        old = next((g for when, g in self._grey if abs(when - t) < 1e-6), None)
        if old is None:
            return boxes
        out = []
        for box, z in zip(boxes, self._flow(old, self._grey[-1][1], boxes), strict=True):
            out.append(box if z is None else _to_box(z).astype(np.float64))
        return out

    def _flow(
        self, old: np.ndarray, new: np.ndarray, boxes: Sequence[np.ndarray]
    ) -> list[np.ndarray | None]:
        """Per box: the box state ``(cx, cy, w, h)`` moved by flow from ``old`` to ``new``."""
        gx, gy = self.grid
        u0, u1, v0, v1 = self.region
        u = u0 + (np.arange(gx) + 0.5) / gx * (u1 - u0)
        v = v0 + (np.arange(gy) + 0.5) / gy * (v1 - v0)
        rel = np.stack(np.meshgrid(u, v), -1).reshape(-1, 2)
        points = [np.asarray(b[:2]) + rel * (np.asarray(b[2:]) - np.asarray(b[:2])) for b in boxes]
        p0 = np.concatenate(points).astype(np.float32).reshape(-1, 1, 2)
        size, levels = (15, 15), self.levels
        p1, ok1, _ = cv2.calcOpticalFlowPyrLK(
            old, new, p0, np.empty_like(p0), winSize=size, maxLevel=levels
        )
        back, ok2, _ = cv2.calcOpticalFlowPyrLK(
            new, old, p1, np.empty_like(p1), winSize=size, maxLevel=levels
        )
        good = (ok1.ravel() == 1) & (ok2.ravel() == 1)
        good &= np.linalg.norm((back - p0).reshape(-1, 2), axis=1) < 1.0
        out: list[np.ndarray | None] = []
        n = rel.shape[0]
        for i, box in enumerate(boxes):
            sel = slice(i * n, (i + 1) * n)
            ok = good[sel]
            if ok.sum() < max(4, n // 4):
                out.append(None)
                continue
            a, b = p0[sel].reshape(-1, 2)[ok], p1[sel].reshape(-1, 2)[ok]
            shift = np.median(b - a, axis=0)
            da = np.linalg.norm(a - np.median(a, axis=0), axis=1)
            db = np.linalg.norm(b - np.median(b, axis=0), axis=1)
            valid = da > 2.0
            scale = float(np.median(db[valid] / da[valid])) if valid.sum() >= 3 else 1.0
            z = _to_state(box)
            z[:2] += shift
            z[2:] *= float(np.clip(scale, 0.9, 1.1))
            out.append(z)
        return out


def _relative(keypoints: np.ndarray | None, index: int, box: np.ndarray) -> np.ndarray | None:
    if keypoints is None:
        return None
    kp = np.array(keypoints[index], np.float64)
    x0, y0, x1, y1 = (float(v) for v in box)
    kp[:, 0] = (kp[:, 0] - x0) / max(x1 - x0, 1e-6)
    kp[:, 1] = (kp[:, 1] - y0) / max(y1 - y0, 1e-6)
    return kp


def _absolute(keypoints: np.ndarray | None, box: np.ndarray) -> np.ndarray:
    if keypoints is None:
        return np.full((17, 3), np.nan, np.float32)
    kp = keypoints.copy()
    x0, y0, x1, y1 = (float(v) for v in box)
    kp[:, 0] = x0 + kp[:, 0] * (x1 - x0)
    kp[:, 1] = y0 + kp[:, 1] * (y1 - y0)
    return kp.astype(np.float32)

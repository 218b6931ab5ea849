"""Image continuity: which track a measurement continues, judged in each camera's own image.

Why: on the floor, people in a crowd stand closer together than a measurement's error. In the
real CMC room (10 people, 4 fps, the true association) a fused floor position is off by
0.3-0.4 m whenever a box is cut by an occluder, and neighbours walk 0.4-1 m apart, so the
tracker's floor-space assignment swapped identities even with perfect clusters. A box's
*horizontal* position in its own image barely suffers from what ruins the range (the bottom
edge, the height): it is the bearing, and it moves smoothly from frame to frame. Every camera
that sees both the track (recently) and the measurement therefore adds an independent test: the
measurement's box centre against the track's last box centre in that camera, moved on by the
track's image velocity there. Appearance-free and calibration-free: it compares a camera's boxes
with that camera's own earlier boxes, never across cameras.

Units are box heights and seconds, so the cost means the same for a near and a far person and
at 4 and 30 fps: a person walking across the line of sight at 1 m/s moves about 0.6 box heights
per second (the shift and the box height both scale with 1 / range, their ratio is the lateral
step over the body height). The expected error of the prediction is ``std_h`` (box jitter) plus
``growth_hps`` per second since the camera last saw the track (an unmodelled turn or speed
change: with the image velocity predicted, less than the 0.6 h/s of a walk itself); a
camera's term is capped at ``cap`` (a box cut or widened by an occluder should not veto a
match on its own).

Rejected options are in ``bench/results/real_cmc_chain_tuning.md``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

# a memory older than this (seconds) is forgotten: the person may have turned any way
MAX_AGE_S = 1.0
# image velocity: exponential average over this time (seconds), from consecutive sightings
VELOCITY_TIME_S = 0.5
# The prediction's std as *measured* on real boxes, for the association's per-camera labels
# (``TrackAnchor.image_std``, ``service.tracking.association._BoxContinuity``): on the real CMC
# room (4 fps, the true association, every camera) a box centre's error against a constant
# image velocity one frame on is 0.056 box heights at the 68th percentile (0.154 at the 95th),
# while a neighbour's box centre lies 0.18 h away at the median in CMC2 (10 people). The cost
# term's ``std_h`` / ``growth_hps`` (the tracker's, tuned as a capped cost) is about 4x wider:
# with it nearly every box of CMC2 had two tracks within reach and none was labelled.
LABEL_STD_H = 0.03
LABEL_GROWTH_HPS = 0.12


@dataclass
class ViewMemory:
    """One track's last box per camera: centre x and height (px), time seen (s), and the
    smoothed horizontal image velocity (px/s)."""

    centre: dict[int, float] = field(default_factory=dict)
    height: dict[int, float] = field(default_factory=dict)
    seen: dict[int, float] = field(default_factory=dict)
    velocity: dict[int, float] = field(default_factory=dict)

    def remember(self, boxes: np.ndarray | None, t: float) -> None:
        """Fold this update's boxes ([K, 4], NaN where a camera does not see the person)."""
        if boxes is None:
            return
        for k, box in enumerate(np.asarray(boxes, np.float64).reshape(-1, 4)):
            if not np.isfinite(box).all() or box[3] <= box[1]:
                continue
            centre = 0.5 * (box[0] + box[2])
            last = self.seen.get(k)
            if last is not None and 0.0 < t - last <= MAX_AGE_S:
                step = (centre - self.centre[k]) / (t - last)
                weight = 1.0 - np.exp(-(t - last) / VELOCITY_TIME_S)
                previous = self.velocity.get(k, step)
                self.velocity[k] = float(previous + weight * (step - previous))
            elif last is None or t - last > MAX_AGE_S:
                self.velocity[k] = 0.0
            self.centre[k] = float(centre)
            self.height[k] = float(box[3] - box[1])
            self.seen[k] = float(t)

    def predict(
        self, cameras: int, now: float, std_h: float, growth_hps: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each camera's predicted box centre x [K] (px, moved on by the image velocity) and its
        std [K] (px: ``std_h`` plus ``growth_hps`` per second since seen, in box heights); NaN
        where the camera has not seen the track within ``MAX_AGE_S``."""
        predicted = np.full(cameras, np.nan)
        scale = np.full(cameras, np.nan)
        for k, seen in self.seen.items():
            age = now - seen
            if k >= cameras or age > MAX_AGE_S:
                continue
            predicted[k] = self.centre[k] + self.velocity.get(k, 0.0) * age
            scale[k] = self.height[k] * (std_h + growth_hps * max(age, 0.0))
        return predicted, scale


@dataclass(frozen=True)
class ImageContinuity:
    """The assignment cost term (module docstring); ``std_h`` 0 disables it."""

    std_h: float = 0.0
    growth_hps: float = 0.6
    cap: float = 16.0

    @property
    def enabled(self) -> bool:
        return self.std_h > 0

    def cost(
        self,
        memories: Sequence[ViewMemory],
        boxes: Sequence[np.ndarray | None],
        now: float,
    ) -> np.ndarray:
        """[T, P]: over the cameras that saw track t within ``MAX_AGE_S`` and see measurement
        p now, the sum of each squared, capped prediction error minus 1 (0 where none does)."""
        shape = (len(memories), len(boxes))
        cameras = max((np.shape(b)[0] for b in boxes if b is not None), default=0)
        if not self.enabled or not all(shape) or cameras == 0:
            return np.zeros(shape)
        measured = np.full((len(boxes), cameras), np.nan)
        for p, b in enumerate(boxes):
            if b is None:
                continue
            b = np.asarray(b, np.float64).reshape(-1, 4)
            measured[p, : len(b)] = 0.5 * (b[:, 0] + b[:, 2])
        predicted, scale = (
            np.stack(side)
            for side in zip(
                *(m.predict(cameras, now, self.std_h, self.growth_hps) for m in memories),
                strict=True,
            )
        )
        z = (measured[None] - predicted[:, None]) / scale[:, None]
        # minus 1, the expected squared error of a right match: a camera more or less in common
        # then neither favours nor penalises a pair by itself
        terms = np.minimum(z**2, self.cap) - 1.0
        return np.where(np.isfinite(terms), terms, 0.0).sum(axis=2)

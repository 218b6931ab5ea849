"""Whether the person has reached the next mark: the set-up page's move step ends on arrival.

Why: the move step had a fixed length (the page's default 5 s, longer for far marks), and with
9 marks that is 45 s of the set-up's time spent waiting for someone who usually arrived in 2-3 s.
Now the move step ends, and the countdown starts, as soon as the person is seen to have moved
since the instruction and then to stand still for ``STILL_S`` after that; the step's planned
length stays the maximum wait (a mark outside every camera's view, a detector that misses most
frames, nobody moving).

Seen to have moved: some camera's single box has its foot point (bottom-centre) more than
``MOVED`` box heights from where that camera first saw it in this step. Without it, the person
still standing on the previous mark (people, and the simulated person, react with a delay)
would count as arrived. Still: over the last ``STILL_S``, every camera that mostly shows one box
(``ONE_SHARE`` of the frames) has ``STILL_SHARE`` of those boxes within ``STILL_BAND`` box heights
of their median foot, at least one camera is such, and no camera mostly shows several boxes
(someone else in the room: the countdown waits). Distances are in box heights, so the rule is
the same at any resolution. A frame's tolerance for stray boxes (a false box, a missed frame)
is the share thresholds: a measured detector misses 20-50 % of frames and shows ~0.3 false boxes
per frame (the ``nanodet`` profile), so requiring every frame to be clean would always wait the
maximum.

A premature start costs little: the countdown follows, and the floor-map fit
(:mod:`models.geometry.mark_fit`) leaves out a mark whose boxes are not where the person stands.
"""

from __future__ import annotations

from collections import deque

import numpy as np

MOVED = 0.3  # box heights: a step or more
STILL_S = 1.0
STILL_BAND = 0.15  # box heights: sway and detector noise, not a walk (~0.6 heights per second)
STILL_SHARE = 0.8
ONE_SHARE = 0.5


class Arrival:
    """Fed every frame set of a move step; :meth:`update` says when the person has arrived."""

    def __init__(self, num_cameras: int) -> None:
        self._start: list[np.ndarray | None] = [None] * num_cameras  # first foot, in pixels
        self._moved_at: float | None = None  # when the person was first seen away from start
        self._frames: deque[tuple[float, list[np.ndarray | None], list[int]]] = deque()

    def update(self, t: float, boxes: list[np.ndarray]) -> bool:
        """One frame set (per camera boxes [M, 4]); whether the person has arrived now."""
        singles: list[np.ndarray | None] = []
        for k, camera in enumerate(boxes):
            one = np.asarray(camera, float).reshape(-1, 4)
            single = _foot(one[0]) if len(one) == 1 else None
            singles.append(single)
            if single is None:
                continue
            start = self._start[k]
            if start is None:
                self._start[k] = single
            elif self._moved_at is None and np.hypot(*(single[:2] - start[:2])) > MOVED * single[2]:
                self._moved_at = t
        self._frames.append((t, singles, [len(b) for b in boxes]))
        while self._frames and self._frames[0][0] < t - STILL_S:
            self._frames.popleft()
        # the still window must lie after the move was seen: a walk's start is not a stand
        return self._moved_at is not None and t - self._moved_at >= STILL_S and self._still()

    def _still(self) -> bool:
        frames = len(self._frames)
        seeing = 0
        for k in range(len(self._start)):
            several = sum(counts[k] > 1 for _, _, counts in self._frames)
            if several > ONE_SHARE * frames:
                return False  # someone else is in the room
            feet = [f for _, s, _ in self._frames if (f := s[k]) is not None]
            if len(feet) < ONE_SHARE * frames:
                continue  # this camera does not see the person (or misses most frames)
            points = np.stack(feet)
            offset = np.hypot(*(points[:, :2] - np.median(points[:, :2], axis=0)).T)
            if np.mean(offset <= STILL_BAND * np.median(points[:, 2])) < STILL_SHARE:
                return False
            seeing += 1
        return seeing > 0


def _foot(box: np.ndarray) -> np.ndarray:
    """(u, v, height) of a box's bottom-centre, in pixels."""
    return np.array([(box[0] + box[2]) / 2, box[3], max(box[3] - box[1], 1e-6)])

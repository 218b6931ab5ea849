"""Places where a camera keeps reading lying: no evidence of a body on the floor there.

A detector's false positives are not white noise: a coat on a chair, a plant, a bag or a door
frame is "seen" as a person for a second or two from the same spot, again and again, with about
the same size (the simulator models them so, :mod:`models.simulate.false_positives`). Such a
box is often short against a standing person's height there, so it reads *lying*
(:mod:`service.tracking.posture`; one narrower than any body on the floor no longer does, but a
bag or a pet bed is as wide as one), and one camera's lying read for 1.5 s is all a fall needs
when the other camera does not see the spot (:mod:`service.outputs.falls`). Traced on the fall
bench's daily life through the serving chain (seed sets 601 and 701, 12 person-hours), six of
twelve false falls were such boxes on one camera (``bench/results/falls.md``).

A person does not come back to lie at the same image place with the same box size again and
again within minutes; a recurring false box does. So each camera keeps, per place of its
*lying* boxes (bottom centre and height in the camera's own pixels), how many separate
*episodes* it read lying there: an episode ends when the place is not read for ``gap_s`` (10 s:
longer than the dropouts a lying person has between two reads, so one fallen body does not
make its own place recurring, and shorter than the pauses between a false positive's
returns). From its ``episodes``-th (3) episode on a place is *recurring*, and a lying box there
is read ``unknown`` instead (:func:`service.tracking.posture.normalise`): no lying evidence,
localized as detected. Nothing else changes: the box is still associated, tracked and served.

Only lying boxes teach it. Learned from every box, the places of people (seats, crouch spots,
legs hidden at the same furniture edge) made 140 recurring places per camera in an hour of
the simulated lounge's daily life, and 26 % of the fall scenes' fallen bodies' lying boxes (their
first 3 s on the floor) matched one; learned from lying boxes, 1-10 places and 0.2-1.9 % (the fall
bench keeps falls and daily life in separate scenes, so its falls do not pay this price:
``bench/results/falls.md``).

What matches a place: bottom centre within ``place_h`` (0.2) of the place's height in both image
axes, and a height within ``height_ratio`` (1.25) of it. The width is left out: a detector's
false box at one spot changes width more than height (the simulator's vary 2× in width, ±10 %
in height).

The price: someone who lies down at the same spot in the image several times within an hour (a
floor mat) is not read lying there from the third time on, and a fall onto exactly such a spot,
with about the same box, is missed until another camera reads it lying. Places unseen for
``forget_s`` (1 h) are forgotten; a camera keeps at most ``max_places`` (512), the least seen
dropped first. Rejected: gating falls on the other camera's coverage of the spot (the other
camera often sees a fallen body lengthwise, or not at all behind furniture: a third of the falls
lost, ``bench/results/falls.md``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

GAP_S = 10.0  # a place unreported this long starts a new episode when reported again
EPISODES = 3  # from this episode on, a place is recurring
PLACE_H = 0.2  # bottom centre within this many of the place's heights, in x and in y
HEIGHT_RATIO = 1.25  # ... and a height within this factor of the place's
FORGET_S = 3600.0  # a place unseen this long is forgotten
MAX_PLACES = 512  # per camera
ADAPT = 0.2  # a matched box moves its place this much towards itself


@dataclass
class _Places:
    """One camera's places: bottom centre x, bottom y, height [P]; when last reported; episodes."""

    u: np.ndarray = field(default_factory=lambda: np.zeros(0))
    v: np.ndarray = field(default_factory=lambda: np.zeros(0))
    h: np.ndarray = field(default_factory=lambda: np.zeros(0))
    seen: np.ndarray = field(default_factory=lambda: np.zeros(0))
    episodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def keep(self, rows: np.ndarray) -> None:
        self.u, self.v, self.h = self.u[rows], self.v[rows], self.h[rows]
        self.seen, self.episodes = self.seen[rows], self.episodes[rows]


class RecurringBoxes:
    """Per camera, the places where the camera keeps reading lying (module docstring)."""

    def __init__(
        self,
        *,
        gap_s: float = GAP_S,
        episodes: int = EPISODES,
        place_h: float = PLACE_H,
        height_ratio: float = HEIGHT_RATIO,
        forget_s: float = FORGET_S,
        max_places: int = MAX_PLACES,
    ) -> None:
        if gap_s <= 0 or episodes < 2 or place_h <= 0 or height_ratio < 1 or max_places < 1:
            raise ValueError(
                "gap_s and place_h > 0, episodes >= 2, height_ratio >= 1, max_places >= 1"
            )
        self.gap_s, self.episodes, self.place_h = float(gap_s), int(episodes), float(place_h)
        self.log_ratio = float(np.log(height_ratio))
        self.forget_s, self.max_places = float(forget_s), int(max_places)
        self._cameras: list[_Places] = []

    def update(self, t: float, camera: int, boxes: np.ndarray) -> np.ndarray:
        """Fold in camera ``camera``'s lying boxes ([M, 4] px) of time ``t``; which of them [M]
        bool lie at a recurring place (counting this report's episode)."""
        while len(self._cameras) <= camera:
            self._cameras.append(_Places())
        return self._camera(self._cameras[camera], float(t), boxes)

    def _camera(self, places: _Places, t: float, boxes: np.ndarray) -> np.ndarray:
        b = np.asarray(boxes, np.float64).reshape(-1, 4)
        ok = np.isfinite(b).all(axis=1) & (b[:, 3] > b[:, 1])
        recurring = np.zeros(len(b), bool)
        places.keep(t - places.seen <= self.forget_s)
        u, v, h = 0.5 * (b[:, 0] + b[:, 2]), b[:, 3], b[:, 3] - b[:, 1]
        nearest: dict[int, tuple[float, int]] = {}  # place -> (distance, its nearest box)
        for i in np.flatnonzero(ok).tolist():
            found = self._match(places, u[i], v[i], h[i])
            if found is not None and (found[0] not in nearest or found[1] < nearest[found[0]][0]):
                nearest[found[0]] = (found[1], i)
        matched = {j: i for j, (_, i) in nearest.items()}
        for j, i in matched.items():
            if t - places.seen[j] >= self.gap_s:
                places.episodes[j] += 1
            places.seen[j] = t
            places.u[j] += ADAPT * (u[i] - places.u[j])
            places.v[j] += ADAPT * (v[i] - places.v[j])
            places.h[j] *= float(np.exp(ADAPT * np.log(h[i] / places.h[j])))
            recurring[i] = places.episodes[j] >= self.episodes
        new = [i for i in np.flatnonzero(ok).tolist() if i not in matched.values()]
        if new:
            idx = np.asarray(new)
            places.u = np.concatenate([places.u, u[idx]])
            places.v = np.concatenate([places.v, v[idx]])
            places.h = np.concatenate([places.h, h[idx]])
            places.seen = np.concatenate([places.seen, np.full(len(idx), t)])
            places.episodes = np.concatenate([places.episodes, np.ones(len(idx), np.int64)])
        if len(places.u) > self.max_places:  # the least seen go, the oldest of them first
            order = np.lexsort((places.seen, places.episodes))[::-1][: self.max_places]
            places.keep(np.sort(order))
        return recurring

    def _match(self, places: _Places, u: float, v: float, h: float) -> tuple[int, float] | None:
        """The nearest place the box matches and its distance in the place's heights, or None."""
        if not len(places.u):
            return None
        reach = self.place_h * places.h
        near = (np.abs(places.u - u) <= reach) & (np.abs(places.v - v) <= reach)
        near &= np.abs(np.log(h / places.h)) <= self.log_ratio
        if not near.any():
            return None
        d = np.where(near, np.hypot(places.u - u, places.v - v) / places.h, np.inf)
        j = int(np.argmin(d))
        return j, float(d[j])

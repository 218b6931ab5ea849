"""How far to trust the localizer's covariances in this room: a scale learned from innovations.

The tracker weighs each floor position by the covariance the localizer gives it
(:mod:`service.tracking.measurements`), multiplied by a scale. How honest those covariances are
depends on the room, not on the model alone: the same model is well calibrated on people who
stand apart, as in the rooms it was set up in, and overconfident in a crowd whose boxes are
half hidden. Measured with the tracker's innovations ``ν = z − ẑ`` of confirmed tracks at the
former fixed scale 9 (``bench/results/tracker_tuning.md``, 2026-12-06): the median of
``d² = νᵀ (P + s R)⁻¹ ν``, 1.39 when the noise is what the filter assumes (the median of χ² with
two degrees of freedom), was 0.21-0.61 in the simulated rooms (the covariances were inflated
several times too much: walkers' turns were followed late) and 0.9-1.0 in the real CMC room with
10 people (about right), 0.3 in the same room with 3 people. No fixed scale suits both: 2
raised the simulated rooms' streamed MOTA by up to 6 points and cost the real crowd 1-4.

So the scale follows the innovations: a stochastic-approximation tracker of the median
(Robbins-Monro). Each frame set, the share of this frame's innovations whose ``d²`` exceeds the
χ² median moves ``log s`` up when above one half and down when below, by at most ``log 4`` per
``time_constant_s`` of real time (so the same at any frame rate). It settles where half the
innovations exceed the median, that is where the covariances, scaled, describe the errors.
Why the median and not the mean of ``d²``: mis-associated boxes give a few huge ``d²`` that
would drive a mean, and the median ignores how far out they lie. Higher quantiles (0.8, 0.9:
targets for heavy tails) were tried on the real room and not kept (same table).

Bounds: ``MIN_SCALE`` 3. The median fits the spread of one frame's errors, but a detector's
errors are correlated over about a second (a box edge stays off for several frames), and a
filter that trusts each frame fully follows them: on the stream gate's scene (indoor-2cam, 3
people, the demo model) a floor of 1 or 2 lost 4 points of MOTA on one of three seeds where 3
lost none (the scale settles at 1-2.6 there); all three lowered the matched error and the
standing jitter alike (``bench/results/tracker_tuning.md``). ``MAX_SCALE`` 16, so a burst of
wrong pairings cannot switch the filter off. A room with nobody in it does not move the scale.

Example::

    scale = NoiseScale(initial=9.0, time_constant_s=10.0)
    scale.observe(d2)        # each confirmed track's innovation, this frame set
    scale.step(dt)           # once per frame set
    r = covariance * scale.value
"""

from __future__ import annotations

import math

CHI2_2_MEDIAN = 2.0 * math.log(2.0)  # median of χ² with 2 degrees of freedom (1.386)
MAX_LOG_STEP = math.log(4.0)  # the most log s moves per time constant
MIN_SCALE = 3.0
MAX_SCALE = 16.0


class NoiseScale:
    """The measurement covariance scale, adapted to the median innovation (module docstring)."""

    def __init__(self, initial: float, time_constant_s: float) -> None:
        if not initial > 0:
            raise ValueError(f"initial scale {initial}: must be positive")
        if time_constant_s < 0:
            raise ValueError(f"time_constant_s {time_constant_s}: must be 0 (fixed) or positive")
        self.initial = self.value = float(initial)
        self.time_constant_s = float(time_constant_s)
        self._above = 0
        self._seen = 0

    @property
    def adapting(self) -> bool:
        return self.time_constant_s > 0

    def observe(self, d2: float) -> None:
        """One confirmed track's squared Mahalanobis innovation, under the current scale."""
        if self.adapting and math.isfinite(d2):
            self._seen += 1
            self._above += d2 > CHI2_2_MEDIAN

    def step(self, dt: float) -> None:
        """Move the scale by this frame set's innovations, ``dt`` seconds after the last."""
        if not self._seen or dt <= 0:
            return
        share = self._above / self._seen
        self._above = self._seen = 0
        move = MAX_LOG_STEP * (2.0 * share - 1.0) * min(dt, self.time_constant_s)
        self.value = min(max(self.value * math.exp(move / self.time_constant_s), MIN_SCALE),
                         MAX_SCALE)  # fmt: skip

"""Motion models of one tracked person on the floor, state ``[x, y, vx, vy]`` (m, m/s).

:class:`ConstantVelocity` is a Kalman filter with white-acceleration process noise
(``accel_std`` m/s²): uncertainty grows with the real time between updates.

:class:`StandOrWalk` is an interacting-multiple-model (IMM) filter of two such models, because
people in a room stand still a lot, and a constant-velocity filter tuned to follow a walk keeps a
standing person's position wandering with the measurement noise
(``bench/results/tracking_filters.md``). The *stand* model holds the position (velocity
reset to 0 at every prediction, a small ``stand_std`` m/√s random walk for sway), the *walk* model
is the constant-velocity one. Each update mixes the two states by the probabilities of switching
(mean stay ``stand_s`` / ``walk_s`` seconds, so the switch rate is in time, not frames), corrects
both, reweighs them by their measurement likelihoods and reports the probability-weighted mean
and covariance. While the person stands the stand model takes over and the position converges
like a running mean; when they start to walk the walk model's likelihood wins within a few frames.

The stand probability saturates well below 1 (a walk model at ~0 m/s explains a standing person
almost as well), so the reported state is the mixture; reporting the more probable model's
state instead changed nothing (the remaining jitter is a few large jumps when a second camera
comes or goes, not the mixture). Served-position stages after the filter were measured and
rejected: holding the position while the person stands (the stand probability drops exactly at
the jumps the hold should absorb), 1€ filters (every setting buys jitter with lag and accuracy)
and damped coasting (costs MOTA). Figures: ``bench/results/tracking_filters.md``.

Offline (``momloc track``) a centred window can smooth without lag: ``service.tracking.smoother``.

Both take a per-measurement covariance ``r`` [2, 2], so a single-view measurement that is
uncertain along the camera's line of sight pulls the state across it only.

Example::

    f = StandOrWalk(z, r0)
    f.predict(1 / 15)
    f.correct(z, r)
    x, y, vx, vy = f.mean
"""

from __future__ import annotations

import numpy as np

_H = np.eye(2, 4)


def _transition(dt: float, keep_velocity: bool = True) -> np.ndarray:
    f = np.eye(4)
    f[0, 2] = f[1, 3] = dt
    if not keep_velocity:
        f[2, 2] = f[3, 3] = 0.0
    return f


def white_acceleration(dt: float, accel_var: float) -> np.ndarray:
    """Process noise [4, 4] of a constant-velocity model over ``dt`` seconds."""
    q1 = np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]]) * accel_var
    q = np.zeros((4, 4))
    q[np.ix_([0, 2], [0, 2])] = q1
    q[np.ix_([1, 3], [1, 3])] = q1
    return q


def initial_covariance(r: np.ndarray) -> np.ndarray:
    """A new track: the measurement's covariance, and an unknown velocity within ~1 m/s."""
    cov = np.zeros((4, 4))
    cov[:2, :2] = r
    cov[2, 2] = cov[3, 3] = 1.0
    return cov


def _kalman(
    mean: np.ndarray, cov: np.ndarray, z: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Corrected mean, covariance and the measurement's log-likelihood."""
    s = _H @ cov @ _H.T + r
    s_inv = np.linalg.inv(s)
    gain = cov @ _H.T @ s_inv
    nu = z - _H @ mean
    mean = mean + gain @ nu
    cov = (np.eye(4) - gain @ _H) @ cov
    cov = (cov + cov.T) / 2
    loglik = -0.5 * (nu @ s_inv @ nu + np.log(np.linalg.det(s)) + 2 * np.log(2 * np.pi))
    return mean, cov, float(loglik)


def _stop(mean: np.ndarray, cov: np.ndarray) -> None:
    """Set a state's velocity [2:] to 0, in place, and forget how it correlated with the
    position."""
    mean[2:] = 0.0
    cov[2:, :2] = cov[:2, 2:] = 0.0


class ConstantVelocity:
    """Kalman filter with white-acceleration process noise (see the module docstring)."""

    def __init__(self, z: np.ndarray, r: np.ndarray, accel_std: float = 2.0) -> None:
        self.mean = np.array([z[0], z[1], 0.0, 0.0], dtype=np.float64)
        self.cov = initial_covariance(r)
        self.accel_var = float(accel_std) ** 2

    def predict(self, dt: float) -> None:
        if dt <= 0:
            return
        f = _transition(dt)
        self.mean = f @ self.mean
        self.cov = f @ self.cov @ f.T + white_acceleration(dt, self.accel_var)

    def correct(self, z: np.ndarray, r: np.ndarray) -> None:
        self.mean, self.cov, _ = _kalman(self.mean, self.cov, np.asarray(z, float), r)

    def settle(self) -> None:
        """The person is down (a body on the floor does not walk): velocity 0."""
        _stop(self.mean, self.cov)

    @property
    def standing(self) -> float:
        return 0.0


class StandOrWalk:
    """Two-model IMM: standing still or walking at a constant velocity (module docstring)."""

    def __init__(
        self,
        z: np.ndarray,
        r: np.ndarray,
        accel_std: float = 2.0,
        *,
        stand_std: float = 0.03,
        stand_s: float = 2.0,
        walk_s: float = 4.0,
        stand_prior: float = 0.5,
    ) -> None:
        start = np.array([z[0], z[1], 0.0, 0.0], dtype=np.float64)
        self._means = [start.copy(), start.copy()]  # 0: stand, 1: walk
        self._covs = [initial_covariance(r), initial_covariance(r)]
        self._covs[0][2:, 2:] = np.eye(2) * 1e-4
        self._prob = np.array([stand_prior, 1.0 - stand_prior])
        self.accel_var = float(accel_std) ** 2
        self.stand_var = float(stand_std) ** 2
        self.stay_s = (float(stand_s), float(walk_s))
        self._combine()

    @property
    def standing(self) -> float:
        """Probability that the person stands still."""
        return float(self._prob[0])

    def predict(self, dt: float) -> None:
        if dt <= 0:
            return
        switch = [1.0 - np.exp(-dt / s) for s in self.stay_s]
        pi = np.array([[1 - switch[0], switch[0]], [switch[1], 1 - switch[1]]])  # from i to j
        predicted = pi.T @ self._prob
        mix = pi * self._prob[:, None] / np.maximum(predicted[None, :], 1e-300)  # [i, j]
        means, covs = [], []
        for j in range(2):
            m = sum(mix[i, j] * self._means[i] for i in range(2))
            c = sum(
                mix[i, j] * (self._covs[i] + np.outer(self._means[i] - m, self._means[i] - m))
                for i in range(2)
            )
            means.append(m)
            covs.append(c)
        stand_q = np.zeros((4, 4))
        stand_q[0, 0] = stand_q[1, 1] = self.stand_var * dt
        stand_q[2, 2] = stand_q[3, 3] = 1e-4
        f0, f1 = _transition(dt, keep_velocity=False), _transition(dt)
        self._means = [f0 @ means[0], f1 @ means[1]]
        self._covs = [
            f0 @ covs[0] @ f0.T + stand_q,
            f1 @ covs[1] @ f1.T + white_acceleration(dt, self.accel_var),
        ]
        self._prob = predicted
        self._combine()

    def correct(self, z: np.ndarray, r: np.ndarray) -> None:
        z = np.asarray(z, dtype=np.float64)
        logliks = np.zeros(2)
        for j in range(2):
            self._means[j], self._covs[j], logliks[j] = _kalman(self._means[j], self._covs[j], z, r)
        weights = self._prob * np.exp(logliks - logliks.max())
        self._prob = np.clip(weights / weights.sum(), 1e-6, 1.0)
        self._prob /= self._prob.sum()
        self._combine()

    def settle(self) -> None:
        """The person is down (a body on the floor does not walk): both models' velocity 0 and
        the stand model taken as sure, so the track stays where the body lies instead of
        coasting on the speed of the fall or of the jump its first lying position made, and
        averages the body's next positions (``bench/results/falls.md``). Rejected: velocity 0
        with the models' probabilities kept (the lying person's streamed error and share of
        time served both worse, ``bench/results/postures.md``)."""
        for mean, cov in zip(self._means, self._covs, strict=True):
            _stop(mean, cov)
        self._prob = np.array([1.0 - 1e-6, 1e-6])
        self._combine()

    def _combine(self) -> None:
        self.mean = self._prob[0] * self._means[0] + self._prob[1] * self._means[1]
        self.cov = sum(
            p * (c + np.outer(m - self.mean, m - self.mean))
            for p, m, c in zip(self._prob, self._means, self._covs, strict=True)
        )

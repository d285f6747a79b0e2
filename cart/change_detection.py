"""Online detection of a step change of the cart's inertial parameters (a payload put in or taken out).

Generalized likelihood ratio (GLR) test on the residuals of the online regression
(:mod:`cart.online_regression`; Willsky and Jones, "A generalized likelihood ratio
approach to the detection and estimation of jumps in linear systems", IEEE TAC 1976).
With the a-priori residual ``r_k = y_k - Y_k p_hat`` of each sample, the rows' weights
``W_k`` and ``Phi_k`` the regressor columns of ``[m, m dx, m dy, J]``, a step change
``delta`` of those parameters shifts the residuals by ``Phi_k delta``. Over an
exponentially weighted window the score ``S = sum w_k Phi_k^T W_k r_k`` has, without a
change, the covariance ``A2 + A P A`` (``A = sum w_k Phi^T W Phi``, ``A2`` the same with
``w_k^2``, ``P`` the covariance of p_hat: the estimate's own error also biases the
residuals); ``g = S^T (A2 + A P A)^-1 S`` is then chi-square with 4 dof. A change is
declared when ``g`` passes the ``1 - alpha`` quantile and the estimated mass change is
at least ``min_change`` of the mass. Its onset is the maximum-likelihood start over
the last ``buffer_s`` seconds (the GLR over every candidate start, :meth:`onset`).
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np

from cart.ekf import chi2_isf
from cart.small_linalg import solve_small

N_INERTIAL = 4


class RingBuffer:
    """The last ``size`` samples of named arrays (one row per sample), oldest first on read."""

    def __init__(self, size: int, shapes: dict[str, tuple[int, ...]]) -> None:
        self.size = int(size)
        self.data = {k: np.zeros((self.size, *s)) for k, s in shapes.items()}
        self.count = 0

    def push(self, **rows: np.ndarray | float) -> None:
        """Store one sample (overwrites the oldest when full)."""
        i = self.count % self.size
        for k, v in rows.items():
            self.data[k][i] = v
        self.count += 1

    def read(self, key: str) -> np.ndarray:
        """Return the stored rows of ``key``, oldest first."""
        arr = self.data[key]
        n = min(self.count, self.size)
        if self.count <= self.size:
            return arr[:n]
        i = self.count % self.size
        return np.concatenate([arr[i:], arr[:i]])

    @property
    def length(self) -> int:
        """Return the number of stored samples."""
        return min(self.count, self.size)

    def at(self, key: str, j: int) -> np.ndarray:
        """Return the row ``j`` (0: the oldest stored) of ``key`` (as :meth:`read` ``[j]``, without the copy)."""
        if not 0 <= j < self.length:
            raise IndexError(f"row {j} of a buffer holding {self.length}")
        start = self.count % self.size if self.count > self.size else 0
        return self.data[key][(start + j) % self.size]

    def clear(self) -> None:
        """Forget every sample."""
        self.count = 0


class ChangeDetector:
    """Windowed GLR test for a step of [m, m dx, m dy, J]; see the module docstring."""

    def __init__(self, window_s: float = 1.5, alpha: float = 1e-6, min_change: float = 0.08) -> None:
        if not (window_s > 0.0 and 0.0 < alpha < 1.0 and min_change >= 0.0):
            from cart.online_regression import OnlineEstimatorError

            raise OnlineEstimatorError(
                f"change detection needs window_s > 0, 0 < alpha < 1, min_change >= 0; got {window_s}, {alpha}, {min_change}"
            )
        self.window_s = float(window_s)
        self.threshold = chi2_isf(float(alpha), N_INERTIAL)
        self.min_change = float(min_change)
        self.statistic = 0.0
        self.delta = np.zeros(N_INERTIAL)
        self.restart()

    def restart(self) -> None:
        """Empty the window (after a detection: the next test uses only residuals of the new estimate)."""
        self._s = np.zeros(N_INERTIAL)
        self._a = np.zeros((N_INERTIAL, N_INERTIAL))
        self._a2 = np.zeros((N_INERTIAL, N_INERTIAL))
        self._filled = 0.0

    def update(
        self,
        dt: float,
        s: np.ndarray,
        info: np.ndarray,
        p_cov: np.ndarray,
        ridge: np.ndarray,
        mass: float,
        misfit: float = 1.0,
    ) -> bool:
        """Add one sample's score ``s`` (4,) and information ``info`` (4, 4); return whether a change is declared.

        ``p_cov``: covariance of the inertial estimate (4, 4); ``ridge``: information added to
        ``A`` when estimating the change (the prior's, so an unexcited direction gives no change);
        ``misfit``: residual ratio of the model (at least 1): the residuals, hence the scores, are that many
        times larger than the noise model says, and their covariance is scaled by its square.
        """
        lam = math.exp(-dt / self.window_s)
        self._s = lam * self._s + s
        self._a = lam * self._a + info
        self._a2 = lam * lam * self._a2 + info
        self._filled += dt
        if self._filled < self.window_s:
            return False
        cov = (self._a2 + self._a @ p_cov @ self._a) * max(misfit, 1.0) ** 2
        cov.flat[:: N_INERTIAL + 1] += 1e-12 * np.diag(cov) + 1e-300
        try:
            self.statistic = float(self._s @ solve_small(cov, self._s))
            self.delta = solve_small(self._a + ridge, self._s)
        except np.linalg.LinAlgError:
            return False
        return self.statistic > self.threshold and abs(float(self.delta[0])) >= self.min_change * abs(mass)

    @staticmethod
    def profile(scores: np.ndarray, infos: np.ndarray, p_cov: np.ndarray) -> np.ndarray:
        """Return the GLR statistic of a change starting at each buffered sample (the samples from it to the end)."""
        s_rev = np.cumsum(scores[::-1], axis=0)[::-1]  # sum from each candidate start to the end
        a_rev = np.cumsum(infos[::-1], axis=0)[::-1]
        cov = a_rev + a_rev @ p_cov @ a_rev
        cov += np.eye(N_INERTIAL) * (1e-12 * np.trace(cov, axis1=1, axis2=2)[:, None, None] + 1e-300)
        return np.einsum("ki,ki->k", s_rev, np.linalg.solve(cov, s_rev[:, :, None])[:, :, 0])

    @staticmethod
    def onset(scores: np.ndarray, infos: np.ndarray, p_cov: np.ndarray) -> int:
        """Return the index (into the buffered samples) of the most likely start of the change (GLR over starts)."""
        return int(np.argmax(ChangeDetector.profile(scores, infos, p_cov)))

    @staticmethod
    def onset_range(g: np.ndarray, misfit: float = 1.0, level: float = 0.95) -> tuple[int, int, int]:
        """Return (most likely start, earliest, latest) of the starts the data cannot tell from it, by index.

        ``g``: the GLR over the starts (:meth:`profile`). Twice the log-likelihood ratio of the best start
        against another is ``g_max - g_k``; a start is kept while that is below the chi-square (1 dof) quantile
        ``level`` scaled by ``misfit ** 2`` (the residual ratio: the residuals, hence ``g``, are that many times
        larger than the noise model says) -- the contiguous run around the best start (a likelihood-ratio
        confidence set of the change time). A change made while the cart cruises changes neither the motion nor
        the wrench until the next acceleration: every start in the cruise fits as well, and the run spans it.
        """
        best = int(np.argmax(g))
        drop = NormalDist().inv_cdf(0.5 + 0.5 * level) ** 2 * max(misfit, 1.0) ** 2  # chi-square, 1 dof
        ok = g >= g[best] - drop
        lo, hi = best, best
        while lo > 0 and ok[lo - 1]:
            lo -= 1
        while hi < len(g) - 1 and ok[hi + 1]:
            hi += 1
        return best, lo, hi


class MomentumTest:
    """A load put in at rest, found by the momentum it takes from the cart at an impulse (paper eq. 3-4).

    A load set on the deck at rest joins the cart in a perfectly inelastic impulse: the wheels' no-slip
    constraint acts sideways only, so the forward momentum of the cart's centre of mass ``m (v - dy omega)``
    (``v`` the forward speed of {b}'s origin, ``omega`` the yaw rate, ``dy`` the CoM's lateral offset) is kept,
    ``m_after u+ = m_before u-``, and the CoM's forward speed ``u`` jumps by the mass ratio ``r = u- / u+``.
    What the sensors measure besides is taken out: the measured net forward force's impulse ``I(t)`` (the wrench
    held over each period minus the damping, :meth:`add`) moves ``u`` by ``(I(t) - I(t_jump)) / m_before``, and
    the yaw rate the wrench's torque gives moves ``v`` by ``dy omega`` without moving the CoM; an arm at its
    limit (a wrench spike, the cart yanked in yaw) is then no jump. :meth:`add` keeps the last ``2 side_s`` s,
    :meth:`arm` marks an impulse (the velocity jump the wrench does not explain, found by the online estimator)
    with the estimate before it, and :meth:`check`, ``side_s`` after it, fits a straight line to
    ``u - (I - I_jump) / m_before`` on each side (ordinary least squares; the lines take out what the mass
    error leaves of the impulse) and evaluates both at the jump (the midpoint of the period before the
    impulse's sample). The noise is the larger of the lines' residual variance and the predicted one
    (``speed_std``: the motion capture's forward speed std; ``force_std``: the measured force's per-period std,
    integrated into ``I`` and scaled by the model's residual ratio: where the wrench misfits the motion, as when
    the arm saturates, its impulse is trusted that much less). The jump is a load put in when the cart moved (both sides the same sign), slowed
    (``r > 1``), and ``r - 1`` is at least ``min_change`` and ``sigma`` times the ratio's std. A load lifted out
    leaves with its own momentum (no jump): the regression's tests find it.
    """

    def __init__(
        self,
        side_s: float = 0.1,
        min_change: float = 0.08,
        sigma: float = 3.0,
        speed_std: float = 0.0,
        force_std: float = 0.0,
    ) -> None:
        if not (side_s > 0.0 and min_change >= 0.0 and sigma >= 0.0 and speed_std >= 0.0 and force_std >= 0.0):
            raise ValueError(
                "MomentumTest needs side_s > 0 and min_change, sigma, speed_std, force_std >= 0; got "
                f"{side_s}, {min_change}, {sigma}, {speed_std}, {force_std}"
            )
        self.side_s = float(side_s)
        self.min_change = float(min_change)
        self.sigma = float(sigma)
        self.speed_std = float(speed_std)
        self.force_std = float(force_std)
        self._rows: list[tuple[float, float, float, float]] = []  # (t, v, omega, impulse I(t))
        self._impulse = 0.0
        self._armed: tuple[float, float, float, float] | None = None  # (t, mass before, dy before, misfit)
        self.tested: list[tuple[float, float, float]] = []  # (impulse time, ratio, its std) of every jump tested

    def add(self, t: float, v: float, omega: float = 0.0, force: float = 0.0) -> None:
        """Store the forward speed ``v`` (m/s) and yaw rate ``omega`` (rad/s) at ``t`` (s), with the measured net
        forward force ``force`` (N) held over the period ending at ``t``; forget what lies more than ``2 side_s``
        back."""
        t = float(t)
        if self._rows:
            self._impulse += float(force) * (t - self._rows[-1][0])
        self._rows.append((t, float(v), float(omega), self._impulse))
        while self._rows[0][0] < t - 2.0 * self.side_s - 1e-9:
            del self._rows[0]

    def arm(
        self, t: float, mass: float = math.inf, dy: float = 0.0, misfit: float = 1.0, force_std: float | None = None
    ) -> None:
        """Mark an impulse at ``t`` (the first sample after the jump): :meth:`check` tests it ``side_s`` later.

        ``mass`` (kg) and ``dy`` (m): the estimate before it (``mass`` inf: the measured impulse is not used);
        ``misfit``: the model's residual ratio (at least 1): the measured force explains the motion that many
        times worse than its sensor noise says, and the force's std is scaled by it; ``force_std`` (N): the
        force's per-period std now (measured online by the estimator; None: the one given at construction)."""
        if force_std is not None:
            if not (math.isfinite(force_std) and force_std >= 0.0):
                raise ValueError(f"MomentumTest.arm needs force_std >= 0, got {force_std}")
            self.force_std = float(force_std)
        self._armed = (float(t), float(mass), float(dy), max(float(misfit), 1.0))

    def check(self, t: float) -> tuple[float, float, float] | None:
        """Return (impulse time, mass ratio ``m_after / m_before``, its std) of a load put in at the armed impulse
        once ``side_s`` of samples follow it (None: nothing armed, too early, or no load put in)."""
        if self._armed is None or t < self._armed[0] + self.side_s - 1e-9:
            return None
        t_imp, mass, dy, misfit = self._armed
        self._armed = None
        rows = np.asarray(self._rows)
        before = rows[:, 0] < t_imp - 1e-9
        if before.sum() < 3 or (~before).sum() < 3:
            return None
        k = int(before.sum())  # the impulse's sample: the jump lies in the period before it
        t_jump = 0.5 * (t_imp + float(rows[k - 1, 0]))
        i_jump = 0.5 * (rows[k - 1, 3] + rows[k, 3])
        u = rows[:, 1] - dy * rows[:, 2] - (rows[:, 3] - i_jump) / mass
        # predicted noise of u: the speed's, and the force's integrated from the jump (a random walk)
        steps = np.abs(np.arange(len(u)) - (k - 0.5))
        var = self.speed_std**2 + steps * (misfit * self.force_std * np.diff(rows[:, 0]).mean() / mass) ** 2
        ub, sb = _line_at(rows[before, 0], u[before], t_jump, var[before])
        ua, sa = _line_at(rows[~before, 0], u[~before], t_jump, var[~before])
        if ub * ua <= 0.0:
            return None
        ratio = ub / ua
        std = abs(ratio) * math.hypot(sb / ub, sa / ua)
        self.tested.append((t_imp, ratio, std))
        if ratio - 1.0 < max(self.min_change, self.sigma * std):
            return None
        return t_imp, ratio, std


def _line_at(t: np.ndarray, v: np.ndarray, t0: float, var_pred: np.ndarray | float = 0.0) -> tuple[float, float]:
    """Return the value at ``t0`` of the least-squares line through (t, v) and its std: the residual variance, or
    the predicted per-sample variance ``var_pred`` (its mean) where that is larger."""
    a = np.column_stack([np.ones_like(t), t - t0])
    coef = np.linalg.lstsq(a, v, rcond=None)[0]
    r = v - a @ coef
    var = max(float(r @ r) / max(len(t) - 2, 1), float(np.mean(var_pred)))
    return float(coef[0]), math.sqrt(max(var * float(np.linalg.inv(a.T @ a)[0, 0]), 0.0))

"""Recursive filtered-regressor least squares with a physical prior: the online form of :mod:`cart.identify`.

The equations of motion are linear in ``p = [m, m dx, m dy, J, c_v, c_w]``
(:func:`cart.dynamics.regressor`, body-frame form of paper eq. 4):
``Y(v, omega, vdot, omegadot) p = [F_u, tau]``. As in :func:`cart.identify.identify`
the measured wrench is the regression's *output* (its noise leaves the estimate
unbiased) and both sides pass through the same low-pass filter ("parallel
filtering"); here the filter is causal: a 3rd-order Butterworth state-variable
filter (:class:`StateVariableFilter`) whose states give the filtered signal and
its derivative without numerical differentiation.

:class:`RecursiveRegression` accumulates the weighted normal equations (with
exponential forgetting of the *data* only) and returns the maximum a-posteriori
estimate under a Gaussian prior on the *physical* parameters
``(m, dx, dy, rho = J / m, c_v, c_w)``: one Gauss-Newton step per sample from
the last estimate. A direction the motion does not excite keeps the prior's
value and variance (a straight push leaves ``dx`` and ``J`` at the guess).
The known power of the differentiated pose noise is removed from the normal
matrix (bias-compensated least squares, as in ``identify``). An optional identifiability gate
(``excitation_margin``, off by default) leaves to the prior every direction the data know less
well than the prior does: a model misfit biases a weakly excited direction most.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm, get_lapack_funcs, solve_discrete_lyapunov

from cart.errors import CartError, NumericalError
from cart.online_casters import Nuisance
from cart.small_linalg import solve_small

#: Names of the physical prior variables of :class:`PhysicalPrior`.
PRIOR_NAMES = ("m", "dx", "dy", "rho", "c_v", "c_w")
#: Relative change of the period below which the filter's discretization is reused (timestamps' rounding).
DT_REL_TOL = 1e-6
#: The prior is linearized at a mass of at least this share of its center (an estimate may run negative).
MIN_MASS_SHARE = 0.05
#: A direction of the regression is used when its data power is above (1 + this) times the regressor-noise power (10 dB).
SIGNAL_MARGIN = 9.0
#: A direction used (above ``SIGNAL_MARGIN``) for ``SIGNAL_HOLD_SOLVES`` solves in a row is established: it stays used
#: while its data power is above (1 + this) times the noise power (a long creep adds noise power and no signal, so
#: the ratio of a direction the pushes excited falls with time).
SIGNAL_HOLD = 4.0
#: Solves (samples) in a row a direction must pass ``SIGNAL_MARGIN`` to be established (2 s at 100 Hz).
SIGNAL_HOLD_SOLVES = 200
#: The identifiability gate's margin for an estimate from the initial guess (``excitation_margin`` of
#: :class:`RecursiveRegression`): a direction of the data is used only beyond the prior's information in it, by this
#: many prior units (soft threshold, :meth:`RecursiveRegression.excited_part`).
EXCITATION_MARGIN = 1.0
#: Largest share of a diagonal entry of the normal matrix that the noise correction removes.
COMPENSATION_SHARE = 0.98

# LAPACK's symmetric-definite generalized eigensolver (the driver scipy.linalg.eigh(a, b) calls) and the Cholesky
# solve: called directly, without scipy's per-call checks (6 x 6 per step)
_SYGVD, _POTRF, _POTRS = get_lapack_funcs(("sygvd", "potrf", "potrs"), (np.zeros((1, 1)),))
_EYE6 = np.eye(6)
_DIAG6 = np.arange(6) * 7  # the diagonal of a flattened 6 x 6


def cholesky_small(a: np.ndarray) -> np.ndarray:
    """Return ``np.linalg.cholesky(a)`` (lower; LAPACK's potrf, the routine numpy calls, without its per-call
    wrapping); raises ``np.linalg.LinAlgError`` when ``a`` is not positive definite."""
    chol, info = _POTRF(a, lower=1, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError("Matrix is not positive definite")
    return chol


def _generalized_eigh(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (w, v) of ``a v = b v w`` (a, b symmetric, b definite; lower triangles), as ``scipy.linalg.eigh(a, b)``.

    Raises ValueError on a non-finite entry and ``np.linalg.LinAlgError`` when LAPACK fails (b not definite)."""
    if not math.isfinite(float(a.sum()) + float(b.sum())):
        raise ValueError("array must not contain infs or NaNs")
    w, v, info = _SYGVD(a, b, itype=1, jobz="V", uplo="L")
    if info != 0:
        raise np.linalg.LinAlgError(f"the generalized eigenproblem failed (LAPACK sygvd info {info})")
    return w, v


#: A direction is one of the established ones (:meth:`RecursiveRegression._kept_count`) when its functional's share in
#: their span (the cosine of the angle to it, in the units of `_units`) is at least this.
HOLD_ALIGNMENT = 0.9


def _units(cv: np.ndarray) -> np.ndarray:
    """Return the columns of ``cv`` (data functionals C v) scaled to unit length, rows by their columns' RMS (the
    parameters' units made comparable)."""
    rows = np.sqrt(np.mean(cv**2, axis=1)) + 1e-300
    u = cv / rows[:, None]
    return u / (np.linalg.norm(u, axis=0) + 1e-300)


def _aligned(u: np.ndarray, basis: np.ndarray | None) -> bool:
    """Return whether the unit vector ``u`` lies within ``HOLD_ALIGNMENT`` of the span of ``basis``."""
    return basis is not None and float(np.linalg.norm(basis.T @ u)) >= HOLD_ALIGNMENT


class OnlineEstimatorError(CartError):
    """Bad input to the online estimator (shape, non-finite value, non-positive time step, option)."""


class StateVariableFilter:
    """Causal 3rd-order Butterworth low-pass per channel; states (y, y', y'') of y = L[u] (ZOH-discretized).

    ``y`` is the filtered signal and ``y'`` = s L[u] its derivative, both from the
    filter's states: the derivative of a noisy input is never formed.
    """

    def __init__(self, cutoff_hz: float, channels: int) -> None:
        if not (math.isfinite(cutoff_hz) and cutoff_hz > 0.0):
            raise OnlineEstimatorError(f"cutoff_hz must be positive and finite, got {cutoff_hz}")
        w = 2.0 * math.pi * float(cutoff_hz)
        # y''' = w^3 (u - y) - 2 w^2 y' - 2 w y'': the Butterworth polynomial s^3 + 2 w s^2 + 2 w^2 s + w^3
        self.a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-(w**3), -2.0 * w * w, -2.0 * w]])
        self.b = np.array([0.0, 0.0, w**3])
        self.cutoff_hz = float(cutoff_hz)
        self.state = np.zeros((3, channels))
        self._dt = -1.0
        self._ad = np.eye(3)
        self._bd = np.zeros(3)

    def discretize(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Return (Ad, Bd) of the zero-order-hold discretization at period dt (cached; kept for a dt equal up to rounding)."""
        if not abs(dt - self._dt) <= DT_REL_TOL * dt:
            m = np.zeros((4, 4))
            m[:3, :3] = self.a * dt
            m[:3, 3] = self.b * dt
            e = expm(m)
            self._ad, self._bd, self._dt = e[:3, :3], e[:3, 3].copy(), dt
        return self._ad, self._bd

    def reset(self, u: np.ndarray) -> None:
        """Set every channel at rest on its input (y = u, derivatives 0): no start-up transient."""
        self.state[...] = 0.0
        self.state[0] = u

    def step(self, u: np.ndarray, dt: float) -> np.ndarray:
        """Advance over dt with the input u held; return the states (3, channels)."""
        ad, bd = self.discretize(dt)
        self.state = ad @ self.state + bd[:, None] * u[None, :]
        return self.state

    def noise_gains(self, dt: float) -> tuple[float, float]:
        """Return (var of y, var of y') per unit variance of white input samples at period dt (discrete Lyapunov)."""
        ad, bd = self.discretize(dt)
        p = solve_discrete_lyapunov(ad, np.outer(bd, bd))
        return float(p[0, 0]), float(p[1, 1])


@dataclass(frozen=True)
class PhysicalPrior:
    """Independent Gaussian prior on (m, dx, dy, rho = J / m, c_v, c_w): ``center`` and ``std`` (6,)."""

    center: np.ndarray
    std: np.ndarray
    _inv_std: np.ndarray = field(init=False, repr=False, compare=False)  # the identity's rows over the stds

    def __post_init__(self) -> None:
        c, s = np.asarray(self.center, float), np.asarray(self.std, float)
        if c.shape != (6,) or s.shape != (6,) or not (np.all(np.isfinite(c)) and np.all(np.isfinite(s))):
            raise OnlineEstimatorError("the prior needs 6 finite centers and stds (m, dx, dy, rho, c_v, c_w)")
        if not (np.all(s > 0.0) and c[0] > 0.0):
            raise OnlineEstimatorError(f"the prior needs a positive mass and positive stds, got {c}, {s}")
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "std", s)
        object.__setattr__(self, "_inv_std", np.eye(6) / s[:, None])

    def residual(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return (r, dr/dp): the prior's whitened residual at p = [m, a, b, J, c_v, c_w] and its Jacobian."""
        m = max(float(p[0]), MIN_MASS_SHARE * float(self.center[0]))  # linearized at a positive mass
        a, b, j, cv, cw = p[1:].tolist()
        phys = np.array([m, a / m, b / m, j / m, cv, cw])
        s1, s2, s3 = self.std[1:4].tolist()
        jac = self._inv_std.copy()  # the identity's rows over the stds
        jac[1, 0], jac[2, 0], jac[3, 0] = -a / m**2 / s1, -b / m**2 / s2, -j / m**2 / s3
        jac[1, 1], jac[2, 2], jac[3, 3] = 1.0 / m / s1, 1.0 / m / s2, 1.0 / m / s3
        return (phys - self.center) / self.std, jac

    def p(self) -> np.ndarray:
        """Return the prior's center as p = [m, m dx, m dy, m rho, c_v, c_w]."""
        m, dx, dy, rho, cv, cw = self.center
        return np.array([m, m * dx, m * dy, m * rho, cv, cw])


class RecursiveRegression:
    """Weighted normal equations with forgetting of the data, solved for the MAP estimate under a physical prior.

    ``D = sum w_k Y_k^T W_k Y_k``, ``d = sum w_k Y_k^T W_k y_k`` and the noise correction ``C``
    (the regressor-noise power, removed from ``D``) decay by ``lam`` per sample; the prior does
    not decay, so an unexcited direction returns to (and stays at) the prior.
    """

    def __init__(self, prior: PhysicalPrior, noise_subspace: bool = True, excitation_margin: float = 0.0) -> None:
        if not (math.isfinite(excitation_margin) and excitation_margin >= 0.0):
            raise OnlineEstimatorError(f"excitation_margin must be >= 0 and finite, got {excitation_margin}")
        self.prior = prior
        self.noise_subspace = bool(noise_subspace)
        self.excitation_margin = float(excitation_margin)
        self.kept_directions = 0
        self.D = np.zeros((6, 6))
        self.d = np.zeros(6)
        self.C = np.zeros((6, 6))
        self.p = prior.p()
        self.H = np.eye(6)
        self.compensated = True
        self.nuisance: Nuisance | None = None
        self.data_weight = 1.0
        self.excitation = np.zeros(6)
        self.established = 0  # directions held down to SIGNAL_HOLD (:meth:`signal_part`)
        self._streak: deque[int] = deque(maxlen=SIGNAL_HOLD_SOLVES)  # directions above SIGNAL_MARGIN at the last solves
        self._basis: np.ndarray | None = None  # the established directions' functionals (`_units`), orthonormal
        self.solve(iterations=3)

    def normal(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the data's normal equations (D, d) of p, with the nuisance columns eliminated when set.

        Both are scaled by ``data_weight`` (1: the noise model's weights; 1 / kappa^2: a model that misfits by
        the residual ratio kappa, whose data carry kappa^2 less information than the noise model says).
        """
        d_mat, d_vec = (self.D, self.d) if self.nuisance is None else self.nuisance.eliminate(self.D, self.d)
        if self.data_weight == 1.0:
            return d_mat.copy(), d_vec.copy()
        return d_mat * self.data_weight, d_vec * self.data_weight

    def add(self, info: np.ndarray, dvec: np.ndarray, noise: np.ndarray, lam: float) -> None:
        """Accumulate one sample: ``info = Y^T W Y`` (6, 6), ``dvec = Y^T W y`` (6,), regressor-noise power (6, 6)."""
        self.D *= lam
        self.D += info
        self.d *= lam
        self.d += dvec
        self.C *= lam
        self.C += noise

    def solve(self, iterations: int = 1) -> np.ndarray:
        """Return the MAP estimate after Gauss-Newton steps from the current one; sets H (the posterior information)."""
        d_mat, d_vec = self.normal()
        sd, sv = self.signal_part(d_mat, d_vec) if self.noise_subspace else (d_mat - self.compensation(d_mat), d_vec)
        for _ in range(iterations):
            r, jr = self.prior.residual(self.p)
            dd, dv = self.excited_part(sd, sv, jr)
            h = dd + jr.T @ jr
            try:
                chol = cholesky_small(h)
                self.compensated = True
            except np.linalg.LinAlgError:  # the noise correction overshoots on little data: drop it
                dd, dv = self.excited_part(d_mat, d_vec, jr)
                h = dd + jr.T @ jr
                h += np.diag(1e-12 * np.diag(h))
                chol = cholesky_small(h)
                self.compensated = False
            g = h @ self.p - (dv + jr.T @ (jr @ self.p - r))
            step = _POTRS(chol, g, lower=1)[0]
            if not math.isfinite(float(step.sum())):
                raise NumericalError("the online regression diverged (non-finite step)")
            self.p = self.p - step
            self.H = h
            if abs(float(step[0])) <= 1e-9 * abs(float(self.p[0])):
                break
        return self.p

    def excited_part(self, dd: np.ndarray, dv: np.ndarray, jr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return (D', d'): the normal equations with each direction's information less ``excitation_margin`` prior units.

        In the prior's whitened coordinates u = J_r p (J_r: the prior residual's Jacobian at the estimate, whose
        information J_r^T J_r is the prior's), the data's information has eigenvalues mu (in units of the prior's)
        along eigenvectors e. Each keeps max(mu - margin, 0) of its information and the data's
        estimate along it (d' is scaled alike): a direction the motion excites less than the prior knows it keeps
        the prior's value and std (a straight push's dx, the yaw rate's corrections on a real cart, whose model
        misfit biases a weak direction most), one it excites well loses a prior unit of information (continuous,
        no switching). ``excitation`` holds mu after each solve (zeros with the gate off, margin 0).
        """
        margin = self.excitation_margin
        if margin <= 0.0:
            return dd, dv
        l_inv = np.linalg.inv(jr)
        dw = l_inv.T @ dd @ l_inv
        mu, e = np.linalg.eigh(0.5 * (dw + dw.T))
        self.excitation = mu
        keep = np.where(mu > margin, 1.0 - margin / np.maximum(mu, 1e-300), 0.0)
        ej = e.T @ jr
        return (ej.T * (mu * keep)) @ ej, ej.T @ (keep * (e.T @ (l_inv.T @ dv)))

    def signal_part(self, d_mat: np.ndarray, d_vec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return (D', d'): the normal equations restricted to the directions where the signal beats the noise.

        With the generalized eigenvectors D V = C V Lambda (V^T C V = I), a direction whose data power
        is at most ``1 + SIGNAL_MARGIN`` times the regressor-noise power C carries no usable information:
        it is dropped from both D and d (the prior then holds it). The others keep D - C (bias-compensated).
        """
        scale = np.maximum(np.diag(d_mat), 1e-300)
        c_reg = self.C * self.data_weight
        c_reg.flat[_DIAG6] += 1e-6 * scale + 1e-300
        try:
            lam, v = _generalized_eigh(d_mat, c_reg)
        except np.linalg.LinAlgError:
            return d_mat - self.compensation(d_mat), d_vec
        n_keep = self._kept_count(lam, c_reg @ v)
        keep = np.arange(lam.size) >= lam.size - n_keep  # lam ascending: the n_keep strongest
        cv = c_reg @ v[:, keep]
        dd = (cv * (lam[keep] - 1.0)) @ cv.T
        dv = cv @ (v[:, keep].T @ d_vec)
        self.kept_directions = int(keep.sum())
        return dd, dv

    def _kept_count(self, lam: np.ndarray, cv: np.ndarray) -> int:
        """Return how many of the strongest directions (generalized eigenvalues ``lam``, ascending; ``cv`` = C V,
        the data functionals they measure) to use: those above ``1 + SIGNAL_MARGIN``, and the established ones
        while above ``1 + SIGNAL_HOLD``. The directions above the margin at each of the last
        ``SIGNAL_HOLD_SOLVES`` solves are established (a noise-driven direction that passes the margin on the
        first few samples is not); a direction is held only while it is one of them (``HOLD_ALIGNMENT``): the
        strongest directions' order changes as the motion does, and a weaker one that took an established one's
        rank carries no more signal than any other below the margin."""
        n_new = int(np.sum(lam > 1.0 + SIGNAL_MARGIN))
        units = _units(cv)
        n_keep = n_new
        n_hold = min(self.established, int(np.sum(lam > 1.0 + SIGNAL_HOLD)))
        while n_keep < n_hold and _aligned(units[:, lam.size - 1 - n_keep], self._basis):
            n_keep += 1
        self.established = min(self.established, n_keep)
        self._streak.append(n_new)
        if len(self._streak) == SIGNAL_HOLD_SOLVES and min(self._streak) >= self.established:
            self.established = min(self._streak)
            self._basis = np.linalg.qr(units[:, lam.size - self.established :])[0] if self.established else None
        return n_keep

    def compensation(self, d_mat: np.ndarray | None = None) -> np.ndarray:
        """Return the noise correction removed from D: C scaled so that at most COMPENSATION_SHARE of each diagonal goes.

        On little data the regressor-noise power in D fluctuates around its expectation C; removing
        all of it could leave a direction with negative information.
        """
        c_diag = np.diag(self.C) * self.data_weight
        d_diag = np.diag(self.D if d_mat is None else d_mat)
        scale = np.sqrt(np.minimum(1.0, COMPENSATION_SHARE * d_diag / np.maximum(c_diag, 1e-300)))
        return self.C * self.data_weight * np.outer(scale, scale)

    def covariance(self) -> np.ndarray:
        """Return the posterior covariance of p (the inverse of the last information matrix H)."""
        return solve_small(self.H, _EYE6)

    def prior_covariance(self) -> np.ndarray:
        """Return the covariance of p under the prior alone, linearized at the current estimate."""
        _, jr = self.prior.residual(self.p)
        return np.linalg.inv(jr.T @ jr)


class ResidualWindow:
    """Exponentially weighted residual power of the regression's rows, evaluated at any estimate p.

    Per row i the window keeps ``sum lam^(n-k) [y_i^2, y_i Y_i, Y_i^T Y_i] / e_i`` (``e_i``: the row's noise
    variance), so ``ratio2(p)``, the windowed mean of ``(y_i - Y_i p)^2 / e_i`` (largest row), is the residual
    power of the *current* estimate over the window: the model's misfit, not the estimate's past errors (a guess
    far off that the data have since corrected raises nothing).
    """

    def __init__(self, time_s: float) -> None:
        if not (math.isfinite(time_s) and time_s > 0.0):
            raise OnlineEstimatorError(f"the residual window needs a positive time constant, got {time_s}")
        self.time_s = float(time_s)
        self.clear()

    def clear(self) -> None:
        """Forget every sample."""
        self.weight = 0.0
        self.elapsed = 0.0
        self.yy = np.zeros(2)
        self.yY = np.zeros((2, 6))
        self.YY = np.zeros((2, 6, 6))

    def add(self, rows: np.ndarray, y: np.ndarray, e: np.ndarray, dt: float) -> None:
        """Add one sample: rows Y (2, 6), outputs y (2,), noise variances e (2,), after a period dt."""
        lam = math.exp(-dt / self.time_s)
        self.weight = lam * self.weight + 1.0
        self.elapsed += dt if math.isfinite(dt) else 0.0
        self.yy = lam * self.yy + y * y / e
        self.yY = lam * self.yY + rows * (y / e)[:, None]
        self.YY = lam * self.YY + rows[:, :, None] * rows[:, None, :] / e[:, None, None]

    def ratio2(self, p: np.ndarray, info: np.ndarray | None = None) -> float:
        """Return the squared residual ratio over the window (largest row; 1 before any sample).

        At p, or with ``info`` (the information (6, 6) behind p) at the estimate the window's samples would give
        added to it at full weight: the model's misfit once the window has had its say (an estimate the data are
        still correcting, or that weighted samples left behind, raises nothing by itself).
        """
        if self.weight <= 0.0:
            return 1.0
        if info is not None:
            a = info + self.YY[0] + self.YY[1]
            a.flat[_DIAG6] += 1e-12 * np.diag(a) + 1e-300
            p = solve_small(a, info @ p + self.yY[0] + self.yY[1])
        power = self.yy - 2.0 * self.yY @ p + (self.YY @ p) @ p
        return float(np.max(power)) / self.weight


class MisfitLevel:
    """The run's typical squared residual ratio since the last change: a quantile of the samples' values, at least 1.

    Feasible weighted least squares with a scale that varies over the run: the noise model gives the rows'
    weights, a sample whose local residual ratio kappa^2 (:meth:`ResidualWindow.ratio2`) is above the run's level
    kappa_ref^2 carries kappa_ref^2 / kappa^2 of the information of the others. A model that misfits uniformly
    (the noise model off by a factor) has kappa = kappa_ref everywhere: its samples keep their relative weights,
    and the level is a property of the whole fit (its stds scale by kappa_ref), not a reason to prefer the prior.
    ``quantile`` (0-1) of the values added since :meth:`clear`; 1 before any. A low quantile is the level of the
    stretches that fit best, the noise model's factor: the weights keep the ratios 1 / kappa^2 between the samples
    above it, and a run most of which misfits more (a cart whose casters swing round in every turn, start and stop)
    does not take its excess for the level, as the median would.
    """

    def __init__(self, quantile: float = 0.05) -> None:
        if not (0.0 <= quantile <= 1.0):
            raise OnlineEstimatorError(f"the misfit level's quantile must be in [0, 1], got {quantile}")
        self.quantile = float(quantile)
        self.clear()

    def clear(self) -> None:
        """Forget every value."""
        self._values: list[float] = []

    def add(self, ratio2: float) -> None:
        """Add one sample's squared residual ratio (a non-finite value is ignored)."""
        if math.isfinite(ratio2):
            bisect.insort(self._values, float(ratio2))

    def level2(self) -> float:
        """Return the squared level: the quantile of the values so far (lower one), at least 1 (1 with none)."""
        if not self._values:
            return 1.0
        k = int(math.floor(self.quantile * (len(self._values) - 1)))
        return max(1.0, self._values[k])

"""Continuous-discrete EKF with the augmented state [q, qd, phi] (paper §II.B, eq. 8-20).

State ``x = [x, y, theta, vx, vy, omega, m, m dx, m dy, J]`` (+ ``[sigma, sigma_yaw]`` when
``estimate_sigma``), measurement ``z = [x, y, theta, vx, vy, omega]`` (eq. 10,
``H = [I_6 0]``). The process model is the *exact* constrained dynamics
(:func:`cart.dynamics.forward_dynamics`), with its analytic Jacobian F
(eq. 11). Prediction: Euler step of the state (eq. 16) and
``P <- Phi (P + Q dt) Phi^T`` with ``Phi = I + F dt`` (the first-order
discretisation of eq. 13/17 that keeps P positive semi-definite; the plain
Euler step of the Riccati equation does not when the parameter variance is
large). Update: Kalman gain (eq. 18-19) with the heading innovation wrapped to
(-pi, pi], ``P <- P - K H P`` (eq. 20) and symmetrisation; phi is then
projected to m >= min_mass, I >= min_inertia. Each update returns the
normalized innovation squared (NIS, chi-square with 6 dof when consistent).

The hot path (:meth:`CartEKF.step`) uses plain floats for f and F, the
sparsity of F (rows 0-2 are a selector, rows 6.. zero) and of H, one LAPACK
``dposv`` for gain and NIS, and preallocated arrays updated in place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from scipy.linalg import cho_factor as _cho_factor, cho_solve as _cho_solve
from scipy.linalg.lapack import dposv as _dposv, dtrtrs as _dtrtrs

from cart._kernels_identify import median
from cart.dynamics import dynamics_jacobian_rows, wrench_input_matrix as _wrench_input_matrix
from cart.errors import NumericalError, ParameterError
from cart.params import CartParams

N_MEAS = 6
#: The fused step symmetrises P every this many updates (and whenever P is read through
#: ``CartEKF.P``): between two, P carries only the rounding asymmetry of the updates
#: (~1e-16 relative), which the Cholesky solve does not see (it reads one triangle of S).
SYMMETRIZE_EVERY = 8
#: Most sub-steps one long interval of a log is split into by :func:`run_ekf` (bounds the work of a huge gap).
MAX_GAP_SUBSTEPS = 10_000


def chi2_isf(alpha: float, dof: int) -> float:
    """Return the chi-square quantile x with P(X > x) = alpha for ``dof`` degrees of freedom.

    Even ``dof`` (the EKF's 6) in closed form, Q(x) = exp(-x/2) sum_{i < dof/2} (x/2)^i / i!,
    solved by bisection on ln Q (no scipy.stats import: it costs ~1 s of start-up); odd ``dof`` via scipy.
    """
    if not 0.0 < alpha < 1.0:
        raise ParameterError(f"chi-square tail probability must be in (0, 1), got {alpha}")
    if dof % 2:
        from scipy.stats import chi2

        return float(chi2.isf(alpha, dof))

    def log_q(x: float) -> float:
        h = 0.5 * x
        term, total = 1.0, 1.0
        for i in range(1, dof // 2):
            term *= h / i
            total += term
        return -h + math.log(total)

    from cart._kernels_identify import bisect_increasing

    return bisect_increasing(lambda x: -log_q(x), -math.log(alpha), 1e-12)


@dataclass(frozen=True)
class EKFConfig:
    """Noise model of the EKF: measurement std (R), process noise densities (Q), limits.

    ``meas_std``: std of (x, y, theta, vx, vy, omega). ``q_pos`` (m^2/s),
    ``q_vel`` (m^2/s^3), ``q_omega`` (rad^2/s^3): white noise on the kinematics
    (unmodelled forces). ``q_phi``: random-walk densities of
    (m, m dx, m dy, J) per second, ``q_sigma`` the same for sigma.

    ``change_detection``: detect a parameter change (e.g. a payload) from the
    innovations and then reset the parameter variances to at least their
    prior (P0), so the filter re-learns them; see :meth:`CartEKF.step`. The
    test is on the mean of the innovations over non-overlapping windows of
    ``change_window`` updates, at false-alarm probability ``change_alpha`` per
    window.

    ``adaptive_q_tau`` (s; 0 = off, the paper's filter): process noise on the velocities that adapts to
    a bias of their innovations (see :meth:`CartEKF.adapt_process_noise`): the exponential mean of each
    normalized innovation of vx, vy, omega over ``adaptive_q_tau`` seconds, squared and normalized to
    chi-square with 1 dof, scales the next prediction's ``q_vel`` / ``q_omega`` (by at least 1). A
    model error that persists (a cart turning faster than the wrench predicts) raises the velocity
    covariance within a few periods, so the filter follows the motion capture with a larger gain instead
    of gating it and then snapping to it after ``gate_max_consecutive`` rejections.
    """

    meas_std: tuple[float, ...] = (0.005, 0.005, 0.005, 0.005, 0.005, 0.005)
    q_pos: float = 1e-8
    q_vel: float = 1e-5
    q_omega: float = 1e-5
    q_phi: tuple[float, float, float, float] = (0.005, 0.005, 0.005, 0.005)
    q_sigma: float = 0.01
    estimate_params: bool = True
    estimate_sigma: bool = False
    min_mass: float = 0.1
    min_inertia: float = 1e-3
    change_detection: bool = False
    change_window: int = 50
    change_alpha: float = 1e-6
    change_converged: float = 0.1
    gate_alpha: float = 1e-6
    gate_max_consecutive: int = 5
    gap_factor: float = 5.0
    adaptive_q_tau: float = 0.0

    @classmethod
    def from_noise(cls, meas_std: Sequence[float] | np.ndarray, **kwargs) -> EKFConfig:
        """Return a config whose R comes from the measurement std (floored at 1e-6)."""
        return cls(meas_std=tuple(max(float(s), 1e-6) for s in meas_std), **kwargs)


def initial_covariance(
    phi0: np.ndarray,
    meas_std: Sequence[float] | np.ndarray,
    sigma0: float = 0.0,
    estimate_sigma: bool = False,
    mass_rel_std: float = 0.5,
    com_std: float = 0.2,
) -> np.ndarray:
    """Return a diagonal P0: the measurement variances for q, qd; a prior on phi from a guess.

    mass std = mass_rel_std * m0; first moments std = m0 * com_std; J std = 0.5 J0 + m0 com_std^2.
    """
    m0 = float(phi0[0])
    diag = [s * s for s in meas_std]
    diag += [
        (mass_rel_std * m0) ** 2,
        (m0 * com_std) ** 2,
        (m0 * com_std) ** 2,
        (0.5 * float(phi0[3]) + m0 * com_std**2) ** 2,
    ]
    if estimate_sigma:
        diag += [max(0.5 * sigma0, 1.0) ** 2, max(0.5 * sigma0, 1.0) ** 2]
    return np.diag(diag)


def dynamics_jacobian(
    x: np.ndarray,
    gamma: Sequence[float] | np.ndarray,
    sigma: float,
    out_f: np.ndarray,
    with_sigma: bool,
    sigma_yaw: float | None = None,
) -> tuple[float, float, float]:
    """Return (xdd, ydd, thetadd) at state x and write rows 3..5 of F = df/dx into ``out_f``.

    Exact constrained dynamics (:func:`cart.dynamics.dynamics_jacobian_rows`); columns are the
    state order [x, y, theta, vx, vy, omega, m, a, b, J, (sigma, sigma_yaw)].
    """
    sw = sigma if sigma_yaw is None else sigma_yaw
    xdd, ydd, od, rows = dynamics_jacobian_rows(x, gamma, sigma, sw, with_sigma)
    n = len(rows) // 3
    out_f[3:6, :n] = (rows[:n], rows[n : 2 * n], rows[2 * n :])
    return xdd, ydd, od


def wrench_input_matrix(x: np.ndarray) -> np.ndarray:
    """Return B = d(xdd, ydd, thetadd) / d(fx, fy, tau) at state x (:func:`cart.dynamics.wrench_input_matrix`)."""
    return _wrench_input_matrix(float(x[2]), float(x[6]), float(x[8]), float(x[9]))


def input_noise_covariance(x: np.ndarray, gamma_cov: np.ndarray, dt: float) -> np.ndarray:
    """Return B gamma_cov B^T dt: the velocity covariance added over dt by white wrench noise (3 x 3)."""
    gamma_cov = np.asarray(gamma_cov, dtype=float)
    if gamma_cov.shape != (3, 3):
        raise ParameterError(f"gamma_cov must be the 3x3 covariance of (fx, fy, tau), got shape {gamma_cov.shape}")
    B = wrench_input_matrix(x)
    return (B @ gamma_cov @ B.T) * dt


class CartEKF:
    """The augmented-state EKF of paper eq. (8-20); see the module docstring."""

    def __init__(
        self,
        q0: npt.ArrayLike,
        qd0: npt.ArrayLike,
        phi0: npt.ArrayLike,
        sigma: float,
        config: EKFConfig = EKFConfig(),
        P0: np.ndarray | None = None,
        sigma_yaw: float | None = None,
    ) -> None:
        self.config = config
        self.with_sigma = bool(config.estimate_sigma)
        self.n = 12 if self.with_sigma else 10
        phi0 = np.asarray(phi0, dtype=float)
        if phi0.shape != (4,) or phi0[0] <= 0.0:
            raise ParameterError(f"initial phi must be [m>0, m dx, m dy, J], got {phi0!r}")
        self.sigma = float(sigma)
        self.sigma_yaw = float(sigma if sigma_yaw is None else sigma_yaw)
        if P0 is None:
            P0 = initial_covariance(phi0, config.meas_std, sigma, self.with_sigma)
        P0 = np.array(P0, dtype=float)
        if P0.shape != (self.n, self.n):
            raise ParameterError(f"P0 must be {self.n}x{self.n}, got {P0.shape}")
        self._init_state(q0, qd0, phi0, P0)
        self._init_noise(config)
        self._init_buffers()
        self._init_monitors(config)

    def _init_state(self, q0: npt.ArrayLike, qd0: npt.ArrayLike, phi0: np.ndarray, P0: np.ndarray) -> None:
        """Allocate A = [x | P] and set x0 = [q0, qd0, phi0 (, sigma, sigma_yaw)] and P0 (eq. 8-9).

        State and covariance share one C-ordered n x (n+1) array A = [x | P], so that the
        measurement update of both is one product and one subtraction (see :meth:`step`).
        """
        n = self.n
        self._A = np.zeros((n, n + 1))
        self._x = self._A[:, 0]
        self._P = self._A[:, 1:]
        self._x[0:3] = q0
        self._x[3:6] = qd0
        self._x[6:10] = phi0
        if self.with_sigma:
            self._x[10:12] = (self.sigma, self.sigma_yaw)
        self._P[...] = P0

    def _init_noise(self, config: EKFConfig) -> None:
        """Set the process-noise density Qc (eq. 13; zero on phi when it is frozen, whose P rows are zeroed) and R."""
        qdiag = [config.q_pos, config.q_pos, config.q_pos, config.q_vel, config.q_vel, config.q_omega]
        if config.estimate_params:
            qdiag += list(config.q_phi)
        else:
            qdiag += [0.0] * 4
            self._P[6:, :] = 0.0
            self._P[:, 6:] = 0.0
        if self.with_sigma:
            qdiag += [config.q_sigma if config.estimate_params else 0.0] * 2
        self.Qc = np.diag(qdiag)
        self._qdiag = np.array(qdiag)
        self.R = np.diag(np.square(np.asarray(config.meas_std, dtype=float)))

    def _init_buffers(self) -> None:
        """Allocate the work buffers of the hot path: views that stay valid (everything is updated in place).

        One flat buffer holds, in this order: Phi6 (rows 0-5 of Phi = I + F dt, C order), the
        state increment of the prediction (6), and [w | T] (6 x (n+1), Fortran order: w = -y, then
        S^-1 (-y); T = rows 0-5 of the predicted P, then S^-1 T). Rows 3-5 of Phi6, the increment
        and w are contiguous, so one assignment writes all three.
        """
        n = self.n
        self._buf = np.zeros(6 * n + 6 + N_MEAS * (n + 1))
        self._phi6 = self._buf[: 6 * n].reshape(N_MEAS, n)
        self._phi6[:] = np.eye(N_MEAS, n)
        self._phi6_t = self._phi6.T
        self._fill = self._buf[3 * n : 6 * n + 12]  # rows 3-5 of Phi6, increment, w
        self._inc = self._buf[6 * n : 6 * n + 6]
        self._tf = self._buf[6 * n + 6 :].reshape((N_MEAS, n + 1), order="F")  # [w | T]
        self._w = self._tf[:, 0]
        self._tt = self._tf.T[1:]  # T^T (n x 6), C-contiguous
        self._tt6 = self._tt[:N_MEAS]  # Phi6 P Phi6^T block
        self._tt_lo = self._tt[N_MEAS:]
        self._sf = np.zeros((N_MEAS, N_MEAS), order="F")  # S, then its Cholesky factor
        self._x6 = self._x[:N_MEAS]
        self._p6 = self._P[:N_MEAS]  # rows 0-5 of P
        self._p6_t = self._p6.T
        self._p_lo = self._P[N_MEAS:, :N_MEAS]
        self._pdiag = self._A.reshape(-1)[1 :: n + 2]  # writable view of P's diagonal
        self._kb = np.empty((n, n + 1))  # [-K y | K T]
        self._dt = 0.0
        self._qdt = np.zeros(n)  # diag(Q) dt
        self._unsym = 0  # updates since P was last symmetrised

    def _init_monitors(self, config: EKFConfig) -> None:
        """Set the projection limits, the NIS gate, the change detection and the robustness counters."""
        self._params_key: list | None = None  # phi (and sigma) of the CartParams cached by params()
        self._params: CartParams | None = None
        self._min_mass = float(config.min_mass)
        self._min_inertia = float(config.min_inertia)
        self.nis = float("nan")
        self._ny = [0.0] * N_MEAS  # minus the last innovation (see step)
        # change detection: innovation sum over the current window, the threshold, the prior variances
        self._ysum = [0.0] * N_MEAS
        self._ycount = 0
        self._change_threshold = chi2_isf(config.change_alpha, N_MEAS)
        self._prior_var = np.diag(self._P)[N_MEAS:].copy() if config.estimate_params else None
        self.changes_detected = 0
        self.change_statistic = float("nan")
        # robustness counters (see EKFConfig): measurements skipped as non-finite, rejected by the gate,
        # accepted after a run of rejections (with P inflated), P repairs (jitter), long intervals split
        self.nonfinite_samples = 0
        self.rejected_samples = 0
        self.forced_accepts = 0
        self.covariance_repairs = 0
        self.gaps = 0
        self.accepted = True  # whether the last step's measurement was used
        alpha = float(config.gate_alpha)
        self._gate = chi2_isf(alpha, N_MEAS) if alpha > 0.0 else math.inf
        self._gate_streak = 0
        self._gate_max = max(int(config.gate_max_consecutive), 0)
        if config.adaptive_q_tau < 0.0 or config.adaptive_q_tau != config.adaptive_q_tau:
            raise ParameterError(f"adaptive_q_tau must be >= 0 (0: off), got {config.adaptive_q_tau}")
        #: the innovation-mean statistics b of vx, vy, omega (chi-square 1 dof when consistent; adaptive_q_tau)
        self.velocity_bias = [0.0, 0.0, 0.0]
        self._innovation_mean = [0.0, 0.0, 0.0]

    # -- accessors ---------------------------------------------------------------------------
    @property
    def x(self) -> np.ndarray:
        """Return the state estimate (the filter's own array, updated in place by each step)."""
        return self._x

    @x.setter
    def x(self, value: npt.ArrayLike) -> None:
        value = np.asarray(value, dtype=float)
        if value.shape != self._x.shape:
            raise ParameterError(f"x must have shape {self._x.shape}, got {value.shape}")
        self._x[...] = value

    @property
    def innovation(self) -> list:
        """Return the last innovation y = z - h(x_pred) (heading wrapped to (-pi, pi])."""
        return [-v for v in self._ny]

    def _symmetrize(self) -> None:
        """P <- (P + P^T) / 2: remove the rounding asymmetry of the last updates (see SYMMETRIZE_EVERY)."""
        P = self._P
        P += P.T
        P *= 0.5
        self._unsym = 0

    @property
    def P(self) -> np.ndarray:
        """Return the state covariance, exactly symmetric (the filter's own array, updated in place by each step)."""
        if self._unsym:
            self._symmetrize()
        return self._P

    @P.setter
    def P(self, value: npt.ArrayLike) -> None:
        value = np.asarray(value, dtype=float)
        if value.shape != self._P.shape:
            raise ParameterError(f"P must be {self._P.shape}, got {value.shape}")
        self._P[...] = value

    @property
    def q(self) -> np.ndarray:
        """Return the estimated pose (x, y, theta)."""
        return self._x[0:3].copy()

    @property
    def qd(self) -> np.ndarray:
        """Return the estimated velocity (vx, vy, omega)."""
        return self._x[3:6].copy()

    @property
    def phi(self) -> np.ndarray:
        """Return the estimated phi = [m, m dx, m dy, J]."""
        return self._x[6:10].copy()

    @property
    def sigma_hat(self) -> float:
        """Return the estimated (or fixed) forward/lateral viscous coefficient (N s/m)."""
        return float(self._x[10]) if self.with_sigma else self.sigma

    @property
    def sigma_yaw_hat(self) -> float:
        """Return the estimated (or fixed) yaw viscous coefficient (N m s/rad)."""
        return float(self._x[11]) if self.with_sigma else self.sigma_yaw

    def params(self) -> CartParams:
        """Return the physical parameters of the current estimate (the same object while phi and sigma stay put)."""
        key = self._x[6:].tolist()
        params = self._params
        # (params is None only before the first call, when the key is None too)
        if params is None or key != self._params_key:  # a frozen phi (no estimation) keeps its CartParams
            params = self._params = CartParams.from_phi(self._x[6:10], self.sigma_hat, self.sigma_yaw_hat)
            self._params_key = key
        return params

    def params_std(self) -> dict:
        """Return the 1-sigma std of m, dx, dy, I (about the CoM) and sigma by linearising the phi map."""
        m, a, b, j = self._x[6:10]
        jac = np.array(
            [
                [1.0, 0.0, 0.0, 0.0],
                [-a / m**2, 1.0 / m, 0.0, 0.0],
                [-b / m**2, 0.0, 1.0 / m, 0.0],
                [(a * a + b * b) / m**2, -2.0 * a / m, -2.0 * b / m, 1.0],
            ]
        )
        cov = jac @ self.P[6:10, 6:10] @ jac.T
        std = np.sqrt(np.maximum(np.diag(cov), 0.0))
        sig = math.sqrt(max(self.P[10, 10], 0.0)) if self.with_sigma else 0.0
        sig_yaw = math.sqrt(max(self.P[11, 11], 0.0)) if self.with_sigma else 0.0
        return {
            "mass": float(std[0]),
            "com": [float(std[1]), float(std[2])],
            "inertia": float(std[3]),
            "sigma": sig,
            "sigma_yaw": sig_yaw,
        }

    def log_det_innovation_covariance(self) -> float:
        """Return ln det S of the last update (from its Cholesky factor)."""
        return 2.0 * float(np.log(np.diagonal(self._sf)).sum())

    # -- filter ------------------------------------------------------------------------------
    def _set_dt(self, dt: float) -> None:
        self._dt = dt
        self._phi6[0, 3] = self._phi6[1, 4] = self._phi6[2, 5] = dt
        np.multiply(self._qdiag, dt, out=self._qdt)

    def adapt_process_noise(self, ny: Sequence[float], s_diag: Sequence[float]) -> None:
        """Scale the velocities' process noise by an innovation-mean test (``EKFConfig.adaptive_q_tau``).

        For a consistent filter the innovations are white with covariance S (Bar-Shalom, Li, Kirubarajan,
        "Estimation with Applications to Tracking and Navigation", 2001, §5.4), so the exponential mean m_i of
        u_i = y_i / sqrt(S_ii) over ``adaptive_q_tau`` seconds (weight beta = dt / tau) has variance
        beta / (2 - beta), and b_i = m_i^2 (2 - beta) / beta is chi-square with 1 dof (mean 1). A model error
        that persists (the prediction lags a turn the wrench model does not explain) biases the innovations
        one way and b_i grows; the next prediction's process noise of vx, vy, omega is the density times
        max(b_i, 1) (covariance matching, R. K. Mehra, "Approaches to adaptive filtering", IEEE TAC 17(5),
        1972), so the gain rises within a few periods and falls back as the bias goes. White noise does not
        bias the mean; each u_i is clipped at the gate's sqrt (Huber), so a lone outlier raises b_i to at
        most about 2 beta gate.
        """
        tau = self.config.adaptive_q_tau
        if tau <= 0.0:
            return
        dt = self._dt
        beta = min(dt / tau, 1.0)
        norm = (2.0 - beta) / beta
        clip = math.sqrt(min(self._gate, 1e6))
        m, b = self._innovation_mean, self.velocity_bias
        for i in range(3):
            s = s_diag[3 + i]
            u = min(max(-ny[3 + i] / math.sqrt(s), -clip), clip) if s > 0.0 else 0.0
            m[i] += beta * (u - m[i])
            b[i] = m[i] * m[i] * norm
            self._qdt[3 + i] = self._qdiag[3 + i] * dt * max(b[i], 1.0)

    def predict(self, gamma: Sequence[float] | np.ndarray, dt: float, gamma_cov: np.ndarray | None = None) -> None:
        """Propagate state (Euler, eq. 16) and covariance (Phi (P + Q dt) Phi^T, Phi = I + F dt, eq. 13/17) over dt.

        F's first three rows are the selector [0 I 0] and its rows 6.. are zero,
        so only the first six rows Phi6 of Phi differ from the identity: with
        T = Phi6 P (one 6 x n product), Phi P Phi^T has the blocks
        [[T Phi6^T, T[:, 6:]], [T[:, 6:]^T, P[6:, 6:]]]. Q dt is added before
        the propagation (first-order equivalent to adding it after). (The plain Euler step of
        the Riccati equation, P + (F P + P F^T) dt, drops F P F^T dt^2 and loses
        positive-definiteness when the parameter variance is large.) ``gamma_cov``: see :meth:`step`.
        """
        x, P = self._x, self._P
        if dt != self._dt:
            self._set_dt(dt)
        q_in = None if gamma_cov is None else input_noise_covariance(x, gamma_cov, dt)
        xdd, ydd, od, rows = dynamics_jacobian_rows(x, gamma, self.sigma, self.sigma_yaw, self.with_sigma, dt, True)
        self._phi6[3:6] = np.reshape(rows, (3, self.n))
        vx, vy, om = x[3:6].tolist()
        x[:6] += (vx * dt, vy * dt, om * dt, xdd * dt, ydd * dt, od * dt)  # eq. (16)
        self._pdiag += self._qdt  # P + Q dt
        if q_in is not None:
            P[3:6, 3:6] += q_in
        phi = self._phi6_full()
        P[...] = phi @ P @ phi.T

    def _phi6_full(self) -> np.ndarray:
        phi = np.eye(self.n)
        phi[:N_MEAS] = self._phi6
        return phi

    @property
    def gate_threshold(self) -> float:
        """Return the NIS above which a measurement is rejected (inf when the gate is off)."""
        return self._gate

    def update(self, z: Sequence[float] | np.ndarray) -> float:
        """Fuse a measurement z = (x, y, theta, vx, vy, omega); return its NIS.

        With H = [I_6 0]: S = P[:6, :6] + R, K = P[:6, :]^T S^-1 (eq. 18),
        x += K y (eq. 19), P -= K P[:6, :] (eq. 20), then P is symmetrised.
        A non-finite z is skipped (NaN returned, counted in ``nonfinite_samples``);
        a z beyond the chi-square gate is rejected (counted in ``rejected_samples``,
        see :class:`EKFConfig`).
        """
        zl = z.tolist() if isinstance(z, np.ndarray) else list(z)
        if not all(math.isfinite(v) for v in zl):
            self.nonfinite_samples += 1
            self.accepted = False
            self.nis = float("nan")
            return self.nis
        return self._update(zl)

    def _cholesky_s(self):
        """Return (Cholesky factor of S = P[:6, :6] + R, lower); repair P (symmetrise, jitter) if S is not PD."""
        P = self._P
        for attempt in range(4):
            S = P[:N_MEAS, :N_MEAS] + self.R
            if np.all(np.isfinite(S)):
                try:
                    return _cho_factor(S, lower=True, check_finite=False)
                except np.linalg.LinAlgError:
                    pass
            else:
                raise NumericalError(
                    "the EKF diverged: its covariance became non-finite (the log's values or "
                    "time steps are out of any plausible range?)"
                )
            self._repair_covariance(attempt)
        raise NumericalError("the EKF's innovation covariance stayed non-positive-definite after repairs")

    def _repair_covariance(self, attempt: int = 0) -> None:
        """Make P symmetric positive definite again: symmetrise, clip its eigenvalues, add diagonal jitter."""
        P = self._P
        if not np.all(np.isfinite(P)):
            raise NumericalError("the EKF diverged: its covariance became non-finite")
        self._symmetrize()
        w, V = np.linalg.eigh(P)
        scale = max(float(np.max(np.abs(w))), 1e-300)
        floor = scale * 1e-12 * (100.0**attempt)
        P[...] = (V * np.maximum(w, floor)) @ V.T
        P += P.T
        P *= 0.5
        self._pdiag += floor
        self.covariance_repairs += 1

    def _update(self, zl: list, inflated: bool = False) -> float:
        """The measurement update of :meth:`update` on a finite z (list), with the gate."""
        x, P = self._x, self._P
        y = [zi - xi for zi, xi in zip(zl, x[:N_MEAS].tolist())]
        y[2] = (y[2] + math.pi) % (2.0 * math.pi) - math.pi
        c, low = self._cholesky_s()
        yv = np.array(y)
        nis = float(yv @ _cho_solve((c, low), yv))
        if nis != nis:
            raise NumericalError("the EKF diverged: its state became non-finite")
        self._ny = [-v for v in y]
        if nis > self._gate and not inflated:
            if self._gate_streak < self._gate_max:
                self._gate_streak += 1
                self.rejected_samples += 1
                self.accepted = False
                self._sf[...] = c
                self.nis = nis
                return nis
            # a run of rejections: a real jump, not a glitch; accept it with the kinematic variances inflated
            self.forced_accepts += 1
            self._pdiag[:N_MEAS] += np.square(yv)
            return self._update(zl, inflated=True)
        self._gate_streak = 0
        self.accepted = True
        k_t = _cho_solve((c, low), P[:N_MEAS])  # K^T = S^-1 P[:6, :]
        self._sf[...] = np.tril(c)
        self.nis = nis
        x += k_t.T @ yv
        P -= P[:N_MEAS].T @ k_t
        P[...] = 0.5 * (P + P.T)
        self._unsym = 0
        self._project()
        if self._prior_var is not None and self.config.change_detection:
            self._detect_change(y, self._prior_var)
        return self.nis

    def _detect_change(self, y: list, prior_var: np.ndarray) -> None:
        """Windowed innovation-mean test; on a detection, reset the parameter variances to their prior.

        For a consistent filter the innovations are white with covariance S, so
        over a window of N updates c = |L^-1 sum(y)|^2 / N (S = L L^T, the last
        update's S standing for the window's) is chi-square with 6 dof
        (innovation mean test, Bar-Shalom, Li, Kirubarajan, "Estimation with
        Applications to Tracking and Navigation", 2001, §5.4). A parameter
        change biases the innovations persistently; c above the 1 - alpha
        quantile triggers P_phi <- P_phi + diag(max(0, P0_phi - diag P_phi)),
        which keeps P positive definite and the estimate itself unchanged.
        """
        s = self._ysum
        for i in range(N_MEAS):
            s[i] += y[i]
        self._ycount += 1
        if self._ycount < self.config.change_window:
            return
        # self._sf holds the Cholesky factor L (lower) of the last S
        u = _dtrtrs(self._sf, np.array(s), lower=1)[0]
        stat = float(u @ u) / self._ycount
        self.change_statistic = stat
        self._ysum = [0.0] * N_MEAS
        self._ycount = 0
        k = N_MEAS + len(prior_var)
        pd = self._pdiag[N_MEAS:k]
        converged = bool(np.all(pd[:4] < self.config.change_converged * prior_var[:4]))
        if stat > self._change_threshold and converged:
            if pd[0] < prior_var[0]:
                pd[0] = prior_var[0]
            self.changes_detected += 1

    def _project(self) -> None:
        x = self._x
        cfg = self.config
        m, a, b, j = x[6:10].tolist()
        if m < cfg.min_mass:
            m = x[6] = cfg.min_mass
        j_min = cfg.min_inertia + (a * a + b * b) / m
        if j < j_min:
            x[9] = j_min
        if self.with_sigma:
            x[10] = max(x[10], 0.0)
            x[11] = max(x[11], 0.0)

    def step(
        self,
        gamma: Sequence[float] | np.ndarray,
        dt: float,
        z: Sequence[float] | np.ndarray,
        gamma_cov: np.ndarray | None = None,
    ) -> float:
        """Predict over dt under gamma, then update with z; return the NIS.

        The same arithmetic as :meth:`predict` then :meth:`update`, fused and in
        place: the predicted covariance's first six rows T = (Phi (P + Q dt) Phi^T)[:6]
        are computed once (as T^T = (P + Q dt) Phi6^T, in a Fortran-ordered buffer
        [w | T] that LAPACK then uses in place); S = T[:, :6] + R; one dposv solves
        S [w' | X] = [-y | T], so K = X^T (eq. 18) and -w' = S^-1 y gives the NIS.
        With A = [x | P] one product T^T [w' | X] = [-K y | K T] and one
        subtraction give x + K y (eq. 19) and P_pred - K T (eq. 20); P is then
        symmetrised.

        ``gamma_cov`` (optional, 3 x 3): covariance of the white noise on the
        measured wrench gamma = (fx, fy, tau) ({s} axes, torque about the {b}
        origin), e.g. the F/T sensor noise mapped through the grasp map of the
        current contact (eq. 23-24). It enters as process noise on the
        velocities, ``B gamma_cov B^T dt`` with ``B = d qdd / d gamma`` of the
        constrained dynamics, added to Q dt for this step only.
        """
        zl = z.tolist() if isinstance(z, np.ndarray) else z
        zsum = zl[0] + zl[1] + zl[2] + zl[3] + zl[4] + zl[5]
        if zsum - zsum != 0.0:  # a NaN or an infinity in z: predict only
            return self._skip_measurement(gamma, dt, gamma_cov)
        if not abs(dt - self._dt) <= 1e-12 * dt:  # a new sampling period (up to rounding), or a NaN dt
            if not 0.0 < dt < math.inf:
                raise ParameterError(f"EKF time step must be positive and finite, got {dt}")
            self._set_dt(dt)
        return self._fused_update(self._fused_predict(gamma, dt, zl, gamma_cov), zl)

    def _fused_predict(
        self, gamma: Sequence[float] | np.ndarray, dt: float, zl: Sequence[float], gamma_cov: np.ndarray | None
    ) -> list:
        """The prediction of :meth:`step` (eq. 13/16/17): x and rows/columns 0-5 of P; return minus the innovation.

        Also writes w = -y into the [w | T] buffer for the update's dposv.
        """
        x = self._x
        P = self._P
        q_in = None if gamma_cov is None else input_noise_covariance(x, gamma_cov, dt)  # at the prior state, like F
        xs = x.tolist()
        xdd, ydd, od, rows = dynamics_jacobian_rows(xs, gamma, self.sigma, self.sigma_yaw, self.with_sigma, dt, True)
        px, py, pth, vx, vy, om = xs[:6]
        ix, iy, ith, ivx, ivy, iom = vx * dt, vy * dt, om * dt, xdd * dt, ydd * dt, od * dt  # eq. (16)
        # minus the innovation: predicted - measured (heading wrapped)
        ny = [
            px + ix - zl[0],
            py + iy - zl[1],
            -((zl[2] - pth - ith + math.pi) % (2.0 * math.pi) - math.pi),
            vx + ivx - zl[3],
            vy + ivy - zl[4],
            om + iom - zl[5],
        ]
        rows += (ix, iy, ith, ivx, ivy, iom)
        rows += ny
        self._fill[:] = rows  # Phi6 rows 3-5, the increment, w = -y
        self._x6 += self._inc
        # -- covariance prediction, eq. (13)/(17): P_pred = Phi (P + Q dt) Phi^T; only rows/columns 0-5 change
        self._pdiag += self._qdt
        if q_in is not None:
            P[3:6, 3:6] += q_in
        t_t = self._tt
        np.dot(P, self._phi6_t, out=t_t)  # (Phi6 P)^T, P symmetric
        np.dot(self._phi6, t_t, out=self._tt6)  # Phi6 P Phi6^T (numpy buffers the overlap)
        self._p6[...] = t_t.T
        self._p_lo[...] = self._tt_lo
        return ny

    def _fused_update(self, ny: list, zl: Sequence[float]) -> float:
        """The update of :meth:`step` (eq. 18-20, H = [I_6 0]) after :meth:`_fused_predict`; return the NIS."""
        x = self._x
        sf = self._sf
        np.add(self._tt6, self.R, out=sf)
        s_diag = sf.diagonal().tolist() if self.config.adaptive_q_tau > 0.0 else None
        _, _, info = _dposv(sf, self._tf, lower=1, overwrite_a=1, overwrite_b=1)
        if info != 0:  # S not positive definite: repair P (predicted already), then the plain update
            self._repair_covariance()
            return self._update(list(zl))
        wl = self._w.tolist()  # S^-1 (-y)
        nis = ny[0] * wl[0] + ny[1] * wl[1] + ny[2] * wl[2] + ny[3] * wl[3] + ny[4] * wl[4] + ny[5] * wl[5]
        if s_diag is not None:
            self.adapt_process_noise(ny, s_diag)
        if nis > self._gate or nis != nis:  # outlier (chi-square gate) or a non-finite state
            return self._gated(nis, ny, list(zl))
        self._gate_streak = 0
        self.accepted = True
        self.nis = nis
        np.dot(self._p6_t, self._tf, out=self._kb)  # T^T [S^-1 (-y) | S^-1 T] = [-K y | K T]
        self._A -= self._kb  # x + K y (eq. 19), P_pred - K T (eq. 20)
        self._unsym += 1
        if self._unsym >= SYMMETRIZE_EVERY:
            self._symmetrize()
        m, a, b, j = x[6:10].tolist()  # keep phi physical (inline _project)
        if (
            m < self._min_mass
            or j < self._min_inertia + (a * a + b * b) / m
            or (self.with_sigma and min(x[10], x[11]) < 0.0)
        ):
            self._project()
        self._ny = ny
        if self._prior_var is not None and self.config.change_detection:
            self._detect_change(ny, self._prior_var)  # the test is on |sum y|^2: the sign does not matter
        return self.nis

    def _skip_measurement(self, gamma: Sequence[float] | np.ndarray, dt: float, gamma_cov: np.ndarray | None) -> float:
        """Predict only (a measurement with a NaN or an infinity); count it; return NaN."""
        if not 0.0 < dt < math.inf:
            raise ParameterError(f"EKF time step must be positive and finite, got {dt}")
        self.predict(gamma, dt, gamma_cov)
        self.nonfinite_samples += 1
        self.accepted = False
        self.nis = float("nan")
        return self.nis

    def _gated(self, nis: float, ny: list, zl: list) -> float:
        """The cold path of :meth:`step` after the prediction: reject an outlier or accept after a run of them."""
        if nis != nis:
            if not (np.all(np.isfinite(self._x)) and np.all(np.isfinite(self._P))):
                raise NumericalError(
                    "the EKF diverged: its state became non-finite (the log's values or time "
                    "steps are out of any plausible range?)"
                )
            self._repair_covariance()
            return self._update(zl)
        self._ny = ny
        self.nis = nis
        if self._gate_streak < self._gate_max:
            self._gate_streak += 1
            self.rejected_samples += 1
            self.accepted = False
            self._unsym += 1
            return nis
        self.forced_accepts += 1
        self._gate_streak = 0
        self._symmetrize()
        self._pdiag[:N_MEAS] += np.square(ny)
        return self._update(zl, inflated=True)


def _log_arrays(t: np.ndarray, gamma: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Return (t, gamma, z, k0) of :func:`run_ekf` as float arrays, checked; k0 the first finite measurement."""
    t = np.asarray(t, dtype=float)
    z = np.asarray(z, dtype=float)
    gamma = np.asarray(gamma, dtype=float)
    n = len(t)
    if n < 1 or z.shape != (n, N_MEAS) or gamma.shape[0] != n:
        raise ParameterError(f"run_ekf needs t (N,), gamma (N, 3), z (N, 6); got {t.shape}, {gamma.shape}, {z.shape}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
        raise ParameterError("run_ekf needs finite, strictly increasing times")
    if not np.all(np.isfinite(gamma)):
        raise ParameterError("run_ekf needs a finite wrench gamma at every sample")
    finite_rows = np.nonzero(np.all(np.isfinite(z), axis=1))[0]
    if finite_rows.size == 0:
        raise ParameterError("run_ekf: no sample has a finite measurement")
    return t, gamma, z, int(finite_rows[0])


def run_ekf(
    t: np.ndarray,
    gamma: np.ndarray,
    z: np.ndarray,
    phi0: npt.ArrayLike,
    sigma: float,
    config: EKFConfig = EKFConfig(),
    nll: list | None = None,
    sigma_yaw: float | None = None,
) -> tuple[CartEKF, np.ndarray, np.ndarray]:
    """Return (ekf, x_history (N, n), nis (N,)) of the EKF run on a whole log.

    ``gamma[k]`` is held between t_k and t_{k+1}; the first sample with a
    finite measurement initialises q, qd. If ``nll`` is a list, the negative
    log-likelihood of the innovations, 0.5 sum_k (y_k^T S_k^-1 y_k + ln det S_k)
    (constant dropped), is appended to it; a measurement rejected by the gate
    counts with the gate's NIS (a capped, robust likelihood), a skipped
    non-finite one not at all.

    Robustness: non-finite measurements are skipped, outliers gated (see
    :class:`EKFConfig`; counters ``ekf.nonfinite_samples``, ``ekf.rejected_samples``);
    an interval longer than ``config.gap_factor`` times the median is split
    into sub-steps of about the median under the held wrench (``ekf.gaps``
    counts them; at most MAX_GAP_SUBSTEPS sub-steps per interval).
    """
    t, gamma, z, k0 = _log_arrays(t, gamma, z)
    n = len(t)
    dts = np.diff(t)
    ekf = CartEKF(z[k0, :3], z[k0, 3:], phi0, sigma, config, sigma_yaw=sigma_yaw)
    ekf.nonfinite_samples = k0
    hist = np.empty((n, ekf.n))
    nis = np.full(n, np.nan)
    hist[: k0 + 1] = ekf.x
    rejected = np.zeros(n, dtype=bool)
    log_det = 0.0
    want_nll = nll is not None
    dt_med = float(median(dts)) if n > 1 else 0.0
    gap_limit = config.gap_factor * dt_med if config.gap_factor > 0 else math.inf
    tl = t.tolist()  # Python floats: the steps' scalar arithmetic stays out of numpy scalars (the same IEEE results)
    for k in range(k0 + 1, n):
        dt = tl[k] - tl[k - 1]
        if dt > gap_limit:  # a gap in the log: sub-steps of about the median under the held wrench
            n_sub = min(int(math.ceil(dt / dt_med)), MAX_GAP_SUBSTEPS)
            dt = dt / n_sub
            for _ in range(n_sub - 1):
                ekf.predict(gamma[k - 1], dt)
            ekf.gaps += 1
        nis[k] = ekf.step(gamma[k - 1], dt, z[k])
        hist[k] = ekf.x
        if not ekf.accepted:
            if nis[k] != nis[k]:  # skipped (non-finite measurement)
                continue
            rejected[k] = True
        if want_nll:
            log_det += ekf.log_det_innovation_covariance()
    if nll is not None:
        robust = np.where(rejected, ekf.gate_threshold, nis)
        nll.append(0.5 * (float(np.nansum(robust)) + log_det))
    return ekf, hist, nis


@dataclass(frozen=True)
class LogEstimate:
    """Parameters estimated from a log, with their 1-sigma std, the noise used and the NIS."""

    params: CartParams
    std: dict
    meas_std: tuple[float, ...]
    mean_nis: float
    velocities_estimated: bool
    history: np.ndarray = field(repr=False)
    rejected_samples: int = 0
    nonfinite_samples: int = 0
    gaps: int = 0


def measurement_std_from_log(
    t: np.ndarray, q: np.ndarray, qd: np.ndarray | None, half_window: float = 0.05
) -> tuple[float, ...]:
    """Return the std of (x, y, theta, vx, vy, omega) estimated from the residuals about local quadratic fits.

    When the velocities are absent (estimated by the same fits), their std is
    the position std propagated through the slope of a least-squares line over
    the window, times sqrt(window size) for the correlation between
    neighbouring estimates (coloured noise: treating them as white with the
    plain slope std made the filter overconfident, mean NIS ~30 at 200 Hz).
    """
    from cart.logs import local_polyfits

    fits, _, width = local_polyfits(t, [q] if qd is None else [q, qd], half_window)  # one set of windows for both
    smooth = fits[0]
    dof = max(width - 3, 1)
    pose_std = np.std(q - smooth, axis=0) * math.sqrt(width / dof)
    pose_std = np.maximum(pose_std, [1e-4, 1e-4, 1e-4])
    if qd is not None:
        vsmooth = fits[1]
        vel_std = np.maximum(np.std(qd - vsmooth, axis=0) * math.sqrt(width / dof), [1e-3, 1e-3, 1e-3])
    else:
        # slope std of a least-squares line over the window, sqrt(12 / width) pose_std / span, inflated by
        # sqrt(width): neighbouring estimates share almost all their samples (strongly coloured errors),
        # so only about one velocity per window is independent information for the white-noise EKF
        span = float(median(np.diff(t))) * (width - 1)
        vel_std = pose_std * math.sqrt(12.0) / max(span, 1e-9)
    pos = 0.5 * (pose_std[0] + pose_std[1])
    vel = 0.5 * (vel_std[0] + vel_std[1])
    return (float(pos), float(pos), float(pose_std[2]), float(vel), float(vel), float(vel_std[2]))


def wrench_noise_std_from_log(log) -> tuple[float, float]:
    """Return the std of the white noise on the logged wrench: (force per axis N, torque N m).

    From the residuals of short local cubic fits (see :func:`cart.log_signals.signals_from_log`);
    (0, 0) for logs too short to fit.
    """
    from cart.errors import LogFormatError
    from cart.log_signals import signals_from_log

    try:
        sig = signals_from_log(log)
    except LogFormatError:
        return 0.0, 0.0
    return float(sig.sigma_force), float(sig.sigma_torque)


def default_starts(guess: CartParams) -> tuple[CartParams, ...]:
    """Return the initial guesses :func:`estimate_from_log` tries: the guess, and its mass x0.6 and x1.6.

    The EKF on a weakly exciting log can lock into a wrong basin from a poor
    mass guess (e.g. 31 kg with an inertia of 700 kg m^2, mean NIS 177, from
    15 kg on a 20 kg cart, while a 20 kg start gives 20.0 kg, NIS 3); starting
    from several masses and keeping the most likely run removes that failure.
    """
    return (guess, guess.with_mass(0.6 * guess.m), guess.with_mass(1.6 * guess.m))


def _start_config(
    start: CartParams,
    meas_std: Sequence[float],
    wrench_std: tuple[float, float],
    dt: float,
    estimate_sigma: bool,
    config: dict,
) -> EKFConfig:
    """Return the EKFConfig of one start of :func:`estimate_from_log` (``config`` overrides the noise it sets).

    White wrench noise (F/T sensor, std ``wrench_std`` = (force N, torque N m)) drives the velocities: its
    density (std / m)^2 dt and (torque std / J)^2 dt at this start's m and J about {b}, floored at the defaults.
    """
    q_in = dict(
        q_vel=max(EKFConfig.q_vel, (wrench_std[0] / start.m) ** 2 * dt),
        q_omega=max(EKFConfig.q_omega, (wrench_std[1] / start.inertia_b) ** 2 * dt),
    )
    return EKFConfig.from_noise(meas_std, estimate_sigma=estimate_sigma, **{**q_in, **config})


def estimate_from_log(
    log,
    guess: CartParams,
    estimate_sigma: bool = True,
    meas_std: Sequence[float] | None = None,
    starts: Sequence[CartParams] | None = None,
    refine: bool = True,
    **config,
) -> LogEstimate:
    """Return the EKF's parameter estimate on a CartLog (velocities estimated from the pose when absent).

    The EKF runs from each of ``starts`` (default :func:`default_starts` of the
    guess; ``starts=[guess]`` for a single run) and, with ``refine``, once more
    from the best run's final parameters (prior covariance as for a guess); the
    run with the smallest negative log-likelihood of its innovations
    (:func:`run_ekf`) is returned (maximum likelihood over the starts).

    The velocity process noise is raised to what the log's wrench noise
    (:func:`wrench_noise_std_from_log`) injects, (std / m)^2 dt and
    (torque std / J)^2 dt at each start's m and J (about {b}) unless ``q_vel`` /
    ``q_omega`` are given: with 3 N of F/T noise treated as an exact input the
    filter is overconfident (mean NIS ~100) and overestimates the mass by ~10 kg
    on a 20 kg cart; with it, by ~0.6 kg (errors in the input still bias the
    EKF slightly, see docs/cart.md).
    """
    meas_std = measurement_std_from_log(log.t, log.q, log.qd) if meas_std is None else meas_std
    wrench_std = wrench_noise_std_from_log(log)
    dt_med = float(median(np.diff(log.t)))
    z = np.hstack([log.q, log.velocities()])
    starts = tuple(default_starts(guess) if starts is None else starts)
    if not starts:
        raise ParameterError("estimate_from_log needs at least one start")
    best = None
    for start in starts + (None,) if refine else starts:
        if start is None:  # refinement: restart from the best run's estimate
            if best is None:
                break
            start = best[1].params()
        cfg = _start_config(start, meas_std, wrench_std, dt_med, estimate_sigma, config)
        nll: list = []
        try:
            ekf, hist, nis = run_ekf(log.t, log.gamma, z, start.phi, start.sigma, cfg, nll, start.sigma_yaw)
        except NumericalError:  # this start diverged; the others may not
            continue
        if np.isfinite(nll[0]) and (best is None or nll[0] < best[0]):
            best = (nll[0], ekf, hist, nis)
    if best is None:
        raise NumericalError("the EKF diverged from every start (non-finite likelihood)")
    _, ekf, hist, nis = best
    return LogEstimate(
        params=ekf.params(),
        std=ekf.params_std(),
        meas_std=tuple(cfg.meas_std),
        mean_nis=float(np.nanmean(nis)),
        velocities_estimated=not log.has_velocities,
        history=hist,
        rejected_samples=ekf.rejected_samples,
        nonfinite_samples=ekf.nonfinite_samples,
        gaps=ekf.gaps,
    )

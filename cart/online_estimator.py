"""Online estimator of the cart's state and parameters for the push loop, unbiased under wrench noise.

:class:`OnlineLSEstimator` satisfies the push loop's ``ParameterEstimator`` protocol
(``x``, ``step(gamma, dt, z)``, ``params()``, ``params_std()``) and combines

1. the *parameters*: recursive filtered-regressor least squares
   (:class:`cart.online_regression.RecursiveRegression`) in which the measured wrench is the
   regression's output (paper eq. 4 in regressor form, :func:`cart.dynamics.regressor`), the
   kinematics come from the motion capture alone (causal Butterworth state-variable filter of
   the velocity and heading; the same filter on the wrench), with a prior on the physical
   parameters that an unexcited direction keeps, and bias compensation of the pose noise;
2. *load changes*: a GLR test on the regression's residuals
   (:class:`cart.change_detection.ChangeDetector`), confirmed by the masses fitted on each side of the
   estimated onset (a misfitting model moves the residuals, not the mass); on a confirmed detection the
   information on mass, CoM and inertia is reset to the samples after the onset (the damping keeps
   what it learnt), and the change is recorded in :attr:`OnlineLSEstimator.events`;
3. *plausibility and run-off*: mass > 0, inertia about the CoM > 0, CoM inside the footprint,
   residual ratio (a windowed innovation test of the regression); each episode is recorded in
   :attr:`OnlineLSEstimator.flags` and the controller receives the estimate projected on the
   plausible set, its CoM pulled from the prior only as far as the misfit-deflated information allows
   (the stds are scaled up by the residual ratio);
4. the *state* ``x`` (pose, velocity) for the controller: the paper's EKF (:class:`cart.ekf.CartEKF`,
   eq. 8-20) with its parameters frozen and overwritten every step by the regression's estimate
   (a state observer only: the wrench enters as its input, never the parameters' update).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from cart.change_detection import ChangeDetector, MomentumTest, RingBuffer
from cart.dynamics import regressor
from cart.ekf import CartEKF, EKFConfig, chi2_isf
from cart.online_casters import CasterBank, Nuisance
from cart.online_regression import (
    DT_REL_TOL,
    MisfitLevel,
    OnlineEstimatorError,
    PhysicalPrior,
    RecursiveRegression,
    ResidualWindow,
    StateVariableFilter,
)
from cart.params import CartParams
from cart.window_changes import WindowChange, WindowChangeDetector

#: Physical parameter names of :meth:`OnlineLSEstimator.unexcited`.
PHYSICAL_NAMES = ("mass", "dx", "dy", "inertia", "sigma", "sigma_yaw")


#: A first GLR detection whose mass lies this many initial prior stds from the guess, with nothing before it to
#: weigh the cart, says the guess was wrong (:meth:`OnlineLSEstimator._guess_far`).
GUESS_FAR_SIGMA = 4.0


@dataclass(frozen=True)
class OnlineOptions:
    """Settings of :class:`OnlineLSEstimator` (defaults: the push loop's sensors and the paper's carts).

    ``cutoff_hz``: low-pass of both sides of the regression; ``noise_subspace``: drop the directions
    where the data power does not beat the regressor noise (else remove the noise power, clamped); ``wrench_std`` (force N, torque N m):
    white noise of the measured wrench, ``None`` = measured online (third differences);
    ``mass_rel_std``, ``com_std`` (m), ``rho_rel_std``, ``damping_rel_std``: the prior around the
    initial guess (damping std at least ``damping_min_std``); ``footprint`` (|dx|, |dy| limits, m);
    ``forgetting_s``: time constant of the data's exponential forgetting (inf: none);
    change detection: ``detect_changes``, ``change_window_s``, ``change_alpha`` (false-alarm
    probability of one test), ``min_change`` (relative mass change), ``buffer_s`` (onset search; an onset whose
    stretch reaches the start of the full buffer is censored and searched again by the window search);
    after a change the prior is re-centered on the estimate before it, with ``change_mass_rel_std``
    (relative), ``change_com_std`` (m, at least the CoM's std before the change) and
    ``change_rho_rel_std`` (relative, J / m): a load changes the mass more than the CoM and the
    radius of gyration;
    ``observer_q_vel`` / ``observer_q_omega``: the state observer's process noise (EKFConfig);
    ``observer_adaptive_q_tau``: the observer's innovation-adaptive process noise (s; `EKFConfig.adaptive_q_tau`,
    0 = off: on, MuJoCo Traj. 2 loses seed 2 in its third turn);
    ``misfit_ratio``: residual ratio flagged as misfit; ``excited_ratio``: posterior / prior std
    above which a parameter counts as not excited;
    ``impulse_alpha``: false-alarm probability of the impulse test (the state observer's NIS: a jump of
    velocity the wrench does not explain, as when a load dropped in exchanges momentum with the cart, or a
    bump); after an impulse the regression skips ``impulse_settle_cycles`` periods of the cut-off (the
    filtered signals carry the jump that long); a change found after an impulse (its onset at most twice that
    before it, or earlier) is dated at the impulse;
    ``momentum_changes``: at each impulse the forward speed's jump is tested for a load put in at rest
    (:class:`cart.change_detection.MomentumTest` over ``momentum_side_s`` s each side): one found restarts the
    parameters from the mass before times the jump's ratio (:meth:`OnlineLSEstimator._restart_from_momentum`);
    ``confirm_sigma``: a detection made while the model misfits (residual ratio at the onset, or that of the samples
    after it against their own fit, above ``misfit_ratio``) is a load change only when the masses fitted on each
    side of the onset differ by this many stds of their difference, scaled up by the larger ratio
    (:meth:`OnlineLSEstimator._confirmed`);
    ``deflate_com``: the CoM given to the controller moves from the prior by the estimate's move deflated by the
    model's misfit (:meth:`OnlineLSEstimator._com_to_use`);
    ``window_changes``: every ``window_every_s`` s the offline segment search on the last ``window_s`` s of the
    loop's own log since the last change (:class:`cart.window_changes.WindowChangeDetector`); a change it finds
    restarts the parameters from the fit after it;
    ``second_look``: a GLR change is judged again by the window search's first fit of the data after it precise
    enough to see ``min_change`` (:meth:`OnlineLSEstimator._second_look`; needs ``window_changes``);
    ``excitation_margin``: the identifiability gate of the regression from the initial guess (prior units; 0: off,
    :data:`cart.online_regression.EXCITATION_MARGIN` the suggested value;
    :meth:`cart.online_regression.RecursiveRegression.excited_part`);
    ``misfit_weights``: each sample enters the regression with weight 1 / max(1, kappa^2 / kappa_ref^2), kappa the
    model's residual ratio over ``misfit_weight_s`` (``None``: the misfit test's window, 2 ``change_window_s``) at the
    current estimate and kappa_ref the run's level, the ``misfit_level_quantile`` of kappa since the last change (full
    windows only; at least 1; e.g. 0.05) or, with ``None`` (default), 1: the noise model's own level
    (:meth:`OnlineLSEstimator._sample_deflation`): a stretch that misfits more than the run (casters swinging round)
    teaches a weak direction less, a model that misfits uniformly keeps its data; after a load change the samples
    after its onset are reweighted against their own fit, relative to their own level.
    """

    cutoff_hz: float = 2.0
    noise_subspace: bool = True
    wrench_std: tuple[float, float] | None = None
    mass_rel_std: float = 0.5
    com_std: float = 0.2
    rho_rel_std: float = 0.5
    damping_rel_std: float = 0.5
    damping_min_std: float = 1.0
    footprint: tuple[float, float] = (1.0, 1.0)
    forgetting_s: float = math.inf
    detect_changes: bool = True
    change_window_s: float = 1.5
    change_alpha: float = 1e-6
    min_change: float = 0.08
    buffer_s: float = 4.0
    change_mass_rel_std: float = 1.0
    change_com_std: float = 0.1
    change_rho_rel_std: float = 0.25
    observer_q_vel: float = 1e-5
    observer_q_omega: float = 1e-5
    observer_input_noise: bool = True
    observer_adaptive_q_tau: float = 0.0
    misfit_ratio: float = 2.0
    excited_ratio: float = 0.9
    noise_time_s: float = 5.0
    impulse_alpha: float = 1e-9
    impulse_settle_cycles: float = 1.5
    momentum_changes: bool = True
    momentum_side_s: float = 0.1
    confirm_sigma: float = 3.0
    deflate_com: bool = True
    casters: bool = True
    window_changes: bool = True
    window_every_s: float = 2.0
    window_s: float = 30.0
    second_look: bool = True
    excitation_margin: float = 0.0
    misfit_weights: bool = True
    misfit_weight_s: float | None = None
    misfit_level_quantile: float | None = None


@dataclass(frozen=True)
class LoadChange:
    """A detected load change: estimated onset, detection time (s), mass before and after (kg), GLR statistic
    (0 for a change the window search or the momentum test found), the test that found it (``glr``, ``window``
    or ``momentum``), and the earliest and latest onsets the data cannot tell from ``t_change`` (s; None: not
    known): a change made while the cart cruises shows only at the next acceleration, and any onset in the
    cruise fits as well (:meth:`cart.change_detection.ChangeDetector.onset_range`, the window search's stretch of
    equal residual, the period of a velocity jump)."""

    t_change: float
    t_detected: float
    mass_before: float
    mass_after: float
    statistic: float
    method: str = "glr"
    t_earliest: float | None = None
    t_latest: float | None = None
    #: the onset may lie before ``t_earliest``: the test that found the change kept too little data to bound it,
    #: and the window search did not date it (a lift-out during a cruise longer than the GLR's buffer)
    censored: bool = False

    def as_dict(self) -> dict:
        """Return the change as a JSON-ready dict."""
        return {k: v if isinstance(v, (str, bool)) or v is None else float(v) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class RunoffFlag:
    """The start of an implausible or misfitting episode: time (s), kind and what was seen."""

    t: float
    kind: str
    detail: str

    def as_dict(self) -> dict:
        """Return the flag as a JSON-ready dict."""
        return {"t": float(self.t), "kind": self.kind, "detail": self.detail}


@dataclass
class _SumsBefore:
    """The regression's state on the samples before a GLR change's onset: what withdrawing the change restores
    (:meth:`OnlineLSEstimator._second_look`)."""

    prior: PhysicalPrior
    excitation_margin: float
    normal: tuple[np.ndarray, np.ndarray, np.ndarray]  # D, d, C of the samples before the onset
    casters: tuple[np.ndarray, ...] | None = None  # the caster bank's sums of those samples
    carried: tuple[np.ndarray, ...] | None = None  # the casters' prior the restart added (CasterBank.carried)


@dataclass
class _Change:
    t_change: float
    t_detected: float
    mass_before: float
    statistic: float
    mass_end: float | None = None
    method: str = "glr"
    window_index: int | None = None  # the change's index in the window search's list (its onset is refined)
    t_range: tuple[float, float] | None = None  # the onsets the data cannot tell apart (earliest, latest)
    censored: bool = False  # the onset may lie before t_range (`LoadChange.censored`)
    before: tuple[float, float, float] | None = None  # GLR: the fit before the onset (mass, std, residual ratio)
    sums_before: _SumsBefore | None = None  # GLR: the regression before the onset, restored if withdrawn


def _vector(value: npt.ArrayLike, n: int, what: str) -> np.ndarray:
    """Return value as a finite float array of shape (n,); raise OnlineEstimatorError otherwise."""
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise OnlineEstimatorError(f"{what} must be {n} numbers, got {value!r}") from None
    if arr.shape != (n,):
        raise OnlineEstimatorError(f"{what} must have {n} entries, got shape {np.shape(value)}")
    if not np.isfinite(arr).all():
        raise OnlineEstimatorError(f"{what} must be finite, got {arr.tolist()}")
    return arr


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _physical_jacobian(p: np.ndarray) -> np.ndarray:
    """Return d(m, dx, dy, I, c_v, c_w) / d(m, a, b, J, c_v, c_w) at p (the linearized phi -> physical map)."""
    m, a, b, _ = p[:4].tolist()
    jac = np.eye(6)
    jac[1, 0], jac[1, 1] = -a / m**2, 1.0 / m
    jac[2, 0], jac[2, 2] = -b / m**2, 1.0 / m
    jac[3, 0], jac[3, 1], jac[3, 2] = (a * a + b * b) / m**2, -2.0 * a / m, -2.0 * b / m
    return jac


def make_prior(params0: CartParams, options: OnlineOptions) -> PhysicalPrior:
    """Return the prior around the initial guess: mass, CoM, J / m, damping with the options' stds."""
    rho0 = params0.inertia_b / params0.m
    sv, sw = params0.damping
    o = options
    return PhysicalPrior(
        center=np.array([params0.m, params0.dx, params0.dy, rho0, sv, sw]),
        std=np.array(
            [
                o.mass_rel_std * params0.m,
                o.com_std,
                o.com_std,
                o.rho_rel_std * rho0,
                max(o.damping_rel_std * sv, o.damping_min_std),
                max(o.damping_rel_std * sw, o.damping_min_std),
            ]
        ),
    )


class OnlineLSEstimator:
    """Online state + parameter estimator for the push loop (see the module docstring).

    ``q0`` (3,) and ``qd0`` (3,): initial pose and velocity; ``params0``: initial guess
    (the prior's center); ``meas_std`` (6,): motion-capture noise std of
    (x, y, theta, vx, vy, omega). ``step(gamma, dt, z)``: gamma = (fx, fy, tau) measured
    over the last period, z the motion capture at its end; returns the state observer's NIS.
    """

    def __init__(
        self,
        q0: npt.ArrayLike,
        qd0: npt.ArrayLike,
        params0: CartParams,
        meas_std: npt.ArrayLike,
        options: OnlineOptions = OnlineOptions(),
    ) -> None:
        q, qd = _vector(q0, 3, "q0"), _vector(qd0, 3, "qd0")
        std = _vector(meas_std, 6, "meas_std")
        if np.any(std < 0.0):
            raise OnlineEstimatorError(f"meas_std must be >= 0, got {std.tolist()}")
        if not isinstance(params0, CartParams):
            raise OnlineEstimatorError(f"params0 must be CartParams, got {type(params0).__name__}")
        self.options = options
        self.t = 0.0
        self._footprint = np.abs(_vector(options.footprint, 2, "footprint"))
        self._prior0 = make_prior(params0, options)
        self.regression = RecursiveRegression(self._prior0, options.noise_subspace, options.excitation_margin)
        self.filter = StateVariableFilter(options.cutoff_hz, 6)
        self.detector = ChangeDetector(options.change_window_s, options.change_alpha, options.min_change)
        self._meas_std = std
        self._init_observer(q, qd, params0, std)
        self._z_prev = np.r_[q, qd]
        self._theta = float(q[2])
        self._started = False
        self._gains_dt = -1.0
        self._noise = [0.0, 0.0, 0.0]  # EW weight sum, EW sums of d3^2 / 20 (force, torque)
        self._raw: list[tuple[float, float]] = []
        self._cov = self.regression.covariance()
        self._std_memo: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # (cov, p, std) of _physical_std
        self._params = params0
        self._misfit = [0.0, 0.0, 0.0]  # EW weight, EW sums of normalized squared residuals (rows)
        self._local = ResidualWindow(options.misfit_weight_s or 2.0 * options.change_window_s)
        self._level = MisfitLevel(options.misfit_level_quantile or 0.0)
        self.residual_ratio = (float("nan"), float("nan"))
        self._changes: list[_Change] = []
        self._flags: list[RunoffFlag] = []
        self._active: set[str] = set()
        self._ended: dict[str, float] = {}  # when each kind's last episode ended
        self._buffer: RingBuffer | None = None
        self.nis = float("nan")
        self._impulse_nis = chi2_isf(options.impulse_alpha, 2)
        self._impulse_t = -math.inf
        self.impulses: list[float] = []
        self.momentum = self._momentum_test(std) if options.momentum_changes and options.detect_changes else None
        self._momentum_before: tuple[CartParams, float] | None = None
        self.casters = CasterBank(StateVariableFilter(options.cutoff_hz, 96)) if options.casters else None
        self.window = (
            WindowChangeDetector(0.0, np.r_[q, qd], options.window_every_s, options.window_s)
            if options.window_changes
            else None
        )

    def _init_observer(self, q0: np.ndarray, qd0: np.ndarray, params0: CartParams, meas_std: np.ndarray) -> None:
        """Create the state observer: the paper's EKF with the parameters frozen (overwritten every step)."""
        cfg = EKFConfig.from_noise(
            meas_std,
            estimate_params=False,
            q_vel=self.options.observer_q_vel,
            q_omega=self.options.observer_q_omega,
            adaptive_q_tau=self.options.observer_adaptive_q_tau,
        )
        self.observer = CartEKF(q0, qd0, params0.phi, params0.sigma, cfg, sigma_yaw=params0.sigma_yaw)

    # -- protocol ---------------------------------------------------------------------------
    @property
    def x(self) -> np.ndarray:
        """Return the state estimate (x, y, theta, vx, vy, omega) (a view of the observer's state)."""
        return self.observer.x[:6]

    def params(self) -> CartParams:
        """Return the current parameter estimate, projected on the plausible set (see :attr:`flags`)."""
        return self._params

    def params_std(self) -> dict:
        """Return the 1-sigma std of mass, com (dx, dy), inertia, sigma, sigma_yaw (like ``CartEKF.params_std``).

        The regression's covariance, scaled up by the residual ratio when the model misfits.
        """
        std = self._physical_std(self._cov) * self._misfit_scale()
        return {
            "mass": float(std[0]),
            "com": [float(std[1]), float(std[2])],
            "inertia": float(std[3]),
            "sigma": float(std[4]),
            "sigma_yaw": float(std[5]),
        }

    def _physical_std(self, cov: np.ndarray) -> np.ndarray:
        """Return the physical parameters' std (:func:`_physical_jacobian`) of the covariance ``cov`` of p at the
        regression's estimate (read-only; kept until ``cov`` or the estimate is replaced: the step, the controller's
        :meth:`params_std` and the next step's impulse test read the same one)."""
        p, last = self.regression.p, self._std_memo
        if last is not None and last[0] is cov and last[1] is p:
            return last[2]
        jac = _physical_jacobian(p)
        std = np.sqrt(np.maximum(np.diag(jac @ cov @ jac.T), 0.0))
        std.flags.writeable = False
        self._std_memo = (cov, p, std)
        return std

    def unexcited(self) -> tuple[str, ...]:
        """Return the parameters the motion has not excited: posterior std above ``excited_ratio`` of the prior's.

        The posterior std is scaled up by the residual ratio when the model misfits (as :meth:`params_std`):
        what a misfitting model seems to identify is not known better than the prior says.
        """
        post = self._physical_std(self._cov) * self._misfit_scale()
        prior = self._physical_std(self.regression.prior_covariance())
        return tuple(n for n, a, b in zip(PHYSICAL_NAMES, post, prior) if a > self.options.excited_ratio * b)

    def _misfit_scale(self, row: int | None = None) -> float:
        """Return the factor (at least 1) by which the stds are scaled up: the model's current residual ratio.

        The residual test's ratio (:meth:`_check_misfit`), also before it is reported: the a-priori residual
        power over what the noise and the estimate's std explain, exponentially weighted over 2
        ``change_window_s`` and the larger of the two rows (force, yaw torque), or of ``row`` alone (0: the
        forward force, which is all the momentum test uses). It forgets: a misfit at the start no longer scales
        the stds a few windows later.
        """
        mf = self._misfit
        if mf[0] <= 0.0:
            return 1.0
        power = max(mf[1], mf[2]) if row is None else mf[1 + row]
        return max(1.0, math.sqrt(power / mf[0]))

    @property
    def events(self) -> tuple[LoadChange, ...]:
        """Return the load changes detected so far.

        Mass after: before the next change, the mass then; for the last change, the online estimate now or the
        window search's latest fit of the data after it (:attr:`cart.window_changes.WindowChangeDetector.fit`,
        the offline estimate on at least ``MIN_SEGMENT_S`` of them), whichever has the smaller std (the fit of
        a short stretch can be far off: Table I test 11's last 10 s fit 9.7 kg for 25).
        """
        out = []
        fit = self.window.fit if self.window is not None else None
        now = float(self.regression.p[0])
        if fit is not None and fit.std["mass"] < self.params_std()["mass"]:
            now = float(fit.params.m)
        for c in self._changes:
            after = c.mass_end if c.mass_end is not None else now
            lo, hi = c.t_range if c.t_range is not None else (None, None)
            out.append(
                LoadChange(c.t_change, c.t_detected, c.mass_before, after, c.statistic, c.method, lo, hi, c.censored)
            )
        return tuple(out)

    @property
    def flags(self) -> tuple[RunoffFlag, ...]:
        """Return the start of every implausible / misfitting episode so far."""
        return tuple(self._flags)

    @property
    def active_flags(self) -> frozenset[str]:
        """Return the kinds of flag that hold at the last step."""
        return frozenset(self._active)

    def report(self) -> dict:
        """Return what the loop reports: events, flags, impulses, unexcited parameters, residual ratio (JSON-ready)."""
        return {
            "load_changes": [e.as_dict() for e in self.events],
            "runoff_flags": [f.as_dict() for f in self.flags],
            "impulses": [float(t) for t in self.impulses],
            "unexcited": list(self.unexcited()),
            "residual_ratio": [None if r != r else float(r) for r in self.residual_ratio],
        }

    # -- step -------------------------------------------------------------------------------
    def step(self, gamma: npt.ArrayLike, dt: float, z: npt.ArrayLike) -> float:
        """Fuse one period: gamma measured over the last dt, z at its end; return the observer's NIS.

        Raises :class:`OnlineEstimatorError` on a wrong shape, a non-finite value or dt <= 0.
        """
        g = _vector(gamma, 3, "gamma")
        zv = _vector(z, 6, "z")
        if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0.0):
            raise OnlineEstimatorError(f"dt must be positive and finite, got {dt!r}")
        dt = float(dt)
        self.t += dt
        obs = self.observer
        p = self._params
        obs.x[6:10] = p.phi
        obs.sigma, obs.sigma_yaw = p.damping
        sf, st = self._wrench_var()
        self.nis = obs.step(
            g, dt, zv, gamma_cov=np.diag([sf, sf, st]) * dt if self.options.observer_input_noise else None
        )
        impulse = self.options.detect_changes and self._started
        impulse = impulse and self._impulse_statistic(g, dt, zv) > self._impulse_nis
        if self.momentum is not None:
            self._add_momentum(g, zv)
        if impulse:
            if self.t - self._impulse_t > self._settle_s():
                self.impulses.append(self.t)
                self._arm_momentum()
            self._impulse_t = self.t
        self._regression_step(g, dt, zv, impulse)
        if self.window is not None:
            self.window.add(self.t, g, zv)
            change = self.window.check()
            if change is not None:
                self._restart_from_window(change)
            if self.options.second_look:
                self._second_look()
            for c in self._changes:
                if c.window_index is not None:
                    found = self.window.changes[c.window_index]
                    c.t_change, c.t_range = found.t_change, found.t_range
                    c.censored = c.censored and not found.refined
        jump = self.momentum.check(self.t) if self.momentum is not None else None
        if jump is not None:
            self._restart_from_momentum(*jump)
        return self.nis

    def _momentum_test(self, meas_std: np.ndarray) -> MomentumTest:
        """Return the momentum test with the motion capture's forward-speed std and the measured force's std."""
        o = self.options
        v_std = math.hypot(float(meas_std[3]), float(meas_std[4])) / math.sqrt(2.0)
        return MomentumTest(o.momentum_side_s, o.min_change, o.confirm_sigma, v_std, (o.wrench_std or (0.0, 0.0))[0])

    def _add_momentum(self, gamma: np.ndarray, z: np.ndarray) -> None:
        """Give the momentum test the forward speed, the yaw rate and the net forward force the estimate predicts
        over the period (the measured wrench minus the damping at the period's start, ``_z_prev``)."""
        if self.momentum is None:
            return
        cth, sth = math.cos(float(z[2])), math.sin(float(z[2]))
        v_prev = cth * self._z_prev[3] + sth * self._z_prev[4]
        force = cth * gamma[0] + sth * gamma[1] - self._params.sigma * v_prev
        self.momentum.add(self.t, cth * z[3] + sth * z[4], float(z[5]), force)

    def _arm_momentum(self) -> None:
        """Mark the impulse for the momentum test, with the mass before it and its std (scaled by the misfit)."""
        if self.momentum is not None:
            force_std = math.sqrt(self._wrench_var()[0])
            self.momentum.arm(self.t, self._params.m, self._params.dy, self._misfit_scale(row=0), force_std)
            std = float(self._physical_std(self._cov)[0]) * self._misfit_scale()
            self._momentum_before = (self._params, std)

    def _restart_from_momentum(self, t_imp: float, ratio: float, ratio_std: float) -> None:
        """Restart from a load put in at rest at ``t_imp``: the mass before times the forward speed's jump ratio
        (:class:`cart.change_detection.MomentumTest`), std from both, enters the new regression as one
        measurement of the mass; its prior is the re-centred one of a GLR change (``change_mass_rel_std``,
        ``change_com_std``, ``change_rho_rel_std``; CoM and radius of gyration kept, the damping's std kept), so
        the GLR's ridge (the prior's information) does not shrink the next change's size."""
        if self._momentum_before is None:
            return
        before, m_std = self._momentum_before
        after = before.with_mass(before.m * ratio)
        post = self._physical_std(self._cov)
        s = self._change_std(after.m, after.inertia_b / after.m, post)
        std = {
            "mass": float(s[0]),
            "com": (float(s[1]), float(s[2])),
            "inertia": float(s[3]) * after.m,
            "sigma": float(post[4]),
            "sigma_yaw": float(post[5]),
        }
        change = WindowChange(t_imp, (t_imp, t_imp), self.t, before, after, std)
        if self.window is not None:
            self.window.add_change(change, 1.0 / self.options.cutoff_hz, dated=True)
        self._restart_from_window(change)
        var = (after.m * math.hypot(ratio_std / ratio, m_std / before.m)) ** 2
        e0 = np.eye(6)[0]
        self.regression.add(np.outer(e0, e0) / var, e0 * after.m / var, np.zeros((6, 6)), 1.0)
        self.regression.solve(iterations=3)
        self._cov = self.regression.covariance()
        self._update_params()
        self._changes[-1].method = "momentum"

    def _impulse_statistic(self, gamma: np.ndarray, dt: float, z: np.ndarray) -> float:
        """Return the normalized jump of forward speed and yaw rate over one period beyond what the wrench explains.

        Chi-square with 2 dof without an impulse (the motion capture's velocity noise, at least 1 mm/s and
        1 mrad/s); the wrench's share is predicted with the current estimate (small over one period).
        """
        zp, prm = self._z_prev, self._params
        c, s = math.cos(float(z[2])), math.sin(float(z[2]))
        v_prev = c * zp[3] + s * zp[4]
        av = (c * gamma[0] + s * gamma[1] - prm.sigma * v_prev) / prm.m * dt
        aw = (gamma[2] - prm.sigma_yaw * zp[5]) / prm.inertia_b * dt
        dv = c * z[3] + s * z[4] - v_prev - av
        dw = z[5] - zp[5] - aw
        ms = self._meas_std
        # the wrench's share is predicted with the estimate: its relative uncertainty (a 16 kg guess for a 90 kg
        # cart predicts 5x the speed change) widens the test, so only a jump the estimate cannot explain counts;
        # so does the wrench's own noise over the period (a 3 N spike moves a 15 kg cart's prediction 2 mm/s at
        # 100 Hz): a spike of the sensor that the motion does not follow is no jump of the motion
        std = self._physical_std(self._cov)
        rel_m, rel_i = std[0] / prm.m, std[3] / max(prm.inertia_b, 1e-9)
        sf, st = self._wrench_var()
        var_v = max(ms[3] ** 2 + ms[4] ** 2, 1e-6) + (av * rel_m) ** 2 + sf * (dt / prm.m) ** 2
        var_w = max(2.0 * ms[5] ** 2, 1e-6) + (aw * rel_i) ** 2 + st * (dt / prm.inertia_b) ** 2
        return float(dv * dv / var_v + dw * dw / var_w)

    def _settle_s(self) -> float:
        """Return how long (s) the filtered signals carry an impulse: ``impulse_settle_cycles`` cut-off periods."""
        return self.options.impulse_settle_cycles / self.options.cutoff_hz

    # -- regression -------------------------------------------------------------------------
    def _filter_inputs(self, gamma: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Return the filter input at the period's midpoint: mean velocity and heading, forward force, torque.

        The wrench is held over the period, so it stands for the midpoint; the motion
        capture samples its ends (average of the two).
        """
        th = self._theta + _wrap(float(z[2]) - self._theta)  # continuous heading
        mid = 0.5 * (self._theta + th)
        self._theta = th
        zp = self._z_prev
        self._z_prev = z
        fu = math.cos(mid) * gamma[0] + math.sin(mid) * gamma[1]
        return np.array([0.5 * (zp[3] + z[3]), 0.5 * (zp[4] + z[4]), 0.5 * (zp[5] + z[5]), mid, fu, gamma[2]])

    def _regression_row(self, st: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return (Y (2, 6), y (2,)) of the filtered signals: body-frame kinematics (constraint w = 0) and wrench."""
        vx, vy, om, th, fu, tau = st[0].tolist()
        ax, ay, al = st[1, :3].tolist()
        c, s = math.cos(th), math.sin(th)
        v = c * vx + s * vy
        w_lat = -s * vx + c * vy
        vdot = c * ax + s * ay + om * w_lat
        return regressor(v, om, vdot, al), np.array([fu, tau])

    def _gains(self, dt: float) -> tuple[float, float, float]:
        """Return the filter's noise gains per unit white input variance at dt: (wrench, velocity, acceleration).

        The velocity and acceleration gains include the midpoint average of two motion-capture samples.
        """
        from scipy.linalg import solve_discrete_lyapunov

        if not abs(dt - self._gains_dt) <= DT_REL_TOL * dt:
            ad, bd = self.filter.discretize(dt)
            p = solve_discrete_lyapunov(ad, np.outer(bd, bd))
            lag1 = ad @ p
            self._g = (float(p[0, 0]), 0.5 * float(p[0, 0] + lag1[0, 0]), 0.5 * float(p[1, 1] + lag1[1, 1]))
            self._gains_dt = dt
        return self._g

    def _update_noise(self, fu: float, tau: float, dt: float) -> None:
        """Update the online white-noise variance of (forward force, torque) from third differences."""
        raw = self._raw
        raw.append((fu, tau))
        if len(raw) > 4:
            raw.pop(0)
        if len(raw) == 4:
            lam = math.exp(-dt / self.options.noise_time_s)
            n = self._noise
            d3f = raw[3][0] - 3.0 * raw[2][0] + 3.0 * raw[1][0] - raw[0][0]
            d3t = raw[3][1] - 3.0 * raw[2][1] + 3.0 * raw[1][1] - raw[0][1]
            n[0] = lam * n[0] + 1.0
            n[1] = lam * n[1] + d3f * d3f / 20.0
            n[2] = lam * n[2] + d3t * d3t / 20.0

    def _wrench_var(self) -> tuple[float, float]:
        """Return the white-noise variance of (forward force, torque): given, or measured (floored)."""
        if self.options.wrench_std is not None:
            f, t = self.options.wrench_std
            return max(f * f, 1e-12), max(t * t, 1e-12)
        c = self._prior0.center
        floor_f, floor_t = (1e-3 * c[0]) ** 2, (1e-3 * c[0] * c[3]) ** 2
        n = self._noise
        if n[0] <= 0.0:
            return floor_f, floor_t
        return max(n[1] / n[0], floor_f), max(n[2] / n[0], floor_t)

    def _noise_known(self, dt: float) -> bool:
        """Return whether the wrench noise is known: given, or measured over at least one cut-off period."""
        return self.options.wrench_std is not None or self._noise[0] * dt * self.options.cutoff_hz >= 1.0

    def _weights(self, dt: float, v: float, om: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (row weights (2,), regressor-noise power (6, 6), expected filtered residual variance (2,)).

        The motion-capture noise, filtered, enters the regressor's entries: dv and domega in the v, omega,
        omega v, omega^2 columns, their derivatives in the vdot, omegadot columns (forward speed v, yaw rate om).
        """
        g_out, g_vel, g_acc = self._gains(dt)
        ms = self._meas_std
        var_v, var_o = 0.5 * (ms[3] ** 2 + ms[4] ** 2), ms[5] ** 2
        sv, so = var_v * g_acc, var_o * g_acc  # acceleration noise
        nv, no = var_v * g_vel, var_o * g_vel  # velocity noise
        sf, st = self._wrench_var()
        m, a, b, j, cv, cw = self.regression.p.tolist()
        var1 = sf + (m * m * sv + b * b * so + cv * cv * nv + 4.0 * a * a * om * om * no) / g_out
        var2 = st + (j * j * so + b * b * sv + (cw + a * v) ** 2 * no + a * a * om * om * nv) / g_out
        w1, w2 = 1.0 / var1, 1.0 / var2
        c = np.zeros((6, 6))
        c[0, 0], c[2, 2], c[4, 4] = w1 * sv, w1 * so + w2 * sv, w1 * nv
        c[1, 1] = w1 * 4.0 * om * om * no + w2 * (v * v * no + om * om * nv)
        c[3, 3], c[5, 5] = w2 * so, w2 * no
        c[1, 5] = c[5, 1] = w2 * v * no
        return np.array([w1, w2]), c, np.array([g_out * var1, g_out * var2])

    def _ring(self) -> RingBuffer:
        """Return the regression samples' buffer (created at the first step)."""
        if self._buffer is None:
            raise OnlineEstimatorError("the regression buffer is read before the first step")
        return self._buffer

    def _init_buffer(self, dt: float) -> None:
        size = max(int(math.ceil(self.options.buffer_s / dt)), 2)
        shapes = {"t": (), "m": (), "k": (), "wd": (), "s": (4,), "info": (4, 4), "D": (6, 6), "d": (6,), "C": (6, 6)}
        shapes.update(
            {"Y": (2, 6), "y": (2,), "e": (2,), "nk": ()}
        )  # rows, wrench less the casters' share, noise variance
        if self.casters is not None:
            g = self.casters.n_geo
            shapes.update({"xc": (g, 6, 4), "xi": (g, 4, 4), "xd": (g, 4)})
        self._buffer = RingBuffer(size, shapes)

    def _regression_step(self, gamma: np.ndarray, dt: float, z: np.ndarray, impulse: bool = False) -> None:
        """Filter, accumulate one regression sample, test for a change, solve, check plausibility.

        ``impulse``: the velocity jumped this period (:meth:`_impulse_statistic`); the filter restarts from the
        motion after the jump (the model has no impulse: filtered, the jump would read as a huge acceleration
        without force for a cut-off period) and the sample is skipped.
        """
        u = self._filter_inputs(gamma, z)
        if impulse:
            u[:3] = z[3:6]
            self.filter.reset(u)
            if self.casters is not None:
                self.casters.restart(self._caster_raw(u, dt))
            self._update_noise(float(u[4]), float(u[5]), dt)
            return
        raw = self._caster_raw(u, dt) if self.casters is not None else None
        if not self._started:
            self.filter.reset(u)
            if self.casters is not None and raw is not None:
                self.casters.restart(raw)
            self._init_buffer(dt)
            self._started = True
        Y, y = self._regression_row(self.filter.step(u, dt))
        self._update_noise(float(u[4]), float(u[5]), dt)
        w, noise, expected = self._weights(dt, float(Y[0, 4]), float(Y[1, 5]))
        reg = self.regression
        p = reg.p
        r = y - Y @ p
        deflate = self._sample_deflation()
        pred = expected + np.einsum("ij,jk,ik->i", Y, self._cov, Y)  # residual variance: noise and the estimate's
        extra = self._caster_sample(Y, y, w, r, raw, dt, pred, deflate) if raw is not None else {}
        share = extra.pop("fit", np.zeros(2))
        r = r - share
        self._check_misfit(r, pred, dt)
        known = self._noise_known(dt)  # the residual window is relative to the noise model: only once it is known
        if known:
            self._local.add(Y, y - share, expected, dt)
        yw = Y * w[:, None]
        info, dvec = yw.T @ Y, yw.T @ y
        s = yw[:, :4].T @ r
        lam = math.exp(-dt / self.options.forgetting_s)
        reg.add(info * deflate, dvec * deflate, noise * deflate, lam)
        misfit = self._misfit_scale()  # the residual ratio, also before the test reports it
        self._record(p, misfit, deflate, s, info, dvec, noise, extra, (Y, y - share, expected), known)
        if self.casters is not None:
            self.casters.choose(reg.p, self._cov, misfit, self.options.misfit_ratio)
            reg.nuisance = self.casters.nuisance()
        if self.options.detect_changes and self._test_change(dt, s, info[:4, :4]):
            self._reset_for_change()
        else:
            reg.solve(1)
            self._cov = reg.covariance()
        self._update_params()

    def _record(
        self,
        p: np.ndarray,
        misfit: float,
        deflate: float,
        s: np.ndarray,
        info: np.ndarray,
        dvec: np.ndarray,
        noise: np.ndarray,
        extra: dict[str, np.ndarray],
        row: tuple[np.ndarray, np.ndarray, np.ndarray],
        known: bool,
    ) -> None:
        """Store one sample in the buffer: its increments at full weight and the weight it entered with (``wd``),
        its row (Y, wrench less the casters' share, noise variance) and whether the noise was known then."""
        rows, y, e = row
        self._ring().push(
            t=self.t,
            m=float(p[0]),
            k=misfit,
            wd=deflate,
            s=s,
            info=info[:4, :4],
            D=info,
            d=dvec,
            C=noise,
            Y=rows,
            y=y,
            e=e,
            nk=float(known),
            **extra,
        )

    def _sample_deflation(self) -> float:
        """Return the weight (at most 1) of this sample's information: 1 / max(1, kappa^2 / kappa_ref^2).

        Feasible weighted least squares with a local scale: the row weights come from the noise model, and a model
        that misfits by kappa (the residual power of the current estimate over the misfit test's window,
        :class:`cart.online_regression.ResidualWindow`) has residuals kappa times larger than that model says.
        Relative to the run's level kappa_ref (:class:`cart.online_regression.MisfitLevel`: the
        ``misfit_level_quantile`` of kappa over the full windows since the last change, at least 1; 1 before the
        first full window, so a start that misfits is weighed against the noise model), a stretch that misfits more
        (a real cart's casters swinging round at a start or a turn) carries (kappa_ref / kappa)^2 of the others'
        information: what it seems to say about a weakly excited direction does not outweigh the rest. A model
        that misfits uniformly (the noise model off by a factor) keeps its samples' weights: the factor scales the
        whole fit's noise, which the stds and the CoM's deflation account for (:meth:`_misfit_scale`), not the
        balance between the samples. ``misfit_level_quantile=None``: kappa_ref = 1 (every sample 1 / kappa^2, a
        uniform misfit loses its data to the prior); ``misfit_weights=False``: always 1.
        """
        if not self.options.misfit_weights:
            return 1.0
        if self._local.weight <= 0.0:
            return 1.0
        ratio2 = self._local.ratio2(self.regression.p, self.regression.H)
        if self.options.misfit_level_quantile is None:
            return 1.0 / max(1.0, ratio2)
        if self._local.elapsed >= self._local.time_s:  # a full window: the run's level counts it
            self._level.add(ratio2)
        return 1.0 / max(1.0, ratio2 / self._level.level2())

    def _caster_raw(self, u: np.ndarray, dt: float) -> np.ndarray:
        """Return the caster bank's raw columns for the period's filter input u (mean velocity, mid heading)."""
        bank = self.casters
        assert bank is not None
        c, s = math.cos(float(u[3])), math.sin(float(u[3]))
        return bank.raw_columns(c * float(u[0]) + s * float(u[1]), float(u[2]), dt)

    def _caster_sample(
        self,
        Y: np.ndarray,
        y: np.ndarray,
        w: np.ndarray,
        r: np.ndarray,
        raw: np.ndarray,
        dt: float,
        pred: np.ndarray,
        deflate: float = 1.0,
    ) -> dict[str, np.ndarray]:
        """Filter the caster columns, compare the models on this sample (prequential), add it to the sums.

        Returns the sample's increments for the buffer (``xc``, ``xi``, ``xd``) and, when the columns are on,
        their a-priori share of the wrench (``fit``: the active geometry's fit on the samples before this one).
        """
        bank, reg = self.casters, self.regression
        assert bank is not None
        cols = bank.filtered(raw, dt)
        bank.compare(r, w, cols, reg.p, dt, pred)
        out = {}
        if reg.nuisance is not None and bank.active is not None:
            out["fit"] = cols[bank.active] @ reg.nuisance.fit(reg.p)
        inc = bank.increments(Y, y, w, cols)
        bank.add(tuple(a * deflate for a in inc))
        out.update(xc=inc[0], xi=inc[1], xd=inc[2])
        return out

    def _test_change(self, dt: float, s: np.ndarray, info: np.ndarray) -> bool:
        """Return whether the GLR test declares a change of mass / CoM / inertia at this sample.

        The test's chi-square holds when the residuals are as large as the noise model says; a model that
        misfits by the residual ratio kappa (:meth:`_misfit_scale`) has scores kappa times larger without any
        change, so their covariance is scaled by kappa^2, with kappa taken one test window back (before a
        change there could raise it).
        """
        _, jr = self.regression.prior.residual(self.regression.p)
        ridge = (jr.T @ jr)[:4, :4]
        buf = self._ring()
        kappa = float(buf.at("k", max(buf.length - 1 - int(self.options.change_window_s / dt), 0)))
        p = float(self.regression.p[0])
        return self.detector.update(dt, s, info, self._cov[:4, :4], ridge, p, kappa)

    def _change_std(self, mass: float, rho: float, post: np.ndarray) -> np.ndarray:
        """Return the re-centred prior's stds of (mass, CoM dx, dy, J / m) after a load change of ``mass`` (kg) and
        radius of gyration squared ``rho``: ``change_mass_rel_std`` and ``change_rho_rel_std`` relative,
        ``change_com_std`` at least the CoM's posterior std ``post[1:3]`` (a load moves the mass more than the
        CoM and the radius of gyration)."""
        o = self.options
        return np.array(
            [
                o.change_mass_rel_std * mass,
                max(float(post[1]), o.change_com_std),
                max(float(post[2]), o.change_com_std),
                o.change_rho_rel_std * rho,
            ]
        )

    def _onset(self) -> tuple[int, float, tuple[float, float], bool]:
        """Return the GLR's onset of the change just detected: its buffer index, time, the stretch of onsets the
        data cannot tell from it (:meth:`ChangeDetector.onset_range`, scaled by the residual ratio at the onset)
        and whether that stretch is censored: it reaches the start of a full buffer, so the data before the buffer
        might fit as well (a change made during a cruise longer than ``buffer_s``).

        A velocity jump near or after the onset (at most twice the settling time before it) dates it: the load came
        with the jump, to the period."""
        buf = self._ring()
        t, k = buf.read("t"), buf.read("k")
        g = self.detector.profile(buf.read("s"), buf.read("info"), self._cov[:4, :4])
        idx, lo, hi = self.detector.onset_range(g, float(k[int(np.argmax(g))]))
        t_change = float(t[idx])
        if self.impulses and self.impulses[-1] >= t_change - 2.0 * self._settle_s():
            return idx, self.impulses[-1], (self.impulses[-1], self.impulses[-1]), False
        return idx, t_change, (float(t[lo]), float(t[hi])), lo == 0 and buf.count > buf.size

    def _reset_for_change(self) -> None:
        """Restart mass / CoM / inertia from the prior widths and the samples after the onset; keep the damping."""
        buf = self._ring()
        idx, t_change, t_range, censored = self._onset()
        m_before = float(buf.read("m")[idx])
        p, prm = self.regression.p, self._params
        center = np.array([prm.m, prm.dx, prm.dy, prm.inertia_b / prm.m, max(p[4], 0.0), max(p[5], 0.0)])
        std = np.r_[
            self._change_std(prm.m, center[3], self._physical_std(self._cov)),
            np.sqrt(np.maximum(np.diag(self._cov)[4:], 1e-12)),
        ]
        full, new, after, local = self._fit_after(idx, PhysicalPrior(center, std))
        self.detector.restart()
        own = math.sqrt(local[0].ratio2(full.p))  # the samples after the onset against their own fit
        sums_before = self._sums_before(idx)
        fit_before, k_old = self._fit_before(sums_before), float(buf.read("k")[idx])
        if self._guess_far(full, fit_before, max(k_old, own, 1.0)):
            self._restart_from(new, local, after)
            buf.clear()
            return
        if not self._confirmed(full, fit_before, (k_old, own)):
            self.regression.solve(1)
            self._cov = self.regression.covariance()
            return
        self._restart_from(new, local, after)
        if self._changes:
            self._changes[-1].mass_end = m_before
        if self.window is not None:
            split = self.window.recent_split(float(self.regression.p[0]) - m_before, t_change)
            if split is not None:  # the window's split, on up to window_s of data, dates the change
                t_change, t_range, censored = split.t_change, split.t_range, False
        self._changes.append(
            _Change(
                t_change,
                self.t,
                m_before,
                self.detector.statistic,
                t_range=t_range,
                censored=censored,
                before=(*fit_before, k_old),
                sums_before=sums_before,
            )
        )
        if self.window is not None:
            before = self._params.with_mass(m_before) if m_before > 0.0 else self._params
            seen = WindowChange(t_change, t_range, self.t, before, self._params, {})
            # an onset inside the buffer is kept as found; a censored one is searched again on the window
            index = self.window.add_change(seen, 1.0 / self.options.cutoff_hz, dated=not censored)
            self._changes[-1].window_index = index
        buf.clear()

    def _second_look(self) -> None:
        """Judge the last GLR change again with the window search's fit of the data after it; withdraw it when the
        two sides no longer differ.

        The GLR confirms a change on the few seconds after its onset (:meth:`_confirmed`); a stretch the model
        misfits (casters swivelling round as the cart starts from rest) can fit a mass far off on so few samples.
        The window's fit (:attr:`cart.window_changes.WindowChangeDetector.fit`: the offline estimate on at least
        ``MIN_SEGMENT_S`` of the data after the onset, its std covering the misfit it sees) judges it once, at
        its first fit whose mass std is below ``min_change`` of the mass before: the change stands when that mass
        and the mass fitted before the onset differ by ``min_change`` of the latter and by ``confirm_sigma`` times
        the std of their difference (the side before's std scaled up by its residual ratio at the onset, as in
        :meth:`_confirmed`). Otherwise it is withdrawn (flagged ``change_withdrawn``) and the restart undone: the
        estimate goes on from all the samples, before the onset and since (:meth:`_undo_restart`).
        """
        window = self.window
        fit = window.fit if window is not None else None
        if window is None or fit is None or not self._changes:
            return
        c = self._changes[-1]
        if c.before is None:
            return
        m_old, std_old, k_old = c.before
        m_new, std_new = float(fit.params.m), float(fit.std["mass"])
        limit = self.options.min_change * abs(m_old)
        if not std_new < limit:
            return
        c.before = None  # judged
        diff = abs(m_new - m_old)
        std = math.hypot(std_new, std_old * max(k_old, 1.0))
        if diff >= limit and diff >= self.options.confirm_sigma * std:
            return
        self._changes.pop()
        if c.sums_before is not None:
            self._undo_restart(c.sums_before)
        if self._changes:
            self._changes[-1].mass_end = None
        if c.window_index is not None and c.window_index == len(window.changes) - 1:
            window.changes.pop()
        self._flags.append(
            RunoffFlag(
                self.t,
                "change_withdrawn",
                f"GLR change at {c.t_change:.2f} s: mass {m_old:.4g} kg before, {m_new:.4g} kg fitted on "
                f"{self.t - c.t_change:.1f} s after it, difference's std {std:.2g} kg",
            )
        )

    def _restart_from_window(self, change: WindowChange) -> None:
        """Restart the parameters from the window search's fit after ``change`` (its estimate and std as the prior).

        The fit holds the samples after the change, so the regression starts with no data of its own; the
        casters' fit so far is carried as a prior (:meth:`CasterBank.carried`), the GLR window and its buffer
        restart.
        """
        a, sd = change.after, change.after_std
        rho = a.inertia_b / a.m
        center = np.array([a.m, a.dx, a.dy, rho, max(a.sigma, 0.0), max(a.sigma_yaw, 0.0)])
        floor = 1e-6 * np.maximum(np.abs(center), 1e-3)
        std = np.maximum(np.array([sd["mass"], *sd["com"], sd["inertia"] / a.m, sd["sigma"], sd["sigma_yaw"]]), floor)
        reg = self.regression
        if self.casters is not None:
            _, jr = reg.prior.residual(reg.p)
            zero = (
                np.zeros_like(self.casters.cross),
                np.zeros_like(self.casters.info),
                np.zeros_like(self.casters.dvec),
            )
            self.casters.cross, self.casters.info, self.casters.dvec = self.casters.carried(
                zero, reg.D + jr.T @ jr, reg.p
            )
        new = RecursiveRegression(PhysicalPrior(center, std), self.options.noise_subspace)
        new.nuisance = self.casters.nuisance() if self.casters is not None else None
        new.solve(iterations=3)
        self.regression, self._cov = new, new.covariance()
        self._local.clear()
        self._level.clear()
        if self._changes:
            self._changes[-1].mass_end = change.before.m
        index = len(self.window.changes) - 1 if self.window is not None else None
        self._changes.append(
            _Change(
                change.t_change,
                change.t_detected,
                change.before.m,
                0.0,
                method="window",
                window_index=index,
                t_range=change.t_range,
            )
        )
        self.detector.restart()
        if self._buffer is not None:
            self._buffer.clear()
        self._update_params()

    def _weighted_sum(self, key: str, idx: int) -> np.ndarray:
        """Return the sum of the buffered samples' ``key`` from ``idx``, each at the weight it entered the regression with."""
        buf = self._ring()
        rows, wd = buf.read(key)[idx:], buf.read("wd")[idx:]
        return np.tensordot(wd, rows, axes=1)

    def _fit_after(
        self, idx: int, prior: PhysicalPrior
    ) -> tuple[
        RecursiveRegression, RecursiveRegression, tuple[np.ndarray, ...] | None, tuple[ResidualWindow, MisfitLevel]
    ]:
        """Return the fits of the samples from the onset ``idx`` under ``prior`` (at full weight; reweighted), the
        reweighted fit's caster sums and the residual window of those samples.

        The samples entered the regression weighted by the residual ratio of the estimate *before* the change
        (:meth:`_sample_deflation`), which the change itself raised. They are fitted at full weight first (what
        the confirmation tests, :meth:`_confirmed`), then reweighted by their own residual ratio against that fit
        (one step of iteratively reweighted least squares, :meth:`_refit_weights`): what still misfits after the
        change (the transient after a load's drop) keeps a small weight in the estimate that goes on.
        The casters' fit on the samples before the onset is carried over as a prior (:meth:`CasterBank.carried`).
        """
        reg = self.regression
        d_before = reg.D - self._weighted_sum("D", idx)
        _, jr = reg.prior.residual(reg.p)
        weights = np.ones(len(self._ring().read("t")) - idx)
        full, after = self._weighted_fit(idx, prior, weights, d_before + jr.T @ jr)
        new, level = full, MisfitLevel(self._level.quantile)
        if self.options.misfit_weights:
            weights, level = self._refit_weights(idx, full)
            new, after = self._weighted_fit(idx, prior, weights, d_before + jr.T @ jr)
        return full, new, after, (self._window_from(idx), level)

    def _weighted_fit(
        self, idx: int, prior: PhysicalPrior, weights: np.ndarray, info_before: np.ndarray
    ) -> tuple[RecursiveRegression, tuple[np.ndarray, ...] | None]:
        """Return the fit of the samples from ``idx`` with ``weights`` under ``prior`` and its caster sums
        (the casters' fit on the samples before, whose information with the prior is ``info_before``, carried)."""
        buf = self._ring()
        new = RecursiveRegression(prior, self.options.noise_subspace)
        new.D, new.d, new.C = (np.tensordot(weights, buf.read(k)[idx:], axes=1) for k in ("D", "d", "C"))
        after = None
        if self.casters is not None:
            bank, keys = self.casters, ("xc", "xi", "xd")
            sums = tuple(np.tensordot(weights, buf.read(k)[idx:], axes=1) for k in keys)
            before = tuple(b - self._weighted_sum(k, idx) for b, k in zip((bank.cross, bank.info, bank.dvec), keys))
            after = bank.carried(sums, info_before, self.regression.p, before)
            if self.casters.active is not None:
                g = self.casters.active
                new.nuisance = Nuisance(after[0][g], after[1][g], after[2][g])
        new.solve(iterations=5)
        return new, after

    def _refit_weights(self, idx: int, fit: RecursiveRegression) -> tuple[np.ndarray, MisfitLevel]:
        """Return the weights of the samples from ``idx`` by their own misfit against ``fit`` and those samples'
        misfit level: 1 / max(1, q / q_ref), q the squared residual ratio smoothed forwards and backwards over one
        cut-off period (the filtered residuals' correlation time), so that a transient (the filter's restart after a
        load's drop) weighs only itself, and q_ref their ``misfit_level_quantile`` (1 with ``None``,
        :meth:`_sample_deflation`)."""
        buf = self._ring()
        t, rows, y, e, known = (buf.read(k)[idx:] for k in ("t", "Y", "y", "e", "nk"))
        r = y - np.einsum("nij,j->ni", rows, fit.p)
        q = np.max(r * r / e, axis=1)
        lam = np.exp(-np.diff(t) * self.options.cutoff_hz)
        n = len(t)
        smooth = np.zeros((2, n))
        for sweep, order in ((0, range(n)), (1, range(n - 1, -1, -1))):
            acc = [0.0, 0.0]
            for k in order:
                j = k - 1 if sweep == 0 else k  # the gap to the previous sample of the sweep
                decay = float(lam[j]) if 0 <= j < n - 1 else 0.0
                acc = [decay * acc[0] + 1.0, decay * acc[1] + float(q[k])]
                smooth[sweep, k] = acc[1] / acc[0]
        ratio = 0.5 * (smooth[0] + smooth[1])
        level = MisfitLevel(self._level.quantile)
        for value in ratio[known > 0.0]:
            level.add(float(value))
        if self.options.misfit_level_quantile is not None:
            ratio = ratio / level.level2()
        return np.where(known > 0.0, 1.0 / np.maximum(1.0, ratio), 1.0), level

    def _window_from(self, idx: int) -> ResidualWindow:
        """Return the residual window of the samples from ``idx``."""
        buf = self._ring()
        t, rows, y, e, known = (buf.read(k)[idx:] for k in ("t", "Y", "y", "e", "nk"))
        window = ResidualWindow(self._local.time_s)
        for k in range(len(t)):
            if known[k]:
                window.add(rows[k], y[k], e[k], float(t[k] - t[k - 1]) if k else math.inf)
        return window

    def _sums_before(self, idx: int) -> _SumsBefore:
        """Return the regression's sums on the samples before the onset ``idx`` (the buffered samples from ``idx``
        taken out at the weight they entered with), with the casters' sums and the caster prior a restart at
        ``idx`` carries over (:meth:`CasterBank.carried`, as :meth:`_fit_after` adds it)."""
        reg = self.regression
        normal = tuple(getattr(reg, k) - self._weighted_sum(k, idx) for k in ("D", "d", "C"))
        sums = _SumsBefore(reg.prior, reg.excitation_margin, normal)
        if self.casters is not None:
            bank = self.casters
            sums.casters = tuple(
                b - self._weighted_sum(k, idx) for b, k in zip((bank.cross, bank.info, bank.dvec), ("xc", "xi", "xd"))
            )
            _, jr = reg.prior.residual(reg.p)
            zero = tuple(np.zeros_like(a) for a in sums.casters)
            sums.carried = bank.carried(zero, normal[0] + jr.T @ jr, reg.p, sums.casters)
        return sums

    def _fit_before(self, sums: _SumsBefore) -> tuple[float, float]:
        """Return (mass, std) fitted on the samples before an onset alone (``sums``, under the regression's prior)."""
        before = RecursiveRegression(sums.prior, self.regression.noise_subspace)
        before.D, before.d, before.C = sums.normal
        if sums.casters is not None and self.casters is not None and self.casters.active is not None:
            g = self.casters.active
            before.nuisance = Nuisance(sums.casters[0][g], sums.casters[1][g], sums.casters[2][g])
        before.solve(iterations=5)
        return float(before.p[0]), float(self._physical_std(before.covariance())[0])

    def _undo_restart(self, sums: _SumsBefore) -> None:
        """Go on as if a withdrawn change had never restarted the estimate: the samples before its onset
        (``sums``, on their prior) and the regression's samples since (those after the onset, reweighted by
        their misfit, and all later ones) in one regression; the casters' sums alike, less the prior the restart
        carried over."""
        reg = self.regression
        merged = RecursiveRegression(sums.prior, reg.noise_subspace, sums.excitation_margin)
        merged.D, merged.d, merged.C = (a + b for a, b in zip(sums.normal, (reg.D, reg.d, reg.C)))
        if self.casters is not None and sums.casters is not None and sums.carried is not None:
            bank = self.casters
            bank.cross, bank.info, bank.dvec = (
                b + now - c for b, now, c in zip(sums.casters, (bank.cross, bank.info, bank.dvec), sums.carried)
            )
            merged.nuisance = bank.nuisance()
        merged.solve(iterations=5)
        self.regression, self._cov = merged, merged.covariance()
        self._update_params()

    def _restart_from(self, new: RecursiveRegression, local: tuple, after: tuple | None) -> None:
        """Go on from ``new``: the regression of the samples after an onset on its re-centred prior (a load change,
        or an initial guess the pushes contradict), with their residuals and caster sums."""
        self.regression = new
        self._cov = new.covariance()
        self._local, self._level = local  # the residuals of the samples after the onset, their level
        if after is not None and self.casters is not None:
            self.casters.cross, self.casters.info, self.casters.dvec = after
            new.nuisance = self.casters.nuisance()

    def _guess_far(self, new: RecursiveRegression, before: tuple[float, float], kappa: float) -> bool:
        """Return whether a GLR detection says the initial guess was wrong (flagged ``guess_far``), not the load.

        Before any change, when the samples before the onset do not excite the mass (their mass is the initial
        guess), those after it do, their fit is plausible and its mass lies more than ``GUESS_FAR_SIGMA`` of the
        initial prior's stds from the guess and ``confirm_sigma`` of its own std (scaled by the residual ratio
        ``kappa``) from it: the data contradict the prior (a 300 kg pallet pushed from a 16 kg guess). The
        estimate then restarts from the samples after the onset on the re-centred prior, as after a load change
        (the samples before it held no mass information), and no load change is reported.
        """
        if self._changes or any(f.kind == "guess_far" for f in self._flags):
            return False
        m0, s0 = float(self._prior0.center[0]), float(self._prior0.std[0])
        m_new = float(new.p[0])
        std_new = float(self._physical_std(new.covariance())[0])
        ratio = self.options.excited_ratio
        if before[1] <= ratio * s0 or std_new > ratio * float(new.prior.std[0]) or self._implausible(new.p):
            return False
        far = abs(m_new - m0)
        if far <= GUESS_FAR_SIGMA * s0 or far <= self.options.confirm_sigma * kappa * std_new:
            return False
        self._flags.append(
            RunoffFlag(
                self.t,
                "guess_far",
                f"the pushes weigh the cart {m_new:.4g} +- {std_new:.2g} kg, {far / s0:.1f} prior stds from the initial "
                f"guess {m0:.4g} kg: the estimate restarts from them (not a load change)",
            )
        )
        return True

    def _confirmed(self, new: RecursiveRegression, before: tuple[float, float], misfit: tuple[float, float]) -> bool:
        """Return whether the two sides of the onset confirm a load change: their masses differ.

        Each side is fitted on its own samples (``new``: after the onset, from its re-centered prior;
        ``before``: (mass, std) before it); ``misfit``: the residual ratios of the two sides, (the windowed one at
        the onset, before the change could raise it; that of the samples after the onset against ``new``, their
        own fit). The GLR statistic also grows when the model misfits (a real cart's casters swivelling round at a
        reversal, a braking's onset): the residuals change while the mass does not, and the fit after the onset
        then misfits its own samples too (a step of the parameters is what a load change is; what they cannot
        express stays in the residuals). A change is confirmed when the samples after the onset excite the mass
        (posterior / prior std at most ``excited_ratio``), their estimate is plausible (:meth:`_implausible`: a
        misfit may fit a negative mass), the samples before it excite the mass as well (else the mass before is
        the initial guess, and the estimate converging from it is not a change) and the two masses differ by
        ``min_change`` of the mass before; when
        either side misfits (its ratio above ``misfit_ratio``: the GLR's chi-square does not hold), also by
        ``confirm_sigma`` times the std of their difference scaled up by the larger ratio (the misfit the stds
        do not contain: the model's, which the side that shows it measures). Otherwise the detection is flagged
        ``change_not_confirmed`` and the estimate goes on with all its samples.
        """
        m_new, (m_old, std_old) = float(new.p[0]), before
        k_old, k_new = (max(k, 1.0) for k in misfit)
        std_new = float(self._physical_std(new.covariance())[0])
        excited = std_new <= self.options.excited_ratio * new.prior.std[0]
        # the side before must be weighed by its own samples too: a start whose first second does not excite the
        # mass keeps the initial guess, and the data converging from it is not a load change
        before_excited = std_old <= self.options.excited_ratio * float(self.regression.prior.std[0])
        diff = abs(m_new - m_old)
        bad = self._implausible(new.p)
        ok = excited and before_excited and diff >= self.options.min_change * abs(m_old) and not bad
        kappa = max(k_old, k_new)
        std = math.hypot(std_new, std_old) * kappa
        if kappa > self.options.misfit_ratio:
            ok = ok and diff >= self.options.confirm_sigma * std
        if not ok:
            self._flags.append(
                RunoffFlag(
                    self.t,
                    "change_not_confirmed",
                    f"GLR {self.detector.statistic:.1f}: mass {m_old:.4g} kg before, {m_new:.4g} kg after, "
                    f"difference's std {std:.2g} kg"
                    + ("" if excited else " (not excited)")
                    + ("" if before_excited else " (the side before not excited)")
                    + "".join(f" ({v})" for v in bad.values()),
                )
            )
        return ok

    # -- plausibility -----------------------------------------------------------------------
    def _flag(self, kind: str, on: bool, detail: str) -> None:
        """Record the start of an episode of ``kind`` (once until it ends).

        An episode that starts again within ``change_window_s`` of the end of the last one of its kind continues
        it (a plausibility test flickering at its bound flagged the wheelchair's Traj. 2 400 times)."""
        if on and kind not in self._active:
            if self.t - self._ended.get(kind, -math.inf) > self.options.change_window_s:
                self._flags.append(RunoffFlag(self.t, kind, detail))
            self._active.add(kind)
        elif not on and kind in self._active:
            self._active.discard(kind)
            self._ended[kind] = self.t

    def _check_misfit(self, r: np.ndarray, pred: np.ndarray, dt: float) -> None:
        """Windowed innovation test: residual power over ``pred`` (what noise and the estimate's std explain), per row."""
        lam = math.exp(-dt / (2.0 * self.options.change_window_s))
        mf = self._misfit
        mf[0] = lam * mf[0] + 1.0
        mf[1] = lam * mf[1] + float(r[0] ** 2 / pred[0])
        mf[2] = lam * mf[2] + float(r[1] ** 2 / pred[1])
        if self.t < 2.0 * self.options.change_window_s:
            return
        self.residual_ratio = (math.sqrt(mf[1] / mf[0]), math.sqrt(mf[2] / mf[0]))
        worst = max(self.residual_ratio)
        self._flag("misfit", worst > self.options.misfit_ratio, f"residual ratio {worst:.2f}")

    def _implausible(self, p: np.ndarray) -> dict[str, str]:
        """Return what is implausible in p = [m, m dx, m dy, J, c_v, c_w] (kind -> what was seen; empty: plausible).

        Plausible: mass above 5 % of the prior's, CoM inside the footprint, inertia about the CoM positive.
        """
        m, a, b, j = p[:4].tolist()
        m_min = 0.05 * float(self._prior0.center[0])
        mp = max(m, m_min)
        dx, dy = a / mp, b / mp
        inertia = j - (a * a + b * b) / mp
        fx, fy = self._footprint
        out = {}
        if m <= m_min:
            out["nonpositive_mass"] = f"mass {m:.4g} kg"
        if abs(dx) > fx or abs(dy) > fy:
            out["com_outside_footprint"] = f"CoM ({dx:.3g}, {dy:.3g}) m"
        if inertia <= 0.0:
            out["nonpositive_inertia"] = f"inertia about the CoM {inertia:.4g} kg m^2"
        return out

    def _update_params(self) -> None:
        """Set the controller's parameters: the estimate when plausible, else the last plausible one (flagged)."""
        p = self.regression.p
        bad = self._implausible(p)
        for kind in ("nonpositive_mass", "com_outside_footprint", "nonpositive_inertia"):
            self._flag(kind, kind in bad, bad.get(kind, ""))
        if not bad:
            m, a, b, j, cv, cw = p.tolist()
            dx, dy = self._com_to_use(a / m, b / m)
            self._params = CartParams(m, dx, dy, j - (a * a + b * b) / m, max(cv, 0.0), max(cw, 0.0))

    def _com_to_use(self, dx: float, dy: float) -> tuple[float, float]:
        """Return the CoM given to the controller: the estimate's pull from the prior, deflated by the misfit.

        The regression weighs its samples by their noise model; when the model misfits (residual ratio
        kappa > 1, :meth:`_misfit_scale`: a real cart's casters in the yaw row), its data carry kappa^2 less
        information than it assumes. Per coordinate, with r = (posterior std / prior std)^2 the prior's share
        of the information, the posterior mean with the data's information divided by kappa^2 moves from the
        prior by 1 / (1 - r + r kappa^2) of the estimate's move: a coordinate the data fix (r small) keeps
        its estimate, one they hardly excite stays near the prior (never worse than the prior). The
        regression keeps its estimate (``deflate_com``); the inertia about the CoM stays the estimate's.
        """
        kappa = self._misfit_scale()
        if not self.options.deflate_com or kappa <= 1.0:
            return dx, dy
        post = self._physical_std(self._cov)[1:3]
        prior = self.regression.prior
        out = []
        for i, est in ((1, dx), (2, dy)):
            r = min(float(post[i - 1] / prior.std[i]) ** 2, 1.0)
            out.append(float(prior.center[i]) + (est - float(prior.center[i])) / (1.0 - r + r * kappa * kappa))
        return out[0], out[1]


def make_online_estimator(
    q0: npt.ArrayLike, params0: CartParams, noise_std: npt.ArrayLike, **options
) -> OnlineLSEstimator:
    """Return an :class:`OnlineLSEstimator` starting at rest at pose q0 (or q0 = 6-state) with the guess params0.

    ``noise_std`` (6,): motion-capture std of (x, y, theta, vx, vy, omega); ``options``: fields of
    :class:`OnlineOptions` (e.g. ``wrench_std=(3.0, 0.3)``, ``detect_changes=False``).
    """
    q = np.asarray(q0, dtype=float).reshape(-1)
    if q.shape not in ((3,), (6,)):
        raise OnlineEstimatorError(f"q0 must be a pose (3,) or a state (6,), got shape {q.shape}")
    try:
        opts = replace(OnlineOptions(), **options)
    except TypeError as exc:
        raise OnlineEstimatorError(f"unknown online estimator option: {exc}") from None
    qd0 = q[3:6] if q.shape == (6,) else np.zeros(3)
    return OnlineLSEstimator(q[:3], qd0, params0, noise_std, opts)

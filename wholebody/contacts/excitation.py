"""Persistence of excitation of a planned push (paper §II.D) and a contact-schedule planner.

The cart's motion has two degrees of freedom (forward speed ``v``, yaw rate
``omega``). Its reduced dynamics, written at the {b} origin in {b} axes, are
linear in ``phi = [m, m dx, m dy, I + m (dx^2 + dy^2)]`` (paper §II.B)::

    f_forward = m vdot - (m dx) omega^2 - (m dy) omegadot      + sigma v
    tau_b     = -(m dy) vdot + (m dx) v omega + J omegadot      + sigma omega

i.e. ``Y(v, vdot, omega, omegadot) phi + sigma [v, omega] = [f_forward, tau_b]``;
the lateral force is absorbed by the wheels and carries no information.

The wrench the estimator uses is uncertain by a noise that is white in the
contact frame {a} (std ``force`` on each force axis, ``torque`` on the yaw
torque): the F/T sensor's noise, the arm's wrench-tracking error, or what is
left of both after fusing them (:func:`input_model`). Through the grasp map
(eqs. 23–24) the noise of ``(f_forward, tau_b)`` depends on where the hand
holds the handle: ``tau_b = tau_z + px fy - py fx``. The contact schedule
therefore changes the Fisher information of phi::

    I = sum_t Y_t^T R(p_t)^{-1} Y_t,   R(p) = S G(p) Sigma_ee G(p)^T S^T.

With the default handle (px fixed, py the lateral offset) R(p)^{-1} is a
quadratic in py with a positive semi-definite py^2 term: the precisely measured
combination is ``tau_b + py f_forward = tau_z + px fy``, so an off-centre hand
weights the forward-force row into the precise row (and the handle's ends
dominate any interior point).

Scores of a push (larger is better, :func:`objective_value`):

* ``"min_eig"``: smallest eigenvalue of ``D I D``, ``D`` the parameter scales;
* ``"com_a"``: minus the trace of the CoM block of the Cramér–Rao bound
  ``J_c (I + P0^{-1})^{-1} J_c^T`` (A-optimality on (dx, dy); ``P0`` the
  estimator's prior, ``J_c = d(dx, dy)/d phi``), what the EKF's CoM error is
  bounded by;
* ``"com_d"``: minus the log-determinant of the same 2x2 block;
* ``"com_a_path"`` (schedules only): minus the mean of that trace at the end of
  each segment, i.e. the CoM bound along the push, which rewards converging early.

The planner picks a piecewise-constant contact schedule (``n_segments`` pieces)
maximizing a score under an effort budget (the allocation effort of
`wholebody.contacts.allocation`, integrated over the push).

The closed-loop study (``studies.excitation_study.com_convergence_traj2``: Traj. 2 with the
paper's EKF fed the wrench and its contact-dependent covariance) is kept apart from this
library module; see docs/contacts.md for the numbers.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from cart.dynamics import regressor
from wholebody.contacts.allocation import ArmLimits, WrenchAllocator
from wholebody.contacts.handle import HandleSegment, grasp_map
from wholebody.contacts.placement import effort_sweep
from wholebody.errors import WholeBodyError

#: Scores the planner can maximize (see the module docstring).
OBJECTIVES = ("min_eig", "com_a", "com_d", "com_a_path")
#: Wrenches the EKF can be fed (see :func:`input_model`).
EKF_INPUTS = ("measured", "fused", "commanded")


@dataclass(frozen=True)
class WrenchNoise:
    """Std of a white end-effector wrench noise in {a}: force (N, each axis), yaw torque (N m)."""

    force: float = 3.0
    torque: float = 0.3

    def __post_init__(self) -> None:
        if not (self.force >= 0.0 and self.torque >= 0.0):
            raise WholeBodyError(f"wrench noise std must be >= 0, got force={self.force}, torque={self.torque}")

    def covariance_ee(self) -> np.ndarray:
        """Return the 6x6 covariance of [f; tau] in {a} (fz, tau_x, tau_y noise-free: planar contact)."""
        return np.diag([self.force**2, self.force**2, 0.0, 0.0, 0.0, self.torque**2])


@dataclass(frozen=True)
class InputModel:
    """The wrench fed to the EKF: ``commanded + gain * (measured - commanded)`` per {a} axis, and its error std.

    ``gain_force`` applies to fx, fy, ``gain_torque`` to tau_z; ``noise`` is the
    std of the applied wrench minus the EKF's input.
    """

    gain_force: float
    gain_torque: float
    noise: WrenchNoise

    def gains_ee(self) -> np.ndarray:
        """Return the per-component gains (6,) of [f; tau] in {a}."""
        return np.array([self.gain_force, self.gain_force, 0.0, 0.0, 0.0, self.gain_torque])


def _fuse(actuation: float, sensor: float) -> tuple[float, float]:
    """Return (gain, error std) of the conditional mean of the applied value given command and measurement."""
    ve, vn = actuation**2, sensor**2
    if ve == 0.0:
        return 0.0, 0.0
    if vn == 0.0:
        return 1.0, 0.0
    return ve / (ve + vn), float(np.sqrt(ve * vn / (ve + vn)))


def input_model(mode: str, sensor: WrenchNoise = WrenchNoise(), actuation: WrenchNoise = WrenchNoise()) -> InputModel:
    """Return how the EKF's wrench input is formed and the std of its error.

    The arm applies ``commanded + e`` (``e`` white in {a}, std ``actuation``:
    its wrench-tracking error); the F/T sensor reads ``applied + n`` (std
    ``sensor``). Modes:

    * ``"measured"``: the F/T reading; error ``-n`` (std ``sensor``). The
      error is correlated with the input itself (errors in variables), which
      biases the EKF's parameters whenever ``sensor`` is not small against the
      applied wrench's own variation;
    * ``"commanded"``: the command; error ``e`` (std ``actuation``);
    * ``"fused"``: the conditional mean ``E[applied | commanded, measured]``,
      gain ``actuation^2 / (actuation^2 + sensor^2)`` per axis; its error is
      uncorrelated with the input (orthogonality of the conditional mean), std
      ``(actuation^-2 + sensor^-2)^-1/2``.
    """
    if mode == "measured":
        return InputModel(1.0, 1.0, sensor)
    if mode == "commanded":
        return InputModel(0.0, 0.0, actuation)
    if mode == "fused":
        gf, sf = _fuse(actuation.force, sensor.force)
        gt, st = _fuse(actuation.torque, sensor.torque)
        return InputModel(gf, gt, WrenchNoise(sf, st))
    raise WholeBodyError(f"unknown EKF input {mode!r}; choose one of {', '.join(EKF_INPUTS)}")


@dataclass(frozen=True)
class PushSamples:
    """A planned cart motion on a time grid: forward speed, its rate, yaw rate, its rate.

    Also the desired motion of the synthetic-log test bed (``studies.testbeds.hidden_effects.Motion``).
    """

    t: np.ndarray
    v: np.ndarray
    vdot: np.ndarray
    omega: np.ndarray
    omegadot: np.ndarray

    @property
    def dt(self) -> float:
        """Return the sampling period."""
        return float(self.t[1] - self.t[0])

    def at(self, t: float) -> tuple[float, float, float, float]:
        """Return (v, vdot, omega, omegadot) at time t (linear interpolation)."""
        return (
            float(np.interp(t, self.t, self.v)),
            float(np.interp(t, self.t, self.vdot)),
            float(np.interp(t, self.t, self.omega)),
            float(np.interp(t, self.t, self.omegadot)),
        )


@dataclass(frozen=True)
class ContactSchedule:
    """Piecewise-constant contact: handle coordinate ``s[k]`` on [boundaries[k], boundaries[k+1])."""

    boundaries: np.ndarray
    s: np.ndarray

    def at(self, t: float) -> float:
        """Return the handle coordinate held at time t."""
        k = int(np.clip(np.searchsorted(self.boundaries, t, side="right") - 1, 0, len(self.s) - 1))
        return float(self.s[k])

    def __call__(self, t: float) -> float:
        """Return the handle coordinate held at time t (same as :meth:`at`)."""
        return self.at(t)


@dataclass(frozen=True)
class SchedulePlan:
    """The planned schedule, its score and effort, and the best fixed contact (by the same score).

    ``com_std`` / ``fixed_com_std``: sqrt of the diagonal of the CoM Cramér–Rao
    bound (dx, dy) in m of the plan / of the best fixed contact, under the
    planning model.
    """

    schedule: ContactSchedule
    score: float
    effort: float
    fixed_s: float
    fixed_score: float
    fixed_effort: float
    budget: float
    objective: str = "min_eig"
    com_std: tuple[float, float] = (float("nan"), float("nan"))
    fixed_com_std: tuple[float, float] = (float("nan"), float("nan"))


def sample_push(trajectory, dt: float = 0.05, duration: float | None = None) -> PushSamples:
    """Return the samples of a unicycle trajectory (``speed(t)``, ``yaw(t)`` as in cart.trajectories)."""
    T = float(duration if duration is not None else trajectory.duration)
    t = np.arange(0.0, T + 1e-9, dt)
    sp = np.array([trajectory.speed(x) for x in t])
    yw = np.array([trajectory.yaw(x) for x in t])
    return PushSamples(t, sp[:, 0], sp[:, 1], yw[:, 1], yw[:, 2])


def reduced_regressor(v, vdot, omega, omegadot) -> np.ndarray:
    """Return Y (..., 2, 4): rows (f_forward, tau_b) per unit of phi (the phi columns of cart.dynamics.regressor)."""
    return regressor(v, omega, vdot, omegadot)[..., :4]


def reduced_wrench(
    samples: PushSamples, phi: Sequence[float], sigma: float = 0.0, sigma_yaw: float | None = None
) -> np.ndarray:
    """Return (N, 2) [f_forward, tau_b] the planned motion needs for parameters phi and the viscous coefficients."""
    p = np.r_[np.asarray(phi, dtype=float), sigma, sigma if sigma_yaw is None else sigma_yaw]
    return regressor(samples.v, samples.omega, samples.vdot, samples.omegadot) @ p


def cart_wrench_covariance(point_b: Sequence[float], cov_ee: np.ndarray, theta: float = 0.0) -> np.ndarray:
    """Return the 3x3 covariance of gamma = (fx, fy, tau) in {s} axes of a wrench noise cov_ee (6x6) in {a}.

    ``R_z(theta) G(p) Sigma_ee G(p)^T R_z(theta)^T`` with G the planar grasp map
    (eqs. 23–24, torque about the {b} origin) and theta the cart heading.
    """
    G = grasp_map(point_b)
    c, s = np.cos(theta), np.sin(theta)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    M = Rz @ G
    return M @ np.asarray(cov_ee, dtype=float) @ M.T


def measurement_covariance(point_b: npt.ArrayLike, noise: WrenchNoise = WrenchNoise()) -> np.ndarray:
    """Return R(p) (2x2): covariance of (f_forward, tau_b) from a wrench noise in {a} at contact p."""
    G = grasp_map(point_b)[[0, 2]][:, [0, 1, 5]]  # rows fx_b, tau_b; columns fx, fy, tau_z at {a}
    return G @ np.diag([noise.force**2, noise.force**2, noise.torque**2]) @ G.T


def fisher_information(
    samples: PushSamples, points_b: np.ndarray, noise: WrenchNoise = WrenchNoise(), sensor_dt: float | None = None
) -> np.ndarray:
    """Return the 4x4 Fisher information of phi for samples held at points_b (N x 3, one per sample).

    One wrench reading per sample, or, with ``sensor_dt``, one every
    ``sensor_dt`` seconds (the sum is scaled by ``samples.dt / sensor_dt``).
    """
    Y = reduced_regressor(samples.v, samples.vdot, samples.omega, samples.omegadot)
    pts = np.asarray(points_b, dtype=float).reshape(len(samples.t), 3)
    Rinv = np.array([np.linalg.inv(measurement_covariance(p, noise)) for p in pts])
    scale = 1.0 if sensor_dt is None else samples.dt / float(sensor_dt)
    return scale * np.einsum("nji,njk,nkl->il", Y, Rinv, Y)


def parameter_scale(phi: Sequence[float], length: float = 0.3) -> np.ndarray:
    """Return D = diag(m, m L, m L, m L^2): the scales that make phi's entries comparable."""
    m = float(phi[0])
    return np.diag([m, m * length, m * length, m * length**2])


def excitation_score(info: np.ndarray, phi: Sequence[float]) -> float:
    """Return the smallest eigenvalue of D I D (the persistence-of-excitation score)."""
    D = parameter_scale(phi)
    return float(np.linalg.eigvalsh(D @ info @ D)[0])


def default_prior(phi: Sequence[float]) -> np.ndarray:
    """Return the 4x4 prior covariance of phi that `cart.ekf.CartEKF` starts from for the guess phi."""
    from cart.ekf import initial_covariance

    return initial_covariance(np.asarray(phi, dtype=float), [1.0] * 6)[6:, 6:]


def com_jacobian(phi: Sequence[float]) -> np.ndarray:
    """Return d(dx, dy)/d phi (2x4) at phi, with dx = phi[1]/phi[0], dy = phi[2]/phi[0]."""
    m, a, b, _ = (float(v) for v in phi)
    if m <= 0.0:
        raise WholeBodyError(f"the planning model needs a positive mass, got phi = {list(phi)}")
    return np.array([[-a / m**2, 1.0 / m, 0.0, 0.0], [-b / m**2, 0.0, 1.0 / m, 0.0]])


def com_covariance(info: np.ndarray, phi: Sequence[float], prior_cov: np.ndarray | None = None) -> np.ndarray:
    """Return the 2x2 Cramér–Rao bound of the CoM (dx, dy): J_c (I + P0^-1)^-1 J_c^T.

    ``prior_cov`` is P0 (default: the EKF's prior for phi, :func:`default_prior`);
    the bound is the posterior covariance of the linearized problem.
    """
    P0 = default_prior(phi) if prior_cov is None else np.asarray(prior_cov, dtype=float)
    C = np.linalg.inv(np.asarray(info, dtype=float) + np.linalg.inv(P0))
    J = com_jacobian(phi)
    return J @ C @ J.T


def objective_value(
    info: np.ndarray, phi: Sequence[float], objective: str = "min_eig", prior_cov: np.ndarray | None = None
) -> float:
    """Return the score of a push with Fisher information ``info`` (larger is better; see the module docstring).

    ``info`` is the 4x4 information of the whole push, or for ``"com_a_path"``
    the (K, 4, 4) stack of the information gathered in each of K consecutive
    segments.
    """
    info = np.asarray(info, dtype=float)
    if objective == "com_a_path":
        cum = np.cumsum(info.reshape(-1, 4, 4), axis=0)
        return float(np.mean([objective_value(c, phi, "com_a", prior_cov) for c in cum]))
    if info.ndim == 3:
        info = info.sum(axis=0)
    if objective == "min_eig":
        return excitation_score(info, phi)
    if objective in ("com_a", "com_d"):
        C = com_covariance(info, phi, prior_cov)
        return -float(np.trace(C)) if objective == "com_a" else -float(np.linalg.slogdet(C)[1])
    raise WholeBodyError(f"unknown objective {objective!r}; choose one of {', '.join(OBJECTIVES)}")


def _segment_tables(samples, phi, sigma, handle, candidates, n_segments, noise, limits, sensor_dt=None):
    """Return boundaries, info[k, j] (4x4) and effort[k, j] for segment k held at candidate j."""
    T = samples.t[-1]
    bounds = np.linspace(0.0, T, n_segments + 1)
    seg = np.clip(np.searchsorted(bounds, samples.t, side="right") - 1, 0, n_segments - 1)
    Y = reduced_regressor(samples.v, samples.vdot, samples.omega, samples.omegadot)
    need = reduced_wrench(samples, phi, sigma)  # (N, 2): f_forward, tau_b
    gam = np.stack([need[:, 0], np.zeros(len(need)), need[:, 1]], axis=1)
    alloc = WrenchAllocator([handle.point(0.0)], limits, only_motion_directions=True)
    scale = 1.0 if sensor_dt is None else samples.dt / float(sensor_dt)
    J = len(candidates)
    pts = np.array([handle.point(float(s)) for s in candidates])
    tol = 1e-6 * np.maximum(1.0, np.max(np.abs(gam), axis=1))
    sweep = effort_sweep(alloc, pts[:, None, :], gam)  # (J, N) allocations, paper eq. (25)
    e_all = np.where(sweep.residual < tol, sweep.effort, np.inf)
    info = np.zeros((n_segments, J, 4, 4))
    effort = np.zeros((n_segments, J))
    for j, p in enumerate(pts):
        Rinv = np.linalg.inv(measurement_covariance(p, noise))
        per = scale * np.einsum("nji,jk,nkl->nil", Y, Rinv, Y)
        for k in range(n_segments):
            mask = seg == k
            info[k, j] = per[mask].sum(axis=0)
            effort[k, j] = e_all[j][mask].sum() * samples.dt
    return bounds, info, effort


def _best_schedule(
    info: np.ndarray,
    effort: np.ndarray,
    budget: float,
    score: Callable[[np.ndarray], float],
    sweeps: int,
    exhaustive_limit: int,
) -> tuple[list[int], float]:
    """Return (candidate index per segment, score) maximizing score(per-segment infos) within the effort budget.

    Exhaustive when J^K <= exhaustive_limit; else coordinate ascent (one segment
    at a time, every candidate) started from every feasible fixed contact.
    """
    K, J = effort.shape
    total = lambda idx: info[np.arange(K), idx]  # noqa: E731  (K, 4, 4): the chosen segments' information
    cost = lambda idx: effort[np.arange(K), idx].sum()  # noqa: E731
    best_idx: np.ndarray | None = None
    best = -np.inf
    if J**K <= exhaustive_limit:
        for combo in itertools.product(range(J), repeat=K):
            idx = np.array(combo)
            if cost(idx) <= budget:
                sc = score(total(idx))
                if sc > best:
                    best_idx, best = idx, sc
    else:
        for j0 in range(J):
            idx = np.full(K, j0)
            if not cost(idx) <= budget:
                continue
            cur = score(total(idx))
            for _ in range(sweeps):
                improved = False
                for k in range(K):
                    for j in range(J):
                        if j == idx[k]:
                            continue
                        trial = idx.copy()
                        trial[k] = j
                        if not cost(trial) <= budget:
                            continue
                        sc = score(total(trial))
                        if sc > cur + 1e-12 * abs(cur):
                            idx, cur, improved = trial, sc, True
                if not improved:
                    break
            if cur > best:
                best_idx, best = idx, cur
    if best_idx is None:  # the callers check that a fixed contact keeps the budget with a finite score
        raise WholeBodyError("no contact schedule within the effort budget has a finite score")
    return _cheapest_ties(best_idx, best, effort, budget, lambda idx: score(total(idx))), float(best)


def _cheapest_ties(
    idx: np.ndarray,
    best: float,
    effort: np.ndarray,
    budget: float,
    score_of: Callable[[np.ndarray], float],
    rtol: float = 1e-9,
) -> list[int]:
    """Return idx with each segment moved to its least-effort candidate that keeps the score (ties, e.g. no motion)."""
    idx = np.array(idx)
    K = len(idx)
    for k in range(K):
        for j in np.argsort(effort[k], kind="stable"):
            if j == idx[k] or effort[k, j] >= effort[k, idx[k]]:
                break
            trial = idx.copy()
            trial[k] = j
            if effort[np.arange(K), trial].sum() <= budget and score_of(trial) >= best - rtol * abs(best):
                idx = trial
                break
    return [int(j) for j in idx]


def _check_schedule_options(n_segments: int, n_candidates: int, objective: str) -> None:
    """Raise `WholeBodyError` for too few segments or candidates, or an unknown objective."""
    if n_segments < 1 or n_candidates < 2:
        raise WholeBodyError("need n_segments >= 1 and n_candidates >= 2")
    if objective not in OBJECTIVES:
        raise WholeBodyError(f"unknown objective {objective!r}; choose one of {', '.join(OBJECTIVES)}")


def _fixed_contact_scores(
    info: np.ndarray, fixed_effort: np.ndarray, budget: float, score: Callable[[np.ndarray], float]
) -> np.ndarray:
    """Return the score of each fixed contact j (-inf over the budget); raise when none is within it."""
    fixed_scores = np.array(
        [score(info[:, j]) if fixed_effort[j] <= budget else -np.inf for j in range(len(fixed_effort))]
    )
    if not np.any(np.isfinite(fixed_scores)):
        raise WholeBodyError(
            f"effort budget {budget:.4g} is below the cheapest fixed contact ({np.min(fixed_effort):.4g})"
        )
    return fixed_scores


def plan_contact_schedule(
    samples: PushSamples,
    phi: Sequence[float],
    sigma: float = 0.0,
    handle: HandleSegment | None = None,
    n_segments: int = 6,
    n_candidates: int = 21,
    effort_budget: float | None = None,
    budget_ratio: float = 1.5,
    noise: WrenchNoise = WrenchNoise(),
    limits: ArmLimits = ArmLimits(),
    sweeps: int = 10,
    objective: str = "min_eig",
    prior_cov: np.ndarray | None = None,
    sensor_dt: float | None = None,
    exhaustive_limit: int = 20_000,
) -> SchedulePlan:
    """Return the piecewise-constant contact schedule maximizing a score within an effort budget.

    ``phi`` (and ``sigma``) are the planning model (the current estimate);
    ``objective`` one of :data:`OBJECTIVES`; ``prior_cov`` the estimator's
    prior (default :func:`default_prior`) and ``sensor_dt`` the wrench sampling
    period, both only used by the CoM objectives. The budget defaults to
    ``budget_ratio`` times the effort of the least-effort fixed contact.
    Search on a grid of ``n_candidates`` handle points: exhaustive when
    ``n_candidates ** n_segments <= exhaustive_limit``, else coordinate ascent
    from every feasible fixed contact.
    """
    handle = HandleSegment.default() if handle is None else handle
    _check_schedule_options(n_segments, n_candidates, objective)
    cand = np.linspace(0.0, handle.length, n_candidates)
    bounds, info, effort = _segment_tables(samples, phi, sigma, handle, cand, n_segments, noise, limits, sensor_dt)
    fixed_effort = effort.sum(axis=0)  # (J,)
    if not np.any(np.isfinite(fixed_effort)):
        raise WholeBodyError("no fixed contact on the handle can produce the planned push within the arm limits")
    budget = float(effort_budget) if effort_budget is not None else budget_ratio * float(np.min(fixed_effort))
    P0 = default_prior(phi) if prior_cov is None else np.asarray(prior_cov, dtype=float)
    score = lambda I: objective_value(I, phi, objective, P0)  # noqa: E731
    fixed_scores = _fixed_contact_scores(info, fixed_effort, budget, score)
    j0 = int(np.argmax(fixed_scores))
    idx, best = _best_schedule(info, effort, budget, score, sweeps, exhaustive_limit)  # >= every fixed contact
    sched = ContactSchedule(bounds, cand[idx])
    total = float(sum(effort[k, j] for k, j in enumerate(idx)))
    std = lambda I: _com_std(I, phi, P0)  # noqa: E731
    return SchedulePlan(
        sched,
        float(best),
        total,
        float(cand[j0]),
        float(fixed_scores[j0]),
        float(fixed_effort[j0]),
        budget,
        objective,
        std(sum(info[k, j] for k, j in enumerate(idx))),
        std(info[:, j0].sum(axis=0)),
    )


def _com_std(I: np.ndarray, phi: Sequence[float], P0: np.ndarray) -> tuple[float, float]:
    """Return the CoM std (dx, dy) of the information I under the prior P0."""
    dx, dy = np.sqrt(np.diag(com_covariance(I, phi, P0)))
    return float(dx), float(dy)


def schedule_points(
    samples: PushSamples, schedule: Callable[[float], float] | ContactSchedule, handle: HandleSegment | None = None
) -> np.ndarray:
    """Return the contact points (N x 3 in {b}) a schedule s(t) holds at the sample times."""
    handle = HandleSegment.default() if handle is None else handle
    at = schedule.at if isinstance(schedule, ContactSchedule) else schedule
    return np.array([handle.point(at(t)) for t in samples.t])


def schedule_score(
    samples: PushSamples,
    schedule: Callable[[float], float] | ContactSchedule,
    phi: Sequence[float],
    handle: HandleSegment | None = None,
    noise: WrenchNoise = WrenchNoise(),
    objective: str = "min_eig",
    prior_cov: np.ndarray | None = None,
    sensor_dt: float | None = None,
    boundaries: npt.ArrayLike | None = None,
) -> float:
    """Return the score (``objective``) of a push whose contact follows ``schedule`` (s(t) on the handle).

    ``"com_a_path"`` evaluates the bound at the ends of the segments
    [boundaries[k], boundaries[k+1]) (default: the schedule's own boundaries).
    """
    pts = schedule_points(samples, schedule, handle)
    if objective != "com_a_path":
        return objective_value(fisher_information(samples, pts, noise, sensor_dt), phi, objective, prior_cov)
    if boundaries is None:
        if not isinstance(schedule, ContactSchedule):
            raise WholeBodyError("objective 'com_a_path' needs segment boundaries for a schedule given as a function")
        boundaries = schedule.boundaries
    b = np.asarray(boundaries, dtype=float)
    seg = np.clip(np.searchsorted(b, samples.t, side="right") - 1, 0, len(b) - 2)
    Y = reduced_regressor(samples.v, samples.vdot, samples.omega, samples.omegadot)
    Rinv = np.array([np.linalg.inv(measurement_covariance(p, noise)) for p in pts])
    per = np.einsum("nji,njk,nkl->nil", Y, Rinv, Y) * (1.0 if sensor_dt is None else samples.dt / float(sensor_dt))
    stack = np.array([per[seg == k].sum(axis=0) for k in range(len(b) - 1)])
    return objective_value(stack, phi, objective, prior_cov)


def schedule_com_std(
    samples: PushSamples,
    schedule: Callable[[float], float] | ContactSchedule,
    phi: Sequence[float],
    handle: HandleSegment | None = None,
    noise: WrenchNoise = WrenchNoise(),
    prior_cov: np.ndarray | None = None,
    sensor_dt: float | None = None,
) -> np.ndarray:
    """Return sqrt(diag) of the CoM Cramér–Rao bound (dx, dy) in m of a push following ``schedule``."""
    info = fisher_information(samples, schedule_points(samples, schedule, handle), noise, sensor_dt)
    return np.sqrt(np.diag(com_covariance(info, phi, prior_cov)))


def com_crlb_course(
    samples: PushSamples,
    schedule: Callable[[float], float] | ContactSchedule,
    phi: Sequence[float],
    times: Sequence[float],
    noise: WrenchNoise = WrenchNoise(),
    prior_cov: np.ndarray | None = None,
    sensor_dt: float | None = None,
    handle: HandleSegment | None = None,
) -> np.ndarray:
    """Return (len(times), 2, 2): the CoM Cramér–Rao bound from the information gathered up to each time."""
    pts = schedule_points(samples, schedule, handle)
    Y = reduced_regressor(samples.v, samples.vdot, samples.omega, samples.omegadot)
    Rinv = np.array([np.linalg.inv(measurement_covariance(p, noise)) for p in pts])
    scale = 1.0 if sensor_dt is None else samples.dt / float(sensor_dt)
    cum = np.cumsum(scale * np.einsum("nji,njk,nkl->nil", Y, Rinv, Y), axis=0)
    out = []
    for t in times:
        k = min(int(np.searchsorted(samples.t, t - 1e-9)), len(samples.t) - 1)
        out.append(com_covariance(cum[k], phi, prior_cov))
    return np.array(out)

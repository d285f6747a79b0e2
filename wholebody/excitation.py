"""Persistence of excitation of a planned push (paper §II.D) and a contact-schedule planner.

The cart's motion has two degrees of freedom (forward speed ``v``, yaw rate
``omega``). Its reduced dynamics, written at the {b} origin in {b} axes, are
linear in ``phi = [m, m dx, m dy, I + m (dx^2 + dy^2)]`` (paper §II.B)::

    f_forward = m vdot - (m dx) omega^2 - (m dy) omegadot      + sigma v
    tau_b     = -(m dy) vdot + (m dx) v omega + J omegadot      + sigma omega

i.e. ``Y(v, vdot, omega, omegadot) phi + sigma [v, omega] = [f_forward, tau_b]``;
the lateral force is absorbed by the wheels and carries no information.

The wrench is measured by the force/torque sensor at the end effector, whose
noise is white in the contact frame {a} (std ``force`` on each force axis,
``torque`` on the yaw torque). Through the grasp map (eqs. 23–24) the noise of
``(f_forward, tau_b)`` depends on where the hand holds the handle:
``tau_b = tau_z + px fy - py fx``. The contact schedule therefore changes the
Fisher information of phi::

    I = sum_t Y_t^T R(p_t)^{-1} Y_t,   R(p) = S G(p) Sigma_ee G(p)^T S^T.

The score of a push is the smallest eigenvalue of ``D I D`` with ``D`` the
parameter scales (so that m, m dx, m dy, J are compared in like units). The
planner picks a piecewise-constant contact schedule (``n_segments`` pieces)
maximizing it under an effort budget (the allocation effort of
`wholebody.allocation`, integrated over the push).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from wholebody.allocation import ArmLimits, WrenchAllocator
from wholebody.contact import HandleSegment, grasp_map
from wholebody.errors import WholeBodyError


@dataclass(frozen=True)
class WrenchNoise:
    """Std of the end-effector force/torque sensor in {a}: force (N, each axis), yaw torque (N m)."""

    force: float = 3.0
    torque: float = 0.3


@dataclass(frozen=True)
class PushSamples:
    """A planned cart motion sampled every dt: forward speed, its rate, yaw rate, its rate."""

    t: np.ndarray
    v: np.ndarray
    vdot: np.ndarray
    omega: np.ndarray
    omegadot: np.ndarray

    @property
    def dt(self) -> float:
        """Return the sampling period."""
        return float(self.t[1] - self.t[0])


@dataclass(frozen=True)
class ContactSchedule:
    """Piecewise-constant contact: handle coordinate ``s[k]`` on [boundaries[k], boundaries[k+1])."""

    boundaries: np.ndarray
    s: np.ndarray

    def at(self, t: float) -> float:
        """Return the handle coordinate held at time t."""
        k = int(np.clip(np.searchsorted(self.boundaries, t, side="right") - 1, 0, len(self.s) - 1))
        return float(self.s[k])


@dataclass(frozen=True)
class SchedulePlan:
    """The planned schedule, its score and effort, and the best fixed contact for comparison."""

    schedule: ContactSchedule
    score: float
    effort: float
    fixed_s: float
    fixed_score: float
    fixed_effort: float
    budget: float


def sample_push(trajectory, dt: float = 0.05, duration: float | None = None) -> PushSamples:
    """Return the samples of a unicycle trajectory (``speed(t)``, ``yaw(t)`` as in cart.trajectories)."""
    T = float(duration if duration is not None else trajectory.duration)
    t = np.arange(0.0, T + 1e-9, dt)
    sp = np.array([trajectory.speed(x) for x in t])
    yw = np.array([trajectory.yaw(x) for x in t])
    return PushSamples(t, sp[:, 0], sp[:, 1], yw[:, 1], yw[:, 2])


def reduced_regressor(v, vdot, omega, omegadot) -> np.ndarray:
    """Return Y (..., 2, 4): rows (f_forward, tau_b) per unit of phi (reduced 2-DoF dynamics)."""
    v, vdot, omega, omegadot = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (v, vdot, omega, omegadot)))
    Y = np.zeros(v.shape + (2, 4))
    Y[..., 0, 0] = vdot
    Y[..., 0, 1] = -omega * omega
    Y[..., 0, 2] = -omegadot
    Y[..., 1, 1] = v * omega
    Y[..., 1, 2] = -vdot
    Y[..., 1, 3] = omegadot
    return Y


def reduced_wrench(samples: PushSamples, phi: Sequence[float], sigma: float = 0.0) -> np.ndarray:
    """Return (N, 2) [f_forward, tau_b] the planned motion needs for parameters phi."""
    Y = reduced_regressor(samples.v, samples.vdot, samples.omega, samples.omegadot)
    return Y @ np.asarray(phi, dtype=float) + sigma * np.stack([samples.v, samples.omega], axis=1)


def measurement_covariance(point_b: Sequence[float], noise: WrenchNoise = WrenchNoise()) -> np.ndarray:
    """Return R(p) (2x2): covariance of (f_forward, tau_b) from sensor noise at contact p."""
    G = grasp_map(point_b)[[0, 2]][:, [0, 1, 5]]  # rows fx_b, tau_b; columns fx, fy, tau_z at {a}
    return G @ np.diag([noise.force**2, noise.force**2, noise.torque**2]) @ G.T


def fisher_information(samples: PushSamples, points_b: np.ndarray, noise: WrenchNoise = WrenchNoise()) -> np.ndarray:
    """Return the 4x4 Fisher information of phi for samples held at points_b (N x 3, one per sample)."""
    Y = reduced_regressor(samples.v, samples.vdot, samples.omega, samples.omegadot)
    pts = np.asarray(points_b, dtype=float).reshape(len(samples.t), 3)
    Rinv = np.array([np.linalg.inv(measurement_covariance(p, noise)) for p in pts])
    return np.einsum("nji,njk,nkl->il", Y, Rinv, Y)


def parameter_scale(phi: Sequence[float], length: float = 0.3) -> np.ndarray:
    """Return D = diag(m, m L, m L, m L^2): the scales that make phi's entries comparable."""
    m = float(phi[0])
    return np.diag([m, m * length, m * length, m * length**2])


def excitation_score(info: np.ndarray, phi: Sequence[float]) -> float:
    """Return the smallest eigenvalue of D I D (the persistence-of-excitation score)."""
    D = parameter_scale(phi)
    return float(np.linalg.eigvalsh(D @ info @ D)[0])


def _segment_tables(samples, phi, sigma, handle, candidates, n_segments, noise, limits):
    """Return boundaries, info[k, j] (4x4) and effort[k, j] for segment k held at candidate j."""
    T = samples.t[-1]
    bounds = np.linspace(0.0, T, n_segments + 1)
    seg = np.clip(np.searchsorted(bounds, samples.t, side="right") - 1, 0, n_segments - 1)
    Y = reduced_regressor(samples.v, samples.vdot, samples.omega, samples.omegadot)
    need = reduced_wrench(samples, phi, sigma)  # (N, 2): f_forward, tau_b
    gam = np.stack([need[:, 0], np.zeros(len(need)), need[:, 1]], axis=1)
    alloc = WrenchAllocator([handle.point(0.0)], limits, only_motion_directions=True)
    J = len(candidates)
    info = np.zeros((n_segments, J, 4, 4))
    effort = np.zeros((n_segments, J))
    for j, s in enumerate(candidates):
        p = handle.point(float(s))
        Rinv = np.linalg.inv(measurement_covariance(p, noise))
        per = np.einsum("nji,jk,nkl->nil", Y, Rinv, Y)
        alloc.set_points([p])
        e = np.empty(len(gam))
        for n, g in enumerate(gam):
            res = alloc.solve(g, raise_on_infeasible=False)
            e[n] = res.effort if res.residual < 1e-6 * max(1.0, np.max(np.abs(g))) else np.inf
        for k in range(n_segments):
            mask = seg == k
            info[k, j] = per[mask].sum(axis=0)
            effort[k, j] = e[mask].sum() * samples.dt
    return bounds, info, effort


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
) -> SchedulePlan:
    """Return the piecewise-constant contact schedule maximizing the excitation score within an effort budget.

    ``phi`` (and ``sigma``) are the planning model (the current estimate). The
    budget defaults to ``budget_ratio`` times the effort of the least-effort
    fixed contact. Search: the best feasible fixed contact, then coordinate
    ascent over segments on a grid of ``n_candidates`` handle points.
    """
    handle = HandleSegment.default() if handle is None else handle
    if n_segments < 1 or n_candidates < 2:
        raise WholeBodyError("need n_segments >= 1 and n_candidates >= 2")
    cand = np.linspace(0.0, handle.length, n_candidates)
    bounds, info, effort = _segment_tables(samples, phi, sigma, handle, cand, n_segments, noise, limits)
    fixed_effort = effort.sum(axis=0)  # (J,)
    if not np.any(np.isfinite(fixed_effort)):
        raise WholeBodyError("no fixed contact on the handle can produce the planned push within the arm limits")
    budget = float(effort_budget) if effort_budget is not None else budget_ratio * float(np.min(fixed_effort))
    score = lambda idx: excitation_score(sum(info[k, j] for k, j in enumerate(idx)), phi)  # noqa: E731
    fixed_scores = np.array([score([j] * n_segments) if fixed_effort[j] <= budget else -np.inf for j in range(len(cand))])
    if not np.any(np.isfinite(fixed_scores)):
        raise WholeBodyError(f"effort budget {budget:.4g} is below the cheapest fixed contact ({np.min(fixed_effort):.4g})")
    j0 = int(np.argmax(fixed_scores))
    idx = [j0] * n_segments
    best = fixed_scores[j0]
    for _ in range(sweeps):
        improved = False
        for k in range(n_segments):
            for j in range(len(cand)):
                if j == idx[k]:
                    continue
                trial = list(idx)
                trial[k] = j
                e = sum(effort[kk, jj] for kk, jj in enumerate(trial))
                if e > budget:
                    continue
                sc = score(trial)
                if sc > best * (1 + 1e-12):
                    best, idx, improved = sc, trial, True
        if not improved:
            break
    sched = ContactSchedule(bounds, cand[idx])
    total = float(sum(effort[k, j] for k, j in enumerate(idx)))
    return SchedulePlan(sched, float(best), total, float(cand[j0]), float(fixed_scores[j0]), float(fixed_effort[j0]), budget)


def schedule_score(samples: PushSamples, schedule: Callable[[float], float] | ContactSchedule, phi: Sequence[float],
                   handle: HandleSegment | None = None, noise: WrenchNoise = WrenchNoise()) -> float:
    """Return the excitation score of a push whose contact follows ``schedule`` (s(t) on the handle)."""
    handle = HandleSegment.default() if handle is None else handle
    at = schedule.at if isinstance(schedule, ContactSchedule) else schedule
    pts = np.array([handle.point(at(t)) for t in samples.t])
    return excitation_score(fisher_information(samples, pts, noise), phi)


# ---------------------------------------------------------------------------- EKF study on Traj. 2
@dataclass(frozen=True)
class ConvergenceResult:
    """CoM-estimate convergence of one run: time to stay below `tol` (None if never), final error."""

    label: str
    seed: int
    time_to_tol: float | None
    final_com_error: float
    final_mass_error: float


class _SensorLoop:
    """Controller callback for cart.simulate: EKF on the *measured* wrench, tracking control, allocation."""

    def __init__(self, controller, guess, config, contact: Callable[[float], float], handle, noise, rng, n) -> None:
        from cart.ekf import CartEKF  # noqa: F401  (imported here: cart is only needed for the study)

        self.ctrl, self.guess, self.config = controller, guess, config
        self.contact, self.handle, self.noise, self.rng = contact, handle, noise, rng
        self.alloc = WrenchAllocator([handle.point(0.0)], ArmLimits(), only_motion_directions=True)
        self.ekf = None
        self.gamma_meas = np.zeros(3)
        self.t_prev = 0.0
        self.k = 0
        self.com_hat = np.zeros((n, 2))
        self.mass_hat = np.zeros(n)

    def __call__(self, t: float, q_meas: np.ndarray, qd_meas: np.ndarray) -> np.ndarray:
        from cart.ekf import CartEKF

        z = np.concatenate([q_meas, qd_meas])
        if self.ekf is None:
            self.ekf = CartEKF(q_meas, qd_meas, self.guess.phi, self.guess.sigma, self.config)
        else:
            self.ekf.step(self.gamma_meas, t - self.t_prev, z)
        params = self.ekf.params()
        self.com_hat[self.k] = (params.dx, params.dy)
        self.mass_hat[self.k] = params.m
        th = float(self.ekf.x[2])
        c, s = np.cos(th), np.sin(th)
        gamma_w = self.ctrl.gamma(t, self.ekf.x[:3], self.ekf.x[3:6], params)
        gamma_b = np.array([c * gamma_w[0] + s * gamma_w[1], 0.0, gamma_w[2]])
        p = self.handle.point(self.contact(t))
        self.alloc.set_points([p])
        w = self.alloc.solve(gamma_b, raise_on_infeasible=False).wrenches_ee[0]
        G = grasp_map(p)
        applied_b = G @ w
        w_meas = w.copy()
        w_meas[[0, 1]] += self.noise.force * self.rng.standard_normal(2)
        w_meas[5] += self.noise.torque * self.rng.standard_normal()
        meas_b = G @ w_meas
        to_world = lambda g: np.array([c * g[0] - s * g[1], s * g[0] + c * g[1], g[2]])  # noqa: E731
        self.gamma_meas = to_world(meas_b)
        self.t_prev = t
        self.k += 1
        return to_world(applied_b)


def com_convergence_traj2(
    contact: Callable[[float], float] | ContactSchedule,
    label: str = "",
    seed: int = 0,
    true_com: tuple[float, float] = (0.3, 0.15),
    tol: float = 0.03,
    duration: float = 30.0,
    dt: float = 0.01,
    noise: WrenchNoise = WrenchNoise(),
    handle: HandleSegment | None = None,
) -> ConvergenceResult:
    """Return the CoM convergence of the EKF on Traj. 2 (Table I test 5 cart) with the given contact schedule.

    The robot tracks Traj. 2 with the paper's feedback-linearization/LQR law on the
    EKF estimate, realizes each wrench with one arm at the scheduled contact
    (allocation QP), and the EKF is fed the wrench measured by the end-effector
    F/T sensor (``noise`` in {a}) mapped through the grasp map.
    """
    from cart.control import make_controller
    from cart.ekf import EKFConfig
    from cart.params import CartParams
    from cart.simulate import MeasurementNoise, simulate
    from cart.trajectories import trajectory_2

    handle = HandleSegment.default() if handle is None else handle
    at = contact.at if isinstance(contact, ContactSchedule) else contact
    traj = trajectory_2(duration)
    truth = CartParams(20.0, true_com[0], true_com[1], 20.0 * (1.0 + 0.36) / 12.0, 4.0)
    guess = CartParams(16.0, 0.3, 0.0, 1.6, 4.0)
    meas = MeasurementNoise.from_level(0.005)
    q_vel = (noise.force / guess.m) ** 2 * dt
    q_om = (float(np.sqrt(measurement_covariance(handle.point(handle.length / 2), noise)[1, 1])) / guess.inertia_b) ** 2 * dt
    config = EKFConfig.from_noise(meas.measurement_std(), q_pos=1e-8, q_vel=q_vel, q_omega=q_om,
                                  q_phi=(0.005, 0.005, 0.005, 0.005))
    n = int(round(duration / dt)) + 1
    rng = np.random.default_rng(seed)
    loop = _SensorLoop(make_controller("fl_lqr", traj), guess, config, at, handle, noise,
                       np.random.default_rng(seed + 10_000), n)
    q0, _, _ = traj.sample(0.0)
    sim = simulate(truth, loop, duration, dt, q0=q0, noise=meas, rng=rng)
    err = np.hypot(loop.com_hat[:, 0] - truth.dx, loop.com_hat[:, 1] - truth.dy)
    ok = err < tol
    t = sim.true.t
    if not ok[-1]:
        t_tol = None
    else:
        bad = np.nonzero(~ok)[0]
        t_tol = float(t[0]) if bad.size == 0 else float(t[bad[-1] + 1])
    return ConvergenceResult(label, seed, t_tol, float(err[-1]), float(abs(loop.mass_hat[-1] - truth.m)))

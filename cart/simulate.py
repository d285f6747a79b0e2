"""Closed-loop simulation of the cart: exact constrained dynamics, RK4, noisy measurements.

:func:`simulate` integrates paper eq. (4) with the constraint kept at
acceleration level (:func:`cart.model.forward_dynamics_fast`), with a
fixed-step RK4 (``substeps`` per control period), under a controller callback
``controller(t, q_meas, qd_meas) -> gamma`` held constant over each period. It
supports discrete parameter changes (payload, paper test 11), a time-varying
contact point and an ``extra_force(t, q, qd, params) -> generalized force`` hook
for effects outside the nominal model. It returns the true and the measured
log (docs/log_format.md columns, velocities included).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from cart import dynamics, model
from cart.logs import CartLog
from cart.params import CartParams

Controller = Callable[[float, np.ndarray, np.ndarray], np.ndarray]
ExtraForce = Callable[[float, np.ndarray, np.ndarray, CartParams], np.ndarray]
ContactPoint = Callable[[float], tuple[float, float]]


@dataclass(frozen=True)
class MeasurementNoise:
    """Standard deviations of the white measurement noise on each measured channel (SI units)."""

    position: float = 0.0
    theta: float = 0.0
    velocity: float = 0.0
    omega: float = 0.0
    force: float = 0.0
    torque: float = 0.0

    @classmethod
    def from_level(cls, level: float) -> MeasurementNoise:
        """Return the noise of a Table I level: ``level`` m on x, y, rad on theta, m/s on vx, vy, rad/s on omega."""
        return cls(position=level, theta=level, velocity=level, omega=level)

    def measurement_std(self) -> np.ndarray:
        """Return the std of (x, y, theta, vx, vy, omega)."""
        return np.array([self.position, self.position, self.theta, self.velocity, self.velocity, self.omega])


@dataclass(frozen=True)
class ParameterChange:
    """A discrete change of the cart parameters at time ``t`` (e.g. a payload put in the cart).

    With ``conserve_momentum`` the payload is picked up at rest: the velocity is
    scaled by m_old / m_new (linear momentum kept), otherwise it is unchanged.
    """

    t: float
    params: CartParams
    conserve_momentum: bool = True


@dataclass(frozen=True)
class SimResult:
    """Simulation output: true and measured logs and the true parameters at every sample."""

    true: CartLog
    measured: CartLog
    params_t: np.ndarray  # (N, 5): m, dx, dy, I, sigma in force at each sample

    @property
    def mass_t(self) -> np.ndarray:
        """Return the true mass at each sample."""
        return self.params_t[:, 0]


def min_effort_gamma(q: np.ndarray, gamma: np.ndarray, point_b: Sequence[float], length: float = 0.5) -> np.ndarray:
    """Return gamma plus the lateral null-space force that minimises |f|^2 + (tau_contact / length)^2.

    A lateral force at the {b} origin is absorbed by the wheel constraint, so
    the manipulator may add any amount of it; choosing it this way is the
    least-effort planar wrench at the contact point ``point_b`` (paper §II.C).
    """
    fu, fl, tau = model.generalized_to_body(q, gamma)
    px, py = float(point_b[0]), float(point_b[1])
    # torque at the contact: tau_a = tau - px * f_lat + py * f_fwd; minimise f_lat^2 + tau_a^2 / length^2
    f_lat = px * (tau + py * fu) / (length * length + px * px)
    extra = f_lat - fl
    s, c = math.sin(q[2]), math.cos(q[2])
    return np.array([gamma[0] - s * extra, gamma[1] + c * extra, gamma[2]])


def _accel(
    t: float,
    q: np.ndarray,
    qd: np.ndarray,
    gamma: np.ndarray,
    p: CartParams,
    phi: np.ndarray,
    extra_force: ExtraForce | None,
    exact: bool,
) -> np.ndarray:
    g = gamma
    if extra_force is not None:
        g = gamma + np.asarray(extra_force(t, q, qd, p), dtype=float)
    if not exact:
        return model.forward_dynamics(q, qd, g, phi, p.damping, exact=False)
    sigma, sigma_yaw = p.damping
    return np.array(
        dynamics.forward_dynamics(
            q[2], qd[0], qd[1], qd[2], g[0], g[1], g[2], phi[0], phi[1], phi[2], phi[3], sigma, sigma_yaw
        )
    )


def rk4_step(
    t: float,
    q: np.ndarray,
    qd: np.ndarray,
    gamma: np.ndarray,
    params: CartParams,
    h: float,
    extra_force: ExtraForce | None = None,
    exact: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Return (q, qd) after one RK4 step of length h under a constant gamma."""
    phi = params.phi
    k1v = _accel(t, q, qd, gamma, params, phi, extra_force, exact)
    k1q = qd
    k2q = qd + 0.5 * h * k1v
    k2v = _accel(t + 0.5 * h, q + 0.5 * h * k1q, k2q, gamma, params, phi, extra_force, exact)
    k3q = qd + 0.5 * h * k2v
    k3v = _accel(t + 0.5 * h, q + 0.5 * h * k2q, k3q, gamma, params, phi, extra_force, exact)
    k4q = qd + h * k3v
    k4v = _accel(t + h, q + h * k3q, k4q, gamma, params, phi, extra_force, exact)
    return (q + h / 6.0 * (k1q + 2 * k2q + 2 * k3q + k4q), qd + h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v))


def _rk4_exact(q: list, qd: list, gamma: list, p: CartParams, h: float, substeps: int) -> tuple[list, list]:
    """Return (q, qd) after ``substeps`` RK4 steps of length h of the exact dynamics (no extra force).

    The arithmetic of :func:`rk4_step` (same operations in the same order, so bit for bit the same
    result) on plain floats: the simulation's hot loop without per-step numpy arrays.
    """
    fd = dynamics.forward_dynamics
    fx, fy, tau = gamma
    m, a, b, j = p.phi.tolist()
    sv, sw = p.damping
    h2, h6 = 0.5 * h, h / 6.0
    x, y, th = q
    vx, vy, om = qd
    for _ in range(substeps):
        a1x, a1y, a1o = fd(th, vx, vy, om, fx, fy, tau, m, a, b, j, sv, sw)
        k2x, k2y, k2o = vx + h2 * a1x, vy + h2 * a1y, om + h2 * a1o
        a2x, a2y, a2o = fd(th + h2 * om, k2x, k2y, k2o, fx, fy, tau, m, a, b, j, sv, sw)
        k3x, k3y, k3o = vx + h2 * a2x, vy + h2 * a2y, om + h2 * a2o
        a3x, a3y, a3o = fd(th + h2 * k2o, k3x, k3y, k3o, fx, fy, tau, m, a, b, j, sv, sw)
        k4x, k4y, k4o = vx + h * a3x, vy + h * a3y, om + h * a3o
        a4x, a4y, a4o = fd(th + h * k3o, k4x, k4y, k4o, fx, fy, tau, m, a, b, j, sv, sw)
        x += h6 * (vx + 2 * k2x + 2 * k3x + k4x)
        y += h6 * (vy + 2 * k2y + 2 * k3y + k4y)
        th += h6 * (om + 2 * k2o + 2 * k3o + k4o)
        vx += h6 * (a1x + 2 * a2x + 2 * a3x + a4x)
        vy += h6 * (a1y + 2 * a2y + 2 * a3y + a4y)
        om += h6 * (a1o + 2 * a2o + 2 * a3o + a4o)
    return [x, y, th], [vx, vy, om]


def simulate(
    params: CartParams,
    controller: Controller,
    duration: float,
    dt: float = 0.01,
    q0: npt.ArrayLike = (0.0, 0.0, 0.0),
    qd0: npt.ArrayLike = (0.0, 0.0, 0.0),
    noise: MeasurementNoise = MeasurementNoise(),
    rng: np.random.Generator | None = None,
    changes: Sequence[ParameterChange] = (),
    contact_point: ContactPoint | None = None,
    extra_force: ExtraForce | None = None,
    substeps: int = 4,
    exact: bool = True,
    metadata: dict | None = None,
    allocate: bool = True,
) -> SimResult:
    """Return the true and measured logs of the cart driven by ``controller`` for ``duration`` seconds.

    At each sample t_k = k dt the measurement (q, qd plus noise drawn from
    ``rng``) is passed to ``controller``; its gamma (plus, with a contact point,
    the least-effort lateral null-space force of :func:`min_effort_gamma`) is
    applied until t_{k+1}. Parameter ``changes`` take effect at the first sample
    with t_k >= change.t. The logs hold the applied gamma (measured: plus
    force/torque noise). With ``allocate=False`` the contact point is only logged
    (the controller then does its own allocation).
    """
    rng = np.random.default_rng(0) if rng is None else rng
    n = int(round(duration / dt)) + 1
    pending = sorted(changes, key=lambda c: c.t)
    p, q, qd = params, np.array(q0, dtype=float), np.array(qd0, dtype=float)
    t_arr = np.arange(n) * dt
    q_true, qd_true, g_log = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    contact = np.zeros((n, 2)) if contact_point is not None else None
    params_t = np.empty((n, 5))
    std = noise.measurement_std()
    meas_noise = rng.standard_normal((n, 6)) * std
    force_noise = rng.standard_normal((n, 3)) * np.array([noise.force, noise.force, noise.torque])
    h = dt / substeps
    for k in range(n):
        t = t_arr[k]
        p, qd = _apply_changes(pending, t, p, qd)
        q_true[k] = q
        qd_true[k] = qd
        params_t[k] = (p.m, p.dx, p.dy, p.I, p.sigma)
        gamma = np.asarray(controller(t, q + meas_noise[k, :3], qd + meas_noise[k, 3:]), dtype=float)
        if contact_point is not None and contact is not None:  # (contact is allocated with contact_point)
            point = contact_point(t)
            contact[k] = point
            if allocate:
                gamma = min_effort_gamma(q, gamma, point)
        g_log[k] = gamma
        if k < n - 1:
            q, qd = _advance(t, q, qd, gamma, p, h, substeps, extra_force, exact)
    meta = {"source": "cart.simulate", "dt": repr(dt), **(metadata or {})}
    true = CartLog(t=t_arr, q=q_true, gamma=g_log, qd=qd_true, contact_b=contact, metadata=meta)
    noisy = (q_true + meas_noise[:, :3], g_log + force_noise, qd_true + meas_noise[:, 3:])
    measured = CartLog(t=t_arr, q=noisy[0], gamma=noisy[1], qd=noisy[2], contact_b=contact, metadata=dict(meta))
    return SimResult(true=true, measured=measured, params_t=params_t)


def _advance(
    t: float,
    q: np.ndarray,
    qd: np.ndarray,
    gamma: np.ndarray,
    p: CartParams,
    h: float,
    substeps: int,
    extra_force: ExtraForce | None,
    exact: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Return (q, qd) one control period later: ``substeps`` RK4 steps of length h under a constant gamma."""
    if exact and extra_force is None:  # the float fast path, bit for bit the same as rk4_step
        ql, qdl = _rk4_exact(q.tolist(), qd.tolist(), gamma.tolist(), p, h, substeps)
        return np.array(ql), np.array(qdl)
    for j in range(substeps):
        q, qd = rk4_step(t + j * h, q, qd, gamma, p, h, extra_force, exact)
    return q, qd


def _apply_changes(pending: list, t: float, p: CartParams, qd: np.ndarray) -> tuple[CartParams, np.ndarray]:
    """Apply (and pop) the parameter changes due at t; return the parameters and velocity in force."""
    while pending and pending[0].t <= t + 1e-12:
        change = pending.pop(0)
        if change.conserve_momentum:
            qd = qd * (p.m / change.params.m)
        p = change.params
    return p, qd

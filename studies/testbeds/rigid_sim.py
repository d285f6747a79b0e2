"""Independent rigid-body cart simulator: synthetic logs with known truth for validating estimators.

This test bed is written from the physics, deliberately *not* from the
project's simulator (``studies.testbeds.hidden_effects``, ``cart.model``, ``cart.simulate``): it
only borrows the log container and writer from ``cart.logs`` (I/O). It models
the planar cart of the paper (*cart inertial estimation*, constrained
Euler–Lagrange dynamics, eq. 1–7) with

* the world frame {s} and the cart frame {b} whose origin is the midpoint of
  the fixed-wheel axle, x forward, heading ``theta``;
* the rolling constraint of eq. 3, ``Lambda(q) qdot = -sin(th) xdot + cos(th) ydot = 0``
  (no lateral slip of the {b} origin), kept **exactly**: the state is
  ``(x, y, theta, v, omega)`` with ``v`` the forward speed of the {b} origin,
  so ``xdot = v cos(th)``, ``ydot = v sin(th)`` by construction;
* CoM at ``(dx, dy)`` in {b}, mass ``m``, inertia ``I`` about the CoM,
  ``J = I + m (dx^2 + dy^2)`` about the {b} origin;
* the applied generalized force ``Gamma = (fx, fy in {s}, tau about the
  vertical through the {b} origin)``;
* viscous damping with two coefficients: ``-c_v * (xdot, ydot)`` on the
  velocity of the {b} origin (forward and lateral, N s/m) and ``-c_w * omega``
  on the yaw rate (N m s/rad).

Equations of motion (Kane's method with generalized speeds ``u = (v, omega)``,
i.e. the constrained Euler–Lagrange equations 1–7 written in the null space of
``Lambda`` so the constraint force drops out exactly). The CoM velocity in {b}
is ``(v - omega dy, omega dx)``, so

    T = 1/2 m |v_com|^2 + 1/2 I omega^2 = 1/2 u^T M u,
    M = [[m, -m dy], [-m dy, J]]        (constant)

and the partial velocities of the CoM are ``e_x`` (for ``v``) and
``(-dy, dx)`` (for ``omega``), with CoM acceleration in {b}
``(vdot - alpha dy - omega^2 dx,  v omega + alpha dx - omega^2 dy)``. Kane's
equations ``F_r + F*_r = 0`` give

    M [vdot, omegadot]^T = [ f_fwd - c_v v + m dx omega^2,
                             tau   - c_w omega - m dx v omega ]

with ``f_fwd = fx cos(th) + fy sin(th)`` (the generalized active force of
``Gamma`` for ``v``; the lateral component of ``Gamma`` is absorbed by the
wheels). The velocity-product terms do no work (``v * m dx w^2 - w * m dx v w = 0``),
so ``dT/dt = f_fwd v + tau omega - c_v v^2 - c_w omega^2``; the tests check this
energy balance and the full KKT form of eq. 1–3 with a numerically
differentiated Lagrangian.

The pusher is a tracking controller updating the wrench every 1 ms
(zero-order hold): feedforward from a deliberately wrong nominal model plus
PI feedback on the forward-speed and yaw-rate errors (PD on the integrated
tracking error), plus an optional smooth random lateral force. The dynamics
are integrated piecewise between wrench updates (and log samples) with
Hairer's DOP853 (``scipy.integrate.ode('dop853')``, rtol 1e-9; ``integrator="solve_ivp"``
uses ``solve_ivp(method="DOP853")`` per piece, slower, same result), a
different integrator from the project's fixed-step RK4. Logs sample the
*instantaneous* held wrench (not an average) and the pose at a rate in
50–250 Hz, optionally irregular, with white noise at every sample.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, fields, replace
from typing import Any
from collections.abc import Sequence

import numpy as np
from scipy.integrate import ode, solve_ivp

from cart.logs import CartLog, write_log

#: Period of the pusher's wrench updates (zero-order hold), s.
WRENCH_PERIOD = 1e-3
#: Relative / absolute tolerances of the DOP853 integration.
RTOL = 1e-9
ATOL = 1e-12
GENERATOR = (
    "studies.testbeds.rigid_sim: independent rigid-body simulator of the paper's model "
    "(exact constraint, DOP853 between 1 ms wrench updates)"
)


# --------------------------------------------------------------------------- cases


@dataclass(frozen=True)
class RigidCart:
    """Physical truth of a cart.

    ``m`` kg; ``(dx, dy)`` m, CoM in {b}; ``I`` kg m^2 about the CoM; ``c_v``
    N s/m viscous damping on the velocity of the {b} origin; ``c_w`` N m s/rad
    viscous damping on the yaw rate.
    """

    m: float
    dx: float
    dy: float
    I: float
    c_v: float
    c_w: float

    def __post_init__(self) -> None:
        for name in ("m", "dx", "dy", "I", "c_v", "c_w"):
            value = float(getattr(self, name))
            if not math.isfinite(value):
                raise ValueError(f"RigidCart.{name} must be finite, got {value}")
            object.__setattr__(self, name, value)
        if self.m <= 0 or self.I <= 0:
            raise ValueError(f"RigidCart needs m > 0 and I > 0, got m={self.m}, I={self.I}")
        if self.c_v < 0 or self.c_w < 0:
            raise ValueError(f"RigidCart needs c_v, c_w >= 0, got {self.c_v}, {self.c_w}")

    @property
    def J(self) -> float:
        """Yaw inertia about the {b} origin, ``I + m (dx^2 + dy^2)`` (kg m^2)."""
        return self.I + self.m * (self.dx**2 + self.dy**2)


@dataclass(frozen=True)
class RigidCase:
    """One synthetic log: the cart, the excitation and the sensors.

    ``duration`` s; ``rate_hz`` nominal log rate; ``jitter`` in [0, 1): every
    sample gap is ``(1 + U(-jitter, jitter)) / rate_hz``; ``pos_std`` m,
    ``theta_std`` rad, ``force_std`` N (each of fx, fy), ``torque_std`` N m:
    white noise at every sample; ``vel_std`` m/s on vx, vy (``None``: no
    velocity columns) and ``omega_std`` rad/s; ``speed_scale`` scales the
    reference speeds (about 1 m/s and 0.8 rad/s at 1); ``lateral_std`` N,
    typical size of the random lateral pushing force (absorbed by the wheels);
    ``nominal_error`` relative error of the controller's nominal model;
    ``wrap_theta`` writes theta wrapped to (-pi, pi]; ``seed`` drives all
    randomness of the simulation; ``load_time`` s (None: no change) and
    ``load_factor``: a load placed on the cart at its CoM (or removed) at that time
    multiplies its mass and its inertia about the CoM (the velocities carry on; the
    pusher's nominal model does not change).
    """

    cart: RigidCart
    duration: float = 40.0
    rate_hz: float = 100.0
    jitter: float = 0.0
    pos_std: float = 1e-3
    theta_std: float = 3e-3
    force_std: float = 3.0
    torque_std: float = 0.5
    vel_std: float | None = 0.005
    omega_std: float = 0.01
    speed_scale: float = 1.0
    lateral_std: float = 5.0
    nominal_error: float = 0.3
    wrap_theta: bool = False
    seed: int = 0
    load_time: float | None = None
    load_factor: float = 1.0

    def __post_init__(self) -> None:
        if not self.duration > 0.1:
            raise ValueError(f"RigidCase.duration must be > 0.1 s, got {self.duration}")
        if not self.rate_hz > 0:
            raise ValueError(f"RigidCase.rate_hz must be positive, got {self.rate_hz}")
        if not 0 <= self.jitter < 1:
            raise ValueError(f"RigidCase.jitter must be in [0, 1), got {self.jitter}")
        for name in (
            "pos_std",
            "theta_std",
            "force_std",
            "torque_std",
            "omega_std",
            "speed_scale",
            "lateral_std",
            "nominal_error",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"RigidCase.{name} must be >= 0, got {getattr(self, name)}")
        if self.vel_std is not None and not self.vel_std >= 0:
            raise ValueError(f"RigidCase.vel_std must be >= 0 or None, got {self.vel_std}")
        if not self.load_factor > 0:
            raise ValueError(f"RigidCase.load_factor must be positive, got {self.load_factor}")

    @property
    def cart_after_load(self) -> RigidCart:
        """The cart after the load change: mass and inertia about the CoM times ``load_factor`` (CoM kept)."""
        return replace(self.cart, m=self.cart.m * self.load_factor, I=self.cart.I * self.load_factor)

    @property
    def has_velocities(self) -> bool:
        """True when the log carries vx, vy, omega columns."""
        return self.vel_std is not None


_CART_FIELDS = {f.name for f in fields(RigidCart)}
_CASE_FIELDS = {f.name for f in fields(RigidCase)}


def random_case(seed: int, **overrides: Any) -> RigidCase:
    """Return a random plausible case drawn from ``seed``; ``overrides`` replace fields.

    Draws: mass 5–150 kg (log-uniform); CoM ``dx`` 0.05–0.6 m forward, ``dy``
    ±0.15 m; radius of gyration about the CoM 0.15–0.45 m (``I = m k^2``);
    ``c_v`` 0.5–15 N s/m and ``c_w`` 0.2–5 N m s/rad, independent,
    log-uniform; duration 30–60 s; rate 50–250 Hz (integer); jitter 0 in half
    the cases, else up to 0.3; velocity columns in half the cases; pose noise
    0.5–4 mm and 1–5 mrad; ``speed_scale`` 0.3–1; lateral force 0–15 N;
    theta wrapped in half the cases. ``overrides`` may name fields of
    :class:`RigidCase` or of :class:`RigidCart` (e.g. ``m=20.0``) or pass
    ``cart=RigidCart(...)``.
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5EED]))
    loguni = lambda lo, hi: float(math.exp(rng.uniform(math.log(lo), math.log(hi))))  # noqa: E731
    m = loguni(5.0, 150.0)
    k = float(rng.uniform(0.15, 0.45))
    cart = RigidCart(
        m=m,
        dx=float(rng.uniform(0.05, 0.6)),
        dy=float(rng.uniform(-0.15, 0.15)),
        I=m * k * k,
        c_v=loguni(0.5, 15.0),
        c_w=loguni(0.2, 5.0),
    )
    jitter = 0.0 if rng.random() < 0.5 else float(rng.uniform(0.0, 0.3))
    with_vel = bool(rng.random() < 0.5)
    case_kw: dict[str, Any] = dict(
        duration=float(rng.uniform(30.0, 60.0)),
        rate_hz=float(rng.integers(50, 251)),
        jitter=jitter,
        pos_std=float(rng.uniform(0.5e-3, 4e-3)),
        theta_std=float(rng.uniform(1e-3, 5e-3)),
        force_std=3.0,
        torque_std=0.5,
        vel_std=0.005 if with_vel else None,
        omega_std=0.01,
        speed_scale=float(rng.uniform(0.3, 1.0)),
        lateral_std=float(rng.uniform(0.0, 15.0)),
        nominal_error=0.3,
        wrap_theta=bool(rng.random() < 0.5),
        seed=int(seed),
    )
    cart_over = {k_: v for k_, v in overrides.items() if k_ in _CART_FIELDS}
    unknown = set(overrides) - _CART_FIELDS - _CASE_FIELDS
    if unknown:
        raise TypeError(f"random_case: unknown override(s) {sorted(unknown)}")
    case_over = {k_: v for k_, v in overrides.items() if k_ in _CASE_FIELDS}
    cart = case_over.pop("cart", cart)
    if cart_over:
        cart = replace(cart, **cart_over)
    case_kw.update(case_over)
    return RigidCase(cart=cart, **case_kw)


# --------------------------------------------------------------------------- dynamics


def mass_matrix(cart: RigidCart) -> np.ndarray:
    """Return the 2x2 mass matrix in the generalized speeds (v, omega): ``[[m, -m dy], [-m dy, J]]``."""
    return np.array([[cart.m, -cart.m * cart.dy], [-cart.m * cart.dy, cart.J]])


def kinetic_energy(state: Sequence[float], cart: RigidCart) -> float:
    """Return ``T = 1/2 m |v_com|^2 + 1/2 I omega^2`` of ``state = (x, y, theta, v, omega)``."""
    v, w = float(state[3]), float(state[4])
    return 0.5 * cart.m * ((v - w * cart.dy) ** 2 + (w * cart.dx) ** 2) + 0.5 * cart.I * w * w


def power(state: Sequence[float], gamma: Sequence[float], cart: RigidCart) -> float:
    """Return the power of the applied wrench plus the damping, ``Gamma . qdot - c_v v^2 - c_w omega^2``."""
    th, v, w = float(state[2]), float(state[3]), float(state[4])
    qd = (v * math.cos(th), v * math.sin(th), w)
    return (
        gamma[0] * qd[0] + gamma[1] * qd[1] + gamma[2] * qd[2] - cart.c_v * (qd[0] ** 2 + qd[1] ** 2) - cart.c_w * w * w
    )


def _make_rhs(cart: RigidCart):
    """Return ``f(t, state, fx, fy, tau) -> state_dot`` in plain floats (Kane's equations above)."""
    m, dx, J, c_v, c_w = cart.m, cart.dx, cart.J, cart.c_v, cart.c_w
    a = m * cart.dy
    det = m * J - a * a  # = m (I + m dx^2) > 0
    mdx = m * dx

    def rhs(t: float, y: Sequence[float], fx: float, fy: float, tau: float) -> list[float]:
        th, v, w = y[2], y[3], y[4]
        c = math.cos(th)
        s = math.sin(th)
        b1 = fx * c + fy * s - c_v * v + mdx * w * w
        b2 = tau - c_w * w - mdx * v * w
        return [v * c, v * s, w, (J * b1 + a * b2) / det, (a * b1 + m * b2) / det]

    return rhs


def dynamics(state: Sequence[float], gamma: Sequence[float], cart: RigidCart) -> np.ndarray:
    """Return ``d/dt (x, y, theta, v, omega)`` under the generalized force ``gamma = (fx, fy, tau)``."""
    return np.array(_make_rhs(cart)(0.0, [float(s) for s in state], *map(float, gamma)))


def world_velocity(state: Sequence[float]) -> tuple[float, float, float]:
    """Return ``qdot = (xdot, ydot, omega)`` of the {b} origin for ``state = (x, y, theta, v, omega)``."""
    th, v, w = float(state[2]), float(state[3]), float(state[4])
    return v * math.cos(th), v * math.sin(th), w


# --------------------------------------------------------------------------- excitation


class SmoothSteps:
    """A sum of smoothed (quintic smoother-step) steps: ``f(t) = sum_i d_i S((t - t_i) / T_i)``.

    ``S(u) = 6u^5 - 15u^4 + 10u^3`` on [0, 1] (C2); :meth:`__call__` returns
    ``(f, fdot)`` for an array of times.
    """

    def __init__(self, starts: Sequence[float], widths: Sequence[float], deltas: Sequence[float]) -> None:
        self.starts = np.asarray(starts, dtype=float)
        self.widths = np.asarray(widths, dtype=float)
        self.deltas = np.asarray(deltas, dtype=float)

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        f = np.zeros_like(t)
        fd = np.zeros_like(t)
        for t0, w, d in zip(self.starts, self.widths, self.deltas):
            u = np.clip((t - t0) / w, 0.0, 1.0)
            f += d * u**3 * (10.0 - 15.0 * u + 6.0 * u * u)
            fd += d * 30.0 * u * u * (1.0 - u) ** 2 / w
        return f, fd

    @classmethod
    def from_levels(
        cls, times: Sequence[float], widths: Sequence[float], levels: Sequence[float], start_level: float = 0.0
    ) -> SmoothSteps:
        """Return the profile that moves from level to level, starting its i-th move at ``times[i]``."""
        prev = np.concatenate([[start_level], np.asarray(levels[:-1], dtype=float)])
        return cls(times, widths, np.asarray(levels, dtype=float) - prev)


def _schedule(
    rng: np.random.Generator,
    t_begin: float,
    t_end: float,
    hold: tuple[float, float],
    width: tuple[float, float],
    draw_level,
) -> tuple[list[float], list[float], list[float], list[str]]:
    """Return (start times, widths, levels, kinds) of successive moves in [t_begin, t_end]."""
    times: list[float] = []
    widths: list[float] = []
    levels: list[float] = []
    kinds: list[str] = []
    t = t_begin
    prev_kind = "rest"
    while True:
        w = float(rng.uniform(*width))
        if t + w > t_end:
            break
        kind, level = draw_level(prev_kind)
        times.append(t)
        widths.append(w)
        levels.append(level)
        kinds.append(kind)
        prev_kind = kind
        t += w + float(rng.uniform(*hold))
    return times, widths, levels, kinds


def make_references(rng: np.random.Generator, duration: float, speed_scale: float) -> tuple[SmoothSteps, SmoothSteps]:
    """Return random smooth references ``(v_ref, omega_ref)``.

    Forward speed: rest, then push (0.3–1.0 m/s), stop and pull (0.2–0.6 m/s
    backwards) segments held 1.5–5 s with 0.6–1.8 s transitions, with at least
    one push, one pull, one reversal and one stop between motions, ending at rest.
    Yaw rate: left / straight / right segments of 0.2–0.8 rad/s held 1–4 s with
    0.4–1.2 s transitions, with turns both ways. Both scale with ``speed_scale``.
    """
    t_rest = float(rng.uniform(0.5, 1.5))
    t_stop = duration - 2.0  # leave time to come to rest

    def draw_v(prev: str) -> tuple[str, float]:
        options = {"push": 0.5, "stop": 0.2, "pull": 0.3}
        if prev in ("rest", "stop"):
            options.pop("stop")
        kinds = list(options)
        p = np.array([options[k] for k in kinds])
        kind = kinds[int(rng.choice(len(kinds), p=p / p.sum()))]
        if kind == "push":
            return kind, float(rng.uniform(0.3, 1.0)) * speed_scale
        if kind == "pull":
            return kind, -float(rng.uniform(0.2, 0.6)) * speed_scale
        return kind, 0.0

    def draw_w(prev: str) -> tuple[str, float]:
        kinds = [k for k in ("left", "straight", "right") if k != prev]
        kind = kinds[int(rng.integers(len(kinds)))]
        sign = {"left": 1.0, "straight": 0.0, "right": -1.0}[kind]
        return kind, sign * float(rng.uniform(0.2, 0.8)) * speed_scale

    for _ in range(1000):
        tv, wv, lv, kv = _schedule(rng, t_rest, t_stop, (1.5, 5.0), (0.6, 1.8), draw_v)
        signs = [np.sign(x) for x in lv if x != 0]
        reversal = any(a * b < 0 for a, b in zip(signs, signs[1:]))
        stop_after_motion = any(k == "stop" for k in kv[1:-1])  # and moving again after it
        if "push" in kv and "pull" in kv and stop_after_motion and reversal and len(kv) >= 4:
            break  # (for very short durations the last draw is kept as it is)
    # end at rest
    end_w = float(rng.uniform(0.6, 1.2))
    tv.append(max(t_stop, (tv[-1] + wv[-1]) if tv else t_rest))
    wv.append(end_w)
    lv.append(0.0)
    for _ in range(1000):
        tw, ww, lw, kw = _schedule(rng, t_rest + float(rng.uniform(0.0, 1.0)), t_stop, (1.0, 4.0), (0.4, 1.2), draw_w)
        if "left" in kw and "right" in kw:
            break
    tw.append(max(t_stop, (tw[-1] + ww[-1]) if tw else t_rest))
    ww.append(end_w)
    lw.append(0.0)
    return SmoothSteps.from_levels(tv, wv, lv), SmoothSteps.from_levels(tw, ww, lw)


def make_lateral(rng: np.random.Generator, duration: float, std: float) -> SmoothSteps:
    """Return a smooth random lateral body force: levels N(0, std) held 1–4 s, 0.3–1 s transitions."""
    t, w, lv, _ = _schedule(
        rng,
        float(rng.uniform(0.5, 2.0)),
        duration,
        (1.0, 4.0),
        (0.3, 1.0),
        lambda prev: ("lat", float(rng.normal(0.0, std))),
    )
    return SmoothSteps.from_levels(t, w, lv)


@dataclass(frozen=True)
class Tracker:
    """The pusher: feedforward from a nominal (wrong) cart + PI feedback on v and omega errors.

    Forward force ``m^ (vdot_r - dy^ alphad_r - dx^ w_r^2) + c_v^ v_r + m^ (kp e_v + ki int e_v)``
    and torque ``J^ alpha_r - m^ dy^ vdot_r + m^ dx^ v_r w_r + c_w^ w_r + J^ (kp e_w + ki int e_w)``
    (the inverse of the equations of motion, with the nominal parameters).
    """

    nominal: RigidCart
    kp: float = 6.0
    ki: float = 9.0

    def body_wrench(
        self, v: float, w: float, v_r: float, vd_r: float, w_r: float, wd_r: float, int_ev: float, int_ew: float
    ) -> tuple[float, float]:
        """Return (forward force, torque about the {b} origin)."""
        n = self.nominal
        f = n.m * (vd_r - n.dy * wd_r - n.dx * w_r * w_r) + n.c_v * v_r + n.m * (self.kp * (v_r - v) + self.ki * int_ev)
        tau = (
            n.J * wd_r
            - n.m * n.dy * vd_r
            + n.m * n.dx * v_r * w_r
            + n.c_w * w_r
            + n.J * (self.kp * (w_r - w) + self.ki * int_ew)
        )
        return f, tau


def nominal_cart(rng: np.random.Generator, cart: RigidCart, error: float) -> RigidCart:
    """Return the controller's guess: m, dx, I, c_v, c_w off by U(-error, error) relative, dy by ±0.05 m."""
    rel = lambda: 1.0 + float(rng.uniform(-error, error))  # noqa: E731
    return RigidCart(
        m=cart.m * rel(),
        dx=cart.dx * rel(),
        dy=cart.dy + float(rng.uniform(-0.05, 0.05)),
        I=cart.I * rel(),
        c_v=cart.c_v * rel(),
        c_w=cart.c_w * rel(),
    )


def sample_times(rng: np.random.Generator, duration: float, rate_hz: float, jitter: float) -> np.ndarray:
    """Return log times from 0 to ``duration``: gaps ``(1 + U(-jitter, jitter)) / rate_hz``, rounded to 1 us."""
    period = 1.0 / rate_hz
    n = int(duration * rate_hz * 1.5) + 10
    if jitter > 0:
        gaps = period * (1.0 + rng.uniform(-jitter, jitter, n))
        t = np.concatenate([[0.0], np.cumsum(gaps)])
    else:
        t = np.arange(n + 1) * period
    t = np.round(t[t <= duration + 1e-12], 6)
    return t


# --------------------------------------------------------------------------- simulation


class _Integrator:
    """Piecewise integration with the wrench held constant over each call of :meth:`advance`."""

    def __init__(self, cart: RigidCart, y0: np.ndarray, kind: str) -> None:
        self.rhs = _make_rhs(cart)
        self.kind = kind
        self.t = 0.0
        self.y = np.array(y0, dtype=float)
        if kind == "dop853":
            self.ode = ode(self.rhs).set_integrator("dop853", rtol=RTOL, atol=ATOL, nsteps=100000)
            self.ode.set_initial_value(self.y, 0.0)
        elif kind != "solve_ivp":
            raise ValueError(f"integrator must be 'dop853' or 'solve_ivp', got {kind!r}")

    def switch_cart(self, cart: RigidCart) -> None:
        """Continue from the current state and time with another cart (a load change)."""
        self.rhs = _make_rhs(cart)
        if self.kind == "dop853":
            self.ode = ode(self.rhs).set_integrator("dop853", rtol=RTOL, atol=ATOL, nsteps=100000)
            self.ode.set_initial_value(self.y, self.t)

    def advance(self, t1: float, gamma: tuple[float, float, float]) -> np.ndarray:
        """Integrate to ``t1`` with ``gamma`` held; return the state."""
        if t1 <= self.t:
            return self.y
        if self.kind == "dop853":
            self.ode.set_f_params(*gamma)
            self.y = np.array(self.ode.integrate(t1))
            if not self.ode.successful():
                raise RuntimeError(f"DOP853 failed at t={self.ode.t}")
        else:
            sol = solve_ivp(self.rhs, (self.t, t1), self.y, method="DOP853", rtol=RTOL, atol=ATOL, args=gamma)
            if not sol.success:
                raise RuntimeError(f"solve_ivp failed at t={self.t}: {sol.message}")
            self.y = sol.y[:, -1].copy()
        self.t = t1
        return self.y


def _noise_std(case: RigidCase) -> dict[str, float]:
    std = {
        "x": case.pos_std,
        "y": case.pos_std,
        "theta": case.theta_std,
        "fx": case.force_std,
        "fy": case.force_std,
        "tau": case.torque_std,
    }
    if case.vel_std is not None:
        std.update(vx=case.vel_std, vy=case.vel_std, omega=case.omega_std)
    return {k: float(v) for k, v in std.items()}


def truth_record(case: RigidCase) -> dict[str, Any]:
    """Return the JSON-able truth of ``case`` in the layout of the validation ``truth.json``."""
    c = case.cart
    jit = f", irregular: gaps (1 +/- {case.jitter:.2f}) x period" if case.jitter > 0 else ""
    return {
        "generator": GENERATOR,
        "m": c.m,
        "dx": c.dx,
        "dy": c.dy,
        "I_about_com": c.I,
        "viscous_damping": {"forward_and_lateral_N_s_per_m": c.c_v, "yaw_N_m_s_per_rad": c.c_w},
        "noise_std": _noise_std(case),
        "noise_note": f"white, independent at every {case.rate_hz:g} Hz sample{jit}",
        "wrench_note": (
            f"the tracker updates the wrench every {WRENCH_PERIOD * 1e3:g} ms; the log samples "
            f"the held wrench (not an average) at {case.rate_hz:g} Hz"
        ),
        "hidden_effects": [],
        "case": {k: v for k, v in asdict(case).items() if k != "cart"},
        **(
            {
                "load_change": {
                    "t": case.load_time,
                    "m_after": case.cart_after_load.m,
                    "I_about_com_after": case.cart_after_load.I,
                }
            }
            if case.load_time is not None
            else {}
        ),
    }


@dataclass(frozen=True)
class _TickReferences:
    """The references and the lateral force on the 1 ms wrench grid ``t`` (``n_ticks + 1`` points)."""

    t: np.ndarray
    v: np.ndarray
    vd: np.ndarray
    w: np.ndarray
    wd: np.ndarray
    lat: np.ndarray

    @classmethod
    def on_grid(cls, t_end: float, v_ref_f: SmoothSteps, w_ref_f: SmoothSteps, lat_f: SmoothSteps) -> _TickReferences:
        """Return the references sampled on the wrench ticks covering [0, ``t_end``]."""
        n_ticks = int(math.floor(t_end / WRENCH_PERIOD + 1e-9)) + 1
        t_ticks = np.arange(n_ticks + 1) * WRENCH_PERIOD
        v_r, vd_r = v_ref_f(t_ticks)
        w_r, wd_r = w_ref_f(t_ticks)
        lat, _ = lat_f(t_ticks)
        return cls(t_ticks, v_r, vd_r, w_r, wd_r, lat)

    @property
    def n_ticks(self) -> int:
        """Number of wrench updates (grid intervals)."""
        return len(self.t) - 1


@dataclass(frozen=True)
class _CleanRun:
    """The noise-free run: states and held wrench at the log times, wrench history on the ticks (world, body)."""

    states: np.ndarray
    gamma_log: np.ndarray
    gamma_ms: np.ndarray
    gamma_body_ms: np.ndarray


def _run_ticks(
    integ: _Integrator,
    tracker: Tracker,
    refs: _TickReferences,
    t_log: np.ndarray,
    load: tuple[float, RigidCart] | None = None,
) -> _CleanRun:
    """Return the closed-loop run: the tracker's wrench held over each 1 ms tick, states sampled at ``t_log``."""
    n_ticks, n_log = refs.n_ticks, len(t_log)
    run = _CleanRun(np.empty((n_log, 5)), np.empty((n_log, 3)), np.empty((n_ticks, 3)), np.empty((n_ticks, 3)))
    # which tick interval [k h, (k+1) h) holds each sample
    tick_of = np.minimum(np.floor(t_log / WRENCH_PERIOD + 1e-9).astype(int), n_ticks - 1)
    int_ev = int_ew = 0.0
    j = 0
    y = integ.y
    for k in range(n_ticks):
        tk = float(refs.t[k])
        if load is not None and tk >= load[0]:
            integ.switch_cart(load[1])
            load = None
        th, v, w = y[2], y[3], y[4]
        f_fwd, tau = tracker.body_wrench(v, w, refs.v[k], refs.vd[k], refs.w[k], refs.wd[k], int_ev, int_ew)
        f_lat = float(refs.lat[k])
        c, s = math.cos(th), math.sin(th)
        gamma = (c * f_fwd - s * f_lat, s * f_fwd + c * f_lat, tau)
        run.gamma_ms[k] = gamma
        run.gamma_body_ms[k] = (f_fwd, f_lat, tau)
        while j < n_log and tick_of[j] == k:
            y = integ.advance(float(t_log[j]), gamma) if t_log[j] > tk else y
            run.states[j] = y
            run.gamma_log[j] = gamma
            j += 1
        y = integ.advance(float(refs.t[k + 1]), gamma)
        # controller integrators (rectangle rule at the 1 ms update rate)
        int_ev += (refs.v[k] - v) * WRENCH_PERIOD
        int_ew += (refs.w[k] - w) * WRENCH_PERIOD
    assert j == n_log
    return run


def _measure(
    case: RigidCase, t_log: np.ndarray, q: np.ndarray, qd: np.ndarray, gamma: np.ndarray, rng: np.random.Generator
) -> CartLog:
    """Return the noisy log of the clean ``q``, ``qd`` and ``gamma`` with the case's white noise stds."""
    noise = rng.standard_normal((len(t_log), 9))
    q_meas = q + noise[:, :3] * np.array([case.pos_std, case.pos_std, case.theta_std])
    g_meas = gamma + noise[:, 3:6] * np.array([case.force_std, case.force_std, case.torque_std])
    qd_meas = None
    if case.vel_std is not None:
        qd_meas = qd + noise[:, 6:9] * np.array([case.vel_std, case.vel_std, case.omega_std])
    return CartLog(
        t=t_log,
        q=q_meas,
        gamma=g_meas,
        qd=qd_meas,
        metadata={"log": f"rigid_seed{case.seed}", "source": "independent simulator"},
    )


def _truth(
    case: RigidCase,
    t_log: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    run: _CleanRun,
    refs: _TickReferences,
    tracker: Tracker,
) -> dict[str, Any]:
    """Return the truth record of ``case`` with the ``"clean"`` arrays (see :func:`simulate`)."""
    truth = truth_record(case)
    truth.update(c_v=case.cart.c_v, c_w=case.cart.c_w)
    truth["clean"] = {
        "t": t_log,
        "q": q,
        "qd": qd,
        "gamma": run.gamma_log,
        "v": run.states[:, 3].copy(),
        "t_wrench": refs.t[:-1].copy(),
        "gamma_wrench": run.gamma_ms,
        "gamma_body_wrench": run.gamma_body_ms,
        "v_ref": refs.v[:-1].copy(),
        "omega_ref": refs.w[:-1].copy(),
        "nominal": tracker.nominal,
    }
    return truth


def simulate(case: RigidCase, integrator: str = "dop853") -> tuple[CartLog, dict[str, Any]]:
    """Simulate ``case``; return (noisy log, truth).

    The truth holds ``m, dx, dy, I_about_com, c_v, c_w``, ``noise_std`` and the
    rest of :func:`truth_record`, plus ``"clean"``: the noise-free arrays at the
    log times (``t``, ``q`` unwrapped, ``qd`` world velocity of the {b} origin,
    ``gamma`` the held wrench, ``v`` forward speed), the 1 ms wrench history
    (``t_wrench``, ``gamma_wrench``, ``gamma_body_wrench`` = forward, lateral,
    tau) and the references (``v_ref``, ``omega_ref`` on the 1 ms grid) and the
    controller's ``nominal`` cart. ``integrator`` ``"dop853"`` (scipy.integrate.ode,
    fast) or ``"solve_ivp"`` (``solve_ivp(method="DOP853")`` per piece, slow).
    """
    cart = case.cart
    ss = np.random.SeedSequence([int(case.seed), 0xCA27]).spawn(5)
    rng_ref, rng_nom, rng_t, rng_noise, rng_init = (np.random.default_rng(s) for s in ss)
    v_ref_f, w_ref_f = make_references(rng_ref, case.duration, case.speed_scale)
    lat_f = make_lateral(rng_ref, case.duration, case.lateral_std)
    tracker = Tracker(nominal_cart(rng_nom, cart, case.nominal_error))
    t_log = sample_times(rng_t, case.duration, case.rate_hz, case.jitter)
    refs = _TickReferences.on_grid(t_log[-1], v_ref_f, w_ref_f, lat_f)
    y0 = np.array([rng_init.uniform(-3, 3), rng_init.uniform(-3, 3), rng_init.uniform(-math.pi, math.pi), 0.0, 0.0])
    load = (case.load_time, case.cart_after_load) if case.load_time is not None else None
    run = _run_ticks(_Integrator(cart, y0, integrator), tracker, refs, t_log, load)
    states = run.states
    th = states[:, 2]
    q = states[:, :3].copy()
    qd = np.column_stack([states[:, 3] * np.cos(th), states[:, 3] * np.sin(th), states[:, 4]])
    log = _measure(case, t_log, q, qd, run.gamma_log, rng_noise)
    return log, _truth(case, t_log, q, qd, run, refs, tracker)


def write_case(case: RigidCase, path: str | os.PathLike) -> dict[str, Any]:
    """Simulate ``case``, write its noisy log to ``path`` (``.csv`` or ``.csv.gz``); return its JSON-able truth."""
    log, truth = simulate(case)
    name = os.path.basename(os.fspath(path)).split(".")[0]
    log = replace(log, metadata={**log.metadata, "log": name})
    write_log(path, log, wrap_theta=case.wrap_theta)
    truth.pop("clean")
    truth.pop("c_v")
    truth.pop("c_w")
    return truth


def generate(
    n: int, seed0: int, out_dir: str | os.PathLike, prefix: str = "rigid", **overrides: Any
) -> dict[str, dict[str, Any]]:
    """Write ``n`` random logs ``{prefix}{i:02d}.csv.gz`` (seeds ``seed0 + i``) and ``truth.json`` to ``out_dir``.

    ``truth.json`` maps each log name to :func:`truth_record` (the layout of
    the validation set's truth.json, plus the case parameters). ``overrides``
    go to :func:`random_case`. Returns that mapping.
    """
    out_dir = os.fspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    truth: dict[str, dict[str, Any]] = {}
    for i in range(n):
        name = f"{prefix}{i:02d}"
        case = random_case(seed0 + i, **overrides)
        truth[name] = write_case(case, os.path.join(out_dir, name + ".csv.gz"))
    with open(os.path.join(out_dir, "truth.json"), "w", encoding="utf-8") as fh:
        json.dump(truth, fh, indent=1)
    return truth


def parse_overrides(items: Sequence[str]) -> dict[str, Any]:
    """Return the overrides of ``key=value`` items (values read as JSON: numbers, true/false, null), e.g.
    ``["rate_hz=30", "vel_std=null"]``; raise ValueError on an item without ``=`` or an unknown field."""
    fields_ = _CART_FIELDS | (_CASE_FIELDS - {"cart", "seed"})
    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or key not in fields_:
            raise ValueError(f"override {item!r}: expected FIELD=VALUE with FIELD one of {sorted(fields_)}")
        out[key] = json.loads(text)
    return out


if __name__ == "__main__":  # python -m studies.testbeds.rigid_sim N SEED0 OUT_DIR [FIELD=VALUE ...]
    import sys

    if len(sys.argv) < 4:
        sys.exit("usage: python -m studies.testbeds.rigid_sim N SEED0 OUT_DIR [FIELD=VALUE ...] (e.g. rate_hz=30)")
    try:
        overrides = parse_overrides(sys.argv[4:])
    except ValueError as exc:
        sys.exit(str(exc))
    generate(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], **overrides)

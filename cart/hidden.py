"""Test bed: simulate a pushed cart with known hidden effects and write the log a robot would record.

:func:`simulate_hidden` integrates the cart (paper eq. 4, exact constraint,
body-frame form of :func:`cart.model.forward_dynamics_fast`) with any of the
contract effects of ``DESIGN.md`` switched on, with known parameters, under a
velocity-tracking controller following a random push/pull motion with turns
(:func:`random_motion`); it samples the state at irregular times, adds
measurement noise and applies the measurement-side effects (wrench bias, time
delay). :func:`random_case` draws a whole random case (cart, motion, noise,
sampling rate, effect size) for tests and the benchmark study.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from cart.errors import ParameterError
from cart.logs import CartLog
from cart.params import CartParams

GRAVITY = 9.81
HIDDEN_NAMES = ("coulomb_friction", "caster_swivel", "wrench_bias", "payload_change", "floor_slope",
                "time_delay", "lateral_slip")


@dataclass(frozen=True)
class HiddenEffect:
    """An effect hidden in a simulated log: contract ``name`` and its known ``params``.

    Parameters by name: coulomb_friction {force [N], torque [N m]};
    caster_swivel {force [N], distance [m]}; wrench_bias {fx, fy [N], tau [N m]} in {b};
    payload_change {time [s], mass [kg], x, y [m] in {b}, inertia [kg m^2]};
    floor_slope {angle [rad], direction [rad], downhill in {s}}; time_delay {delay [s]};
    lateral_slip {compliance [m/(s N)]}.
    """

    name: str
    params: Dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.name not in HIDDEN_NAMES:
            raise ParameterError(f"unknown hidden effect {self.name!r}; known: {', '.join(HIDDEN_NAMES)}")


@dataclass(frozen=True)
class Motion:
    """Desired forward speed and yaw rate on a time grid (t, v, vdot, omega, omegadot)."""

    t: np.ndarray
    v: np.ndarray
    vdot: np.ndarray
    omega: np.ndarray
    omegadot: np.ndarray

    def at(self, t: float) -> Tuple[float, float, float, float]:
        """Return (v, vdot, omega, omegadot) at time t (linear interpolation)."""
        return (float(np.interp(t, self.t, self.v)), float(np.interp(t, self.t, self.vdot)),
                float(np.interp(t, self.t, self.omega)), float(np.interp(t, self.t, self.omegadot)))


@dataclass(frozen=True)
class HiddenLog:
    """A simulated log with hidden effects: ``measured`` (what diagnose sees), ``true`` state, the truth."""

    measured: CartLog
    true: CartLog
    params: CartParams
    effects: Tuple[HiddenEffect, ...]
    rate: float
    noise: Dict[str, float]


def _smooth_step(u: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Return (s, ds/du) of the raised-cosine step 0 -> 1 on u in [0, 1]."""
    u = np.clip(u, 0.0, 1.0)
    return 0.5 * (1.0 - np.cos(np.pi * u)), 0.5 * np.pi * np.sin(np.pi * u)


def random_motion(rng: np.random.Generator, duration: float = 30.0, dt: float = 0.002,
                  min_reversals: int = 1) -> Motion:
    """Return a random push/pull motion: smooth speed changes, >= ``min_reversals`` push-to-pull reversals, turns."""
    t = np.arange(0.0, duration + dt, dt)
    v = np.zeros_like(t)
    vd = np.zeros_like(t)
    levels = []
    sign = 1.0
    tc = 1.0 + rng.uniform(0.0, 1.0)
    cur = 0.0
    n_rev = 0
    while tc < duration - 4.0:
        ramp = rng.uniform(1.0, 2.5)
        hold = rng.uniform(1.5, 4.0)
        if levels and (n_rev < min_reversals and len(levels) >= 1 or rng.uniform() < 0.4):
            sign = -sign
            n_rev += 1
        target = sign * (rng.uniform(0.3, 0.9) if sign > 0 else rng.uniform(0.2, 0.6))
        if rng.uniform() < 0.1:
            target = 0.0
        levels.append((tc, ramp, cur, target))
        cur = target
        tc += ramp + hold
    levels.append((max(tc, duration - 3.5), 2.0, cur, 0.0))
    for t0, ramp, a, b in levels:
        s, ds = _smooth_step((t - t0) / ramp)
        mask = t >= t0
        v[mask] = a + (b - a) * s[mask]
        vd[mask] = (b - a) * ds[mask] / ramp
    om = np.zeros_like(t)
    omd = np.zeros_like(t)
    tt = 2.0 + rng.uniform(0.0, 2.0)
    while tt < duration - 3.0:
        length = rng.uniform(1.5, 3.0)
        peak = rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 0.8)
        u = (t - tt) / length
        inside = (u > 0) & (u < 1)
        om[inside] += 0.5 * peak * (1.0 - np.cos(2.0 * np.pi * u[inside]))
        omd[inside] += 0.5 * peak * 2.0 * np.pi / length * np.sin(2.0 * np.pi * u[inside])
        tt += length + rng.uniform(1.0, 4.0)
    return Motion(t=t, v=v, vdot=vd, omega=om, omegadot=omd)


def payload_params(p: CartParams, mass: float, x: float, y: float, inertia: float = 0.0) -> CartParams:
    """Return the cart parameters after adding a point-like payload of ``mass`` at (x, y) in {b}."""
    m2 = p.m + mass
    dx2 = (p.m * p.dx + mass * x) / m2
    dy2 = (p.m * p.dy + mass * y) / m2
    i2 = (p.I + p.m * ((p.dx - dx2) ** 2 + (p.dy - dy2) ** 2) + inertia
          + mass * ((x - dx2) ** 2 + (y - dy2) ** 2))
    return CartParams(m=m2, dx=dx2, dy=dy2, I=i2, sigma=p.sigma)


def simulate_hidden(params: CartParams, effects: Sequence[HiddenEffect] = (), duration: float = 30.0,
                    rate: float = 100.0, jitter: float = 0.2, position_noise: float = 0.003,
                    theta_noise: float = 0.004, force_noise: float = 3.0, torque_noise: float = 1.5,
                    velocity_noise: float = 0.01, with_velocities: bool = True,
                    motion: Optional[Motion] = None, rng: Optional[np.random.Generator] = None,
                    contact: Tuple[float, float] = (-0.8, 0.0), control_rate: float = 100.0,
                    model_error: float = 0.2, h: float = 0.002) -> HiddenLog:
    """Return the measured and true logs of a cart with ``effects`` hidden, pushed along ``motion``.

    Samples are taken every ``(1 + jitter U(-1, 1)) / rate`` s; noise stds are
    per sample (position [m], theta [rad], force [N], torque [N m], velocity
    [m/s]). The controller knows the cart only up to ``model_error`` (relative)
    and tracks the motion's speed and yaw rate by feedback.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    motion = random_motion(rng, duration) if motion is None else motion
    eff = {e.name: e.params for e in effects}
    p = params
    change = eff.get("payload_change")
    p_after = payload_params(p, change["mass"], change["x"], change["y"], change.get("inertia", 0.0)) \
        if change else p
    # the controller's guess of the cart
    guess = [v * (1.0 + model_error * rng.uniform(-1.0, 1.0)) for v in (p.m, p.m * p.dx, p.m * p.dy, p.inertia_b)]
    guess[3] = max(guess[3], 0.2 * p.inertia_b)
    kv, kw = 2.5, 3.0
    px, py = contact
    n = int(round(duration / h)) + 1
    ts = np.arange(n) * h
    state = np.zeros((n, 5))  # x, y, theta, v, omega
    lat = np.zeros(n)
    gam_w = np.zeros((n, 3))  # applied (fx, fy, tau) in {s}
    x = np.zeros(5)
    control_every = max(1, int(round(1.0 / (control_rate * h))))
    fu = fl = tq = 0.0
    dist = math.inf
    direction = 0
    sw = eff.get("caster_swivel")
    cf = eff.get("coulomb_friction")
    sl = eff.get("floor_slope")
    slip = eff.get("lateral_slip")
    g_slope = (GRAVITY * math.sin(sl["angle"]) * math.cos(sl["direction"]),
               GRAVITY * math.sin(sl["angle"]) * math.sin(sl["direction"])) if sl else (0.0, 0.0)

    def deriv(xs: np.ndarray, ph: CartParams, fu: float, fl: float, tq: float, dist: float):
        m, a, b, j, sig = ph.m, ph.m * ph.dx, ph.m * ph.dy, ph.inertia_b, ph.sigma
        th, v, om = xs[2], xs[3], xs[4]
        c, s = math.cos(th), math.sin(th)
        e_f = e_t = e_l = 0.0
        if cf:
            e_f -= cf["force"] * math.tanh(v / 0.005)
            e_t -= cf.get("torque", 0.0) * math.tanh(om / 0.01)
        if sw and dist < sw["distance"]:
            e_f -= sw["force"] * math.tanh(v / 0.005) * 0.5 * (1.0 + math.cos(math.pi * dist / sw["distance"]))
        if sl:
            gx, gy = g_slope
            e_f += m * (c * gx + s * gy)
            e_l += m * (-s * gx + c * gy)
            e_t += a * (c * gy - s * gx) - b * (s * gy + c * gx)
        r1 = fu + e_f - sig * v + a * om * om
        r2 = tq + e_t - sig * om - a * om * v
        det = m * j - b * b
        vdot = (j * r1 + b * r2) / det
        odot = (b * r1 + m * r2) / det
        w = 0.0
        if slip:
            w = slip["compliance"] * (fl + e_l - (m * v * om + a * odot - b * om * om))
        return np.array([c * v - s * w, s * v + c * w, om, vdot, odot]), w

    for k in range(n):
        t = ts[k]
        ph = p_after if (change and t >= change["time"]) else p
        if k % control_every == 0:
            vd_, vdd_, wd_, wdd_ = motion.at(t)
            av = vdd_ + kv * (vd_ - x[3])
            aw = wdd_ + kw * (wd_ - x[4])
            m_, a_, b_, j_ = guess
            fu = m_ * av - a_ * x[4] ** 2 - b_ * aw
            tq = j_ * aw - b_ * av + a_ * x[4] * x[3]
            # least-effort lateral force for a grasp at the handle (cart.simulate.min_effort_gamma)
            fl = px * (tq + py * fu) / (0.5 ** 2 + px * px)
        c, s = math.cos(x[2]), math.sin(x[2])
        state[k] = x
        gam_w[k] = (c * fu - s * fl, s * fu + c * fl, tq)
        if k == n - 1:
            break
        k1, w1 = deriv(x, ph, fu, fl, tq, dist)
        k2, _ = deriv(x + 0.5 * h * k1, ph, fu, fl, tq, dist)
        lat[k] = w1
        v_old = x[3]
        x = x + h * k2
        # caster state: distance travelled since the last reversal of the forward speed
        new_dir = 1 if x[3] > 0.01 else (-1 if x[3] < -0.01 else direction)
        if new_dir != direction and direction != 0:
            dist = 0.0
        direction = new_dir
        dist += 0.5 * (abs(v_old) + abs(x[3])) * h
    # irregular sampling
    steps = (1.0 + jitter * rng.uniform(-1.0, 1.0, size=int(duration * rate * 1.5) + 10)) / rate
    ti = np.concatenate([[0.0], np.cumsum(steps)])
    ti = ti[ti <= duration]
    st = np.column_stack([np.interp(ti, ts, state[:, i]) for i in range(5)])
    g_true = gam_w[np.clip(np.searchsorted(ts, ti, side="right") - 1, 0, n - 1)]
    g_log = g_true.copy()
    if "time_delay" in eff:  # the logged wrench at t was applied at t - delay
        g_log = gam_w[np.clip(np.searchsorted(ts, ti - eff["time_delay"]["delay"], side="right") - 1, 0, n - 1)]
    th = st[:, 2]
    c, s = np.cos(th), np.sin(th)
    if "wrench_bias" in eff:
        bx, by, bt = (eff["wrench_bias"].get(k, 0.0) for k in ("fx", "fy", "tau"))
        g_log = g_log + np.column_stack([c * bx - s * by, s * bx + c * by, np.full_like(th, bt)])
    lat_i = np.interp(ti, ts, lat)
    qd_true = np.column_stack([c * st[:, 3] - s * lat_i, s * st[:, 3] + c * lat_i, st[:, 4]])
    q_true = st[:, :3]
    nn = len(ti)
    q_meas = q_true + rng.standard_normal((nn, 3)) * np.array([position_noise, position_noise, theta_noise])
    g_meas = g_log + rng.standard_normal((nn, 3)) * np.array([force_noise, force_noise, torque_noise])
    qd_meas = qd_true + rng.standard_normal((nn, 3)) * np.array([velocity_noise, velocity_noise,
                                                                  velocity_noise]) if with_velocities else None
    meta = {"source": "cart.hidden", "rate": f"{rate:g}"}
    measured = CartLog(t=ti, q=q_meas, gamma=g_meas, qd=qd_meas, metadata=meta)
    true = CartLog(t=ti, q=q_true, gamma=g_true, qd=qd_true, metadata=dict(meta))
    noise = {"position": position_noise, "theta": theta_noise, "force": force_noise, "torque": torque_noise}
    return HiddenLog(measured=measured, true=true, params=params, effects=tuple(effects), rate=rate, noise=noise)


def random_cart(rng: np.random.Generator) -> CartParams:
    """Return a random cart: 15-60 kg, CoM 0.1-0.5 m forward and +-0.15 m sideways, plausible inertia, sigma."""
    m = rng.uniform(15.0, 60.0)
    dx = rng.uniform(0.1, 0.5)
    dy = rng.uniform(-0.15, 0.15)
    length, width = rng.uniform(0.8, 1.2), rng.uniform(0.5, 0.7)
    inertia = m * (length ** 2 + width ** 2) / 12.0
    return CartParams(m=m, dx=dx, dy=dy, I=inertia, sigma=rng.uniform(0.5, 3.0))


def random_effect(name: str, rng: np.random.Generator, params: CartParams, duration: float) -> HiddenEffect:
    """Return a contract effect with random, physically plausible size (see HiddenEffect for the units)."""
    sgn = lambda: float(rng.choice([-1.0, 1.0]))  # noqa: E731
    if name == "coulomb_friction":
        return HiddenEffect(name, {"force": rng.uniform(0.015, 0.05) * params.m * GRAVITY,
                                   "torque": rng.uniform(0.0, 2.0)})
    if name == "caster_swivel":
        return HiddenEffect(name, {"force": rng.uniform(0.4, 1.0) * params.m, "distance": rng.uniform(0.1, 0.4)})
    if name == "wrench_bias":
        return HiddenEffect(name, {"fx": sgn() * rng.uniform(3.0, 10.0), "fy": rng.uniform(-5.0, 5.0),
                                   "tau": sgn() * rng.uniform(1.0, 4.0)})
    if name == "payload_change":
        return HiddenEffect(name, {"time": rng.uniform(0.35, 0.65) * duration,
                                   "mass": rng.uniform(0.3, 1.0) * params.m,
                                   "x": rng.uniform(0.1, 0.5), "y": rng.uniform(-0.15, 0.15),
                                   "inertia": rng.uniform(0.0, 0.5)})
    if name == "floor_slope":
        return HiddenEffect(name, {"angle": math.radians(rng.uniform(1.0, 3.0)),
                                   "direction": rng.uniform(-math.pi, math.pi)})
    if name == "time_delay":
        return HiddenEffect(name, {"delay": sgn() * rng.uniform(0.05, 0.25) if rng.uniform() < 0.25
                                   else rng.uniform(0.05, 0.25)})
    if name == "lateral_slip":
        return HiddenEffect(name, {"compliance": rng.uniform(2e-3, 6e-3)})
    raise ParameterError(f"unknown hidden effect {name!r}; known: {', '.join(HIDDEN_NAMES)}")


def random_case(effect: Optional[str], rng: np.random.Generator, duration: float = 30.0) -> HiddenLog:
    """Return a random test case with ``effect`` hidden (None: nominal cart) and randomized rate, noise, columns."""
    params = random_cart(rng)
    effects = (random_effect(effect, rng, params, duration),) if effect else ()
    return simulate_hidden(params, effects, duration=duration, rate=float(rng.uniform(50.0, 200.0)),
                           jitter=float(rng.uniform(0.0, 0.3)), position_noise=float(rng.uniform(0.001, 0.004)),
                           theta_noise=float(rng.uniform(0.002, 0.008)), force_noise=float(rng.uniform(2.0, 4.0)),
                           torque_noise=float(rng.uniform(0.5, 2.0)), with_velocities=bool(rng.uniform() < 0.5),
                           contact=(-0.8, float(rng.uniform(-0.15, 0.15))), rng=rng)

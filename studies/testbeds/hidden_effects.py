"""Test bed: simulate a pushed cart with known hidden effects and write the log a robot would record.

:func:`simulate_hidden` integrates the cart (paper eq. 4, exact constraint,
body-frame form of :func:`cart.model.forward_dynamics_fast`) with any of the
contract effects of ``docs/architecture.md`` switched on, with known parameters, under a
velocity-tracking controller following a random push/pull motion with turns
(:func:`random_motion`); it samples the state at irregular times, adds
measurement noise and applies the measurement-side effects (wrench bias, time
delay). :func:`random_case` draws a whole random case (cart, motion, noise,
sampling rate, effect size) for tests and the benchmark study.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Sequence

import numpy as np

from cart.dynamics import body_accelerations, lateral_inertial_force
from cart.effects import CONTRACT_NAMES
from cart.errors import ParameterError
from cart.logs import CartLog
from cart.params import CartParams
from wholebody.contacts.excitation import PushSamples

GRAVITY = 9.81
#: the effects a log can hide: the diagnosis contract's names, in its order
HIDDEN_NAMES = CONTRACT_NAMES


@dataclass(frozen=True)
class HiddenEffect:
    """An effect hidden in a simulated log: contract ``name`` and its known ``params``.

    Parameters by name: coulomb_friction {force [N], torque [N m]};
    caster_swivel, two forms: the resistance profile {force [N], distance [m]} (after a reversal,
    -force tanh(v / 5 mm/s) times a raised cosine fading over ``distance``), or swivelling casters
    {trail [m], torque [N m], damping [N m s/rad], eps [rad/s], inertia [kg m^2], x [m], half_track [m],
    roughness [rad/sqrt(m)]}
    (selected by the key ``trail``; see :class:`SwivelCasters`); wrench_bias {fx, fy [N], tau [N m]} in {b};
    payload_change {time [s], mass [kg], x, y [m] in {b}, inertia [kg m^2]};
    floor_slope {angle [rad], direction [rad], downhill in {s}}; time_delay {delay [s]};
    lateral_slip {compliance [m/(s N)]}.
    """

    name: str
    params: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.name not in HIDDEN_NAMES:
            raise ParameterError(f"unknown hidden effect {self.name!r}; known: {', '.join(HIDDEN_NAMES)}")


#: The desired forward speed and yaw rate on a time grid (t, v, vdot, omega, omegadot; ``at(t)`` interpolates):
#: the library's planned-push record.
Motion = PushSamples


@dataclass(frozen=True)
class HiddenLog:
    """A simulated log with hidden effects: ``measured`` (what diagnose sees), ``true`` state, the truth."""

    measured: CartLog
    true: CartLog
    params: CartParams
    effects: tuple[HiddenEffect, ...]
    rate: float
    noise: dict[str, float]
    #: the hidden effects' generalized force on the cart at the sample times: (forward, lateral, yaw) in {b}
    effect_force: np.ndarray | None = None


def _smooth_step(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (s, ds/du) of the raised-cosine step 0 -> 1 on u in [0, 1]."""
    u = np.clip(u, 0.0, 1.0)
    return 0.5 * (1.0 - np.cos(np.pi * u)), 0.5 * np.pi * np.sin(np.pi * u)


def random_motion(
    rng: np.random.Generator, duration: float = 30.0, dt: float = 0.002, min_reversals: int = 1
) -> Motion:
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
    i2 = p.I + p.m * ((p.dx - dx2) ** 2 + (p.dy - dy2) ** 2) + inertia + mass * ((x - dx2) ** 2 + (y - dy2) ** 2)
    return CartParams(m=m2, dx=dx2, dy=dy2, I=i2, sigma=p.sigma)


class SwivelCasters:
    """Two swivelling casters at (x, +-half_track) in {b}, with trail, swivel friction, damping and inertia.

    Each caster's wheel rolls along the direction ``alpha`` (in {b}) and
    touches the floor ``trail`` behind its swivel axis P. The wheel does not
    slide sideways, so alpha follows the velocity of P (kinematics):
    trail (alpha' + omega) = n . v_P, n = (-sin alpha, cos alpha): stable when
    the wheel trails, unstable when it leads -- after a reversal each caster
    swings round by ~180 deg over a few trails of travel. The swivel bearing
    resists with T = torque tanh(alpha' / eps) + damping alpha' (``eps``: the
    Coulomb friction's regularisation, rad/s); the fork's torque balance about
    the swivel axis, with its ``inertia`` (kg m^2) about that axis, makes the
    floor push the wheel sideways with -(T + inertia (alpha' + omega)') / trail
    along n, which acts on the cart at P, and the bearing returns T to the
    cart: E_fwd = sum F . x, E_yaw = sum (P x F) + T. So the cart is resisted
    during the swing (and when the casters realign in turns), and gets a yaw
    torque whose sign depends on which way each caster swings. ``roughness``:
    the floor kicks each caster angle by a random walk of that std per
    sqrt(metre) of travel, so a caster never stays exactly on its unstable
    equilibrium. The swivel acceleration is taken from the previous step
    (the fork's inertia is small against the cart's).
    """

    def __init__(self, p: dict[str, float], params: CartParams) -> None:
        self.trail = float(p["trail"])
        self.torque = float(p.get("torque", 0.0))
        self.damping = float(p.get("damping", 0.0))
        self.eps = float(p.get("eps", 0.5))
        self.inertia = float(p.get("inertia", 0.0))
        x = float(p.get("x", params.dx + 0.4))
        yc = float(p.get("half_track", 0.25))
        self.pos = ((x, yc), (x, -yc))
        self.roughness = float(p.get("roughness", 0.01))
        self.acc = np.zeros(2)  # absolute swivel acceleration (alpha' + omega)' of the last step

    def rates(self, v: float, om: float, alphas: np.ndarray) -> np.ndarray:
        """Return the swivel rates alpha' (relative to the cart) at speed v, yaw rate om."""
        return np.array(
            [
                (-(v - om * cy) * math.sin(al) + om * cx * math.cos(al)) / self.trail - om
                for (cx, cy), al in zip(self.pos, alphas)
            ]
        )

    def terms(self, v: float, om: float, alphas: np.ndarray) -> tuple[float, float, float, np.ndarray]:
        """Return (E_fwd, E_lat, E_yaw) on the cart and the swivel rates alpha' at speed v, yaw rate om."""
        e_f = e_l = e_t = 0.0
        rates = self.rates(v, om, alphas)
        for k, ((cx, cy), al) in enumerate(zip(self.pos, alphas)):
            sa, ca = math.sin(al), math.cos(al)
            tq = self.torque * math.tanh(rates[k] / self.eps) + self.damping * rates[k]
            fn = -(tq + self.inertia * self.acc[k]) / self.trail  # floor force on the wheel along n, at P
            fx, fy = -fn * sa, fn * ca
            e_f += fx
            e_l += fy
            e_t += cx * fy - cy * fx + tq
        return e_f, e_l, e_t, rates


@dataclass
class Effects:
    """The hidden effects of one simulation, grouped by role (None: off); see :class:`HiddenEffect` for units.

    ``caster_profile`` is the resistance-profile form of ``caster_swivel``,
    ``casters`` its swivelling-caster form (holds the swivel state of a run).
    """

    coulomb_friction: dict[str, float] | None = None
    caster_profile: dict[str, float] | None = None
    casters: SwivelCasters | None = None
    floor_slope: dict[str, float] | None = None
    lateral_slip: dict[str, float] | None = None
    payload_change: dict[str, float] | None = None
    time_delay: dict[str, float] | None = None
    wrench_bias: dict[str, float] | None = None

    @classmethod
    def from_hidden(cls, effects: Sequence[HiddenEffect], params: CartParams) -> Effects:
        """Return the grouped effects of the contract ``effects`` on the cart ``params``."""
        eff = {e.name: e.params for e in effects}
        sw = eff.get("caster_swivel")
        casters = SwivelCasters(sw, params) if sw and "trail" in sw else None
        return cls(
            coulomb_friction=eff.get("coulomb_friction"),
            caster_profile=None if casters is not None else sw,
            casters=casters,
            floor_slope=eff.get("floor_slope"),
            lateral_slip=eff.get("lateral_slip"),
            payload_change=eff.get("payload_change"),
            time_delay=eff.get("time_delay"),
            wrench_bias=eff.get("wrench_bias"),
        )

    def slope_gravity(self) -> tuple[float, float]:
        """Return the downhill gravity (gx, gy) in {s} of the floor slope (zero without one)."""
        sl = self.floor_slope
        if not sl:
            return (0.0, 0.0)
        return (
            GRAVITY * math.sin(sl["angle"]) * math.cos(sl["direction"]),
            GRAVITY * math.sin(sl["angle"]) * math.sin(sl["direction"]),
        )

    def params_at(self, t: float, before: CartParams, after: CartParams) -> CartParams:
        """Return the cart parameters at time ``t`` (``after`` once the payload has changed)."""
        change = self.payload_change
        return after if (change and t >= change["time"]) else before


def _coulomb_terms(cf: dict[str, float], v: float, om: float) -> tuple[float, float]:
    """Return the (forward, yaw) Coulomb friction on the cart at speed v, yaw rate om (regularised by tanh)."""
    return cf["force"] * math.tanh(v / 0.005), cf.get("torque", 0.0) * math.tanh(om / 0.01)


def _profile_force(sw: dict[str, float], v: float, dist: float) -> float:
    """Return the caster resistance-profile force magnitude ``dist`` after the last reversal (0 beyond it)."""
    if dist < sw["distance"]:
        return sw["force"] * math.tanh(v / 0.005) * 0.5 * (1.0 + math.cos(math.pi * dist / sw["distance"]))
    return 0.0


def _slope_terms(g_slope: tuple[float, float], th: float, m: float, a: float, b: float) -> tuple[float, float, float]:
    """Return the (forward, lateral, yaw) gravity terms on the cart at heading ``th`` (phi = (m, a, b, j))."""
    gx, gy = g_slope
    c, s = math.cos(th), math.sin(th)
    return m * (c * gx + s * gy), m * (-s * gx + c * gy), a * (c * gy - s * gx) - b * (s * gy + c * gx)


def _effect_terms(
    fx: Effects, g_slope: tuple[float, float], xs: np.ndarray, al: np.ndarray, phi: list[float], dist: float
) -> tuple[float, float, float, np.ndarray | None]:
    """Return the hidden effects' (E_fwd, E_lat, E_yaw) on the cart and the caster swivel rates (or None)."""
    m, a, b, _ = phi
    th, v, om = xs[2], xs[3], xs[4]
    e_f = e_t = e_l = 0.0
    rates = None
    if fx.casters is not None:
        e_f, e_l, e_t, rates = fx.casters.terms(v, om, al)
    if fx.coulomb_friction:
        f_c, t_c = _coulomb_terms(fx.coulomb_friction, v, om)
        e_f -= f_c
        e_t -= t_c
    if fx.caster_profile and dist < fx.caster_profile["distance"]:
        e_f -= _profile_force(fx.caster_profile, v, dist)
    if fx.floor_slope:
        s_f, s_l, s_t = _slope_terms(g_slope, th, m, a, b)
        e_f += s_f
        e_l += s_l
        e_t += s_t
    return e_f, e_l, e_t, rates


def _cart_ode(
    fx: Effects,
    g_slope: tuple[float, float],
    xs: np.ndarray,
    al: np.ndarray,
    ph: CartParams,
    u: tuple[float, float, float],
    dist: float,
):
    """Return (x', lateral slip speed w, swivel rates, effect terms) of the cart state (x, y, theta, v, omega).

    Paper eq. 4 in body-frame form with the hidden effects added to the
    applied body wrench ``u`` = (forward force, lateral force, torque).
    """
    m, a, b, j = phi = ph.phi.tolist()
    fu, fl, tq = u
    th, v, om = xs[2], xs[3], xs[4]
    c, s = math.cos(th), math.sin(th)
    e_f, e_l, e_t, rates = _effect_terms(fx, g_slope, xs, al, phi, dist)
    vdot, odot = body_accelerations(v, om, fu + e_f, tq + e_t, m, a, b, j, ph.sigma, ph.sigma_yaw)
    w = 0.0
    if fx.lateral_slip:
        w = fx.lateral_slip["compliance"] * (fl + e_l - lateral_inertial_force(v, om, odot, m, a, b))
    return np.array([c * v - s * w, s * v + c * w, om, vdot, odot]), w, rates, (e_f, e_l, e_t)


@dataclass(frozen=True)
class _Controller:
    """Velocity-tracking feedback on a guessed cart ``guess`` = (m, m dx, m dy, inertia about {b})."""

    guess: list[float]
    contact: tuple[float, float]
    kv: float = 2.5
    kw: float = 3.0

    @classmethod
    def guessing(
        cls, p: CartParams, model_error: float, rng: np.random.Generator, contact: tuple[float, float]
    ) -> _Controller:
        """Return a controller whose cart model is off by up to ``model_error`` (relative, uniform)."""
        guess = [v * (1.0 + model_error * rng.uniform(-1.0, 1.0)) for v in (p.m, p.m * p.dx, p.m * p.dy, p.inertia_b)]
        guess[3] = max(guess[3], 0.2 * p.inertia_b)
        return cls(guess=guess, contact=contact)

    def wrench(self, motion: Motion, t: float, x: np.ndarray) -> tuple[float, float, float]:
        """Return the body wrench (forward force, lateral force, torque) tracking ``motion`` at ``t`` from ``x``."""
        px, py = self.contact
        vd_, vdd_, wd_, wdd_ = motion.at(t)
        av = vdd_ + self.kv * (vd_ - x[3])
        aw = wdd_ + self.kw * (wd_ - x[4])
        m_, a_, b_, j_ = self.guess
        fu = m_ * av - a_ * x[4] ** 2 - b_ * aw
        tq = j_ * aw - b_ * av + a_ * x[4] * x[3]
        # least-effort lateral force for a grasp at the handle (cart.simulate.min_effort_gamma)
        fl = px * (tq + py * fu) / (0.5**2 + px * px)
        return fu, fl, tq


@dataclass
class _Trajectory:
    """The fine-step simulation: times, states (x, y, theta, v, omega), slip speed, effect terms, wrench in {s}."""

    ts: np.ndarray
    state: np.ndarray
    lat: np.ndarray
    eff_force: np.ndarray
    gam_w: np.ndarray

    @classmethod
    def empty(cls, n: int, h: float) -> _Trajectory:
        """Return a zero trajectory of ``n`` steps of ``h`` s."""
        return cls(np.arange(n) * h, np.zeros((n, 5)), np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)))


@dataclass
class _Travel:
    """Distance travelled since the last reversal of the forward speed (the caster profile's state)."""

    dist: float = math.inf
    direction: int = 0

    def update(self, v_old: float, v_new: float, h: float) -> None:
        """Advance by one step of ``h`` s from speed ``v_old`` to ``v_new`` (trapezoidal distance)."""
        new_dir = 1 if v_new > 0.01 else (-1 if v_new < -0.01 else self.direction)
        if new_dir != self.direction and self.direction != 0:
            self.dist = 0.0
        self.direction = new_dir
        self.dist += 0.5 * (abs(v_old) + abs(v_new)) * h


def _swivel_step(
    casters: SwivelCasters,
    alphas: np.ndarray,
    x: np.ndarray,
    ra1: np.ndarray,
    ra2: np.ndarray,
    om_old: float,
    h: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Return the caster angles after a midpoint step plus the floor's random kicks; update the swivel acceleration."""
    kick = casters.roughness * math.sqrt(abs(x[3]) * h + 1e-12) * rng.standard_normal(2)
    alphas = alphas + h * ra2 + kick
    if casters.inertia > 0.0:
        casters.acc = (casters.rates(x[3], x[4], alphas) + x[4] - ra1 - om_old) / h
    return alphas


def _integrate(
    p: CartParams,
    fx: Effects,
    ctrl: _Controller,
    motion: Motion,
    alphas: np.ndarray,
    duration: float,
    h: float,
    control_rate: float,
    rng: np.random.Generator,
) -> _Trajectory:
    """Return the cart's trajectory under ``ctrl`` by the midpoint rule with step ``h`` (control held between ticks)."""
    change = fx.payload_change
    p_after = payload_params(p, change["mass"], change["x"], change["y"], change.get("inertia", 0.0)) if change else p
    g_slope = fx.slope_gravity()
    n = int(round(duration / h)) + 1
    tr = _Trajectory.empty(n, h)
    x = np.zeros(5)
    control_every = max(1, int(round(1.0 / (control_rate * h))))
    u = (0.0, 0.0, 0.0)
    travel = _Travel()
    for k in range(n):
        ph = fx.params_at(tr.ts[k], p, p_after)
        if k % control_every == 0:
            u = ctrl.wrench(motion, tr.ts[k], x)
        fu, fl, tq = u
        c, s = math.cos(x[2]), math.sin(x[2])
        tr.state[k] = x
        tr.gam_w[k] = (c * fu - s * fl, s * fu + c * fl, tq)
        if k == n - 1:
            break
        k1, w1, ra1, tr.eff_force[k] = _cart_ode(fx, g_slope, x, alphas, ph, u, travel.dist)
        al_mid = alphas + 0.5 * h * ra1 if fx.casters is not None else alphas
        k2, _, ra2, _ = _cart_ode(fx, g_slope, x + 0.5 * h * k1, al_mid, ph, u, travel.dist)
        tr.lat[k] = w1
        v_old, om_old = x[3], x[4]
        x = x + h * k2
        if fx.casters is not None:
            alphas = _swivel_step(fx.casters, alphas, x, ra1, ra2, om_old, h, rng)
        travel.update(v_old, x[3], h)
    return tr


def _sample_times(duration: float, rate: float, jitter: float, rng: np.random.Generator) -> np.ndarray:
    """Return irregular sample times: steps of ``(1 + jitter U(-1, 1)) / rate`` s from 0 up to ``duration``."""
    steps = (1.0 + jitter * rng.uniform(-1.0, 1.0, size=int(duration * rate * 1.5) + 10)) / rate
    ti = np.concatenate([[0.0], np.cumsum(steps)])
    return ti[ti <= duration]


def _resample(tr: _Trajectory, fx: Effects, ti: np.ndarray):
    """Return (q, qd, true wrench, logged wrench, effect terms) at the times ``ti``, with delay and bias applied."""
    ts, n = tr.ts, len(tr.ts)
    st = np.column_stack([np.interp(ti, ts, tr.state[:, i]) for i in range(5)])
    g_true = tr.gam_w[np.clip(np.searchsorted(ts, ti, side="right") - 1, 0, n - 1)]
    g_log = g_true.copy()
    if fx.time_delay is not None:  # the logged wrench at t was applied at t - delay
        g_log = tr.gam_w[np.clip(np.searchsorted(ts, ti - fx.time_delay["delay"], side="right") - 1, 0, n - 1)]
    th = st[:, 2]
    c, s = np.cos(th), np.sin(th)
    if fx.wrench_bias is not None:
        bx, by, bt = (fx.wrench_bias.get(k, 0.0) for k in ("fx", "fy", "tau"))
        g_log = g_log + np.column_stack([c * bx - s * by, s * bx + c * by, np.full_like(th, bt)])
    lat_i = np.interp(ti, ts, tr.lat)
    eff_i = np.column_stack([np.interp(ti, ts, tr.eff_force[:, i]) for i in range(3)])
    qd_true = np.column_stack([c * st[:, 3] - s * lat_i, s * st[:, 3] + c * lat_i, st[:, 4]])
    return st[:, :3], qd_true, g_true, g_log, eff_i


def _add_noise(
    q: np.ndarray, g: np.ndarray, qd: np.ndarray, std: dict[str, float], with_velocities: bool, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Return (q, gamma, qd or None) with white noise of the stds ``std`` (position, theta, force, torque, velocity)."""
    nn = len(q)
    q_meas = q + rng.standard_normal((nn, 3)) * np.array([std["position"], std["position"], std["theta"]])
    g_meas = g + rng.standard_normal((nn, 3)) * np.array([std["force"], std["force"], std["torque"]])
    vel = std["velocity"]
    qd_meas = qd + rng.standard_normal((nn, 3)) * np.array([vel, vel, vel]) if with_velocities else None
    return q_meas, g_meas, qd_meas


def simulate_hidden(
    params: CartParams,
    effects: Sequence[HiddenEffect] = (),
    duration: float = 30.0,
    rate: float = 100.0,
    jitter: float = 0.2,
    position_noise: float = 0.003,
    theta_noise: float = 0.004,
    force_noise: float = 3.0,
    torque_noise: float = 1.5,
    velocity_noise: float = 0.01,
    with_velocities: bool = True,
    motion: Motion | None = None,
    rng: np.random.Generator | None = None,
    contact: tuple[float, float] = (-0.8, 0.0),
    control_rate: float = 100.0,
    model_error: float = 0.2,
    h: float = 0.002,
) -> HiddenLog:
    """Return the measured and true logs of a cart with ``effects`` hidden, pushed along ``motion``.

    Samples are taken every ``(1 + jitter U(-1, 1)) / rate`` s; noise stds are
    per sample (position [m], theta [rad], force [N], torque [N m], velocity
    [m/s]). The controller knows the cart only up to ``model_error`` (relative)
    and tracks the motion's speed and yaw rate by feedback.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    motion = random_motion(rng, duration) if motion is None else motion
    fx = Effects.from_hidden(effects, params)
    ctrl = _Controller.guessing(params, model_error, rng, contact)
    alphas = np.zeros(2)
    if fx.casters is not None:
        h = min(h, 0.001 if fx.casters.eps >= 0.3 else 0.0005)  # the swivel friction is stiff
        alphas = rng.normal(0.0, 0.05, 2)
    tr = _integrate(params, fx, ctrl, motion, alphas, duration, h, control_rate, rng)
    ti = _sample_times(duration, rate, jitter, rng)
    q_true, qd_true, g_true, g_log, eff_i = _resample(tr, fx, ti)
    noise = {"position": position_noise, "theta": theta_noise, "force": force_noise, "torque": torque_noise}
    q_meas, g_meas, qd_meas = _add_noise(
        q_true, g_log, qd_true, {**noise, "velocity": velocity_noise}, with_velocities, rng
    )
    meta = {"source": "studies.testbeds.hidden_effects", "rate": f"{rate:g}"}
    measured = CartLog(t=ti, q=q_meas, gamma=g_meas, qd=qd_meas, metadata=meta)
    true = CartLog(t=ti, q=q_true, gamma=g_true, qd=qd_true, metadata=dict(meta))
    return HiddenLog(
        measured=measured, true=true, params=params, effects=tuple(effects), rate=rate, noise=noise, effect_force=eff_i
    )


def random_cart(rng: np.random.Generator) -> CartParams:
    """Return a random cart: 15-60 kg, CoM 0.1-0.5 m forward and +-0.15 m sideways, plausible inertia, sigma."""
    m = rng.uniform(15.0, 60.0)
    dx = rng.uniform(0.1, 0.5)
    dy = rng.uniform(-0.15, 0.15)
    length, width = rng.uniform(0.8, 1.2), rng.uniform(0.5, 0.7)
    inertia = m * (length**2 + width**2) / 12.0
    return CartParams(m=m, dx=dx, dy=dy, I=inertia, sigma=rng.uniform(0.5, 3.0))


CASTER_FORMS = ("profile", "swivel")


def random_casters(rng: np.random.Generator, params: CartParams) -> dict[str, float]:
    """Return random swivelling-caster parameters (:class:`SwivelCasters`): trail 3-5 cm, in front of the CoM.

    The swivel friction is sized by the peak forward resistance of the two
    casters side-on, 2 torque / trail = 0.3-0.8 N per kg of cart, its
    regularisation eps 0.2-0.8 rad/s (log-uniform); half of the casters also
    get viscous swivel damping (0.1-0.5 of that peak at 0.4 m/s), half a fork
    inertia of 0.5-4 g m^2 about the swivel axis.
    """
    trail = rng.uniform(0.03, 0.05)
    peak = rng.uniform(0.3, 0.8) * params.m
    damping = rng.uniform(0.1, 0.5) * peak * trail**2 / (2.0 * 0.4) if rng.uniform() < 0.5 else 0.0
    out = {
        "trail": trail,
        "torque": 0.5 * peak * trail,
        "damping": damping,
        "x": min(params.dx + rng.uniform(0.3, 0.6), 1.1),
        "half_track": rng.uniform(0.2, 0.3),
        "roughness": 0.01,
    }
    out["eps"] = float(math.exp(rng.uniform(math.log(0.2), math.log(0.8))))
    out["inertia"] = rng.uniform(0.0005, 0.004) if rng.uniform() < 0.5 else 0.0
    return out


def _random_caster_effect(
    rng: np.random.Generator, params: CartParams, caster_form: str | None, k: float
) -> HiddenEffect:
    """Return a random caster_swivel effect of ``caster_form`` (None: either, equal odds), sized by ``k``."""
    form = caster_form if caster_form is not None else CASTER_FORMS[int(rng.uniform() < 0.5)]
    if form == "swivel":
        c = random_casters(rng, params)
        c["torque"] *= k
        c["damping"] *= k
        return HiddenEffect("caster_swivel", c)
    if form != "profile":
        raise ParameterError(f"unknown caster form {form!r}; known: {', '.join(CASTER_FORMS)}")
    return HiddenEffect(
        "caster_swivel", {"force": k * rng.uniform(0.4, 1.0) * params.m, "distance": rng.uniform(0.1, 0.4)}
    )


def random_effect(
    name: str,
    rng: np.random.Generator,
    params: CartParams,
    duration: float,
    caster_form: str | None = None,
    scale: float = 1.0,
) -> HiddenEffect:
    """Return a contract effect with random, physically plausible size (see HiddenEffect for the units).

    ``caster_form``: "profile" (the resistance profile) or "swivel" (swivelling
    casters); None draws one of the two with equal odds. ``scale`` multiplies
    the effect's size (forces, torques, mass, angle, delay, compliance; not
    distances or times) to go outside the default ranges.
    """
    sgn = lambda: float(rng.choice([-1.0, 1.0]))  # noqa: E731
    k = float(scale)
    if name == "coulomb_friction":
        return HiddenEffect(
            name, {"force": k * rng.uniform(0.015, 0.05) * params.m * GRAVITY, "torque": k * rng.uniform(0.0, 2.0)}
        )
    if name == "caster_swivel":
        return _random_caster_effect(rng, params, caster_form, k)
    if name == "wrench_bias":
        return HiddenEffect(
            name,
            {
                "fx": k * sgn() * rng.uniform(3.0, 10.0),
                "fy": k * rng.uniform(-5.0, 5.0),
                "tau": k * sgn() * rng.uniform(1.0, 4.0),
            },
        )
    if name == "payload_change":
        return HiddenEffect(
            name,
            {
                "time": rng.uniform(0.35, 0.65) * duration,
                "mass": k * rng.uniform(0.3, 1.0) * params.m,
                "x": rng.uniform(0.1, 0.5),
                "y": rng.uniform(-0.15, 0.15),
                "inertia": k * rng.uniform(0.0, 0.5),
            },
        )
    if name == "floor_slope":
        return HiddenEffect(
            name, {"angle": k * math.radians(rng.uniform(1.0, 3.0)), "direction": rng.uniform(-math.pi, math.pi)}
        )
    if name == "time_delay":
        return HiddenEffect(
            name, {"delay": k * (sgn() * rng.uniform(0.05, 0.25) if rng.uniform() < 0.25 else rng.uniform(0.05, 0.25))}
        )
    if name == "lateral_slip":
        return HiddenEffect(name, {"compliance": k * rng.uniform(2e-3, 6e-3)})
    raise ParameterError(f"unknown hidden effect {name!r}; known: {', '.join(HIDDEN_NAMES)}")


def random_case(
    effect: str | None,
    rng: np.random.Generator,
    duration: float = 30.0,
    caster_form: str | None = None,
    scale: float = 1.0,
    **overrides,
) -> HiddenLog:
    """Return a random test case with ``effect`` hidden (None: nominal cart) and randomized rate, noise, columns.

    Defaults: 50-200 Hz with up to 30 % jitter, position noise 1-4 mm, heading
    2-8 mrad, force 2-4 N, torque 0.5-2 N m, velocity columns in half the logs.
    ``caster_form`` and ``scale`` go to :func:`random_effect`; ``overrides``
    replace any :func:`simulate_hidden` keyword (e.g. ``rate=50.0``,
    ``position_noise=0.008``, ``with_velocities=False``) after the random draws,
    so a case differs from its default twin only in what is overridden.
    """
    params = random_cart(rng)
    effects = (random_effect(effect, rng, params, duration, caster_form, scale),) if effect else ()
    kw = dict(
        rate=float(rng.uniform(50.0, 200.0)),
        jitter=float(rng.uniform(0.0, 0.3)),
        position_noise=float(rng.uniform(0.001, 0.004)),
        theta_noise=float(rng.uniform(0.002, 0.008)),
        force_noise=float(rng.uniform(2.0, 4.0)),
        torque_noise=float(rng.uniform(0.5, 2.0)),
        with_velocities=bool(rng.uniform() < 0.5),
        contact=(-0.8, float(rng.uniform(-0.15, 0.15))),
    )
    unknown = set(overrides) - set(kw) - {"velocity_noise", "control_rate", "model_error", "h", "motion"}
    if unknown:
        raise ParameterError(f"unknown simulate_hidden keyword(s) {sorted(unknown)}")
    kw.update(overrides)
    return simulate_hidden(params, effects, duration=duration, rng=rng, **kw)


# --------------------------------------------------------------------------- log defects (effect-free twins)

#: the defects :func:`defective_log` writes into a log: none of them is a physical effect
DEFECTS = ("held_pose", "mocap_rows", "gap", "time_offset", "wrench_in_cart_frame")


def _ar1(rng: np.random.Generator, n: int, sigma: float, rho_lag10: float) -> np.ndarray:
    """Return a stationary AR(1) sequence of std ``sigma`` whose lag-10 correlation is ``rho_lag10``."""
    a = rho_lag10 ** (1.0 / 10.0)
    e = np.empty(n)
    e[0] = rng.normal(0.0, sigma)
    w = rng.normal(0.0, sigma * math.sqrt(1.0 - a * a), n)
    for i in range(1, n):
        e[i] = a * e[i - 1] + w[i]
    return e


def _dropout_mask(rng: np.random.Generator, t: np.ndarray, count: int) -> np.ndarray:
    """Return booleans: False inside ``count`` random dropouts of 0.15-0.5 s."""
    keep = np.ones(len(t), bool)
    for _ in range(count):
        t0 = rng.uniform(t[0] + 2.0, t[-1] - 2.0)
        keep &= ~((t >= t0) & (t < t0 + rng.uniform(0.15, 0.5)))
    return keep


def multirate_log(
    rng: np.random.Generator,
    merging: str,
    duration: float = 60.0,
    ft_rate: float = 500.0,
    mocap_rate: float = 120.0,
) -> tuple[CartLog, CartParams]:
    """Return an effect-free log sensed as a real set-up does, written into one table, and its cart.

    The cart (:func:`random_cart`) is simulated noise-free at ``ft_rate``; the F/T stream gets AR(1)
    noise (2-3 N, 0.4-0.6 N m; lag-10 correlation 0.6-0.8) and a small offset, the motion-capture
    stream (``mocap_rate``, 0.2 ms timestamp jitter, three dropouts) white noise of 0.5-1.5 mm and 2-4
    mrad. ``merging``: ``"held_pose"`` (a row per F/T sample, the last pose repeated) or
    ``"mocap_rows"`` (a row per pose sample, the F/T averaged over the interval); ``t`` starts at 3-50 s.
    """
    params = random_cart(rng)
    quiet = dict(position_noise=0.0, theta_noise=0.0, force_noise=0.0, torque_noise=0.0, velocity_noise=0.0)
    hl = simulate_hidden(params, (), duration=duration, rate=ft_rate, jitter=0.0, rng=rng, **quiet)
    t_ft, q_true, g_true = hl.measured.t, hl.true.q, hl.measured.gamma
    g_ft = g_true + np.column_stack(
        [_ar1(rng, len(t_ft), rng.uniform(2.0, 3.0), rng.uniform(0.6, 0.8)) + rng.uniform(-0.3, 0.3) for _ in range(2)]
        + [_ar1(rng, len(t_ft), rng.uniform(0.4, 0.6), rng.uniform(0.6, 0.8)) + rng.uniform(-0.1, 0.1)]
    )
    t_mc = np.arange(t_ft[0] + 0.5 / mocap_rate, t_ft[-1], 1.0 / mocap_rate)
    t_mc = t_mc[_dropout_mask(rng, t_mc, 3)]
    pos_std, th_std = rng.uniform(5e-4, 1.5e-3), rng.uniform(0.002, 0.004)
    q_mc = np.column_stack([np.interp(t_mc, t_ft, q_true[:, k]) for k in range(3)])
    q_mc += rng.normal(0.0, 1.0, q_mc.shape) * np.array([pos_std, pos_std, th_std])
    t_mc_logged = t_mc + rng.normal(0.0, 2e-4, len(t_mc))
    t_ft_logged = t_ft + rng.normal(0.0, 2e-4, len(t_ft))
    if merging == "held_pose":
        rows = np.flatnonzero(t_ft >= t_mc[0])
        last = np.searchsorted(t_mc, t_ft[rows], side="right") - 1
        t, q, g = t_ft_logged[rows], q_mc[last], g_ft[rows]
    elif merging == "mocap_rows":
        idx = np.searchsorted(t_ft, t_mc, side="right")
        lo = np.r_[max(idx[0] - int(ft_rate / mocap_rate), 0), idx[:-1]]
        cum = np.vstack([np.zeros((1, 3)), np.cumsum(g_ft, axis=0)])
        g = (cum[idx] - cum[lo]) / np.maximum(idx - lo, 1)[:, None]
        t, q = t_mc_logged, q_mc
    else:
        raise ParameterError(f"unknown merging {merging!r}; known: held_pose, mocap_rows")
    t = np.maximum.accumulate(t) + 1e-7 * np.arange(len(t))  # strictly increasing, as a logger writes it
    t = t + rng.uniform(3.0, 50.0)
    meta = {"source": "studies.testbeds.hidden_effects.multirate_log", "merging": merging}
    return CartLog(t=t, q=q, gamma=g, metadata=meta), params


def defective_log(log: CartLog, defect: str, rng: np.random.Generator) -> CartLog:
    """Return ``log`` with a recording defect that is no physical effect (``DEFECTS``).

    ``gap``: 10 s of rows missing in the middle; ``time_offset``: the clock starts at a Unix time;
    ``wrench_in_cart_frame``: (fx, fy) written in {b} instead of {s}. The multi-rate defects are
    :func:`multirate_log`.
    """
    t, q, g = np.array(log.t), np.array(log.q), np.array(log.gamma)
    if defect == "gap":
        t0 = rng.uniform(0.35, 0.55) * (t[-1] - t[0]) + t[0]
        keep = (t < t0) | (t >= t0 + 10.0)
        return CartLog(t=t[keep], q=q[keep], gamma=g[keep], metadata=dict(log.metadata))
    if defect == "time_offset":
        return CartLog(t=t + 1.7e9 + rng.uniform(0.0, 1e6), q=q, gamma=g, metadata=dict(log.metadata))
    if defect == "wrench_in_cart_frame":
        c, s = np.cos(q[:, 2]), np.sin(q[:, 2])
        gb = np.column_stack([c * g[:, 0] + s * g[:, 1], -s * g[:, 0] + c * g[:, 1], g[:, 2]])
        return CartLog(t=t, q=q, gamma=gb, metadata=dict(log.metadata))
    raise ParameterError(f"unknown defect {defect!r}; known: {', '.join(DEFECTS)}")

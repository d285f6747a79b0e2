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

from cart.dynamics import body_accelerations, lateral_inertial_force
from cart.errors import ParameterError
from cart.logs import CartLog
from cart.params import CartParams
from wholebody.contacts.excitation import PushSamples

GRAVITY = 9.81
HIDDEN_NAMES = ("coulomb_friction", "caster_swivel", "wrench_bias", "payload_change", "floor_slope",
                "time_delay", "lateral_slip")


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
    params: Dict[str, float] = field(default_factory=dict)

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
    effects: Tuple[HiddenEffect, ...]
    rate: float
    noise: Dict[str, float]
    #: the hidden effects' generalized force on the cart at the sample times: (forward, lateral, yaw) in {b}
    effect_force: Optional[np.ndarray] = None


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

    def __init__(self, p: Dict[str, float], params: CartParams) -> None:
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
        return np.array([(-(v - om * cy) * math.sin(al) + om * cx * math.cos(al)) / self.trail - om
                         for (cx, cy), al in zip(self.pos, alphas)])

    def terms(self, v: float, om: float, alphas: np.ndarray) -> Tuple[float, float, float, np.ndarray]:
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
    sw = eff.get("caster_swivel")
    casters = SwivelCasters(sw, p) if sw and "trail" in sw else None
    if casters is not None:
        sw = None
        h = min(h, 0.001 if casters.eps >= 0.3 else 0.0005)  # the swivel friction is stiff
    alphas = rng.normal(0.0, 0.05, 2) if casters is not None else np.zeros(2)
    kv, kw = 2.5, 3.0
    px, py = contact
    n = int(round(duration / h)) + 1
    ts = np.arange(n) * h
    state = np.zeros((n, 5))  # x, y, theta, v, omega
    lat = np.zeros(n)
    eff_force = np.zeros((n, 3))  # E_fwd, E_lat, E_yaw of the hidden forces (for tests and oracles)
    gam_w = np.zeros((n, 3))  # applied (fx, fy, tau) in {s}
    x = np.zeros(5)
    control_every = max(1, int(round(1.0 / (control_rate * h))))
    fu = fl = tq = 0.0
    dist = math.inf
    direction = 0
    cf = eff.get("coulomb_friction")
    sl = eff.get("floor_slope")
    slip = eff.get("lateral_slip")
    g_slope = (GRAVITY * math.sin(sl["angle"]) * math.cos(sl["direction"]),
               GRAVITY * math.sin(sl["angle"]) * math.sin(sl["direction"])) if sl else (0.0, 0.0)

    def deriv(xs: np.ndarray, al: np.ndarray, ph: CartParams, fu: float, fl: float, tq: float, dist: float):
        m, a, b, j = ph.phi.tolist()
        th, v, om = xs[2], xs[3], xs[4]
        c, s = math.cos(th), math.sin(th)
        e_f = e_t = e_l = 0.0
        rates = None
        if casters is not None:
            e_f, e_l, e_t, rates = casters.terms(v, om, al)
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
        vdot, odot = body_accelerations(v, om, fu + e_f, tq + e_t, m, a, b, j, ph.sigma, ph.sigma_yaw)
        w = 0.0
        if slip:
            w = slip["compliance"] * (fl + e_l - lateral_inertial_force(v, om, odot, m, a, b))
        return np.array([c * v - s * w, s * v + c * w, om, vdot, odot]), w, rates, (e_f, e_l, e_t)

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
        k1, w1, ra1, eff_force[k] = deriv(x, alphas, ph, fu, fl, tq, dist)
        k2, _, ra2, _ = deriv(x + 0.5 * h * k1, alphas + 0.5 * h * ra1 if casters is not None else alphas, ph, fu, fl,
                           tq, dist)
        lat[k] = w1
        v_old = x[3]
        x_om_old = x[4]
        x = x + h * k2
        if casters is not None:  # swivel (midpoint rule) + the floor's random kicks
            kick = casters.roughness * math.sqrt(abs(x[3]) * h + 1e-12) * rng.standard_normal(2)
            alphas = alphas + h * ra2 + kick
            if casters.inertia > 0.0:
                casters.acc = (casters.rates(x[3], x[4], alphas) + x[4] - ra1 - x_om_old) / h
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
    eff_i = np.column_stack([np.interp(ti, ts, eff_force[:, i]) for i in range(3)])
    qd_true = np.column_stack([c * st[:, 3] - s * lat_i, s * st[:, 3] + c * lat_i, st[:, 4]])
    q_true = st[:, :3]
    nn = len(ti)
    q_meas = q_true + rng.standard_normal((nn, 3)) * np.array([position_noise, position_noise, theta_noise])
    g_meas = g_log + rng.standard_normal((nn, 3)) * np.array([force_noise, force_noise, torque_noise])
    qd_meas = qd_true + rng.standard_normal((nn, 3)) * np.array([velocity_noise, velocity_noise,
                                                                  velocity_noise]) if with_velocities else None
    meta = {"source": "studies.testbeds.hidden_effects", "rate": f"{rate:g}"}
    measured = CartLog(t=ti, q=q_meas, gamma=g_meas, qd=qd_meas, metadata=meta)
    true = CartLog(t=ti, q=q_true, gamma=g_true, qd=qd_true, metadata=dict(meta))
    noise = {"position": position_noise, "theta": theta_noise, "force": force_noise, "torque": torque_noise}
    return HiddenLog(measured=measured, true=true, params=params, effects=tuple(effects), rate=rate, noise=noise,
                     effect_force=eff_i)


def random_cart(rng: np.random.Generator) -> CartParams:
    """Return a random cart: 15-60 kg, CoM 0.1-0.5 m forward and +-0.15 m sideways, plausible inertia, sigma."""
    m = rng.uniform(15.0, 60.0)
    dx = rng.uniform(0.1, 0.5)
    dy = rng.uniform(-0.15, 0.15)
    length, width = rng.uniform(0.8, 1.2), rng.uniform(0.5, 0.7)
    inertia = m * (length ** 2 + width ** 2) / 12.0
    return CartParams(m=m, dx=dx, dy=dy, I=inertia, sigma=rng.uniform(0.5, 3.0))


CASTER_FORMS = ("profile", "swivel")


def random_casters(rng: np.random.Generator, params: CartParams) -> Dict[str, float]:
    """Return random swivelling-caster parameters (:class:`SwivelCasters`): trail 3-5 cm, in front of the CoM.

    The swivel friction is sized by the peak forward resistance of the two
    casters side-on, 2 torque / trail = 0.3-0.8 N per kg of cart, its
    regularisation eps 0.2-0.8 rad/s (log-uniform); half of the casters also
    get viscous swivel damping (0.1-0.5 of that peak at 0.4 m/s), half a fork
    inertia of 0.5-4 g m^2 about the swivel axis.
    """
    trail = rng.uniform(0.03, 0.05)
    peak = rng.uniform(0.3, 0.8) * params.m
    damping = rng.uniform(0.1, 0.5) * peak * trail ** 2 / (2.0 * 0.4) if rng.uniform() < 0.5 else 0.0
    out = {"trail": trail, "torque": 0.5 * peak * trail, "damping": damping,
           "x": min(params.dx + rng.uniform(0.3, 0.6), 1.1), "half_track": rng.uniform(0.2, 0.3),
           "roughness": 0.01}
    out["eps"] = float(math.exp(rng.uniform(math.log(0.2), math.log(0.8))))
    out["inertia"] = rng.uniform(0.0005, 0.004) if rng.uniform() < 0.5 else 0.0
    return out


def random_effect(name: str, rng: np.random.Generator, params: CartParams, duration: float,
                  caster_form: Optional[str] = None, scale: float = 1.0) -> HiddenEffect:
    """Return a contract effect with random, physically plausible size (see HiddenEffect for the units).

    ``caster_form``: "profile" (the resistance profile) or "swivel" (swivelling
    casters); None draws one of the two with equal odds. ``scale`` multiplies
    the effect's size (forces, torques, mass, angle, delay, compliance; not
    distances or times) to go outside the default ranges.
    """
    sgn = lambda: float(rng.choice([-1.0, 1.0]))  # noqa: E731
    k = float(scale)
    if name == "coulomb_friction":
        return HiddenEffect(name, {"force": k * rng.uniform(0.015, 0.05) * params.m * GRAVITY,
                                   "torque": k * rng.uniform(0.0, 2.0)})
    if name == "caster_swivel":
        form = caster_form if caster_form is not None else CASTER_FORMS[int(rng.uniform() < 0.5)]
        if form == "swivel":
            c = random_casters(rng, params)
            c["torque"] *= k
            c["damping"] *= k
            return HiddenEffect(name, c)
        if form != "profile":
            raise ParameterError(f"unknown caster form {form!r}; known: {', '.join(CASTER_FORMS)}")
        return HiddenEffect(name, {"force": k * rng.uniform(0.4, 1.0) * params.m, "distance": rng.uniform(0.1, 0.4)})
    if name == "wrench_bias":
        return HiddenEffect(name, {"fx": k * sgn() * rng.uniform(3.0, 10.0), "fy": k * rng.uniform(-5.0, 5.0),
                                   "tau": k * sgn() * rng.uniform(1.0, 4.0)})
    if name == "payload_change":
        return HiddenEffect(name, {"time": rng.uniform(0.35, 0.65) * duration,
                                   "mass": k * rng.uniform(0.3, 1.0) * params.m,
                                   "x": rng.uniform(0.1, 0.5), "y": rng.uniform(-0.15, 0.15),
                                   "inertia": k * rng.uniform(0.0, 0.5)})
    if name == "floor_slope":
        return HiddenEffect(name, {"angle": k * math.radians(rng.uniform(1.0, 3.0)),
                                   "direction": rng.uniform(-math.pi, math.pi)})
    if name == "time_delay":
        return HiddenEffect(name, {"delay": k * (sgn() * rng.uniform(0.05, 0.25) if rng.uniform() < 0.25
                                                 else rng.uniform(0.05, 0.25))})
    if name == "lateral_slip":
        return HiddenEffect(name, {"compliance": k * rng.uniform(2e-3, 6e-3)})
    raise ParameterError(f"unknown hidden effect {name!r}; known: {', '.join(HIDDEN_NAMES)}")


def random_case(effect: Optional[str], rng: np.random.Generator, duration: float = 30.0,
                caster_form: Optional[str] = None, scale: float = 1.0, **overrides) -> HiddenLog:
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
    kw = dict(rate=float(rng.uniform(50.0, 200.0)), jitter=float(rng.uniform(0.0, 0.3)),
              position_noise=float(rng.uniform(0.001, 0.004)), theta_noise=float(rng.uniform(0.002, 0.008)),
              force_noise=float(rng.uniform(2.0, 4.0)), torque_noise=float(rng.uniform(0.5, 2.0)),
              with_velocities=bool(rng.uniform() < 0.5), contact=(-0.8, float(rng.uniform(-0.15, 0.15))))
    unknown = set(overrides) - set(kw) - {"velocity_noise", "control_rate", "model_error", "h", "motion"}
    if unknown:
        raise ParameterError(f"unknown simulate_hidden keyword(s) {sorted(unknown)}")
    kw.update(overrides)
    return simulate_hidden(params, effects, duration=duration, rng=rng, **kw)

"""A MuJoCo shopping cart that writes cart logs (LOG_FORMAT) with its rigid-body truth.

This is a physics-engine test bed, not library API: nothing in it is written
to match the project's cart equations. The cart model is the library's
(:mod:`wholebody.push.mujoco_cart`, re-exported here). A chassis box (plus an optional payload
box placed off-centre) rides on a free joint over a plane floor, on two fixed
rear wheels and two swivelling front casters with trail. Every wheel is a
cylinder with its own mass and spin inertia; contacts have ``condim=6``
(sliding, torsional and rolling friction) and MuJoCo's soft constraints. A
robot pushes the cart through a handle behind it: a planar wrench
``(fx, fy, tau_z)`` applied to the chassis with ``xfrc_applied`` by a
tracking controller updated every physics step (1 ms) that follows a random
forward-speed / yaw-rate reference (push, stop, pull, turns both ways).

The log follows ``docs/log_format.md``: the pose of {b} (origin at the
midpoint of the fixed rear axle, x towards the casters, the handle at -x), the
applied force in {s}, the torque about the vertical axis through the {b}
origin, optionally the {b}-origin velocity, and the handle point in {b}.
MuJoCo applies ``xfrc_applied`` at the chassis body's centre of mass
(``xipos``), so the logged torque is re-expressed exactly:
``tau_b = tau_applied + ((xipos - p_b) x f)_z``.

The truth (:func:`truth`) is the rigid-body mass, centre of mass in {b} and
yaw inertia about the centre of mass of the whole model, read from MuJoCo
after 1 s of settling with the casters trailing, plus the effective forward
mass including the spin inertia of the four wheels.

Usage::

    from studies.testbeds.mujoco_cart import random_case, simulate, generate
    log, info = simulate(random_case(3))
    generate(5, seed0=100, out_dir="/tmp/mjlogs")   # mj100.csv.gz ... + truth.json
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field, replace
from typing import Any
from collections.abc import Callable

import numpy as np

from cart.logs import CartLog, write_log

try:  # optional dependency (extra "studies"; also a run-time dependency of wholebody.push.mujoco_plant)
    import mujoco

    from wholebody.push.mujoco_cart import (  # noqa: F401  (re-exported: the test bed's cart is the library's)
        CART_BODY,
        CASTER_FORKS,
        GRAVITY,
        REAR_WHEELS,
        SETTLE_TIME,
        WHEEL_BODIES,
        MujocoCart,
        build,
        composite_inertia,
        mjcf,
        place,
        settle,
        truth,
        truth_from_state,
        wheel_spin_inertias,
    )
except ImportError:  # pragma: no cover - exercised only without mujoco
    mujoco = None  # type: ignore[assignment]


def _require_mujoco() -> None:
    if mujoco is None:
        raise ImportError("studies.testbeds.mujoco_cart needs the 'mujoco' package (pip install -e '.[studies]')")


@dataclass(frozen=True)
class MujocoCase:
    """One simulated log: the cart, the run and the measurement.

    ``rate_hz`` is the log rate (50-250 Hz); ``jitter`` the half-width of a uniform
    perturbation of each sample time as a fraction of the period (< 0.5; times are
    rounded to the 1 ms physics grid). White noise at every logged sample with the
    standard deviations ``position_noise`` (m, on x and y), ``theta_noise`` (rad),
    ``force_noise`` (N, on fx and fy), ``torque_noise`` (N m), ``velocity_noise``
    (m/s, on vx, vy) and ``omega_noise`` (rad/s). ``q0`` is the initial pose of {b}
    (None: random from ``seed``). ``mass_guess_error`` is the relative error of the
    tracker's feedforward guess of mass and inertia; ``lateral_share`` the part of
    the yaw torque the robot makes with a lateral force at the handle (the rest is
    a wrist torque; None: random; on a floor the wheels slide on, ``cart.sliding_friction`` below
    :data:`SLIPPERY`, capped by :func:`sliding_share`). ``v_max`` / ``omega_max`` bound the reference.
    """

    cart: MujocoCart = field(default_factory=MujocoCart)
    duration: float = 40.0
    rate_hz: float = 100.0
    jitter: float = 0.0
    position_noise: float = 5e-4
    theta_noise: float = 2e-3
    force_noise: float = 3.0
    torque_noise: float = 0.5
    velocity_noise: float = 0.0
    omega_noise: float = 0.0
    with_velocities: bool = True
    with_contact: bool = True
    seed: int = 0
    name: str = ""
    q0: tuple[float, float, float] | None = None
    mass_guess_error: float = 0.3
    lateral_share: float | None = None
    v_max: float = 1.0
    omega_max: float = 0.6

    def __post_init__(self) -> None:
        if not self.duration > 0.0:
            raise ValueError(f"MujocoCase.duration must be > 0, got {self.duration!r}")
        if not 1.0 <= self.rate_hz <= 0.5 / self.cart.timestep:
            raise ValueError(f"MujocoCase.rate_hz must be in [1, {0.5 / self.cart.timestep:g}], got {self.rate_hz!r}")
        if not 0.0 <= self.jitter < 0.5:
            raise ValueError(f"MujocoCase.jitter must be in [0, 0.5), got {self.jitter!r}")


def tau_about_b(
    fx: float, fy: float, tau_applied: float, com_xy: tuple[float, float], b_xy: tuple[float, float]
) -> float:
    """Return the torque about the vertical axis through the {b} origin of a planar wrench.

    ``(fx, fy)`` in {s} and ``tau_applied`` (z) act at ``com_xy`` (where MuJoCo applies
    ``xfrc_applied``: the body's ``xipos``): ``tau_b = tau_applied + ((com - p_b) x f)_z``.
    """
    return tau_applied + (com_xy[0] - b_xy[0]) * fy - (com_xy[1] - b_xy[1]) * fx


# --------------------------------------------------------------------------- reference


def _smooth_steps(
    times: np.ndarray, knots: np.ndarray, values: np.ndarray, ramps: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Return (y, dy/dt): piecewise-constant ``values`` joined by raised-cosine ramps starting at ``knots``."""
    y = np.full_like(times, values[0])
    dy = np.zeros_like(times)
    for k in range(1, len(values)):
        step = values[k] - values[k - 1]
        u = np.clip((times - knots[k]) / ramps[k], 0.0, 1.0)
        y += step * 0.5 * (1.0 - np.cos(math.pi * u))
        inside = (u > 0.0) & (u < 1.0)
        dy[inside] += step * 0.5 * math.pi / ramps[k] * np.sin(math.pi * u[inside])
    return y, dy


def reference(
    duration: float, rng: np.random.Generator, dt: float = 0.001, v_max: float = 1.0, omega_max: float = 0.6
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (t, v, dv/dt, omega, domega/dt) of a random push / stop / pull reference with turns.

    Segments of 2.5-6 s: push (0.3 v_max to v_max), stop (0), pull (-0.6 v_max to -0.2 v_max);
    each may carry a yaw rate of 0.15-1 omega_max either way; raised-cosine ramps of 1-1.6 s.
    For durations of 12 s or more the profile is redrawn until it has a reversal (a push and
    a pull) and turns both ways.
    """
    t = np.arange(int(round(duration / dt)) + 1) * dt
    for _ in range(1000):
        knots, speeds, rates = [0.0], [0.0], [0.0]
        tk = rng.uniform(0.3, 1.0)
        kinds: list[str] = []
        while tk < duration - 1.0:
            kind = rng.choice(["push", "push", "stop", "pull"]) if kinds else "push"
            if kinds and kinds[-1] == kind == "stop":
                kind = "push"
            kinds.append(str(kind))
            v = {"push": rng.uniform(0.3, 1.0), "stop": 0.0, "pull": -rng.uniform(0.2, 0.6)}[kind] * v_max
            w = 0.0
            if rng.random() < (0.3 if kind == "stop" else 0.65):
                w = rng.choice([-1.0, 1.0]) * rng.uniform(0.15, 1.0) * omega_max
            knots.append(tk)
            speeds.append(v)
            rates.append(w)
            tk += rng.uniform(2.5, 6.0)
        knots.append(max(duration - 1.6, knots[-1] + 1.6))
        speeds.append(0.0)
        rates.append(0.0)
        sp, rt = np.array(speeds), np.array(rates)
        if duration < 12.0 or ((sp > 0).any() and (sp < 0).any() and (rt > 0).any() and (rt < 0).any()):
            break
    ramps = rng.uniform(1.0, 1.6, size=len(knots))
    v, dv = _smooth_steps(t, np.array(knots), sp, ramps)
    w, dw = _smooth_steps(t, np.array(knots), rt, ramps)
    return t, v, dv, w, dw


# --------------------------------------------------------------------------- cases


def random_case(seed: int, **overrides: Any) -> MujocoCase:
    """Return a random case: a cart of 10-80 kg total with the payload anywhere on the deck, 30-60 s.

    ``overrides`` replace :class:`MujocoCase` fields; keys that are :class:`MujocoCart` fields
    replace those of the random cart (e.g. ``random_case(3, payload_mass=0.0, duration=10)``).
    """
    rng = np.random.default_rng([seed, 0x6D6A])
    wheelbase = rng.uniform(0.5, 0.9)
    half_track = rng.uniform(0.18, 0.30)
    wheel_radius = rng.uniform(0.05, 0.10)
    wheel_mass = rng.uniform(0.2, 1.0)
    caster_wheel_radius = rng.uniform(0.035, 0.06)
    caster_wheel_mass = rng.uniform(0.08, 0.35)
    fork_mass = rng.uniform(0.08, 0.25)
    total = rng.uniform(10.0, 80.0)
    wheels = 2 * (wheel_mass + caster_wheel_mass + fork_mass)
    chassis = rng.uniform(0.3, 0.8) * (total - wheels)
    chassis = max(chassis, 4.0)
    payload = max(total - wheels - chassis, 0.0)
    psize = (rng.uniform(0.15, 0.4), rng.uniform(0.15, 2 * half_track - 0.06), rng.uniform(0.08, 0.35))
    px = rng.uniform(psize[0] / 2 - 0.05, wheelbase - psize[0] / 2 + 0.05)
    py = rng.uniform(-1.0, 1.0) * max(half_track - psize[1] / 2 - 0.02, 0.0)
    cart = MujocoCart(
        chassis_mass=chassis,
        payload_mass=payload,
        payload_offset=(px, py),
        payload_size=psize,
        wheelbase=wheelbase,
        half_track=half_track,
        wheel_radius=wheel_radius,
        wheel_width=rng.uniform(0.02, 0.045),
        wheel_mass=wheel_mass,
        caster_half_track=half_track - rng.uniform(0.0, 0.05),
        caster_trail=rng.uniform(0.02, 0.05),
        caster_fork_height=caster_wheel_radius + rng.uniform(0.01, 0.04),
        caster_fork_mass=fork_mass,
        caster_wheel_radius=caster_wheel_radius,
        caster_wheel_width=rng.uniform(0.018, 0.035),
        caster_wheel_mass=caster_wheel_mass,
        chassis_overhang=rng.uniform(0.05, 0.15),
        chassis_width=2 * half_track - 0.06,
        chassis_thickness=rng.uniform(0.02, 0.06),
        deck_height=rng.uniform(0.05, 0.25),
        rolling_friction=rng.uniform(3e-4, 1.5e-3),
        torsional_friction=rng.uniform(5e-4, 3e-3),
        sliding_friction=rng.uniform(0.6, 1.0),
        swivel_damping=rng.uniform(0.005, 0.05),
        swivel_frictionloss=rng.uniform(0.005, 0.05),
        handle_distance=rng.uniform(0.15, 0.4),
        handle_y=rng.uniform(-0.05, 0.05),
    )
    cart_fields = {k: overrides.pop(k) for k in list(overrides) if k in MujocoCart.__dataclass_fields__}
    if cart_fields:
        cart = replace(cart, **cart_fields)
    q0 = (float(rng.uniform(-3, 3)), float(rng.uniform(-3, 3)), float(rng.uniform(-math.pi, math.pi)))
    base = MujocoCase(cart=cart, duration=float(rng.uniform(30.0, 60.0)), seed=int(seed), name=f"mj{seed}", q0=q0)
    return replace(base, **overrides) if overrides else base


# --------------------------------------------------------------------------- simulation


def _sample_steps(case: MujocoCase, n_steps: int, rng: np.random.Generator) -> np.ndarray:
    """Return the physics-step indices of the log samples (strictly increasing)."""
    dt = case.cart.timestep
    period = 1.0 / case.rate_hz
    nominal = np.arange(0.0, n_steps * dt - 1e-12, period)
    times = nominal + rng.uniform(-case.jitter, case.jitter, size=len(nominal)) * period
    steps = np.clip(np.round(times / dt).astype(int), 0, n_steps - 1)
    steps = np.maximum.accumulate(steps)
    return steps[np.r_[True, np.diff(steps) > 0]]


@dataclass(frozen=True)
class _Reference:
    """The reference on the physics-step grid: speed, acceleration, yaw rate and acceleration, and their integrals."""

    v: np.ndarray
    a: np.ndarray
    w: np.ndarray
    al: np.ndarray
    s: np.ndarray
    th: np.ndarray

    @classmethod
    def draw(cls, case: MujocoCase, rng: np.random.Generator, dt: float) -> _Reference:
        """Return a random :func:`reference` of ``case`` with its progress and heading (trapezoidal rule)."""
        _t, v_ref, a_ref, w_ref, al_ref = reference(case.duration, rng, dt, case.v_max, case.omega_max)
        s_ref = np.concatenate([[0.0], np.cumsum(0.5 * (v_ref[1:] + v_ref[:-1]) * dt)])
        th_ref = np.concatenate([[0.0], np.cumsum(0.5 * (w_ref[1:] + w_ref[:-1]) * dt)])
        return cls(v_ref, a_ref, w_ref, al_ref, s_ref, th_ref)


#: a floor friction coefficient below this lets the wheels slide under the handle's lateral force
SLIPPERY = 0.3


def sliding_share(share: float, dx: float, handle_distance: float) -> float:
    """Return the lateral share that keeps half the commanded yaw torque about the CoM of a cart that slides.

    The tracker makes ``share`` of its yaw torque about {b}, t_b, with a lateral force at the handle
    (``handle_distance`` behind {b}) and the rest with a wrist torque. Held by its wheels, the cart turns
    about {b}; sliding, it turns about its CoM (``dx`` ahead of {b}), where the same wrench has the torque
    t_b (1 - share dx / handle_distance). Beyond share = handle_distance / dx that torque turns the other
    way, the yaw loop feeds back positively and the pushed cart spins up until the simulation diverges
    (``random_case(60001, sliding_friction=0.04, lateral_share=0.8)``: dx 0.28 m, handle 0.17 m, the cart
    spinning at 760 rad/s by 22.6 s). The share is capped so that the torque about the CoM keeps half of t_b.
    """
    if dx <= 0.0:
        return share
    return min(share, 0.5 * handle_distance / dx)


@dataclass(frozen=True)
class _Tracker:
    """The pushing robot's controller: feedforward from a rough guess of the cart plus PD on progress / heading."""

    ref: _Reference
    m_g: float
    i_g: float
    f_roll_g: float
    share: float
    handle: tuple[float, float]
    wn_v: float = 2.5
    wn_w: float = 3.0

    @classmethod
    def guessing(cls, case: MujocoCase, info: dict[str, float], ref: _Reference, rng: np.random.Generator) -> _Tracker:
        """Return a tracker whose mass and yaw inertia about {b} are off by up to ``case.mass_guess_error``."""
        m_true, i_b_true = info["m"], info["I_about_com"] + info["m"] * (info["dx"] ** 2 + info["dy"] ** 2)
        err = case.mass_guess_error
        m_g = m_true * float(rng.uniform(1.0 - err, 1.0 + err))
        i_g = i_b_true * float(rng.uniform(1.0 - err, 1.0 + err))
        f_roll_g = m_g * GRAVITY * float(rng.uniform(0.003, 0.02))
        share = float(rng.uniform(0.2, 0.8)) if case.lateral_share is None else float(case.lateral_share)
        if case.cart.sliding_friction < SLIPPERY:
            share = min(share, sliding_share(share, info["dx"], case.cart.handle_distance))
        return cls(ref, m_g, i_g, f_roll_g, share, (-case.cart.handle_distance, case.cart.handle_y))

    def wrench(self, i: int, v: float, omega: float, s_meas: float, th_rel: float) -> tuple[float, float, float]:
        """Return the handle wrench (forward, lateral force, wrist torque) in {b} at step ``i``."""
        r = self.ref
        m_g, i_g, hx, hy = self.m_g, self.i_g, self.handle[0], self.handle[1]
        kp_s, kd_s = m_g * self.wn_v**2, 2.0 * m_g * self.wn_v
        kp_th, kd_th = i_g * self.wn_w**2, 2.0 * i_g * self.wn_w
        e_s = min(max(r.s[i] - s_meas, -0.2), 0.2)
        e_th = min(max(r.th[i] - th_rel, -0.2), 0.2)
        f_fwd = m_g * r.a[i] + self.f_roll_g * math.tanh(r.v[i] / 0.05) + kd_s * (r.v[i] - v) + kp_s * e_s
        t_b = i_g * r.al[i] + kd_th * (r.w[i] - omega) + kp_th * e_th
        f_lat = -self.share * t_b / hx
        tau_h = t_b - (hx * f_lat - hy * f_fwd)  # wrist torque: the rest of t_b about {b}
        return f_fwd, f_lat, tau_h


def _planar_state(qpos: np.ndarray, qvel: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """Return (x, y, yaw, vx, vy, yaw rate) of the free joint's position ``qpos`` and velocity ``qvel``."""
    x, y, _z, qw, qx, qy, qz = qpos[:7].tolist()
    vx, vy, _vz, wx, wy, wz = qvel[:6].tolist()
    th = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    # yaw rate: world z of the body angular velocity (row 2 of R times omega_local)
    omega = 2.0 * (qx * qz - qw * qy) * wx + 2.0 * (qy * qz + qw * qx) * wy + (1.0 - 2.0 * (qx * qx + qy * qy)) * wz
    return x, y, th, vx, vy, omega


@dataclass
class _Unwrap:
    """Continuous heading from successive yaw angles in (-pi, pi]; ``start`` is the first angle."""

    value: float = 0.0
    prev: float | None = None
    start: float | None = None

    def update(self, th: float) -> float:
        """Return the unwrapped heading after the yaw angle ``th``."""
        if self.prev is None:
            self.start, self.value = th, th
        else:
            self.value += math.remainder(th - self.prev, 2.0 * math.pi)
        self.prev = th
        return self.value


@dataclass(frozen=True)
class _Record:
    """Clean arrays at the log samples: ``rec`` (t, x, y, theta, fx, fy, tau_b, vx, vy, omega), the applied
    torque and chassis CoM, the CoM in {b} and the caster swivel angles."""

    rec: np.ndarray
    applied: np.ndarray
    com_b: np.ndarray
    swivel: np.ndarray

    @classmethod
    def empty(cls, n: int) -> _Record:
        """Return an unfilled record of ``n`` samples."""
        return cls(np.empty((n, 10)), np.empty((n, 3)), np.empty((n, 2)), np.empty((n, 2)))


def _swivel_addresses(model: mujoco.MjModel) -> list[int]:
    """Return the qpos addresses of the left and right caster swivel joints."""
    return [
        int(model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"swivel_{side}")])
        for side in ("left", "right")
    ]


def _run(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    tracker: _Tracker,
    n_steps: int,
    samples: np.ndarray,
    on_step: Callable[[int], None] | None = None,
) -> _Record:
    """Step the pushed cart ``n_steps`` physics steps; return the clean record at the step indices ``samples``.

    ``on_step(i)`` (optional) runs before step ``i`` (e.g. a load put in or taken out, :mod:`.mujoco_loads`).
    """
    chassis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, CART_BODY)
    dt = model.opt.timestep
    is_sample = np.zeros(n_steps, dtype=bool)
    is_sample[samples] = True
    out = _Record.empty(len(samples))
    swivel_adr = _swivel_addresses(model)
    qpos, qvel, xfrc, xipos = data.qpos, data.qvel, data.xfrc_applied, data.xipos
    hx, hy = tracker.handle
    heading, s_meas, k = _Unwrap(), 0.0, 0
    for i in range(n_steps):
        if on_step is not None:
            on_step(i)
        mujoco.mj_step1(model, data)  # kinematics and CoM of the current state (xipos used by xfrc_applied)
        x, y, th, vx, vy, omega = _planar_state(qpos, qvel)
        th_unwrapped = heading.update(th)
        c, s = math.cos(th), math.sin(th)
        v = c * vx + s * vy
        f_fwd, f_lat, tau_h = tracker.wrench(i, v, omega, s_meas, th_unwrapped - heading.start)
        fx, fy = c * f_fwd - s * f_lat, s * f_fwd + c * f_lat
        px, py = x + c * hx - s * hy, y + s * hx + c * hy  # handle in {s}
        cx, cy = float(xipos[chassis, 0]), float(xipos[chassis, 1])
        tau_app = tau_h + (px - cx) * fy - (py - cy) * fx  # same wrench, moved to the chassis CoM
        xfrc[chassis, 0] = fx
        xfrc[chassis, 1] = fy
        xfrc[chassis, 5] = tau_app
        if is_sample[i]:
            tau_b = tau_about_b(fx, fy, tau_app, (cx, cy), (x, y))
            out.rec[k] = (i * dt, x, y, th_unwrapped, fx, fy, tau_b, vx, vy, omega)
            out.applied[k] = (tau_app, cx, cy)
            sc = data.subtree_com[chassis]
            rx, ry = float(sc[0]) - x, float(sc[1]) - y
            out.com_b[k] = (c * rx + s * ry, -s * rx + c * ry)
            out.swivel[k] = (qpos[swivel_adr[0]], qpos[swivel_adr[1]])
            k += 1
        mujoco.mj_step2(model, data)
        s_meas += v * dt
    return out


def _noise_std(case: MujocoCase) -> dict[str, float]:
    """Return the log's noise standard deviations by column."""
    return {
        "x": case.position_noise,
        "y": case.position_noise,
        "theta": case.theta_noise,
        "fx": case.force_noise,
        "fy": case.force_noise,
        "tau": case.torque_noise,
        "vx": case.velocity_noise,
        "vy": case.velocity_noise,
        "omega": case.omega_noise,
    }


def _noisy_log(case: MujocoCase, rec: np.ndarray, handle: tuple[float, float], rng: np.random.Generator) -> CartLog:
    """Return the log of the clean samples ``rec`` with white noise of the case's stds."""
    n = len(rec)
    noise = np.column_stack(
        [
            rng.normal(0.0, case.position_noise, (n, 2)),
            rng.normal(0.0, case.theta_noise, n),
            rng.normal(0.0, case.force_noise, (n, 2)),
            rng.normal(0.0, case.torque_noise, n),
            rng.normal(0.0, case.velocity_noise, (n, 2)),
            rng.normal(0.0, case.omega_noise, n),
        ]
    )
    meas = rec.copy()
    meas[:, 1:] += noise
    metadata = {
        "log": case.name or f"mj{case.seed}",
        "source": "MuJoCo cart (studies.testbeds.mujoco_cart)",
        "mujoco": mujoco.__version__,
        "seed": str(case.seed),
        "rate_hz": f"{case.rate_hz:g}",
        "jitter": f"{case.jitter:g}",
    }
    contact = np.tile(list(handle), (n, 1)) if case.with_contact else None
    qd = meas[:, 7:10] if case.with_velocities else None
    return CartLog(t=meas[:, 0], q=meas[:, 1:4], gamma=meas[:, 4:7], qd=qd, contact_b=contact, metadata=metadata)


def _minmeanmax(x: np.ndarray) -> list[float]:
    """Return [min, mean, max] of ``x`` as floats."""
    return [float(x.min()), float(x.mean()), float(x.max())]


def _truth_notes(case: MujocoCase, out: _Record, tracker: _Tracker, ref: _Reference, samples: np.ndarray) -> dict:
    """Return the truth entries added to the settled state's :func:`truth_from_state` (see :func:`simulate`)."""
    rec, com_b = out.rec, out.com_b
    return {
        "generator": f"MuJoCo {mujoco.__version__}: cart with two fixed rear wheels, two swivelling casters "
        "with trail, rolling and torsional friction, wheel spin inertia, soft contacts",
        "noise_std": _noise_std(case),
        "stats": {
            "dx": _minmeanmax(com_b[:, 0]),
            "dy": _minmeanmax(com_b[:, 1]),
            "stats_note": "min, mean, max over the log samples",
        },
        "truth_note": "m, dx, dy, I from the MuJoCo model after 1 s settling (casters trailing); dx/dy vary "
        "slightly as the casters swivel (see stats); the engine adds caster swivel dynamics, "
        "wheel spin inertia, rolling/torsional friction, load transfer, soft contacts.",
        "wrench_note": "the tracker updates the wrench every 1 ms; the log samples the held wrench",
        "controller": {"mass_guess": tracker.m_g, "inertia_b_guess": tracker.i_g, "lateral_share": tracker.share},
        "cart": asdict(case.cart),
        "duration": case.duration,
        "seed": case.seed,
        "true_log": {
            "t": rec[:, 0],
            "q": rec[:, 1:4],
            "gamma": rec[:, 4:7],
            "qd": rec[:, 7:10],
            "v_ref": ref.v[samples],
            "omega_ref": ref.w[samples],
            "com_b": com_b,
            "swivel": out.swivel,
            "tau_applied": out.applied[:, 0],
            "chassis_com": out.applied[:, 1:],
        },
    }


def simulate(case: MujocoCase) -> tuple[CartLog, dict[str, Any]]:
    """Simulate ``case`` and return (the noisy log, its truth dict).

    The truth dict holds :func:`truth`'s keys (from the settled initial state), the
    noise standard deviations, the min/mean/max of dx and dy over the log samples
    (``stats``: the casters swivel), the cart parameters and notes, and ``true_log``
    (arrays at the log samples, without noise: ``t``, ``q``, ``gamma``, ``qd``, the
    reference ``v_ref`` / ``omega_ref``, ``com_b`` (CoM in {b}), caster ``swivel`` angles,
    ``tau_applied`` (the z torque put in ``xfrc_applied``) and ``chassis_com`` (where
    MuJoCo applies it); :func:`generate` drops ``true_log`` from truth.json).
    """
    _require_mujoco()
    rng = np.random.default_rng([case.seed, 0x5EED])
    model, data = build(case.cart)
    settle(model, data, case.cart, case.q0 if case.q0 is not None else (0.0, 0.0, 0.0))
    info = truth_from_state(model, data)
    data.time = 0.0
    dt = model.opt.timestep
    n_steps = int(round(case.duration / dt)) + 1
    ref = _Reference.draw(case, rng, dt)
    tracker = _Tracker.guessing(case, info, ref, rng)
    samples = _sample_steps(case, n_steps, rng)
    out = _run(model, data, tracker, n_steps, samples)
    # MuJoCo resets the state where the accelerations blow up (a warning, not an error): a log of restarts
    resets = int(data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number)
    if resets or not np.all(np.isfinite(out.rec)):
        raise RuntimeError(f"{case.name or case.seed}: the simulation diverged ({resets} reset(s) by MuJoCo)")
    log = _noisy_log(case, out.rec, tracker.handle, rng)
    info.update(_truth_notes(case, out, tracker, ref, samples))
    return log, info


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def generate(n: int, seed0: int, out_dir: str | os.PathLike, **overrides: Any) -> None:
    """Write ``n`` logs ``mj<seed>.csv.gz`` (seeds ``seed0 .. seed0 + n - 1``) and ``truth.json`` to ``out_dir``."""
    out_dir = os.fspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    table: dict[str, Any] = {}
    for seed in range(seed0, seed0 + n):
        case = random_case(seed, **overrides)
        log, info = simulate(case)
        name = case.name or f"mj{seed}"
        write_log(os.path.join(out_dir, f"{name}.csv.gz"), log)
        info.pop("true_log")
        table[name] = _jsonable(info)
    with open(os.path.join(out_dir, "truth.json"), "w", encoding="utf-8") as fh:
        json.dump(table, fh, indent=1)
        fh.write("\n")


#: Variants of :func:`mass_bias` (:func:`random_case` overrides): the caster swivel's bearing friction and
#: damping off, the wheels' rolling and torsional (scrub) friction on the floor off, both; a stiffer contact;
#: no sensor noise.
BIAS_VARIANTS: dict[str, dict[str, Any]] = {
    "all effects": {},
    "no swivel friction": {"swivel_damping": 0.0, "swivel_frictionloss": 0.0},
    "no rolling/torsional friction": {"rolling_friction": 0.0, "torsional_friction": 0.0},
    "neither": {
        "swivel_damping": 0.0,
        "swivel_frictionloss": 0.0,
        "rolling_friction": 0.0,
        "torsional_friction": 0.0,
    },
    "stiffer contact": {"solref": (0.005, 1.0)},
    "no sensor noise": {"force_noise": 0.0, "torque_noise": 0.0, "position_noise": 1e-6, "theta_noise": 1e-6},
}


def mass_bias(seeds: range, variant: dict[str, Any], casters: bool = True) -> dict[str, float]:
    """Return the mass error of ``estimate``'s least squares against the effective forward mass over ``seeds``.

    ``variant``: :class:`MujocoCart` overrides (:data:`BIAS_VARIANTS`); ``casters`` False fits without the
    caster columns (:mod:`cart.identify_casters`). Keys: mean, min, max (%), and the logs where they are kept.
    """
    from cart import identify_casters
    from cart.identify import identify

    errors, kept = [], 0
    saved = identify_casters.MIN_HALF_TURNS
    try:
        identify_casters.MIN_HALF_TURNS = saved if casters else math.inf
        for seed in seeds:
            log, info = simulate(random_case(seed, **variant))
            res = identify(log)
            errors.append(100.0 * (res.params.m / info["m_effective_forward_incl_wheel_spin"] - 1.0))
            kept += int(res.casters is not None and res.casters.kept)
    finally:
        identify_casters.MIN_HALF_TURNS = saved
    e = np.array(errors)
    return {"mean_pct": float(e.mean()), "min_pct": float(e.min()), "max_pct": float(e.max()), "casters_kept": kept}


if __name__ == "__main__":  # pragma: no cover
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("n", type=int)
    parser.add_argument("out_dir", nargs="?")
    parser.add_argument("--seed0", type=int, default=0)
    parser.add_argument(
        "--mass-bias", action="store_true", help="the mass error on n carts with effects switched off (no logs written)"
    )
    args = parser.parse_args()
    if args.mass_bias:
        for name, variant in BIAS_VARIANTS.items():
            for with_casters in (False, True):
                row = mass_bias(range(args.seed0, args.seed0 + args.n), variant, with_casters)
                label = "with caster columns" if with_casters else "nominal model"
                print(json.dumps({"variant": name, "fit": label, **row}), flush=True)
    else:
        generate(args.n, args.seed0, args.out_dir)

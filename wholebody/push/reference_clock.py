"""Online time scaling of the desired cart motion: the reference slows down while the arms cannot give its wrench.

A cart too heavy for the hands' bounds (force, grip torque, joint torques, the tip-over bound) cannot follow the
desired motion q_d(t) at its speed: the allocation (eq. 25) saturates, the cart falls behind and the feedback asks
ever more. Following Dahl and Nielsen ("Torque-limited path following by online trajectory time scaling", IEEE
Trans. Robotics and Automation 6(5), 1990), the path stays the desired one and only its timing changes: the
reference is q_d(s) with the reference time s advancing at the rate r = ds/dt in [r_min, 1],

    q_ref = q_d(s),   qd_ref = q_d'(s) r,   qdd_ref = q_d''(s) r^2 + q_d'(s) r_dot,

which the cart controller (eq. 26) tracks as it would q_d(t). The inertial demand scales with r^2 (the turn's
yaw acceleration and the CoM's swing out of it, which the tip-over bound counts): when the allocation gives only
part of the desired wrench (its residual, a share d of the demand) the rate heads for r (1 - d) with time constant
`TimeScaling.tau_down` (fast: the error a missing turn leaves grows quickly); when it gives all of it, back to 1. The rate's change is the reference's own acceleration along
the path (q_d' r_dot). At the edge of what the arms can give, a period that saturates slows the rate and the next,
given in full, lets it recover, and with each period's own r_dot the feed-forward would alternate with them (the
WMRA's Traj. 2, seed 0: the desired push between +5 and -11 N period by period, the hand's allocated press on the
handle between 0 and 55 N): a change of the rate that reverses the last one, the rate staying below 1, gives r_dot
the mean of the two, which cancels that alternation; any other change is the period's own. Its slowing is kept
within `TimeScaling.brake_share` of what the hands' force gives the
estimated mass (toppra-style: the admissible path acceleration from the estimated dynamics; Pham and Pham,
"A new approach to time-optimal path parameterization based on reachability analysis", IEEE T-RO 34(3), 2018).
While r = 1 the reference time is the run's time exactly (s = t).

The reaction comes after the cart has fallen behind, and a turn's demand grows with the error it leaves; a heavy
cart at speed also keeps its momentum while its reference slows. So the clock can also look ahead (`admissible_rate`,
`TimeScaling(horizon=4.0)`, `cartpush push --look-ahead 4`; off by default): at samples of the desired path over the next `TimeScaling.horizon` seconds of reference time, the
largest rate of a grid whose feed-forward wrench there (`planned_wrench`: cart paper eq. 4 with the estimated
parameters, v r, vdot r^2, omega r, omegadot r^2, grown by `TimeScaling.feedback_share` for the feedback) the arms
can give (the allocation's limits at their current configuration, the tip-over bound under that motion's load);
the rate now is at most the one from which the reference can slow to each of those in time, at a path deceleration
within the brake bound (`plan_share` of it): the backward pass of time-optimal path parameterization at the grid's
rates. The turn ahead is judged with the estimate's yaw inertia and CoM, but at least those of its mass spread over
the wheels' footprint (`footprint_params`): before the first turn nothing has excited them and the estimate's are
its prior, scaled from a small cart.

Two more guards, on by default. A cart that still falls behind once the rate has reached `rate_min` (a turn
tighter than the hands can yaw it at that speed) gets its rate capped by its distance from the reference
(`error_rate_cap`) until the rate is back at 1. And without a horizon the clock looks ahead over
`TimeScaling.momentum_horizon` while the estimated cart would stop, under the hands' whole force, beyond
`TimeScaling.stop_distance` at the path's speed ahead (`needs_look_ahead`): its momentum would carry it off the path
before the reaction slowed it (the hospital bed, not the shopping cart or the wheelchair; docs/mujoco.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cart.params import CartParams
from wholebody.errors import WholeBodyError


#: a rate within this of 1 is 1 (within 1 % of the desired speed): the reference is back on it, its delay kept
RATE_SNAP = 1e-2


@dataclass(frozen=True)
class TimeScaling:
    """How fast the reference slows and recovers (module docstring)."""

    #: the slowest rate (share of the desired speed) the reference may take
    rate_min: float = 0.1
    #: time constant (s) of the rate's approach to its target while the allocation saturates
    tau_down: float = 0.3
    #: time constant (s) of its return to 1 once the allocation gives the whole wrench
    tau_up: float = 1.5
    #: share of the hands' total force the reference's slowing may ask of the estimated mass
    brake_share: float = 0.5
    #: the allocation's residual, as a share of the demand, below which it counts as giving the whole wrench
    deficit_tol: float = 0.02
    #: how far ahead (s of reference time) the desired motion's feed-forward must be one the arms can give at a rate
    #: the reference can slow to in time (`admissible_rate`), at how many samples, and how often (s, of reference
    #: time) that is checked. 0 (the default): no look-ahead. 4 s keeps heavy or off-centre carts' turns (docs/mujoco.md,
    #: "Example cart files"), but slows the default carts' turns and lowers their hand force more than its error
    horizon: float = 0.0
    horizon_samples: int = 17
    check_period: float = 0.1
    #: the feed-forward checked is grown by this share: room for the feedback. A trade-off measured on Traj. 2:
    #: 0.5 slows the default cart's turns to 63 % (hand-force error 9.4 %), 0 leaves the wheelchair's too fast (61.5 mm)
    feedback_share: float = 0.25
    #: the rates tried at each sample, from the top
    rate_grid: tuple[float, ...] = (1.0, 0.8, 0.6, 0.45, 0.3, 0.2, 0.15, 0.1)
    #: share of the slowing `brake_share` allows that the look-ahead plans with (the rate's approach to its target
    #: is exponential, `tau_down`, and slower than that bound near the target)
    plan_share: float = 0.5
    #: the tracking error (m, the estimated {b} from the reference q_d(s)) over which, once the rate has reached
    #: `rate_min`, the rate is capped from 1 at the first to `error_rate_min` at the second (`error_rate_cap`): a
    #: cart that falls behind its path at the slowest rate (a turn tighter than the hands can yaw it at that speed)
    #: gets a slower reference still, until the rate is back at 1
    error_band: tuple[float, float] = (0.04, 0.14)
    error_rate_min: float = 0.01
    #: the rate counts as at `rate_min` within this share above it (its approach to a target is asymptotic)
    floor_share: float = 0.25
    #: without a look-ahead (`horizon` 0), a cart whose stopping distance at the path's speed ahead under the hands'
    #: whole force (estimated mass) is over `stop_distance` (m) is looked ahead over `momentum_horizon` (s): its
    #: momentum would carry it off the path before the reference's reaction slowed it (`needs_look_ahead`)
    stop_distance: float = 0.4
    momentum_horizon: float = 4.0

    def __post_init__(self) -> None:
        if not (0.0 < self.rate_min <= 1.0 and self.tau_down > 0 and self.tau_up > 0 and 0 < self.brake_share <= 1):
            raise WholeBodyError("time scaling: rate_min in (0, 1], tau_down, tau_up > 0, brake_share in (0, 1]")
        lo, hi = self.error_band
        if not (0.0 <= lo < hi and 0.0 < self.error_rate_min <= self.rate_min):
            raise WholeBodyError("time scaling: error_band (lo, hi) with 0 <= lo < hi, error_rate_min in (0, rate_min]")


@dataclass
class ReferenceClock:
    """The reference time s and its rate r (`TimeScaling`): ``time(t)`` = s, ``advance`` after each period."""

    settings: TimeScaling
    #: the run's time minus the reference time (s): how far the reference is behind the desired motion
    delay: float = 0.0
    rate: float = 1.0
    #: the reference's path acceleration r_dot (1/s): the rate's change over the last period, or its mean with the
    #: change before when it reverses that one below a rate of 1 (module docstring)
    rate_dot: float = 0.0
    #: the rate's change over the last period, over its length (1/s)
    rate_step: float = 0.0
    #: the largest rate whose feed-forward over the horizon the arms can give (`admissible_rate`), and when (run
    #: time, s) it was last checked
    admissible: float = 1.0
    checked_at: float = -math.inf
    #: the largest rate the robots' bases allow here (`wholebody.push.base_plan.BasePlan.rate_cap`: a base plan's
    #: window that meets the wheel limits only slower than the desired speed); 1: none
    cap: float = 1.0
    #: whether the rate has reached `TimeScaling.rate_min` (within `floor_share`) since it was last at 1: the tracking
    #: error then caps it (`error_rate_cap`)
    floored: bool = False

    def time(self, t: float) -> float:
        """Return the reference time s at the run's time t (t itself until the reference first slows)."""
        return t - self.delay if self.delay != 0.0 else t

    def advance(self, deficit: float, dt: float, path_speed: float, accel_bound: float, error: float = 0.0) -> None:
        """Set the rate of the next period from this period's allocation `deficit` (residual / demand, in [0, 1];
        NaN: the arms could not brake as hard as asked, and the rate is held, `deficit`).

        ``path_speed``: |q_d'(s)| of the forward motion (m/s); ``accel_bound``: the hands' total force over the
        estimated mass (m/s^2), which bounds the slowing: r_dot >= -brake_share accel_bound / path_speed.
        ``error``: the tracking error (m), which caps the rate once it has reached `rate_min` (`error_rate_cap`).
        """
        s = self.settings
        if math.isnan(deficit):  # a braking deficit: slowing would ask more braking; hold the rate
            self._rate_changed(0.0, self.rate < 1.0)
            self.delay += (1.0 - self.rate) * dt
            return
        admissible = min(self.admissible, self.cap, error_rate_cap(error, s) if self.floored else 1.0)
        slowing = deficit > s.deficit_tol or admissible < self.rate
        target = min(self.rate * (1.0 - max(deficit, 0.0)), admissible) if slowing else admissible
        tau = s.tau_down if slowing else s.tau_up
        step = (target - self.rate) * min(1.0, dt / tau)
        if path_speed > 1e-9 and math.isfinite(accel_bound):
            step = max(step, -s.brake_share * accel_bound / path_speed * dt)
        new = min(1.0, max(min(s.rate_min, admissible), self.rate + step))
        if not slowing and new > 1.0 - RATE_SNAP:  # the approach to 1 is asymptotic: it ends
            new = 1.0
        self.floored = new < 1.0 and (self.floored or new <= s.rate_min * (1.0 + s.floor_share))
        self._rate_changed((new - self.rate) / dt, new < 1.0)
        self.rate = new
        self.delay += (1.0 - new) * dt

    def _rate_changed(self, step: float, slowed: bool) -> None:
        """Take this period's rate change (1/s) and whether the rate stays below 1: r_dot is the change, or its mean
        with the last period's when it reverses that one while slowed (module docstring)."""
        reverses = slowed and step * self.rate_step < 0.0
        self.rate_dot = 0.5 * (step + self.rate_step) if reverses else step
        self.rate_step = step


def error_rate_cap(error: float, settings: TimeScaling) -> float:
    """Return the largest rate the tracking `error` (m) allows once the rate has reached `rate_min`: 1 up to
    `TimeScaling.error_band`'s first value, `error_rate_min` from its second, geometric between (halfway the
    geometric mean of 1 and `error_rate_min`: the rate a cart can follow is found within the band however slow)."""
    lo, hi = settings.error_band
    share = min(1.0, max(0.0, (error - lo) / (hi - lo)))
    return settings.error_rate_min**share


def needs_look_ahead(mass: float, speed: float, force: float, settings: TimeScaling) -> bool:
    """Return whether a cart of estimated `mass` (kg) at the path `speed` (m/s) ahead stops, under the hands' whole
    `force` (N), over more than `TimeScaling.stop_distance`: m v^2 / (2 F)."""
    return force > 0.0 and mass * speed * speed / (2.0 * force) > settings.stop_distance


class ScaledReference:
    """A desired cart motion read on a `ReferenceClock`: ``sample(s)`` = q_d(s), q_d'(s) r, q_d'' r^2 + q_d' r_dot.

    The cart controller holds it as its trajectory and is asked at the reference time s (`ReferenceClock.time`).
    """

    def __init__(self, trajectory, clock: ReferenceClock) -> None:
        self.trajectory = trajectory
        self.clock = clock

    @property
    def duration(self) -> float:
        """Return the desired motion's duration (s, in reference time)."""
        return float(self.trajectory.duration)

    def sample(self, s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (q, qd, qdd) of the reference at reference time s with the clock's current rate."""
        q, qd, qdd = self.trajectory.sample(s)
        r, rd = self.clock.rate, self.clock.rate_dot
        if r == 1.0 and rd == 0.0:
            return q, qd, qdd
        return q, qd * r, qdd * (r * r) + qd * rd


def deficit(gamma_desired: np.ndarray, gamma_achieved: np.ndarray, path_braking: bool = False) -> float:
    """Return the share of the desired body wrench (the allocation's rows: fx, tau or fx, fy, tau) the allocation
    left out, in [0, 1]. NaN while the desired motion brakes (`path_braking`: its speed along the path falls at the
    reference time) and the arms could not brake as hard as asked (fx < 0 missing): slowing the reference, which
    asks more braking (q_d' r_dot), would not help."""
    missing = np.asarray(gamma_desired, dtype=float) - np.asarray(gamma_achieved, dtype=float)
    demand = float(np.linalg.norm(gamma_desired))
    if demand <= 1e-9:
        return 0.0
    share = min(1.0, float(np.linalg.norm(missing)) / demand)
    braking = path_braking and gamma_desired[0] < 0.0 and missing[0] < 0.0
    return math.nan if share > 0.0 and braking else share


#: the desired motion brakes when q_d' . q_d'' is below minus this (m^2/s^3): a turn at constant speed has it at
#: rounding's 1e-17 of either sign, which is no braking
BRAKING_TOL = 1e-9


def path_braking(qd: np.ndarray, qdd: np.ndarray) -> bool:
    """Return whether the desired motion's speed along its path falls (q_d' . q_d'' < -`BRAKING_TOL`; planar rates
    `qd`, accelerations `qdd`, their x and y read): `deficit`'s ``path_braking``."""
    return float(qd[0] * qdd[0] + qd[1] * qdd[1]) < -BRAKING_TOL


def planned_wrench(trajectory, s: float, rate: float, settings: TimeScaling, params) -> np.ndarray:
    """Return the body wrench (f_forward, 0, tau) the desired motion needs at reference time `s` read at `rate`,
    with the estimated parameters (`cart.dynamics.inverse_dynamics`, paper eq. 4) and the feedback's share on top,
    and the state it is needed at: the row (f, 0, tau, v, omega)."""
    from cart.dynamics import inverse_dynamics

    m, a, b, j = params.phi
    c_v, c_w = params.damping
    grow = 1.0 + settings.feedback_share
    q, qd, qdd = trajectory.sample(s)
    c, sn = math.cos(q[2]), math.sin(q[2])
    v, vdot = rate * (c * qd[0] + sn * qd[1]), rate * rate * (c * qdd[0] + sn * qdd[1])
    om, omdot = rate * qd[2], rate * rate * qdd[2]
    fu, tau = inverse_dynamics(v, om, vdot, omdot, m, a, b, j, c_v, c_w)
    return np.array([grow * fu, 0.0, grow * tau, v, om])


def sample_rate(trajectory, s: float, settings: TimeScaling, params, achievable) -> float:
    """Return the largest rate of `TimeScaling.rate_grid` whose feed-forward at reference time `s` (`planned_wrench`)
    is ``achievable(row)`` (the caller's allocation test); `rate_min` when none is."""
    for r in settings.rate_grid:
        if achievable(planned_wrench(trajectory, s, r, settings, params)):
            return r
    return settings.rate_min


def admissible_rate(trajectory, s: float, settings: TimeScaling, params, achievable, decel: float) -> float:
    """Return the largest rate now from which the reference can slow, at the path deceleration `decel` (1/s, r_dot
    = -decel), to a rate the arms can give at every sample ahead (`sample_rate` at s + h, h from 0 to the horizon).

    Slowing from r to r_k at r_dot = -decel covers (r^2 - r_k^2) / (2 decel) of reference time (the reference
    advances at ds/dt = r), so the rate now is at most sqrt(r_k^2 + 2 decel h_k) for each sample k: the
    backward pass of time-optimal path parameterization (Pham and Pham 2018) at a constant deceleration. The
    samples are tested nearest first, and none further once their bound cannot go below the smallest so far.
    """
    best = 1.0
    for h in np.linspace(0.0, settings.horizon, settings.horizon_samples):
        if decel > 0.0 and math.isfinite(decel) and settings.rate_min**2 + 2.0 * decel * float(h) >= best * best:
            break  # no sample this far can ask for a slower rate now
        r_k = sample_rate(trajectory, s + float(h), settings, params, achievable)
        reach = math.sqrt(r_k * r_k + 2.0 * decel * float(h)) if math.isfinite(decel) else (1.0 if h > 0 else r_k)
        best = min(best, reach)
    return max(settings.rate_min, min(1.0, best))


def footprint_params(params: CartParams, points: np.ndarray) -> CartParams:
    """Return the estimate `params` with its yaw inertia about {b} at least that of its mass spread evenly over the
    rectangle around the cart's wheel contacts `points` ((K, 2) in {b}), and its CoM along each axis at least as
    far from {b} as that rectangle's centre.

    Before the first turn the estimate's yaw inertia and CoM are its prior (nothing excited them); the look-ahead
    judges a turn it has not met with the larger of the two, so a 2 m bed is not entered into a turn as if it
    were a 0.8 m shopping cart."""
    pts = np.asarray(points, dtype=float)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, size = 0.5 * (lo + hi), hi - lo
    m = float(params.m)
    dx = float(centre[0]) if abs(centre[0]) > abs(params.dx) else float(params.dx)
    dy = float(centre[1]) if abs(centre[1]) > abs(params.dy) else float(params.dy)
    spread_b = m * (float(size @ size) / 12.0 + float(centre @ centre))
    j_b = max(float(params.inertia_b), spread_b)
    inertia = max(j_b - m * (dx * dx + dy * dy), float(params.I))
    return CartParams(m, dx, dy, inertia, params.sigma, params.sigma_yaw)

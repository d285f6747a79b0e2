"""Desired cart trajectories of the paper (Fig. 3), feasible for a nonholonomic cart.

Both are unicycle motions of the {b} origin, so the desired velocity always
satisfies the no-lateral-slip constraint. The speed has a step acceleration
to cruise speed and a step stop (paper §III); Traj. 2 adds three large turns
whose yaw rate is a raised-cosine bump (continuous, so the desired torque is
bounded) starting at t = 7, 16 and 23 s.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np
import numpy.typing as npt

#: Position grids of the trajectories built so far, keyed by the (frozen, hashable) trajectory:
#: (times, x, y) as arrays and as lists (for :func:`_interp`). Shared by equal trajectories, so the
#: 11 Table I tests build each of their two grids once per process.
_GRIDS: dict[UnicycleTrajectory, tuple[np.ndarray, np.ndarray, np.ndarray, list[float], list[float], list[float]]] = {}


def _interp(t: float, tg: list[float], yg: list[float]) -> float:
    """Return ``np.interp(t, tg, yg)`` for a scalar t, bit for bit, without numpy's per-call overhead."""
    j = bisect_right(tg, t) - 1
    if j < 0:
        return yg[0]
    if j >= len(tg) - 1 or tg[j] == t:
        return yg[j]
    slope = (yg[j + 1] - yg[j]) / (tg[j + 1] - tg[j])
    return slope * (t - tg[j]) + yg[j]


@dataclass(frozen=True)
class Turn:
    """A yaw-rate bump: heading changes by ``angle`` between ``start`` and ``start + length``."""

    start: float
    length: float
    angle: float


@dataclass(frozen=True)
class UnicycleTrajectory:
    """Speed profile (step acceleration, cruise, step stop) plus turns, sampled by :meth:`sample`."""

    duration: float = 30.0
    accel_start: float = 1.0
    accel: float = 0.4
    cruise_speed: float = 0.8
    stop_start: float = 27.0
    turns: tuple[Turn, ...] = ()
    grid_dt: float = 1e-3

    def speed(self, t: float) -> tuple[float, float]:
        """Return (v, vdot): forward speed and its derivative at t."""
        t_ramp = self.cruise_speed / self.accel
        if t < self.accel_start:
            return 0.0, 0.0
        if t < self.accel_start + t_ramp:
            return self.accel * (t - self.accel_start), self.accel
        if t < self.stop_start:
            return self.cruise_speed, 0.0
        if t < self.stop_start + t_ramp:
            return self.cruise_speed - self.accel * (t - self.stop_start), -self.accel
        return 0.0, 0.0

    def yaw(self, t: float) -> tuple[float, float, float]:
        """Return (theta, omega, omegadot) at t."""
        th = om = od = 0.0
        for turn in self.turns:
            u = (t - turn.start) / turn.length
            if u <= 0.0:
                continue
            if u >= 1.0:
                th += turn.angle
                continue
            peak = 2.0 * turn.angle / turn.length  # omega = peak * (1 - cos 2 pi u) / 2
            om += 0.5 * peak * (1.0 - math.cos(2.0 * math.pi * u))
            od += 0.5 * peak * 2.0 * math.pi / turn.length * math.sin(2.0 * math.pi * u)
            th += turn.angle * (u - math.sin(2.0 * math.pi * u) / (2.0 * math.pi))
        return th, om, od

    def _grid(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[float], list[float], list[float]]:
        """Return the position grid (trapezoidal integral of the velocity every ``grid_dt``), built once."""
        cache = self.__dict__.get("_cache")  # the instance's own first: hashing the dataclass is slower
        if cache is None:
            cache = _GRIDS.get(self)
            if cache is None:
                cache = _GRIDS[self] = self._build_grid()
            object.__setattr__(self, "_cache", cache)
        return cache

    def _build_grid(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[float], list[float], list[float]]:
        tg = np.arange(0.0, self.duration + 2 * self.grid_dt, self.grid_dt)
        vel = np.empty((len(tg), 2))
        for i, t in enumerate(tg.tolist()):
            v = self.speed(t)[0]
            th = self.yaw(t)[0]
            vel[i] = (v * math.cos(th), v * math.sin(th))
        pos = np.zeros_like(vel)
        pos[1:] = np.cumsum(0.5 * (vel[1:] + vel[:-1]) * self.grid_dt, axis=0)
        return tg, pos[:, 0], pos[:, 1], tg.tolist(), pos[:, 0].tolist(), pos[:, 1].tolist()

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (q_d, qd_d, qdd_d) at time t (held at the end after ``duration``)."""
        _, _, _, tg, xg, yg = self._grid()
        t = float(t)
        v, vdot = self.speed(t)
        th, om, od = self.yaw(t)
        c, s = math.cos(th), math.sin(th)
        q = np.array([_interp(t, tg, xg), _interp(t, tg, yg), th])
        qd = np.array([v * c, v * s, om])
        qdd = np.array([vdot * c - v * om * s, vdot * s + v * om * c, od])
        return q, qd, qdd

    def path_speed(self, t: float) -> float:
        """Return the desired path speed at t: ``np.hypot`` of ``sample(t)``'s planar velocity, bit for bit, without
        the position grid (the push controller reads it at every look-ahead sample)."""
        v = self.speed(float(t))[0]
        th = self.yaw(float(t))[0]
        return float(np.hypot(v * math.cos(th), v * math.sin(th)))

    def poses(self, ts: npt.ArrayLike) -> np.ndarray:
        """Return the desired poses q_d (N, 3) at the times ``ts``: ``sample(t)[0]`` for each t, at once."""
        tg, xg, yg = self._grid()[:3]
        ts = np.asarray(ts, dtype=float)
        th = [self.yaw(t)[0] for t in ts.tolist()]
        return np.column_stack([np.interp(ts, tg, xg), np.interp(ts, tg, yg), th])


def trajectory_1(duration: float = 30.0) -> UnicycleTrajectory:
    """Return the paper's Traj. 1: a straight line with step acceleration to cruise and a step stop."""
    return UnicycleTrajectory(duration=duration, stop_start=duration - 3.0)


def trajectory_2(duration: float = 30.0, turns: Sequence[Turn] | None = None) -> UnicycleTrajectory:
    """Return the paper's Traj. 2: the same speed profile with three large turns (Fig. 3)."""
    if turns is None:
        turns = (Turn(7.0, 3.0, math.pi / 2), Turn(16.0, 3.0, -math.pi / 2), Turn(23.0, 3.0, math.pi / 2))
    return UnicycleTrajectory(duration=duration, stop_start=duration - 3.0, turns=tuple(turns))


class CartTrajectory(Protocol):
    """A desired cart motion: what the cart controllers (eq. 26) and the push loop sample."""

    @property
    def duration(self) -> float:
        """Return the time (s) at which the motion ends (it is held after)."""

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (q_d, qd_d, qdd_d) at time t: pose (x, y, theta) and its first two derivatives."""


@dataclass(frozen=True)
class WaypointTrajectory:
    """A nonholonomic path through planar waypoints (m), driven with a trapezoidal speed profile.

    The path is a C2 cubic spline through the waypoints, parameterised by its chord length; the heading
    is the path's tangent (so the desired velocity satisfies the no-slip constraint, eq. 1-3); the
    speed ramps at ``accel`` to ``speed``, cruises, and ramps down to stop at the last waypoint. The
    motion starts at ``start`` s and is held at the end.
    """

    waypoints: tuple[tuple[float, float], ...]
    speed: float = 0.5
    accel: float = 0.4
    start: float = 1.0

    def __post_init__(self) -> None:
        pts = np.asarray(self.waypoints, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 2 or not np.all(np.isfinite(pts)):
            raise ValueError(f"waypoints must be >= 2 finite (x, y) pairs, got shape {pts.shape}")
        if np.any(np.linalg.norm(np.diff(pts, axis=0), axis=1) < 1e-6):
            raise ValueError("consecutive waypoints must differ")
        if not (self.speed > 0 and self.accel > 0 and self.start >= 0):
            raise ValueError("speed and accel must be > 0 and start >= 0")

    def _spline(self):
        cache = self.__dict__.get("_cache")
        if cache is None:
            from scipy.interpolate import CubicSpline

            pts = np.asarray(self.waypoints, dtype=float)
            u = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]
            spline = CubicSpline(u, pts, bc_type="natural")
            fine = np.linspace(0.0, u[-1], 2000)
            ds = np.linalg.norm(spline(fine, 1), axis=1)
            s = np.r_[0.0, np.cumsum(0.5 * (ds[1:] + ds[:-1]) * np.diff(fine))]
            cache = (spline, fine, s)
            object.__setattr__(self, "_cache", cache)
        return cache

    @property
    def length(self) -> float:
        """Return the path's arc length (m)."""
        return float(self._spline()[2][-1])

    @property
    def duration(self) -> float:
        """Return the time (s) at which the cart stops at the last waypoint."""
        L, v, a = self.length, self.speed, self.accel
        v_top = min(v, math.sqrt(L * a))
        return self.start + 2.0 * v_top / a + max(0.0, L - v_top**2 / a) / v_top

    def _progress(self, t: float) -> tuple[float, float, float]:
        """Return (s, sdot, sddot): arc length travelled and its derivatives at t."""
        L, a = self.length, self.accel
        v = min(self.speed, math.sqrt(L * a))
        t_ramp, t_end = v / a, self.duration
        tau = t - self.start
        if tau <= 0.0:
            return 0.0, 0.0, 0.0
        if t >= t_end:
            return L, 0.0, 0.0
        if tau < t_ramp:
            return 0.5 * a * tau**2, a * tau, a
        if t < t_end - t_ramp:
            return 0.5 * v * t_ramp + v * (tau - t_ramp), v, 0.0
        r = t_end - t
        return L - 0.5 * a * r**2, a * r, -a

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (q_d, qd_d, qdd_d) at time t."""
        spline, fine, s_of_u = self._spline()
        s, sd, sdd = self._progress(float(t))
        u = float(np.interp(s, s_of_u, fine))
        p, dp, ddp = spline(u), spline(u, 1), spline(u, 2)
        n = float(np.hypot(*dp))
        tx, ty = dp / n  # unit tangent
        kappa = (dp[0] * ddp[1] - dp[1] * ddp[0]) / n**3  # signed curvature
        th = math.atan2(ty, tx)
        om, omd = kappa * sd, kappa * sdd  # curvature held over the sample (its derivative along s neglected)
        q = np.array([p[0], p[1], th])
        qd = np.array([sd * tx, sd * ty, om])
        qdd = np.array([sdd * tx - sd * om * ty, sdd * ty + sd * om * tx, omd])
        return q, qd, qdd


@dataclass(frozen=True)
class FunctionTrajectory:
    """A user's desired motion given as a function of time ``f(t) -> (q_d, qd_d, qdd_d)``, over ``duration`` s."""

    function: Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]]
    duration: float

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the function's (q_d, qd_d, qdd_d) at t, checked for shape (3,) each."""
        out = tuple(np.asarray(v, dtype=float) for v in self.function(float(t)))
        if len(out) != 3 or any(v.shape != (3,) for v in out):
            raise ValueError("a trajectory function must return (q_d, qd_d, qdd_d), each of shape (3,)")
        return out[0], out[1], out[2]


def paper_trajectory(number: int, duration: float = 30.0) -> UnicycleTrajectory:
    """Return the paper's Traj. 1 or 2 (Fig. 3)."""
    if number not in (1, 2):
        raise ValueError(f"the paper has trajectories 1 and 2, got {number}")
    return trajectory_1(duration) if number == 1 else trajectory_2(duration)

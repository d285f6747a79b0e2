"""Contact points on the handle during the push: fixed, or re-planned from the estimate (cart paper §II.D)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from cart.dynamics import inverse_dynamics
from cart.params import CartParams
from cart.trajectories import CartTrajectory
from wholebody.contacts.allocation import WrenchAllocator
from wholebody.contacts.handle import CONTACT_GRID_STEP, contact_grid
from wholebody.contacts.placement import ReachMap, effort_sweep
from wholebody.errors import InfeasibleWrenchError
from wholebody.push.config import PushConfig
from wholebody.push.robot import handle_point

#: A planned contact keeps its static joint torques (gravity + J^T w) below this fraction of the effortLimit,
#: leaving the rest for the arm's own dynamics.
STATIC_TORQUE_FRACTION = 0.8


def side_by_side(reach: ReachMap | Sequence[ReachMap], contact_y: np.ndarray) -> bool:
    """Return True when one robot's `ReachMap` stands for several robots side by side, one contact each.

    The map is the reach of one robot standing at its own place behind the cart; robots side by side stand
    behind their own contacts (`wholebody.push.robot.base_lateral_places`), so it does not say which of their
    contacts they hold: each robot's grasp IK does (`wholebody.push.robot.make_robots` raises when it fails).
    """
    return not isinstance(reach, Sequence) and len(contact_y) > 1


class ContactScheduler:
    """Contact points on the handle: fixed, or re-planned from the estimate and slid towards the plan.

    With a `ReachMap` (a robot whose base stands at a fixed place behind the cart), only points the arm
    holds with margin are candidates, and a plan whose static joint torques exceed the effortLimit is avoided.
    """

    def __init__(
        self, config: PushConfig, trajectory: CartTrajectory, reach: ReachMap | Sequence[ReachMap] | None = None
    ) -> None:
        self.config = config
        self.trajectory = trajectory
        #: one map for every contact, or one per contact (one base holding the handle with several arms)
        self.reach = reach
        self.y = config.contact_y0().copy()
        self._maps = [] if reach is None else list(reach) if isinstance(reach, Sequence) else [reach] * len(self.y)
        if reach is not None and not (config.contact == "fixed" and side_by_side(reach, self.y)):
            if config.contact == "fixed":
                self._check_fixed_reach()
            self.y = np.array(
                [
                    r.nearest_reachable(float(v)) if not r.is_reachable(v) else float(v)
                    for r, v in zip(self._maps, self.y)
                ]
            )
        self.plan = self.y.copy()
        self.ydot = np.zeros_like(self.y)
        self.next_replan = 0.0
        self.geometry = config.cart_geometry()
        self.alloc = WrenchAllocator(
            [handle_point(v, self.geometry) for v in self.y], list(config.hand_limits()), only_motion_directions=True
        )
        self.handle = self.geometry.handle
        n = config.n_arms
        step = CONTACT_GRID_STEP if n == 1 else 2 * CONTACT_GRID_STEP
        grid = contact_grid(step) if config.geometry is None and config.cart_model is None else self.geometry.grid(step)
        self.candidates = (
            [np.array([g]) for g in grid]
            if n == 1
            else [np.array([a, b]) for a in grid for b in grid if b - a >= 0.2 - 1e-9]
        )
        if reach is not None:
            self.candidates = [c for c in self.candidates if all(r.is_reachable(v) for r, v in zip(self._maps, c))]
        self.y_lo = min(float(c.min()) for c in self.candidates) if self.candidates else float(grid[0])
        self.y_hi = max(float(c.max()) for c in self.candidates) if self.candidates else float(grid[-1])

    def _check_fixed_reach(self) -> None:
        """Raise when a fixed contact is out of the arm's reach: anywhere on the handle, or a point the user gave.

        A default point (``fixed_contact_y`` not given) out of reach moves to the nearest point held with margin
        (the caller does it; `wholebody.push.report.what_happened` says so); a point the user gave is kept or refused.
        """
        config = self.config
        bad = [k for k, (r, v) in enumerate(zip(self._maps, self.y)) if not r.is_reachable(v)]
        if not bad:
            return
        k = bad[0]
        rm = self._maps[k]
        ok = rm.y[rm.reachable]
        if not ok.size:  # out of reach along the whole handle: say where it is
            geo = config.cart_geometry()
            p = handle_point(float(self.y[k]), geo)
            raise InfeasibleWrenchError(
                f"robot {config.robot!r} reaches the handle nowhere along it: its point at y = "
                f"{self.y[k]:.3f} m is at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m in the cart frame, "
                f"{p[2] + geo.frame_height:.2f} m above the floor: out of the arm's reach from any base place",
                binding="reach",
            )
        if config.fixed_contact_y is not None:
            i = rm.index(float(self.y[k]))
            raise InfeasibleWrenchError(
                f"robot {config.robot!r} cannot hold the handle at y = {self.y[k]:.3f} m with margin "
                f"({rm.reason[i] or 'outside the reachable span'}); it reaches [{ok.min():.3f}, {ok.max():.3f}] m: "
                "give a contact point there (--contact-y, PushConfig.fixed_contact_y)",
                binding="reach",
            )

    def _planned_wrenches(self, t: float, params: CartParams) -> list[np.ndarray]:
        """Return the feed-forward body wrenches (fx_b, 0, tau_b) along the next replan_horizon seconds."""
        out = []
        ts = t + np.linspace(0.0, self.config.replan_horizon, 7)
        m, a, b, j = params.phi
        for tk in ts:
            _, qd_d, qdd_d = self.trajectory.sample(tk)
            th = math.atan2(qd_d[1], qd_d[0]) if np.hypot(qd_d[0], qd_d[1]) > 1e-6 else self.trajectory.sample(tk)[0][2]
            c, s = math.cos(th), math.sin(th)
            v = c * qd_d[0] + s * qd_d[1]
            vdot = c * qdd_d[0] + s * qdd_d[1]
            om, odot = qd_d[2], qdd_d[2]
            fu, tau = inverse_dynamics(v, om, vdot, odot, m, a, b, j, *params.damping)
            out.append(np.array([fu, 0.0, tau]))
        return out

    def _best_candidate(self, gammas: list[np.ndarray]) -> np.ndarray:
        """Return the candidate with the least total effort over the planned wrenches (penalties included).

        One `effort_sweep` over every candidate and wrench; an unachievable wrench adds 1e6 residual^2, and
        with a `ReachMap` static joint torques beyond STATIC_TORQUE_FRACTION of the effortLimit add
        1e6 excess^2. Ties keep the earlier candidate (improvement by more than 1e-9 needed).
        """
        if not self.candidates:
            return self.plan
        pts = np.array([[handle_point(v, self.geometry) for v in cand] for cand in self.candidates])
        sweep = effort_sweep(self.alloc, pts, np.array(gammas))
        totals = np.zeros(len(self.candidates))
        for k in range(len(gammas)):  # the same summation order as one candidate at a time
            totals = totals + (sweep.effort[:, k] + 1e6 * sweep.residual[:, k] ** 2)
            if self.reach is not None:
                over = (
                    np.array([self._torque_ratio(c, sweep.wrenches_ee[m, k]) for m, c in enumerate(self.candidates)])
                    - STATIC_TORQUE_FRACTION
                )
                totals = totals + 1e6 * np.maximum(0.0, over) ** 2
        best, best_v = self.plan, np.inf
        for cand, total in zip(self.candidates, totals):
            if total < best_v - 1e-9:
                best, best_v = cand, total
        return best

    def _torque_ratio(self, c: np.ndarray, wrenches: np.ndarray) -> float:
        """Return the largest static |tau| / limit of a candidate's wrenches: of its first contact with one map for
        every contact, of every contact with one map per contact (one base, several arms)."""
        if not isinstance(self.reach, Sequence):
            return self._maps[0].torque_ratio(float(c[0]), wrenches[0])
        return max(r.torque_ratio(float(v), w) for r, v, w in zip(self._maps, c, wrenches))

    def update(self, t: float, params: CartParams, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Return (contact y per arm, their rates) after one period."""
        if self.config.contact == "fixed":
            return self.y, np.zeros_like(self.y)
        if t >= self.next_replan - 1e-12:
            self.next_replan = t + self.config.replan_period
            self.plan = self._best_candidate(self._planned_wrenches(t, params)).copy()
        # slide towards the plan with bounded speed and acceleration (a trapezoidal profile that stops on the
        # plan): the hand's velocity never jumps, so the arm's joint torques stay continuous at a re-plan
        a, vmax = self.config.slide_acceleration, self.config.slide_speed
        e = self.plan - self.y
        # discrete braking curve: from speed n a dt, decelerating a dt per step covers n (n + 1) / 2 a dt^2
        n_stop = np.sqrt(0.25 + 2.0 * np.abs(e) / (a * dt * dt)) - 0.5
        v_stop = np.sign(e) * np.minimum(vmax, n_stop * a * dt)
        v = self.ydot + np.clip(v_stop - self.ydot, -a * dt, a * dt)
        step = v * dt
        land = (np.abs(step) >= np.abs(e)) & (np.abs(v) <= a * dt + 1e-12)  # slow enough: stop on the plan
        step = np.where(land, e, step)
        self.ydot = np.where(land, 0.0, v)
        self.y = np.clip(self.y + step, self.y_lo, self.y_hi)  # never past the handle's (reachable) ends
        return self.y, self.ydot.copy()

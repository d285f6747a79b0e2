"""Contact points on the handle during the push: fixed, or re-planned from the estimate (cart paper §II.D)."""
from __future__ import annotations

import math
from typing import List, Tuple

import numpy as np

from cart.dynamics import inverse_dynamics
from cart.params import CartParams
from cart.trajectories import UnicycleTrajectory
from wholebody.contacts.allocation import WrenchAllocator
from wholebody.contacts.handle import HandleSegment
from wholebody.push.config import PushConfig
from wholebody.push.robot import handle_point


class ContactScheduler:
    """Contact points on the handle: fixed, or re-planned from the estimate and slid towards the plan."""

    def __init__(self, config: PushConfig, trajectory: UnicycleTrajectory) -> None:
        self.config = config
        self.trajectory = trajectory
        self.y = config.contact_y0().copy()
        self.plan = self.y.copy()
        self.next_replan = 0.0
        self.alloc = WrenchAllocator([handle_point(v) for v in self.y], config.arm_limits,
                                     only_motion_directions=True)
        self.handle = HandleSegment.default()
        n = config.n_arms
        grid = np.round(np.arange(-0.25, 0.2501, 0.025 if n == 1 else 0.05), 6)
        self.candidates = [np.array([g]) for g in grid] if n == 1 else [
            np.array([a, b]) for a in grid for b in grid if b - a >= 0.2 - 1e-9]

    def _planned_wrenches(self, t: float, params: CartParams) -> List[np.ndarray]:
        """Return the feed-forward body wrenches (fx_b, 0, tau_b) along the next replan_horizon seconds."""
        out = []
        ts = t + np.linspace(0.0, self.config.replan_horizon, 7)
        m, a, b, j = params.phi
        for tk in ts:
            _, qd_d, qdd_d = self.trajectory.sample(tk)
            th = math.atan2(qd_d[1], qd_d[0]) if np.hypot(qd_d[0], qd_d[1]) > 1e-6 else self.trajectory.yaw(tk)[0]
            c, s = math.cos(th), math.sin(th)
            v = c * qd_d[0] + s * qd_d[1]
            vdot = c * qdd_d[0] + s * qdd_d[1]
            om, odot = qd_d[2], qdd_d[2]
            fu, tau = inverse_dynamics(v, om, vdot, odot, m, a, b, j, *params.damping)
            out.append(np.array([fu, 0.0, tau]))
        return out

    def update(self, t: float, params: CartParams, dt: float) -> Tuple[np.ndarray, np.ndarray]:
        """Return (contact y per arm, their rates) after one period."""
        if self.config.contact == "fixed":
            return self.y, np.zeros_like(self.y)
        if t >= self.next_replan - 1e-12:
            self.next_replan = t + self.config.replan_period
            gammas = self._planned_wrenches(t, params)
            best, best_v = self.plan, np.inf
            for cand in self.candidates:
                self.alloc.set_points([handle_point(v) for v in cand])
                total = 0.0
                for g in gammas:
                    res = self.alloc.solve(g, raise_on_infeasible=False)
                    total += res.effort + 1e6 * res.residual ** 2
                if total < best_v - 1e-9:
                    best, best_v = cand, total
            self.plan = best.copy()
        step = np.clip(self.plan - self.y, -self.config.slide_speed * dt, self.config.slide_speed * dt)
        self.y = self.y + step
        return self.y, step / dt

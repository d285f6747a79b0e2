"""Holding a sliding cart sideways: the hands take the lateral force the cart's missing axle does not give.

The cart model (paper eq. 3-4) has a fixed axle: its wheels take any lateral force at {b} (the no-slip constraint),
and the allocation (eq. 25) only matches the rows the cart moves along, the forward force and the yaw torque
(`WrenchAllocator(only_motion_directions=True)`). Its lateral hand force is free, and the allocation uses it for
the yaw torque it makes at a handle behind {b}. A cart with no fixed axle (a trolley on four swivel casters) has
nothing to take that force: the hand's sideways push for a turn's torque shoves it sideways (the four-caster
trolley's Traj. 2, seed 0: -54 N at 7.4 s, the cart sliding at 0.5 m/s by 7.7 s, lost at 7.9 s), and the turn's
centripetal force m v omega, which the model puts on the axle, is asked of nobody.

`SlipHold` watches the estimated lateral speed of {b} (the state observer's, from the motion capture): once it has
been above `SlipHoldSettings.speed` for `SlipHoldSettings.hold_time` the cart is taken as sliding for the rest of the
run, and the controller asks the hands for the lateral force of {b}'s motion too (`lateral_demand`: the reference's
lateral inertial force, `cart.dynamics.lateral_inertial_force`, and a critically damped feedback on the lateral
position and speed errors, scaled by the estimated mass), allocated on all three rows. A cart whose axle holds
never slides that fast (the carts with a fixed axle in docs/mujoco.md: at most 0.02 m/s), and the kinematic plant's
cart cannot slide at all: their runs do not change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cart.dynamics import lateral_inertial_force
from cart.params import CartParams


@dataclass(frozen=True)
class SlipHoldSettings:
    """When a cart counts as sliding and how hard the hands hold its lateral motion."""

    #: estimated lateral speed of {b} (m/s) above which the cart slides (the report's "slid" threshold)
    speed: float = 0.05
    #: how long (s) it must stay above it (one noisy period is no slide)
    hold_time: float = 0.2
    #: natural frequency (rad/s) of the lateral error's feedback (critically damped)
    omega_n: float = 3.0


@dataclass
class SlipHold:
    """Whether the cart slides (latched) and the lateral force (N, in {b}) its motion then asks of the hands."""

    settings: SlipHoldSettings = SlipHoldSettings()
    #: run time (s) from which the cart is taken as sliding; None: not (yet)
    since: float | None = None
    _above: float = 0.0

    @property
    def sliding(self) -> bool:
        """Return whether the cart has been seen sliding."""
        return self.since is not None

    def update(self, t: float, q: np.ndarray, qd: np.ndarray, dt: float) -> bool:
        """Take the estimated pose `q` and rate `qd` (x, y, theta and their rates) at time t; return `sliding`."""
        if self.since is None:
            lateral = -math.sin(q[2]) * qd[0] + math.cos(q[2]) * qd[1]
            self._above = self._above + dt if abs(lateral) > self.settings.speed else 0.0
            if self._above >= self.settings.hold_time - 1e-9:
                self.since = t
        return self.since is not None


def lateral_demand(
    q: np.ndarray,
    qd: np.ndarray,
    ref: tuple[np.ndarray, np.ndarray, np.ndarray],
    params: CartParams,
    settings: SlipHoldSettings,
) -> float:
    """Return the lateral force (N, along {b}'s y) the hands should give a sliding cart at pose `q`, rate `qd`, to
    follow the reference `ref` = (q_d, q_d', q_d'') (read on the reference clock): the lateral inertial force of the
    reference's motion with the estimated mass and CoM (`cart.dynamics.lateral_inertial_force`), plus the estimated
    mass times a critically damped feedback on {b}'s lateral position and speed errors (in {b})."""
    q_d, qd_d, qdd_d = ref
    c, s = math.cos(q[2]), math.sin(q[2])
    cd, sd = math.cos(q_d[2]), math.sin(q_d[2])
    v_r = cd * qd_d[0] + sd * qd_d[1]
    m, a, b, _ = params.phi
    ff = lateral_inertial_force(v_r, float(qd_d[2]), float(qdd_d[2]), m, a, b)
    e_y = -s * (q_d[0] - q[0]) + c * (q_d[1] - q[1])
    e_ydot = -s * (qd_d[0] - qd[0]) + c * (qd_d[1] - qd[1])
    w = settings.omega_n
    return float(ff + m * (w * w * e_y + 2.0 * w * e_ydot))

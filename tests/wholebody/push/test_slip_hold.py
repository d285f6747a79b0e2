"""A sliding cart is held sideways by the hands (`wholebody.push.slip_hold`).

The latch takes the estimated lateral speed of {b}; the lateral demand is checked against the free planar rigid
body's lateral equation written out here (not through `cart.dynamics`); the four-caster trolley (no fixed axle) is
pushed into Traj. 2's first turn, which it slid out of with the lateral hand force left free.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from cart.params import CartParams
from wholebody.push import PushConfig, build_controller
from wholebody.push.loop import run_loop
from wholebody.push.mujoco_plant import MujocoPlant
from wholebody.push.plants import plant_report
from wholebody.push.report import cart_lateral_speed
from wholebody.push.slip_hold import SlipHold, SlipHoldSettings, lateral_demand

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "carts"


def _pose_rate(theta: float, forward: float, lateral: float) -> tuple[np.ndarray, np.ndarray]:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([0.0, 0.0, theta]), np.array([c * forward - s * lateral, s * forward + c * lateral, 0.0])


def test_the_latch_needs_a_lateral_speed_held_for_its_time():
    hold = SlipHold(SlipHoldSettings(speed=0.05, hold_time=0.2))
    q, qd = _pose_rate(0.7, 0.8, 0.049)  # just below: a cart on its axle
    assert not any(hold.update(0.01 * k, q, qd, 0.01) for k in range(100))
    q, qd = _pose_rate(0.7, 0.8, -0.06)
    flags = [hold.update(1.0 + 0.01 * k, q, qd, 0.01) for k in range(25)]
    assert not flags[18] and flags[19] and all(flags[19:])  # the 20th period above it: 0.2 s
    assert hold.since == pytest.approx(1.19)
    q, qd = _pose_rate(0.7, 0.8, 0.0)
    assert hold.update(2.0, q, qd, 0.01)  # latched: a held cart slides no more, and stays held


def test_a_noisy_period_does_not_latch():
    hold = SlipHold()
    q = np.zeros(3)
    for k in range(200):  # one period in five above the speed
        qd = np.array([0.8, 0.2 if k % 5 == 0 else 0.0, 0.0])
        assert not hold.update(0.01 * k, q, qd, 0.01)


def test_the_lateral_demand_is_the_free_body_lateral_equation():
    m, dx, dy = 46.0, 0.35, 0.04
    params = CartParams(m, dx, dy, 3.0, 1.0, 1.0)
    settings = SlipHoldSettings(omega_n=3.0)
    # on the reference, moving along its heading (v, omega, omega_dot): no error, only the inertial force
    th, v, om, omdot = 0.3, 0.8, 0.9, -0.4
    q_d = np.array([1.0, 2.0, th])
    qd_d = np.array([v * math.cos(th), v * math.sin(th), om])
    qdd_d = np.array([0.0, 0.0, omdot])
    # {b} moves along its heading at v, turning at omega: its lateral acceleration v omega; the CoM's is that plus
    # omega_dot dx - omega^2 dy (rigid body), times the mass
    expected = m * (v * om + omdot * dx - om * om * dy)
    assert lateral_demand(q_d, qd_d, (q_d, qd_d, qdd_d), params, settings) == pytest.approx(expected, rel=1e-12)
    # 2 cm to the right of the reference and sliding right at 0.1 m/s, on a straight reference: pushed left
    q_ref = np.array([0.0, 0.0, 0.0])
    qd_ref = np.array([0.8, 0.0, 0.0])
    q = np.array([0.0, -0.02, 0.0])
    qd = np.array([0.8, -0.1, 0.0])
    f = lateral_demand(q, qd, (q_ref, qd_ref, np.zeros(3)), params, settings)
    assert f == pytest.approx(m * (9.0 * 0.02 + 6.0 * 0.1), rel=1e-12)


def test_the_four_caster_trolley_is_held_through_the_first_turn():
    """Traj. 2's first turn (from 7.1 s): with the lateral hand force free the trolley slid out of it (0.5 m/s by
    7.7 s, lost at 7.9 s); held sideways it stays on the reference."""
    path = EXAMPLES / "four_caster_trolley.xml"
    config = PushConfig(trajectory=2, plant="mujoco", contact="fixed", cart_model=str(path), duration=8.6)
    setup = build_controller(config)
    plant = MujocoPlant(setup.controller.robots, setup.q0, path, noise=config.noise, seed=config.seed)
    result = replace(run_loop(config, setup.controller, plant), plant_report=plant_report(plant))
    assert setup.controller.slip.sliding  # it slid before the turn (0.07 m/s at 4 s)
    assert result.metrics.tracking_lost_at_s is None
    assert result.metrics.tracking_max_mm < 60.0
    assert float(np.abs(cart_lateral_speed(result)).max()) < 0.15

"""A base plan that meets the wheel limits only at a slower reference: the window's rate caps the reference clock.

`BasePlan.rate_cap` against the closed form of slowing at a constant path deceleration, the clock's rate held
under the cap (`ReferenceClock.cap`), and `plan_base` on a turn its rigid place cannot follow at the desired speed:
the plan's rim speeds, from its poses by finite differences at the window's rate, within the wheel limit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import robots
from cart.trajectories import Turn, UnicycleTrajectory
from wholebody.push.base_plan import BasePlan, plan_base
from wholebody.contacts.handle import HandleSegment
from wholebody.push.base_settings import BasePlanSettings
from wholebody.push.geometry import CartGeometry
from wholebody.push.reference_clock import ReferenceClock, TimeScaling
from wholebody.push.robot import make_robots


def _plan(windows: list[tuple[float, float, float]]) -> BasePlan:
    """Return a plan whose windows span (t0, t1) at rate r, with nothing else in them."""
    times = tuple(np.linspace(t0, t1, 5) for t0, t1, _ in windows)
    zeros = tuple(np.zeros((5, 3)) for _ in windows)
    return BasePlan(times, zeros, zeros, tuple(0.7 for _ in windows), 0.7, tuple(r for *_, r in windows))


def test_the_cap_is_the_rate_from_which_the_reference_slows_to_the_window_in_time():
    plan = _plan([(10.0, 13.0, 0.45), (20.0, 23.0, 1.0)])
    decel = 0.2
    assert plan.rate_cap(0.0, decel) == 1.0  # sqrt(0.45^2 + 2 0.2 10) > 1
    # slowing from r at r_dot = -decel to 0.45 covers (r^2 - 0.45^2) / (2 decel) of reference time
    for ahead in (0.1, 0.5, 1.0, 1.9):  # from 1.99 s ahead the cap is 1
        r = plan.rate_cap(10.0 - ahead, decel)
        assert (r * r - 0.45**2) / (2.0 * decel) == pytest.approx(ahead)
    assert plan.rate_cap(11.0, decel) == 0.45 == plan.rate_cap(13.0, decel)
    assert plan.rate_cap(13.5, decel) == 1.0  # past the window; the next one is planned at the desired speed
    assert plan.rate_cap(9.0, math.inf) == 1.0  # a path at rest can stop at once


def test_the_clock_keeps_below_its_cap_and_returns_to_one_after_it():
    clock = ReferenceClock(TimeScaling())
    clock.cap = 0.45
    for _ in range(300):
        clock.advance(0.0, 0.01, 0.8, 10.0)
    assert clock.rate == pytest.approx(0.45, abs=1e-3) and clock.delay > 1.0
    clock.cap = 1.0
    for _ in range(1000):
        clock.advance(0.0, 0.01, 0.8, 10.0)
    assert clock.rate == 1.0


#: Traj. 2's first turn (pi/2 over 3 s at 0.8 m/s from t = 7 s), the motion held after 13 s
FIRST_TURN = UnicycleTrajectory(duration=13.0, stop_start=13.0, turns=(Turn(7.0, 3.0, math.pi / 2),))
#: a long cart's push bar 1.1 m behind its axle ({b}), 0.75 m above it: through the turn the base behind it sweeps
#: a circle 1.1 m wider than behind the default cart's handle
LONG_CART = CartGeometry(HandleSegment((-1.1, -0.22, 0.75), (-1.1, 0.22, 0.75)), frame_height=0.1)
SETTINGS = BasePlanSettings(step=0.2, lead=1.0, tail=2.0)


def test_a_turn_the_base_cannot_follow_at_speed_is_planned_slower_within_the_wheel_limits():
    mm = make_robots(robots.load("ridgeback_iiwa"), np.zeros(3), [0.0], geometry=LONG_CART)[0]
    plan = plan_base(mm, FIRST_TURN, 0.0, SETTINGS)
    assert len(plan.rates) == len(plan.times) >= 1 and min(plan.rates) < 1.0
    for ts, rel, rate in zip(plan.times, plan.relative, plan.rates):
        cart = np.array([FIRST_TURN.sample(float(t))[0] for t in ts])
        cart[:, 2] = np.unwrap(cart[:, 2])
        c, s = np.cos(cart[:, 2]), np.sin(cart[:, 2])
        base = np.c_[cart[:, 0] + c * rel[:, 0] - s * rel[:, 1], cart[:, 1] + s * rel[:, 0] + c * rel[:, 1]]
        poses = np.c_[base, cart[:, 2] + rel[:, 2]]
        d = np.diff(poses, axis=0) * rate / SETTINGS.step  # per second of the run at the window's rate
        th = 0.5 * (poses[1:, 2] + poses[:-1, 2])
        vx, vy = np.cos(th) * d[:, 0] + np.sin(th) * d[:, 1], -np.sin(th) * d[:, 0] + np.cos(th) * d[:, 1]
        span = float(abs(mm.wb.base.twist_to_wheels()[0, 2]) * mm.wb.base.wheel_radius)
        rim = np.abs(vx) + np.abs(vy) + span * np.abs(d[:, 2])
        assert rim.max() <= mm.wb.base.wheel_radius * float(np.min(mm.wb.wheel_velocity_limit)) * (1 + 1e-3) + 1e-6

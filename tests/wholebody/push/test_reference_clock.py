"""The reference's time scaling: a saturating push slows its reference down instead of losing the cart."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from cart.params import CartParams
from cart.trajectories import trajectory_1
from wholebody.contacts.allocation import ArmLimits
from wholebody.push import PushConfig, build_controller, run_push
from wholebody.push.config import PUSH_ARM_LIMITS
from cart.trajectories import trajectory_2
from wholebody.push.config import TRUE_CART
from wholebody.push.reference_clock import (
    RATE_SNAP,
    ReferenceClock,
    ScaledReference,
    TimeScaling,
    admissible_rate,
    deficit,
    error_rate_cap,
    footprint_params,
    needs_look_ahead,
    path_braking,
    planned_wrench,
    sample_rate,
)
from wholebody.push.report import what_happened


def test_without_a_deficit_the_reference_time_is_the_run_time_exactly():
    clock = ReferenceClock(TimeScaling())
    ref = ScaledReference(trajectory_1(10.0), clock)
    for k in range(300):
        t = 0.01 * k
        assert clock.time(t) == t
        for a, b in zip(ref.sample(t), trajectory_1(10.0).sample(t)):
            assert np.array_equal(a, b)
        clock.advance(deficit(np.array([50.0, 2.0]), np.array([50.0, 2.0])), 0.01, 0.8, 5.0)
    assert clock.rate == 1.0 and clock.delay == 0.0


def test_a_deficit_slows_the_reference_within_the_brake_bound_and_it_recovers():
    settings = TimeScaling()
    clock = ReferenceClock(settings)
    dt, speed, accel = 0.01, 0.8, 0.4
    braked = ReferenceClock(settings)
    rates = []
    for _ in range(100):  # half the demand cannot be given for 1 s
        clock.advance(0.5, dt, speed, 10 * accel)
        braked.advance(0.5, dt, speed, accel)
        rates.append(braked.rate)
    assert settings.rate_min <= clock.rate < 0.5
    # the slowing is the reference's deceleration along the path: within brake_share of what the force gives
    bound = settings.brake_share * accel / speed
    assert np.diff(np.r_[1.0, rates]) / dt == pytest.approx(np.full(100, -bound))
    assert clock.delay > 0.3
    for _ in range(1000):  # then the whole wrench: back to the desired speed, the delay kept
        clock.advance(0.0, dt, speed, accel)
    delay = clock.delay
    assert clock.rate == 1.0 and clock.rate_dot == 0.0
    assert clock.time(20.0) == pytest.approx(20.0 - delay)
    s = clock.time(20.0)
    q, qd, qdd = ScaledReference(trajectory_1(30.0), clock).sample(s)
    assert np.array_equal(qd, trajectory_1(30.0).sample(s)[1])


def test_a_missing_push_counts_a_missing_brake_on_a_braking_path_holds_the_rate():
    assert deficit(np.array([40.0, 1.0]), np.array([30.0, 1.0])) == pytest.approx(0.25, rel=1e-3)
    # the desired motion brakes and the arms could not brake as hard: hold (slowing asks more braking)
    assert np.isnan(deficit(np.array([-40.0, 1.0]), np.array([-30.0, 1.0]), path_braking=True))
    assert deficit(np.array([-40.0, 1.0]), np.array([-30.0, 1.0])) == pytest.approx(0.25, rel=1e-3)
    # a push given in full or more while the torque is missing: slow down (a turn the arms cannot make)
    assert deficit(np.array([6.8, 12.9]), np.array([9.1, 11.3])) == pytest.approx(0.19, abs=0.01)
    clock = ReferenceClock(TimeScaling(), rate=0.5)
    clock.advance(float("nan"), 0.01, 0.8, 5.0)
    assert clock.rate == 0.5 and clock.rate_dot == 0.0 and clock.delay == pytest.approx(0.005)


def test_a_turn_at_constant_speed_is_not_braking_but_the_stop_is():
    """Traj. 2's turns keep 0.8 m/s: q_d' . q_d'' is rounding there (1e-17 of either sign), which must not read as
    braking (the rate would be held on every other period of a turn the arms cannot make); its final stop brakes."""
    traj = trajectory_2(30.0)
    turns = [traj.sample(float(s)) for s in np.arange(7.05, 10.0, 0.01)]
    dots = [float(qd[:2] @ qdd[:2]) for _, qd, qdd in turns]
    assert min(dots) < 0.0 < max(dots) and max(abs(v) for v in dots) < 1e-12  # noise of both signs
    assert not any(path_braking(qd, qdd) for _, qd, qdd in turns)
    speeds = [np.hypot(*traj.sample(float(s))[1][:2]) for s in np.arange(0.0, 30.0, 0.01)]
    slowing = [k for k in range(1, len(speeds)) if speeds[k - 1] - speeds[k] > 1e-4 and speeds[k] > 0.1]
    _, qd, qdd = traj.sample(0.01 * slowing[-1])  # in the final stop, still moving
    assert path_braking(qd, qdd)


def test_the_scaled_reference_is_the_time_derivative_of_the_slowed_path():
    clock = ReferenceClock(TimeScaling())
    traj = trajectory_1(30.0)
    ref = ScaledReference(traj, clock)
    clock.rate, clock.rate_dot = 0.6, -0.3
    s, h = 2.3, 1e-5
    q, qd, qdd = ref.sample(s)
    r = clock.rate
    # d/dt q(s(t)) = q'(s) r;  d/dt (q'(s) r) = q''(s) r^2 + q'(s) r_dot
    fd = (traj.sample(s + h * r)[0] - traj.sample(s - h * r)[0]) / (2 * h)
    assert qd == pytest.approx(fd, abs=1e-6)
    v1 = traj.sample(s + h * r)[1] * (r + h * clock.rate_dot)
    v0 = traj.sample(s - h * r)[1] * (r - h * clock.rate_dot)
    assert qdd == pytest.approx((v1 - v0) / (2 * h), abs=1e-4)


def test_a_saturating_push_slows_its_reference_instead_of_losing_the_cart():
    # one hand that pushes at most 5 N: Traj. 1's 0.4 m/s^2 ramp asks 8 N of the 20 kg cart
    weak = ArmLimits(max_force=5.0, grasp=PUSH_ARM_LIMITS.grasp)
    config = PushConfig(trajectory=1, duration=6.0, arm_limits=weak)
    assert config.scaling_settings() is None  # the kinematic plant's default: the desired timing
    lost = run_push(config).metrics
    assert lost.tracking_lost_at_s is not None and lost.reference_time_scale_min == 1.0
    # the look-ahead slows the reference before the ramp: the allocation never leaves a share out
    ahead = run_push(replace(config, time_scaling=TimeScaling(horizon=4.0))).metrics
    assert ahead.tracking_lost_at_s is None and ahead.saturated_steps == 0 and ahead.reference_time_scale_min < 0.9
    # the reaction alone (5 N stops the cart in more than stop_distance: it would be looked ahead by default)
    result = run_push(replace(config, time_scaling=TimeScaling(horizon=0.0, momentum_horizon=0.0)))
    m = result.metrics
    assert m.tracking_lost_at_s is None and m.tracking_rms_mm < 20.0
    assert m.saturated_steps > 0 and m.reference_time_scale_min < 0.9 and m.reference_delay_s > 0.5
    assert result.reference_time is not None and result.reference_time[-1] == pytest.approx(6.0 - m.reference_delay_s)
    # the tracking is against the slowed reference: q_desired is the desired motion at the reference time
    assert np.allclose(result.q_desired, [trajectory_1(6.0).sample(s)[0] for s in result.reference_time])
    lines = what_happened(result)
    # not lost, but 1.3 s behind at 6 s: the verdict says how far along the trajectory the cart got
    reached = f"reached only the trajectory's t = {result.reference_time[-1]:.1f} s of {result.t[-1]:.1f} s"
    assert lines[0].startswith("tracked the slowed reference:") and reached in lines[0]
    assert any(line.startswith("saturation: reference slowed to") for line in lines)
    # a run lost later: the sentence says what the reference did before the loss
    first = float(result.t[int(np.argmax(result.reference_rate < 1.0))])
    lost = replace(result, metrics=replace(m, tracking_lost_at_s=first + 0.5))
    said = [line for line in what_happened(lost) if line.startswith("saturation: reference slowed before the loss")]
    assert len(said) == 1 and "slower for 0.50 s in all" in said[0]
    never = replace(result, metrics=replace(m, tracking_lost_at_s=first))
    assert not any("reference slowed" in line for line in what_happened(never))


def test_the_look_ahead_slows_before_the_turn_to_a_rate_whose_torque_the_arms_give_at_its_peak():
    settings = TimeScaling(horizon=4.0, feedback_share=0.0)
    traj = trajectory_2(30.0)
    peak = 7.9  # s: Traj. 2's first turn's largest torque (yaw acceleration and v omega together)
    full = abs(planned_wrench(traj, peak, 1.0, settings, TRUE_CART)[2])
    half = abs(planned_wrench(traj, peak, 0.5, settings, TRUE_CART)[2])
    assert 0.0 < half < 0.5 * full  # the turn's torque falls at least as fast as the rate
    limit = 0.2 * full  # arms that give a fifth of the full-speed turn's torque

    def arms(row):
        return abs(row[2]) <= limit

    at_peak = sample_rate(traj, peak, settings, TRUE_CART, arms)
    assert at_peak < 1.0 and at_peak in settings.rate_grid
    assert all(
        abs(planned_wrench(traj, peak, r, settings, TRUE_CART)[2]) > limit for r in settings.rate_grid if r > at_peak
    )
    # on the straight before it the arms give the full speed; from 2 s of reference time ahead of the peak the rate
    # now is the one the reference can slow from, at `decel`, to the peak's: sqrt(r_k^2 + 2 decel h), at most 1
    decel = 0.1
    assert sample_rate(traj, 5.0, settings, TRUE_CART, arms) == 1.0
    now = admissible_rate(traj, peak - 2.0, settings, TRUE_CART, arms, decel)
    assert at_peak < now <= math.sqrt(at_peak**2 + 2.0 * decel * 2.0) + 1e-9
    assert now < 1.0
    # far from the turn (the horizon does not reach it) and with an unbounded deceleration: no slowing now
    assert admissible_rate(traj, 2.0, settings, TRUE_CART, arms, decel) == 1.0
    assert admissible_rate(traj, peak - 2.0, settings, TRUE_CART, arms, math.inf) == 1.0
    assert admissible_rate(traj, peak, settings, TRUE_CART, lambda row: False, decel) == settings.rate_min


def test_the_look_ahead_judges_a_turn_with_at_least_the_inertia_of_the_mass_spread_over_the_wheels():
    bed = CartParams(250.0, 0.3, 0.0, 250.0 * 0.2)  # a prior scaled from a small cart: CoM 0.3 m, j/m 0.2 m^2
    wheels = np.array([[0.0, 0.4], [0.0, -0.4], [1.74, 0.4], [1.74, -0.4]])
    spread = footprint_params(bed, wheels)
    plate = 250.0 * ((1.74**2 + 0.8**2) / 12.0 + 0.87**2)  # a uniform 1.74 m x 0.8 m plate about {b}
    assert spread.m == bed.m and spread.dx == pytest.approx(0.87) and spread.dy == 0.0
    assert spread.inertia_b == pytest.approx(plate)
    # an estimate already larger than the spread mass is kept
    heavy = CartParams(250.0, 0.9, 0.05, 400.0)
    kept = footprint_params(heavy, wheels)
    assert (kept.dx, kept.dy, kept.I) == (heavy.dx, heavy.dy, heavy.I)


def test_a_reference_slowed_by_less_than_half_a_percent_is_not_called_saturation():
    result = run_push(PushConfig(trajectory=1, duration=1.0))
    rate = np.ones_like(result.t)
    rate[len(rate) // 2] = 0.999
    barely = replace(result, reference_rate=rate, reference_time=result.t.copy())
    assert not any("reference slowed" in line for line in what_happened(barely))
    rate[len(rate) // 2] = 0.9
    slowed = replace(result, reference_rate=rate, reference_time=result.t.copy())
    assert any(line.startswith("saturation: reference slowed to 90 %") for line in what_happened(slowed))


def test_a_rate_that_alternates_between_slowing_and_recovering_gives_a_steady_path_acceleration():
    # at the edge of what the arms can give: a period saturates (the rate slows), the next is given in full (it
    # recovers), and so on; from the first reversal on, the path acceleration r_dot is the mean of the last two
    # periods' rate changes
    dt = 0.01
    clock = ReferenceClock(TimeScaling(), rate=0.7)
    rates, rate_dots = [clock.rate], []
    for k in range(20):
        clock.advance(0.2 if k % 2 == 0 else 0.0, dt, 0.5, 10.0)
        rates.append(clock.rate)
        rate_dots.append(clock.rate_dot)
    steps = np.diff(rates) / dt
    assert rate_dots[0] == pytest.approx(steps[0])  # the first slowing is the period's own
    assert np.allclose(rate_dots[1:], 0.5 * (steps[1:] + steps[:-1]), rtol=0, atol=1e-12)
    # each period's own change alternates by about 0.6 /s; their two-period mean by less than a tenth of that
    assert np.abs(np.diff(steps[5:])).min() > 0.5
    assert np.abs(np.diff(rate_dots[5:])).max() < 0.1 * np.abs(np.diff(steps[5:])).min()


def test_a_rate_that_slows_steadily_or_returns_to_one_keeps_each_periods_change():
    dt = 0.01
    clock = ReferenceClock(TimeScaling(), rate=0.99)
    for _ in range(3):  # slowing, period after period
        before = clock.rate
        clock.advance(0.3, dt, 0.5, 10.0)
        assert clock.rate_dot == pytest.approx((clock.rate - before) / dt)
    clock.rate = 1.0 - 0.5 * RATE_SNAP
    clock.advance(0.0, dt, 0.5, 10.0)  # given in full: back to 1 within the period, a reversal that is not averaged
    assert clock.rate == 1.0 and clock.rate_dot == pytest.approx(0.5 * RATE_SNAP / dt)


class _Sigma:
    """An estimator stand-in that reports a given 1-sigma (`params_std`)."""

    def __init__(self, mass: float, com: tuple[float, float]) -> None:
        self.std = {"mass": mass, "com": list(com)}

    def params_std(self) -> dict:
        return self.std


def test_the_tip_over_margin_takes_at_most_a_quarter_of_the_mass_and_of_the_footprints_half_size():
    from wholebody.push.controller import TIP_MARGIN_SHARE
    from wholebody.push.loop import build_controller

    config = PushConfig(plant="mujoco", contact="fixed", duration=8.0, base_plan=None, tip_bound=True)
    ctrl = build_controller(config).controller
    assert ctrl.support is not None
    pts = np.asarray(ctrl.support.points)
    half = 0.5 * (pts.max(axis=0) - pts.min(axis=0))
    params, factor = TRUE_CART, config.tip_std_factor
    q, qd, gamma = np.zeros(3), np.array([0.5, 0.0, 0.0]), np.array([10.0, 0.0, 0.0])
    # a misfit-inflated 1-sigma (the bed's: 116 kg on 206, CoM +- 2.5 m): the margin is capped
    ctrl.estimator = _Sigma(0.6 * params.m, (2.5, 0.2))
    load = ctrl._cart_load(q, qd, gamma, params)
    assert factor * load.mass_std == pytest.approx(TIP_MARGIN_SHARE * params.m)
    assert factor * np.asarray(load.com_std) == pytest.approx(TIP_MARGIN_SHARE * half)
    assert TIP_MARGIN_SHARE * params.m < factor * 0.6 * params.m
    # a small one (the WMRA's CoM +- 0.015 m) is kept as it is
    ctrl.estimator = _Sigma(0.4, (0.01, 0.015))
    load = ctrl._cart_load(q, qd, gamma, params)
    assert load.mass_std == 0.4 and tuple(load.com_std) == (0.01, 0.015)


def test_the_tracking_error_caps_the_rate_geometrically_over_its_band():
    settings = TimeScaling(error_band=(0.04, 0.14), error_rate_min=0.01)
    assert error_rate_cap(0.0, settings) == 1.0 and error_rate_cap(0.04, settings) == 1.0
    assert error_rate_cap(0.09, settings) == pytest.approx(0.1, rel=1e-12)  # halfway: sqrt(1 x 0.01)
    assert error_rate_cap(0.14, settings) == pytest.approx(0.01)
    assert error_rate_cap(1.0, settings) == pytest.approx(0.01)
    caps = [error_rate_cap(e, settings) for e in np.linspace(0.0, 0.2, 41)]
    assert np.all(np.diff(caps) <= 0.0)


def test_a_cart_falling_behind_slows_its_reference_below_the_deficit_floor_and_back():
    """A deficit alone stops at rate_min; a cart that keeps falling behind (a turn it cannot yaw through at that
    speed) takes the rate down to error_rate_min, and once back on the path the reference returns to 1. A cart
    whose rate never reached rate_min is not slowed by its error."""
    settings = TimeScaling()
    alone, behind, given = ReferenceClock(settings), ReferenceClock(settings), ReferenceClock(settings)
    for _ in range(1000):
        alone.advance(0.9, 0.01, 0.8, 5.0)
        behind.advance(0.9, 0.01, 0.8, 5.0, error=0.2)
        given.advance(0.0, 0.01, 0.8, 5.0, error=0.2)
    assert alone.rate == pytest.approx(settings.rate_min)
    assert behind.rate == pytest.approx(settings.error_rate_min)
    assert given.rate == 1.0
    # the rate approaches its target asymptotically: within floor_share above rate_min it counts as there
    near, above = ReferenceClock(settings, rate=0.12), ReferenceClock(settings, rate=0.2)
    near.advance(0.1, 0.01, 0.8, 5.0, error=0.2)
    above.advance(0.1, 0.01, 0.8, 5.0, error=0.2)
    assert near.floored and not above.floored
    for _ in range(1000):
        near.advance(0.1, 0.01, 0.8, 5.0, error=0.2)
    assert near.rate == pytest.approx(settings.error_rate_min)
    for _ in range(1500):
        behind.advance(0.0, 0.01, 0.8, 5.0, error=0.01)
    assert behind.rate == 1.0


def test_a_cart_that_stops_beyond_the_stop_distance_is_looked_ahead():
    settings = TimeScaling(stop_distance=0.25)
    # m v^2 / (2 F): the hospital bed (245 kg) at 0.8 m/s under one hand's 150 N stops in 0.52 m; the shopping cart
    # (20.7 kg) in 0.044 m
    assert needs_look_ahead(245.0, 0.8, 150.0, settings)
    assert not needs_look_ahead(20.7, 0.8, 150.0, settings)
    assert not needs_look_ahead(245.0, 0.8, 0.0, settings)
    edge = 2.0 * 150.0 * 0.25 / 0.8**2  # the mass that stops in exactly 0.25 m
    assert not needs_look_ahead(edge * (1 - 1e-9), 0.8, 150.0, settings)
    assert needs_look_ahead(edge * (1 + 1e-9), 0.8, 150.0, settings)


def test_the_controller_looks_ahead_for_a_heavy_cart_only():
    """Without --look-ahead the controller looks ahead (`TimeScaling.momentum_horizon`) while the estimated cart
    would stop beyond `stop_distance` at the path's speed ahead: the hospital bed's mass, not the shopping cart's."""
    config = PushConfig(plant="mujoco", contact="fixed", trajectory=2)
    controller = build_controller(config).controller
    clock = controller.clock
    assert clock is not None
    settings = clock.settings
    assert settings.horizon == 0.0
    heavy, light = CartParams(245.0, 0.8, 0.0, 100.0, 10.0), CartParams(20.7, 0.4, 0.0, 1.5, 3.0)
    ahead = controller._look_ahead_settings(5.0, heavy)
    assert ahead is not None and ahead.horizon == settings.momentum_horizon
    assert controller._look_ahead_settings(5.0, light) is None
    clock.settings = replace(settings, momentum_horizon=0.0)  # off
    assert controller._look_ahead_settings(5.0, heavy) is None
    clock.settings = settings
    controller._look_ahead(5.0, heavy)
    assert clock.checked_at == 5.0  # it checked


def test_a_reference_slowed_in_the_turns_while_the_grip_twists_at_its_limit_says_the_turns_are_why():
    from wholebody.push.report import what_happened

    result = run_push(PushConfig(trajectory=2, duration=1.0))
    n = len(result.t)
    rate = np.ones(n)
    rate[n // 4 : n // 2] = 0.3
    sat = {"arm0 grip torque limit (tau_z)": {"first_s": 0.2, "total_s": 0.4}}
    bound = replace(result.metrics, saturation=sat)

    def slowed_line(s0: float, metrics) -> str:  # the reference time runs from s0 (Traj. 2 turns from 7.2 s)
        r = replace(result, reference_rate=rate, reference_time=s0 + result.t, metrics=metrics)
        return next(line for line in what_happened(r) if line.startswith("saturation: reference slowed"))

    assert "100 % of the slowing came in the turns, where the grips' yaw torque bound" in slowed_line(8.0, bound)
    assert "turns" not in slowed_line(2.0, bound)  # slowed on the straight before the first turn
    assert "turns" not in slowed_line(8.0, result.metrics)  # in a turn, but no grip twisted at its limit

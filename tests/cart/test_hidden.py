"""Test bed (studies.testbeds.hidden_effects): the swivelling casters against closed-form kinematics and force balances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cart.errors import ParameterError
from studies.testbeds.hidden_effects import (
    HiddenEffect,
    Motion,
    SwivelCasters,
    random_case,
    random_cart,
    simulate_hidden,
)
from cart.params import CartParams


def _straight(t, v):
    """Return a Motion at constant forward speed v(t) (array), no turning."""
    return Motion(t=t, v=v, vdot=np.gradient(v, t), omega=np.zeros_like(t), omegadot=np.zeros_like(t))


def test_caster_swing_follows_the_closed_form_on_a_straight_line():
    # straight motion backwards (axle velocity (v, 0), v < 0): alpha' = -(v / e) sin(alpha) ... the wheel leads
    # and tan(alpha / 2) grows as exp(s / e) with s the distance travelled (closed form of the swivel ODE)
    p = CartParams(m=30.0, dx=0.3, dy=0.0, I=2.5)
    c = SwivelCasters({"trail": 0.04, "torque": 0.0, "x": 0.8, "half_track": 0.25, "roughness": 0.0}, p)
    alpha = np.array([0.05, -0.02])
    v, h = -0.3, 1e-4
    for _ in range(int(0.2 / h)):  # 6 cm of travel
        alpha = alpha + h * c.rates(v, 0.0, alpha)
    s = 0.2 * abs(v)
    expected = 2.0 * np.arctan(np.tan(np.array([0.05, -0.02]) / 2.0) * math.exp(s / 0.04))
    np.testing.assert_allclose(alpha, expected, rtol=1e-3)


def test_caster_force_balance_and_yaw_torque():
    # massless fork: the floor's side force on the wheel is -T / e along n, applied at the axle, plus the bearing T
    p = CartParams(m=30.0, dx=0.3, dy=0.0, I=2.5)
    c = SwivelCasters({"trail": 0.05, "torque": 0.4, "damping": 0.0, "eps": 0.5, "x": 0.9, "half_track": 0.2}, p)
    alphas = np.array([1.0, 2.0])
    v, om = -0.4, 0.1
    e_f, e_l, e_t, rates = c.terms(v, om, alphas)
    ef = el = et = 0.0
    for (x, y), a, r in zip(c.pos, alphas, rates):
        tq = 0.4 * math.tanh(r / 0.5)
        f = -tq / 0.05 * np.array([-math.sin(a), math.cos(a)])
        ef, el, et = ef + f[0], el + f[1], et + x * f[1] - y * f[0] + tq
        # the kinematic rate: the contact point does not slide sideways
        vp = np.array([v - om * y, om * x])
        assert r == pytest.approx(vp @ np.array([-math.sin(a), math.cos(a)]) / 0.05 - om)
    assert (e_f, e_l, e_t) == pytest.approx((ef, el, et))


def test_swivel_casters_resist_after_a_reversal_and_stay_quiet_when_aligned():
    rng = np.random.default_rng(2)
    p = random_cart(rng)
    t = np.arange(0.0, 12.0, 0.002)
    v = np.where(t < 6.0, 0.4, -0.4) * np.clip(np.minimum(t, np.abs(t - 6.0)) / 1.0, 0.0, 1.0)
    eff = HiddenEffect("caster_swivel", {"trail": 0.04, "torque": 0.4, "x": p.dx + 0.4, "half_track": 0.25, "eps": 0.5})
    h = simulate_hidden(
        p,
        (eff,),
        duration=12.0,
        rate=100.0,
        jitter=0.0,
        position_noise=0.0,
        theta_noise=0.0,
        force_noise=0.0,
        torque_noise=0.0,
        motion=_straight(t, v),
        rng=rng,
    )
    th = h.true.q[:, 2]
    vt = np.cos(th) * h.true.qd[:, 0] + np.sin(th) * h.true.qd[:, 1]
    ef = h.effect_force[:, 0]
    cruise = (h.true.t > 3.0) & (h.true.t < 5.0)
    assert np.max(np.abs(ef[cruise])) < 0.05  # trailing casters: no force while cruising straight
    after = (h.true.t > 6.0) & (h.true.t < 11.0) & (np.abs(vt) > 0.02)
    assert np.max(ef[after] * -np.sign(vt[after])) > 0.5 * 2 * 0.4 / 0.04  # they swing round: >= half the peak
    assert np.all(ef[after] * vt[after] <= 1e-6)  # and the force opposes the motion


def test_random_case_overrides_change_only_what_they_name():
    base = random_case("caster_swivel", np.random.default_rng(5), caster_form="profile")
    slow = random_case(
        "caster_swivel", np.random.default_rng(5), caster_form="profile", rate=50.0, with_velocities=False
    )
    assert slow.effects == base.effects and slow.params == base.params
    assert slow.rate == 50.0 and slow.measured.qd is None
    assert np.median(np.diff(slow.measured.t)) > 1.5 * np.median(np.diff(base.measured.t)) or base.rate < 75
    big = random_case("coulomb_friction", np.random.default_rng(5), scale=1.6)
    ref = random_case("coulomb_friction", np.random.default_rng(5))
    assert big.effects[0].params["force"] == pytest.approx(1.6 * ref.effects[0].params["force"])
    with pytest.raises(ParameterError):
        random_case(None, np.random.default_rng(5), sampling_rate=10.0)


def test_both_caster_forms_are_drawn():
    forms = {("trail" in random_case("caster_swivel", np.random.default_rng(k)).effects[0].params) for k in range(12)}
    assert forms == {True, False}
    with pytest.raises(ParameterError):
        random_case("caster_swivel", np.random.default_rng(0), caster_form="wobbly")

"""``lateral_slip``'s sliding form (:mod:`cart.diagnose_slide`): wheels that hold up to a friction force, then slide.

A MuJoCo cart on a floor with sliding friction 0.04 (``mujoco_cart.random_case(seed, sliding_friction=0.04,
lateral_share=0.8)``) slides sideways tens of times the pose noise; the creep form of ``lateral_slip``
(sideways speed proportional to the lateral force) does not describe it (Delta BIC -3.7 on seed 60000), and
nothing was named.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cart.diagnose_slide import slide_speed


def _trapezoid_windows(t, w, edges):
    c = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))])
    return c[edges[1:]] - c[edges[:-1]]


def test_the_speed_carried_over_from_the_previous_window_is_exact_kinematics():
    # a sideways speed with a piecewise-constant acceleration: the trapezoid rule is exact on it
    t = np.linspace(0.0, 6.0, 601)
    accel = np.where(t < 2.5, 0.4, -0.3)
    w = 0.05 + np.concatenate([[0.0], np.cumsum(0.5 * (accel[1:] + accel[:-1]) * np.diff(t))])
    edges = np.arange(0, 601, 30)
    travel = _trapezoid_windows(t, w, edges)
    sig = SimpleNamespace(t=t, breaks=(), n=len(t))
    got = slide_speed(sig, edges, accel, np.zeros(len(t), bool), travel)
    # the first window starts from rest (nothing before it); every later one from the travel before it
    # (to the trapezoid rule's error where the acceleration jumps: dt^2 a / 8 = 4e-6 m/s a window)
    later = t >= t[edges[1]]
    assert np.max(np.abs(got[later] - w[later])) < 1e-4
    assert np.max(np.abs(got[:30] - (w[:30] - w[0]))) < 1e-12
    # held at a window's start: the wheels hold the cart, it starts from rest there
    held = np.zeros(len(t), bool)
    held[edges[5]] = True
    got = slide_speed(sig, edges, accel, held, travel)
    inside = (t >= t[edges[5]]) & (t < t[edges[6]])
    assert got[edges[5]] == 0.0 and np.allclose(got[inside], w[inside] - w[edges[5]])


def test_a_cart_sliding_on_a_slippery_floor_is_named_lateral_slip_in_the_sliding_form():
    mc = pytest.importorskip("studies.testbeds.mujoco_cart")
    pytest.importorskip("mujoco")
    from cart.diagnose import diagnose

    log, info = mc.simulate(mc.random_case(60000, duration=30.0, sliding_friction=0.04, lateral_share=0.8))
    rep = diagnose(log)
    assert rep.lateral_slip_ratio > 10.0
    assert rep.names[0] == "lateral_slip"
    slip = rep.effects[0]
    assert set(slip.parameters) >= {"friction", "slide_speed"}  # the sliding form, not the creep
    # the friction the wheels carry sideways: some of the weight times the floor's 0.04, never more
    weight = info["m"] * 9.81
    assert 0.0 < slip.parameters["friction"] < 0.04 * weight
    assert rep.gap_after < 0.5 * rep.gap_before

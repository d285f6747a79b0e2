"""A floor slope with a payload change: the slope's force is m(t) g, with the mass after the change.

The product of the slope and the mass step is bilinear in the fit's parameters; the fits take a
Gauss-Newton step about the iterate (``cart.diagnose._bilinear``), so the payload's step carries its
own weight on the slope and the slope is fitted with the mass of each sample.
"""

from __future__ import annotations

import math

import numpy as np

from cart.diagnose import diagnose, fit_model
from cart.effects import FloorSlope, PayloadChange
from cart.log_signals import signals_from_log, window_edges
from cart.params import CartParams
from studies.testbeds.hidden_effects import HiddenEffect, simulate_hidden

PARAMS = CartParams(m=25.3, dx=0.21, dy=0.04, I=2.28, sigma=2.06, sigma_yaw=2.06)
CHANGE = {"time": 17.4, "mass": 15.1, "x": 0.25, "y": 0.07, "inertia": 0.49}
SLOPE = {"angle": 0.0264, "direction": -3.06}


def _log(seed: int):
    effects = (HiddenEffect("payload_change", CHANGE), HiddenEffect("floor_slope", SLOPE))
    rng = np.random.default_rng(seed)
    return simulate_hidden(PARAMS, effects, duration=40.0, rate=100.0, jitter=0.1, rng=rng)


def test_the_joint_fit_of_slope_and_payload_converges_to_the_truth_on_a_noise_free_log():
    h = _log(71)
    sig = signals_from_log(h.true, half_window=0.05)
    edges = window_edges(sig.t, 0.1)
    sig.extras["noise_dv"] = (0.0, 0.0)
    fit = fit_model(sig, edges, [(FloorSlope(), ()), (PayloadChange(), (CHANGE["time"],))])
    slope_g = 9.81 * math.sin(SLOPE["angle"])
    # a fixed point with the mass before the change: slope 0.331 m/s^2 (28 % high), sigma 0.39, step 14.6 kg
    np.testing.assert_allclose(fit.x[0], PARAMS.m, rtol=0.01)
    np.testing.assert_allclose(fit.x[4], PARAMS.sigma, rtol=0.05)
    np.testing.assert_allclose(fit.thetas[1][0], CHANGE["mass"], rtol=0.02)
    np.testing.assert_allclose(np.hypot(*fit.thetas[0]), slope_g, rtol=0.02)


def test_a_slope_with_a_payload_change_names_both_and_closes_the_gap():
    rep = diagnose(_log(72).measured)
    assert {"floor_slope", "payload_change"} == set(rep.names), rep.names
    pay = next(e for e in rep.effects if e.name == "payload_change")
    assert abs(pay.parameters["delta_m"] - CHANGE["mass"]) < 3 * max(pay.uncertainties["delta_m"], 0.5)
    assert abs(pay.parameters["time"] - CHANGE["time"]) < 1.0
    # the slope's force with the mass before the change left 9.6 of the 48.4 mm
    assert rep.gap_after < 0.1 * rep.gap_before

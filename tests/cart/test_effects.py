"""Effect library and test bed: columns against independent computations (cart.model / cart.simulate)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cart import model
from cart.diagnose import diagnose, fit_model
from cart.effects import (
    CONTRACT_NAMES,
    Effect,
    FloorSlope,
    distance_since_reversal,
    measured_rows,
    nominal_columns,
    register_effect,
    registered_effects,
    unregister_effect,
)
from studies.testbeds.hidden_effects import HiddenEffect, payload_params, random_cart, simulate_hidden
from cart.log_signals import local_poly, signals_from_log, velocity_change_noise, window_edges
from cart.params import CartParams
from cart.simulate import simulate


def test_registry_holds_the_contract_names():
    assert [e.name for e in registered_effects()][:7] == list(CONTRACT_NAMES)


def test_local_poly_recovers_derivatives_of_a_quadratic_on_irregular_times():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.005, 0.015, 400))
    y = 1.0 + 2.0 * t - 0.7 * t**2
    val, d1, d2, _ = local_poly(t, y, 0.1)
    np.testing.assert_allclose(val[:, 0], y, atol=1e-9)
    np.testing.assert_allclose(d1[:, 0], 2.0 - 1.4 * t, atol=1e-7)
    np.testing.assert_allclose(d2[:, 0], -1.4, atol=1e-6)


def _controller(t, q, qd):
    """Push forward, pull back, turn: a generalized force in {s} from body-frame components."""
    f_fwd = 30.0 * math.sin(0.6 * t) + 5.0
    tau = 6.0 * math.sin(1.1 * t)
    return np.array([math.cos(q[2]) * f_fwd, math.sin(q[2]) * f_fwd, tau])


def test_nominal_rows_hold_on_the_exact_simulator():
    # cart.simulate (exact constrained dynamics, another implementation) must satisfy A x = y
    p = CartParams(m=30.0, dx=0.3, dy=-0.1, I=2.5, sigma=1.5)
    res = simulate(p, _controller, duration=12.0, dt=0.005)
    sig = signals_from_log(res.true, half_window=0.05)
    a = nominal_columns(sig)
    x = np.r_[p.phi, p.damping]
    pred = np.einsum("nrp,p->nr", a, x)
    y = measured_rows(sig)
    inner = slice(50, -50)
    scale = np.std(y[inner, :2], axis=0)
    err = np.std(pred[inner, :2] - y[inner, :2], axis=0)
    assert np.all(err < 0.02 * scale), (err, scale)
    assert np.max(np.abs(y[inner, 2])) < 1e-3  # no lateral slip of {b}


def test_floor_slope_fit_recovers_the_slope_of_the_exact_simulator():
    p = CartParams(m=25.0, dx=0.25, dy=0.08, I=2.0, sigma=1.0)
    gx, gy = 0.3, -0.2  # m/s^2 along the floor

    def slope(t, q, qd, params):
        # force m g at the CoM: generalized force through the planar grasp map (cart.model)
        c, s = math.cos(q[2]), math.sin(q[2])
        f_b = np.array([c * gx + s * gy, -s * gx + c * gy]) * params.m
        return model.contact_wrench_to_generalized(q, params.com, f_b)

    res = simulate(p, _controller, duration=20.0, dt=0.005, extra_force=slope)
    sig = signals_from_log(res.true, half_window=0.05)
    edges = window_edges(sig.t, 0.1)
    sig.extras["noise_dv"] = (0.0, 0.0)
    fit = fit_model(sig, edges, [(FloorSlope(), ())])
    np.testing.assert_allclose(fit.thetas[0], [gx, gy], atol=0.02)
    np.testing.assert_allclose(fit.x[:4], p.phi, rtol=0.05, atol=0.05)


def test_distance_since_reversal_counts_from_the_zero_crossing():
    t = np.linspace(0.0, 10.0, 1001)
    v = np.where(t < 5.0, 0.5, -0.5)  # reversal at t = 5
    q = np.column_stack([np.cumsum(v) * 0.01, np.zeros_like(t), np.zeros_like(t)])
    from cart.logs import CartLog

    sig = signals_from_log(CartLog(t=t, q=q, gamma=np.zeros((len(t), 3))), half_window=0.02)
    d = distance_since_reversal(sig)
    assert np.all(np.isinf(d[t < 4.9]))
    k = np.searchsorted(t, 7.0)
    assert d[k] == pytest.approx(1.0, abs=0.02)  # 2 s at 0.5 m/s after the crossing


def test_payload_params_add_phi_linearly():
    p = CartParams(m=20.0, dx=0.3, dy=0.05, I=1.5)
    q = payload_params(p, 10.0, 0.4, -0.1, inertia=0.2)
    expected = p.phi + np.array([10.0, 4.0, -1.0, 0.2 + 10.0 * (0.16 + 0.01)])
    np.testing.assert_allclose(q.phi, expected, rtol=1e-12)


def test_hidden_time_delay_and_bias_are_in_the_log_only():
    rng = np.random.default_rng(3)
    p = random_cart(rng)
    kw = dict(
        duration=8.0, rate=100.0, jitter=0.0, position_noise=0.0, theta_noise=0.0, force_noise=0.0, torque_noise=0.0
    )
    base = simulate_hidden(p, (), rng=np.random.default_rng(1), **kw)
    delayed = simulate_hidden(p, (HiddenEffect("time_delay", {"delay": 0.2}),), rng=np.random.default_rng(1), **kw)
    np.testing.assert_allclose(delayed.true.q, base.true.q, atol=1e-12)  # motion unchanged
    # the log at t shows what was applied at t - 0.2 (2 s of samples at 100 Hz = 20 samples back)
    diff = {k: np.abs(delayed.measured.gamma[k:] - base.true.gamma[:-k]) for k in (19, 20, 21)}
    assert np.median(diff[20]) < 1e-9
    assert np.mean(diff[20] < 1e-9) > 0.9
    assert np.median(diff[19]) > 1e-4 and np.median(diff[21]) > 1e-4
    biased = simulate_hidden(
        p, (HiddenEffect("wrench_bias", {"fx": 5.0, "fy": 0.0, "tau": 2.0}),), rng=np.random.default_rng(1), **kw
    )
    body = np.array(
        [model.generalized_to_body(q, g) for q, g in zip(biased.true.q, biased.measured.gamma - base.true.gamma)]
    )
    np.testing.assert_allclose(body, np.tile([5.0, 0.0, 2.0], (len(body), 1)), atol=1e-9)


def test_unknown_hidden_effect_is_rejected():
    from cart.errors import ParameterError

    with pytest.raises(ParameterError):
        HiddenEffect("gremlins", {})


def test_a_user_effect_can_be_registered_and_named():
    class HandleSpring(Effect):
        """A yaw spring towards heading 0: torque -k theta."""

        name = "yaw_spring"
        param_names = ("stiffness",)

        def columns(self, sig, nl, phi, base):
            g = np.zeros((sig.n, 3, 1))
            g[:, 1, 0] = sig.q[:, 2]  # E = -k theta  ->  G = +theta
            return g

    register_effect(HandleSpring)
    try:
        rng = np.random.default_rng(5)
        p = random_cart(rng)
        h = simulate_hidden(p, (), duration=25.0, rng=rng)
        # hide a yaw spring by adding its torque to the logged wrench (measured = applied + k theta)
        g = h.measured.gamma.copy()
        g[:, 2] += 8.0 * h.true.q[:, 2]
        from dataclasses import replace

        rep = diagnose(replace(h.measured, gamma=g))
        assert rep.names and rep.names[0] == "yaw_spring"
        assert rep.effects[0].parameters["stiffness"] == pytest.approx(8.0, rel=0.2)
    finally:
        unregister_effect("yaw_spring")
    assert "yaw_spring" not in [e.name for e in registered_effects()]


def test_velocity_change_noise_matches_the_full_pipeline_on_pure_noise():
    from cart.logs import CartLog
    from cart.log_signals import window_integrals

    rng = np.random.default_rng(2)
    t = np.cumsum(rng.uniform(0.007, 0.013, 1500))
    vals = []
    for k in range(6):
        q = rng.standard_normal((len(t), 3)) * np.array([0.003, 0.003, 0.005])
        sig = signals_from_log(CartLog(t=t, q=q, gamma=np.zeros((len(t), 3))))
        edges = window_edges(sig.t, 0.3)
        vals.append(window_integrals(sig.t, sig.vdot, edges))
    s2v, _ = velocity_change_noise(sig, edges, replicates=8)
    empirical = float(np.mean(np.concatenate(vals) ** 2))
    assert s2v == pytest.approx(empirical, rel=0.25)
    assert sig.sigma_pos == pytest.approx(0.003, rel=0.15)  # noise level recovered from the residuals


def _log_of(t, x, y, th):
    from cart.logs import CartLog

    return CartLog(t=t, q=np.column_stack([x, y, th]), gamma=np.zeros((len(t), 3)))


def test_caster_kinematics_match_the_test_bed_casters_and_the_columns_their_forces():
    # cart.effects steps the swivel exactly (half-angle form) along the log; studies.testbeds.hidden_effects.SwivelCasters integrates
    # the same ODE with small Euler steps: the natural lane must agree, and the columns per unit torque must be
    # the generalized force the test bed computes for those angles
    import cart.effects as fx
    from studies.testbeds.hidden_effects import SwivelCasters

    t = np.arange(0.0, 14.0, 0.01)
    v = 0.5 * np.sin(2 * np.pi * t / 14.0)  # forward, then backward: one reversal at t = 7
    om = 0.3 * np.sin(2 * np.pi * t / 5.0)  # turning throughout
    th = np.concatenate([[0.0], np.cumsum(0.5 * (om[1:] + om[:-1]) * np.diff(t))])
    xy = np.zeros((len(t), 2))
    for k in range(1, len(t)):
        a = 0.5 * (th[k] + th[k - 1])
        xy[k] = xy[k - 1] + 0.5 * (v[k] + v[k - 1]) * 0.01 * np.array([np.cos(a), np.sin(a)])
    sig = signals_from_log(_log_of(t, xy[:, 0], xy[:, 1], th), half_window=0.05)
    model = fx.SwivelCasterModel(0.8)
    e = model.TRAILS[8]
    lanes, i, j = model._lanes(sig, e)
    alpha = lanes.alpha0[:, i, j]  # the natural lane (N, 2 casters)
    # independent: fine Euler steps of SwivelCasters with the same speeds (the kinematic yaw rate of the model)
    omk = fx.kinematic_yaw_rate(sig)
    cas = SwivelCasters(
        {"trail": e, "torque": 1.0, "damping": 0.0, "eps": model.EPS[0], "x": 0.8, "half_track": fx.CASTER_HALF_TRACK},
        CartParams(m=30.0, dx=0.3, dy=0.0, I=2.0),
    )
    al = np.zeros(2)
    ref = np.empty((len(t), 2))
    for k in range(len(t)):
        ref[k] = al
        if k + 1 < len(t):
            for j in range(20):
                u = (j + 0.5) / 20
                vv = (1 - u) * sig.v[k] + u * sig.v[k + 1]
                ww = (1 - u) * omk[k] + u * omk[k + 1]
                al = al + 0.01 / 20 * cas.rates(vv, ww, al)
    d = np.angle(np.exp(1j * (alpha - ref)))
    assert np.percentile(np.abs(d), 95) < 0.05, np.percentile(np.abs(d), 95)
    assert np.max(np.abs(np.angle(np.exp(1j * alpha[t > 12])))) > 2.5  # swung round: trailing backwards
    # columns per unit sharp torque = -(generalized force of the test bed's casters with torque 1, eps 0.2)
    g = model.columns(sig, (e,), None, None)
    for k in range(0, len(t), 37):
        e_f, _, e_t, _ = cas.terms(sig.v[k], omk[k], alpha[k])
        assert g[k, 0, 0] == pytest.approx(-e_f, abs=1e-6 + 1e-6 * abs(e_f))
        assert g[k, 1, 0] == pytest.approx(-e_t, abs=1e-6 + 1e-6 * abs(e_t))


def test_a_push_against_a_held_cart_counts_as_a_reversal():
    from cart.effects import distance_since_reversal, travel_direction
    from cart.logs import CartLog

    t = np.arange(0.0, 12.0, 0.01)
    v = np.where(t < 4.0, 0.4, 0.0) * np.clip(4.0 - t, 0.0, 1.0)  # forward, stop at t = 4, then held still
    x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * 0.01)])
    f = np.where((t > 6.0) & (t < 9.0), -30.0, 0.0)  # a 30 N pull from 6 s to 9 s that does not move it
    log = CartLog(
        t=t,
        q=np.column_stack([x, np.zeros_like(t), np.zeros_like(t)]),
        gamma=np.column_stack([f, np.zeros_like(t), np.zeros_like(t)]),
    )
    sig = signals_from_log(log, half_window=0.05)
    d = travel_direction(sig)
    assert np.all(d[(t > 1.0) & (t < 2.5)] == 1) and np.all(d[(t > 4.5)] == -1)  # the rest run carries the pull
    s = distance_since_reversal(sig)
    assert np.all(np.isinf(s[t < 2.5])) and np.all(s[t > 4.5] < 1e-3)  # armed, no travel since


def test_local_mean_matches_a_loop():
    from cart.effects import local_mean

    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.005, 0.02, 300))
    y = rng.standard_normal((300, 2))
    got = local_mean(t, y, 0.05)
    for i in range(0, 300, 17):
        sel = np.abs(t - t[i]) <= 0.05 + 1e-12
        np.testing.assert_allclose(got[i], y[sel].mean(axis=0), rtol=1e-10)


def test_caster_lanes_streamed_in_chunks_equal_one_pass_and_keep_only_the_swings(monkeypatch):
    # the caster pass steps the log in chunks, the state carried over; a chunk of 64 samples must give what
    # one chunk gives, and the lanes kept on the swings must be the full lanes there (all kept when every
    # sample counts as a swing)
    import cart.caster_lanes as cl
    from cart.effects import CASTER_HALF_TRACK, SWING_MODES

    t = np.arange(0.0, 14.0, 0.01)
    v = 0.5 * np.sin(2 * np.pi * t / 14.0)  # one reversal at t = 7, straight: the casters reach leading
    om = np.full_like(t, 1e-4)
    args = (t, v, om, (0.5, 1.1), (0.02, 0.05), SWING_MODES, CASTER_HALF_TRACK)
    monkeypatch.setattr(cl, "CHUNK", len(t) + 1)
    one = cl.caster_lanes(*args)
    monkeypatch.setattr(cl, "SWING_SPLIT", -1.0)
    full = cl.caster_lanes(*args)
    monkeypatch.setattr(cl, "SWING_SPLIT", 0.02)
    monkeypatch.setattr(cl, "CHUNK", 64)
    lanes = cl.caster_lanes(*args)
    assert np.array_equal(lanes.alpha0, one.alpha0) and np.array_equal(lanes.rate0, one.rate0)
    assert lanes.swings == one.swings and any(lanes.swings.values())
    for key, ranges in lanes.swings.items():
        assert full.swings[key] == [(0, len(t))]
        for (i0, i1), a, r in zip(ranges, lanes.swing_alpha[key], lanes.swing_rate[key]):
            assert np.array_equal(a, full.swing_alpha[key][0][i0:i1])
            assert np.array_equal(r, full.swing_rate[key][0][i0:i1])
        assert np.array_equal(lanes.alpha0[:, key[0], key[1]], full.swing_alpha[key][0][:, :, 0])
    kept = lanes.alpha0.nbytes + sum(a.nbytes for v_ in lanes.swing_alpha.values() for a in v_)
    every = full.alpha0.nbytes + sum(a.nbytes for v_ in full.swing_alpha.values() for a in v_)
    assert kept < 0.5 * every  # the swings are a part of the log: most lanes are not kept


def test_the_caches_that_grow_with_the_log_are_bounded():
    from cart.log_signals import Signals, cache_bounded

    sig = Signals.__new__(Signals)
    object.__setattr__(sig, "extras", {})
    for k in range(50):
        cache_bounded(sig, "cols", ("cols", k), np.zeros(250), 10_000)  # 2000 bytes each
        cache_bounded(sig, "other", ("other", k), np.zeros(10), 10_000)
    cols = [k for k in sig.extras if isinstance(k, tuple) and k[0] == "cols"]
    assert sum(sig.extras[k].nbytes for k in cols) <= 10_000 and len(cols) == 5
    assert ("cols", 49) in sig.extras and ("cols", 0) not in sig.extras
    assert all(("other", k) in sig.extras for k in range(50))  # groups are bounded apart


def test_a_payload_steps_window_integrals_equal_those_of_the_stepped_columns():
    # the payload's columns are the nominal phi columns after the change time; their window integrals are taken
    # from the nominal window rows (only the window holding the change integrated again): the same sums as the
    # per-sample product, at change times on, between and beyond the samples
    from cart.effects import PayloadChange, nominal_columns, stepped_window_integrals
    from cart.log_signals import window_integrals
    from studies.testbeds.hidden_effects import random_case

    sig = signals_from_log(random_case(None, np.random.default_rng(5), duration=20.0).measured)
    edges = window_edges(sig.t, 0.3, sig.breaks)
    a_s = nominal_columns(sig)
    sig.extras["base"] = (a_s, window_integrals(sig.t, a_s, edges), None)
    assert stepped_window_integrals(sig, a_s, edges, 5.0) is None  # rows on other windows: not these
    sig.extras["base_edges"] = edges
    times = np.concatenate([[sig.t[0] - 1.0, sig.t[-1] + 1.0], sig.t[edges[3:-3:9]], sig.t[edges[5:-5:9]] + 1e-9])
    for tc in np.concatenate([times, np.linspace(sig.t[0], sig.t[-1], 41)]):
        want = window_integrals(sig.t, a_s[:, :, :4] * (sig.t >= tc)[:, None, None], edges)
        assert np.array_equal(stepped_window_integrals(sig, a_s, edges, float(tc)), want)
        assert np.array_equal(PayloadChange().window_columns(sig, (float(tc),), None, a_s, edges), want)
    assert stepped_window_integrals(sig, a_s.copy(), edges, 5.0) is None  # rows carrying another force


def test_swivel_caster_window_columns_equal_the_integrals_of_the_per_sample_columns():
    # SwivelCasterModel.window_columns takes the windows clear of a chosen swing from the natural lane's integrals
    # and integrates the others again; a swing's rows are its mode mixture on kept combination-major rows: the
    # same numbers as the per-sample columns integrated, and as the mixture computed from the lanes directly
    import cart.effects as fx
    from cart.log_signals import window_integrals
    from studies.testbeds.hidden_effects import random_case

    log = random_case("caster_swivel", np.random.default_rng(3), duration=30.0, caster_form="swivel").measured
    sig = signals_from_log(log)
    edges = window_edges(sig.t, 0.3, sig.breaks)
    a_s = fx.nominal_columns(sig)
    model = fx.SwivelCasterModel(0.8)
    phi = np.array([30.0, 6.0, 0.0, 12.0])
    chosen = 0
    for e in model.TRAILS[::4]:
        for theta in (None, np.array([1.0, 0.5, 0.1]), np.array([0.2, 2.0, -0.1])):
            model.offset(sig, (e,), phi, a_s, theta)  # None: the natural swings; else the swing modes weighed
            cols = model.columns(sig, (e,), None, a_s)
            got = model.window_columns(sig, (e,), None, a_s, edges)
            assert np.array_equal(got, window_integrals(sig.t, cols, edges))
            lanes, i, j = model._lanes(sig, e)
            choice = model._choice(sig, e)
            for k, rng_k in enumerate(lanes.swings[(i, j)]):
                if rng_k not in choice:
                    continue
                w = choice[rng_k]
                used = np.flatnonzero(w > 0.0)
                alpha, rate = lanes.swing_alpha[(i, j)][k], lanes.swing_rates(i, j, k)
                c1, c2 = model.COMBO_LANES[0][used], model.COMBO_LANES[1][used]
                al = np.stack([alpha[:, 0, c1], alpha[:, 1, c2]], axis=-1)
                ra = np.stack([rate[:, 0, c1], rate[:, 1, c2]], axis=-1)
                want = np.tensordot(w[used], model._unit_rows(al, ra, e), axes=(0, 1))
                assert np.array_equal(cols[rng_k[0] : rng_k[1], :2], want)
                chosen += 1
    assert chosen >= 8

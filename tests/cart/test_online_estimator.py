"""Tests of the online estimator (issue 27): unbiased under wrench noise, prior kept, load changes, run-off, input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cart.online_estimator import OnlineLSEstimator, make_online_estimator
from cart.online_regression import OnlineEstimatorError
from cart.params import CartParams
from cart.simulate import MeasurementNoise, ParameterChange, simulate

TRUTH = CartParams(20.0, 0.3, 0.15, 2.3, 4.0)
GUESS = CartParams(16.0, 0.3, 0.0, 1.85, 4.0)
MOCAP = MeasurementNoise(position=0.003, theta=0.003, velocity=0.01, omega=0.01)


def _wrench(turn: bool):
    """Open-loop wrench: forward pushes with stops (and, with ``turn``, yaw torques), as a function of time."""

    def ctrl(t, q, qd):
        f = 12.0 * math.sin(0.9 * t) + 6.0 * math.sin(2.3 * t) + 4.0
        tau = (3.0 * math.sin(1.3 * t) + 1.5 * math.sin(3.1 * t)) if turn else 0.0
        return np.array([f * math.cos(q[2]), f * math.sin(q[2]), tau])

    return ctrl


def _run(log, est: OnlineLSEstimator, seed: int = 1, force: float = 0.0, torque: float = 0.0) -> OnlineLSEstimator:
    """Feed a true log to the estimator with white wrench noise added (the log's motion capture as z)."""
    rng = np.random.default_rng(seed)
    z = np.hstack([log.q, log.qd])
    g = log.gamma + rng.standard_normal(log.gamma.shape) * np.array([force, force, torque])
    for k in range(1, len(log.t)):
        est.step(g[k - 1], log.t[k] - log.t[k - 1], z[k])
    return est


def _sim(duration: float, turn: bool, seed: int = 0, changes=(), truth=TRUTH):
    return simulate(
        truth, _wrench(turn), duration, noise=MOCAP, rng=np.random.default_rng(seed), changes=changes, substeps=2
    )


@pytest.fixture(scope="module")
def turning_log():
    return _sim(40.0, True).measured


def test_unbiased_under_wrench_noise(turning_log):
    """3 N / 0.3 N m of wrench noise: mass within 3 % and CoM within 3 cm, over several noise draws (no drift up)."""
    masses = []
    for seed in (1, 2, 3):
        est = _run(turning_log, make_online_estimator(turning_log.q[0], GUESS, MOCAP.measurement_std()), seed, 3.0, 0.3)
        p = est.params()
        masses.append(p.m)
        assert abs(p.dx - TRUTH.dx) < 0.03 and abs(p.dy - TRUTH.dy) < 0.03
        assert est.params_std()["mass"] > 0.0
    assert abs(np.mean(masses) - TRUTH.m) < 0.03 * TRUTH.m
    # the same noise fed to the wrench-as-input EKF pushes its mass up (errors in variables); ours stays put
    assert abs(np.mean(masses) - TRUTH.m) < 1.0


def test_straight_push_keeps_the_prior_on_dx():
    """A straight push (no turning) says nothing about dx and J: they keep the guess and the prior's std."""
    truth = CartParams(20.0, 0.45, 0.0, 2.3, 4.0)  # dy = 0 and no torque: the cart goes straight
    log = _sim(20.0, False, truth=truth).measured
    assert np.ptp(log.q[:, 2]) < 0.05
    est = _run(log, make_online_estimator(log.q[0], GUESS, MOCAP.measurement_std()), 1, 3.0, 0.3)
    p, std = est.params(), est.params_std()
    assert abs(p.dx - GUESS.dx) < 0.02  # the guess, not the truth (0.45): nothing says otherwise
    assert std["com"][0] == pytest.approx(0.2, rel=0.15)  # the prior's com_std
    assert "dx" in est.unexcited() and "mass" not in est.unexcited()
    assert abs(p.m - TRUTH.m) < 1.0  # the forward pushes do excite the mass


def test_load_change_detected_within_one_second():
    """A 10 kg load put in at 12 s during pushes and turns: detected within 1 s, the new mass within 5 %."""
    new = TRUTH.with_mass(30.0)
    sim = _sim(30.0, True, changes=[ParameterChange(12.0, new, conserve_momentum=False)])
    log = sim.measured
    est = _run(log, make_online_estimator(log.q[0], GUESS, MOCAP.measurement_std()), 1, 3.0, 0.3)
    assert len(est.events) == 1
    ev = est.events[0]
    assert 12.0 <= ev.t_detected <= 13.0
    assert abs(ev.t_change - 12.0) < 1.0
    assert ev.t_earliest is not None and ev.t_latest is not None
    assert ev.t_earliest <= ev.t_change <= ev.t_latest and ev.t_earliest - 1.0 < 12.0 < ev.t_latest + 1.0
    assert abs(ev.mass_after - 30.0) < 0.05 * 30.0
    assert abs(ev.mass_before - 20.0) < 1.5


def test_no_change_detected_without_one(turning_log):
    est = _run(turning_log, make_online_estimator(turning_log.q[0], GUESS, MOCAP.measurement_std()), 4, 3.0, 0.3)
    assert est.events == () and est.impulses == []


def test_a_guess_far_from_a_heavy_cart_is_no_impulse():
    """A 16 kg guess for a 90 kg cart pushed hard predicts 5x its speed changes: the impulse test allows for the
    estimate's own uncertainty, so it does not fire (it did, at 0.13 s, and the restart sent the mass to 220 kg)."""
    heavy = CartParams(90.0, 0.3, 0.1, 12.0, 4.0)

    def ctrl(t, q, qd):
        f = 250.0 if t < 1.0 else 120.0 * math.sin(0.9 * t) + 60.0  # a hard push from rest, then pushes and pulls
        return np.array([f * math.cos(q[2]), f * math.sin(q[2]), 8.0 * math.sin(1.3 * t)])

    log = simulate(heavy, ctrl, 8.0, noise=MOCAP, rng=np.random.default_rng(3), substeps=2).measured
    est = _run(log, make_online_estimator(log.q[0], GUESS, MOCAP.measurement_std()), 5, 3.0, 0.3)
    assert est.impulses == []
    assert abs(est.params().m - 90.0) < 9.0


def test_runoff_flagged_and_params_held():
    """A wrench that does not fit the cart (a large constant lateral torque offset) is flagged, never given as a CoM outside."""
    log = _sim(15.0, True).measured
    bad = log.gamma.copy()
    bad[:, 2] += 25.0
    est = make_online_estimator(log.q[0], GUESS, MOCAP.measurement_std(), footprint=(0.5, 0.5))
    z = np.hstack([log.q, log.qd])
    for k in range(1, len(log.t)):
        est.step(bad[k - 1], 0.01, z[k])
    kinds = {f.kind for f in est.flags}
    assert kinds & {"misfit", "com_outside_footprint", "nonpositive_inertia"}
    p = est.params()
    assert abs(p.dx) <= 0.5 and abs(p.dy) <= 0.5 and p.m > 0 and p.I > 0
    assert est.report()["runoff_flags"]


def test_protocol_conformance():
    est = make_online_estimator([1.0, 2.0, 0.3], GUESS, MOCAP.measurement_std())
    assert est.x.shape == (6,)
    np.testing.assert_allclose(est.x[:3], [1.0, 2.0, 0.3])
    nis = est.step([5.0, 0.0, 0.0], 0.01, [1.0, 2.0, 0.3, 0.01, 0.0, 0.0])
    assert isinstance(nis, float)
    assert isinstance(est.params(), CartParams)
    std = est.params_std()
    assert set(std) >= {"mass", "com"} and len(std["com"]) == 2
    from wholebody.push.config import ParameterEstimator  # noqa: F401  (the protocol it satisfies)

    for name in ("x", "step", "params"):
        assert hasattr(est, name)


@pytest.mark.parametrize(
    "gamma, dt, z",
    [
        ([1.0, 0.0], 0.01, [0.0] * 6),
        ([1.0, 0.0, 0.0], 0.01, [0.0] * 5),
        ([1.0, 0.0, 0.0], 0.0, [0.0] * 6),
        ([1.0, 0.0, 0.0], -0.01, [0.0] * 6),
        ([1.0, 0.0, 0.0], float("nan"), [0.0] * 6),
        ([float("nan"), 0.0, 0.0], 0.01, [0.0] * 6),
        ([1.0, 0.0, 0.0], 0.01, [0.0, float("inf"), 0, 0, 0, 0]),
    ],
)
def test_bad_input_raises(gamma, dt, z):
    est = make_online_estimator([0.0, 0.0, 0.0], GUESS, MOCAP.measurement_std())
    with pytest.raises(OnlineEstimatorError):
        est.step(gamma, dt, z)


def test_bad_construction_raises():
    with pytest.raises(OnlineEstimatorError):
        make_online_estimator([0.0, 0.0], GUESS, MOCAP.measurement_std())
    with pytest.raises(OnlineEstimatorError):
        make_online_estimator([0.0, 0.0, 0.0], GUESS, [0.1] * 5)
    with pytest.raises(OnlineEstimatorError):
        make_online_estimator([0.0, 0.0, 0.0], GUESS, MOCAP.measurement_std(), no_such_option=1)
    with pytest.raises(OnlineEstimatorError):
        make_online_estimator([0.0, 0.0, 0.0], GUESS, MOCAP.measurement_std(), cutoff_hz=-1.0)


def test_a_load_dropped_in_is_an_impulse_dated_and_learnt_at_once():
    """A 10 kg load picked up at rest at 12 s (the cart's velocity drops by 1/3, no wrench does it).

    The impulse is found in the period it happens, the filter restarts after it (filtered, the jump would read
    as a huge deceleration without force: a mass near zero), and the change is dated at the impulse.
    """
    new = TRUTH.with_mass(30.0)
    sim = _sim(30.0, True, changes=[ParameterChange(12.0, new, conserve_momentum=True)])
    log = sim.measured
    est = _run(log, make_online_estimator(log.q[0], GUESS, MOCAP.measurement_std()), 1, 3.0, 0.3)
    assert len(est.impulses) == 1 and abs(est.impulses[0] - 12.0) <= 0.02
    assert len(est.events) == 1
    ev = est.events[0]
    assert ev.t_change == est.impulses[0] and ev.t_detected <= 13.0
    assert ev.t_earliest == ev.t_latest == ev.t_change  # a velocity jump dates it to the period
    assert abs(ev.mass_after - 30.0) < 0.05 * 30.0
    assert abs(est.params().m - 30.0) < 1.0


def test_table1_test11_with_the_load_dropped_in_is_within_1kg_for_24s():
    """README: Table I test 11 with momentum exchange (load dropped in at 10 s): impulse at 10.00 s, >= 24 s within 1 kg."""
    from dataclasses import replace

    from cart.table1 import OnlineLoop, TESTS, contact_point, ekf_config, estimation_error_metrics, guess_params
    from cart.table1 import simulate_test

    test = replace(TESTS[10], momentum_exchange=True)
    std = MeasurementNoise.from_level(test.noise).measurement_std()

    def make_loop(ctrl, n):
        return OnlineLoop(ctrl, guess_params(test), ekf_config(test.noise), contact_point(test), n, meas_std=std)

    run, loop = simulate_test(test, make_loop)
    assert loop.ekf.impulses == [pytest.approx(10.0, abs=0.015)]
    assert run.events[0]["t_change"] == pytest.approx(10.0, abs=0.015)
    assert estimation_error_metrics(run)["time_mass_within_1kg_s"] >= 24.0


def test_a_guess_the_pushes_contradict_restarts_the_estimate_without_a_load_change():
    """A 300 kg cart from the 16 kg guess, standing for 1 s before the pushes: the first GLR detection has no
    mass information before its onset, and its mass lies 35 prior stds from the guess -- the guess was wrong, not
    the load. The estimate restarts from the pushes (flag ``guess_far``; it was 113 kg at 3 s, held back by
    the prior), and no load change is reported."""
    from cart.online_estimator import GUESS_FAR_SIGMA

    heavy = CartParams(300.0, 0.3, 0.05, 40.0, 20.0)

    def ctrl(t, q, qd):
        f = 0.0 if t < 1.0 else 150.0 * math.sin(0.8 * (t - 1.0)) + 60.0 * math.sin(2.1 * t) + 20.0
        return np.array([f * math.cos(q[2]), f * math.sin(q[2]), 10.0 * math.sin(1.1 * t)])

    log = simulate(heavy, ctrl, 3.0, noise=MOCAP, rng=np.random.default_rng(4), substeps=2).measured
    est = _run(log, make_online_estimator(log.q[0], GUESS, MOCAP.measurement_std()), 4, 3.0, 0.3)
    far = [f for f in est.flags if f.kind == "guess_far"]
    assert len(far) == 1 and est.events == (), est.flags
    pushes = float(far[0].detail.split("weigh the cart ")[1].split(" ")[0])  # the mass the pushes give, far out
    assert abs(pushes - GUESS.m) > GUESS_FAR_SIGMA * 0.5 * GUESS.m and abs(pushes - 300.0) < 30.0
    assert abs(est.params().m - 300.0) < 15.0


def test_a_guess_near_the_cart_never_restarts(turning_log):
    est = _run(turning_log, make_online_estimator(turning_log.q[0], GUESS, MOCAP.measurement_std()), 1, 3.0, 0.3)
    assert not [f for f in est.flags if f.kind == "guess_far"]

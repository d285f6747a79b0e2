"""`cart.estimate_report`: multi-rate tables, coloured F/T noise, glitches, stuck sensors, units, load changes.

Logs are written by the independent simulator (studies.testbeds.rigid_sim) through the recorders of
studies.testbeds.log_recorders (a naive logger's held-pose table, mocap rows with averaged F/T,
AR(1) F/T noise with an offset, dropouts, jitter).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from cart.estimate_report import estimate_log
from cart.jsonout import dumps_strict
from cart.logs import CartLog
from cart.units import UnitsError
from studies.testbeds import log_recorders as lr
from studies.testbeds import rigid_sim


@pytest.fixture(scope="module")
def recording():
    case = rigid_sim.random_case(101, duration=40.0)
    return lr.record(case, seed=1)


def test_held_pose_table_and_mocap_rows_give_the_same_answer_within_the_truths_std(recording):
    m = recording.truth["m"]
    held = estimate_log(lr.held_pose_table(recording))
    rows = estimate_log(lr.mocap_rows_table(recording))
    for r in (held, rows):
        assert r.model_fits, r.warnings
        assert abs(r.params.m - m) < 3 * r.std["mass"] and abs(r.params.m / m - 1) < 0.05
        assert len(r.segments) == 1
    assert held.streams.multi_rate and held.streams.held_rows > 0.5 * len(held.streams.wrench.t)
    assert 110 < held.streams.pose_hz < 130 and 480 < held.streams.wrench_hz < 520
    assert len(held.streams.dropouts) == 3 and len(rows.streams.dropouts) == 3
    assert abs(held.params.m - rows.params.m) < 0.5 * held.std["mass"]
    out = json.loads(dumps_strict(held.to_dict()))
    assert set(out["streams"]) >= {"pose_hz", "wrench_hz", "held_rows", "dropouts"}
    assert out["noise_model"]["force"]["lag1_corr"] > 0.5  # the coloured F/T noise is seen as coloured


def test_one_glitch_costs_at_most_one_percent_and_a_stuck_sensor_is_excluded(recording):
    log = lr.mocap_rows_table(recording)
    clean = estimate_log(log)
    glitched = estimate_log(lr.with_glitch(log, 20.0, size=5.0))
    assert glitched.streams.glitches and abs(glitched.params.m / clean.params.m - 1) < 0.01
    stuck = estimate_log(lr.with_stuck_wrench(log, 15.0, seconds=10.0))
    assert stuck.streams.stuck and any("stuck force sensor" in w for w in stuck.warnings)
    assert stuck.std["mass"] < 2 * clean.std["mass"]
    assert abs(stuck.params.m - recording.truth["m"]) < 3 * stuck.std["mass"]


@pytest.mark.parametrize("mistake, words", [("mm", "millimetres"), ("deg", "degrees"), ("ms", "milliseconds")])
def test_unit_mistakes_are_refused_with_the_fix(recording, mistake, words):
    with pytest.raises(UnitsError, match=words):
        estimate_log(lr.in_wrong_units(lr.mocap_rows_table(recording), mistake))


def test_a_parameter_the_log_cannot_identify_is_null_with_a_reason():
    # pushed straight ahead only: the yaw row never moves, the inertia and CoM cannot be told
    t = np.arange(0.0, 20.0, 0.01)
    rng = np.random.default_rng(0)
    v = 0.5 * np.sin(0.5 * t) ** 2
    x = np.cumsum(v) * 0.01
    a = np.gradient(v, t)
    q = np.column_stack([x, np.zeros_like(t), np.zeros_like(t)]) + rng.normal(0, 1e-3, (len(t), 3))
    g = np.column_stack([20.0 * a + 2.0 * v, np.zeros_like(t), np.zeros_like(t)]) + rng.normal(0, 1.0, (len(t), 3))
    out = estimate_log(CartLog(t=t, q=q, gamma=g)).to_dict()
    assert out["inertia"] is None and "inertia" in out["not_identified"]
    assert out["mass"] is not None and abs(out["mass"] - 20.0) < 3 * out["std"]["mass"]


def test_the_ekf_bias_is_named_when_its_std_does_not_cover_it():
    case = rigid_sim.random_case(3, duration=60.0, m=55.0, rate_hz=100.0, force_std=3.0, vel_std=0.005)
    log, truth = rigid_sim.simulate(case)
    ekf = estimate_log(log, method="ekf", mass_guess=20.0)
    covered = abs(ekf.params.m - truth["m"]) < 3 * ekf.std["mass"]
    assert covered or (not ekf.model_fits and any("bias" in w for w in ekf.warnings))


def test_a_load_change_gives_two_segments_with_the_after_mass():
    # a 40 kg cart loaded to 60 kg at 25 s, recorded as mocap rows with coloured F/T noise
    case = rigid_sim.random_case(201, duration=50.0, m=40.0)
    rec = lr.record(case, seed=1, load_change=(25.0, 1.5))
    r = estimate_log(lr.mocap_rows_table(rec))
    assert len(r.segments) == 2
    assert abs(r.segments[1]["t0"] - 25.0) < 1.0
    assert abs(r.segments[1]["mass"] / rec.truth["m_after"] - 1) < 0.05
    assert r.params.m == r.segments[1]["mass"] and any("load changes" in w for w in r.warnings)


def test_a_light_carts_mass_is_as_close_as_the_information_in_its_log_allows():
    # issue 30's light carts (5-10 kg) missed 5 %: not a bias but the F/T noise at the cart's own frequencies.
    # An oracle that knows the exact motion and the AR(1) noise (generalised least squares, the Cramer-Rao
    # bound: lr.mass_information_bound) has a mass std of 7 % here; the estimate must be within 3 of those
    # and its own std neither overconfident nor far above it
    rec = lr.record(rigid_sim.random_case(506, duration=45.0), ft_rho10=0.7, seed=3)
    m, bound = rec.truth["m"], rec.truth["mass_std_bound"]
    assert m < 10.0 and bound > 0.05 * m  # 5 % is within one bound-std: no estimator is within it every time
    r = estimate_log(lr.mocap_rows_table(rec))
    assert abs(r.params.m - m) < 3.0 * bound, (r.params.m, m, bound)
    assert 0.5 < r.std["mass"] / bound < 4.0, (r.std["mass"], bound)
    # the bound is the noise's: twice the F/T noise, twice the bound
    twice = lr.record(rigid_sim.random_case(506, duration=45.0), ft_rho10=0.7, seed=3, ft_sigma=(5.0, 5.0, 1.0))
    assert twice.truth["mass_std_bound"] == pytest.approx(2.0 * bound, rel=1e-9)

"""Tests of the MuJoCo load-change test bed (studies/testbeds/mujoco_loads.py) and of `estimate`'s segments on it."""

from __future__ import annotations

import copy
import math
import pathlib
import sys
from dataclasses import replace

import numpy as np

from tests.optional import require_module

mujoco = require_module("mujoco")

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # `studies` is not an installed package
    sys.path.insert(0, str(ROOT))

from cart.estimate_report import estimate_log  # noqa: E402
from studies.testbeds import mujoco_cart as mc  # noqa: E402
from studies.testbeds import mujoco_loads as ml  # noqa: E402


def _momentum(model, data, body: int) -> float:
    """Return the forward (x) linear momentum of the subtree of ``body``."""
    mujoco.mj_subtreeVel(model, data)
    return float(model.body_subtreemass[body] * data.subtree_linvel[body][0])


def _speed(data) -> float:
    return float(math.hypot(data.qvel[0], data.qvel[1]))


def test_a_load_dropped_in_shares_the_momentum_and_one_lifted_out_does_not():
    case, load = ml.random_load_case(100)
    model = mujoco.MjModel.from_xml_string(ml.mjcf_with_load(case.cart, load))
    data = mujoco.MjData(model)
    mover = ml._Load(model, data, case.cart, load)
    mc.place(model, data, case.cart, (0.0, 0.0, 0.0))
    for _ in range(300):  # settle on the wheels
        mujoco.mj_step(model, data)
    data.qvel[0] = 0.6  # rolling forward (x of {b} at heading 0)
    for _ in range(100):
        mujoco.mj_step(model, data)
    before = mover.truth()
    control = copy.deepcopy(data)  # the same cart coasting on without the load
    mover.put_in()
    after = mover.truth()
    for _ in range(60):  # the weld brings the load to the cart's speed within a few ms
        mujoco.mj_step(model, data)
        mujoco.mj_step(model, control)
    assert abs(after["m"] - before["m"] - load.mass) < 1e-9
    # the cart's and the load's momentum sum to the cart's alone (the floor's rolling resistance as in control)
    p_cart, p_load = _momentum(model, data, mover.cart_body), _momentum(model, data, mover.body)
    assert abs(p_cart + p_load - _momentum(model, control, mover.cart_body)) < 0.01 * abs(p_load + p_cart)
    assert abs(p_load / load.mass / _speed(data) - 1.0) < 0.05  # the load rides with the cart
    assert abs(_speed(data) / _speed(control) - before["m"] / after["m"]) < 0.03  # the cart slowed down
    v1 = _speed(data)
    mover.take_out()
    for _ in range(5):
        mujoco.mj_step(model, data)
    assert abs(_speed(data) / v1 - 1.0) < 0.03  # lifted out: the cart keeps its velocity (the soft contacts unload)
    assert np.allclose(data.xpos[mover.body], (50, 50, 1), atol=1e-3)


def test_estimate_splits_a_mujoco_log_at_the_load_and_not_the_same_cart_without():
    case, load = ml.random_load_case(100)  # 63.7 kg, 27.4 kg dropped in at 18.4 s
    log, truth = ml.simulate_with_load(case, load)
    segs = estimate_log(log).segments
    assert len(segs) == 2 and abs(segs[1]["t0"] - load.t) < 1.0
    # the after-segment reuses the whole log's caster model (alone it is too short to test it: +4.9 % without it)
    assert abs(segs[1]["mass"] / truth["after"]["m_effective_forward_incl_wheel_spin"] - 1) < 0.025
    log0, _ = ml.simulate_with_load(case, replace(load, kind="none_in"))
    assert len(estimate_log(log0).segments) == 1


def test_a_lift_out_before_an_acceleration_cannot_be_dated_closer_than_its_cruise():
    """Seed 103: 31 kg lifted out at 33.39 s, late in a straight cruise at 0.59 m/s, just before the cart
    brakes: the motion cannot date it within the cruise, so the stretch holds the change, reaches back into the
    cruise and ends at the braking, and an estimator dating it anywhere there is within 1 s with probability
    2 / width."""
    row = ml.dating_information(103)
    lo, hi = row["stretch"]
    assert row["kind"] == "out" and lo < -5.0 and 0.0 <= hi < 0.5
    assert abs(row["p_date"] - 2.0 / (hi - lo)) < 1e-12 and row["p_date"] < 0.3

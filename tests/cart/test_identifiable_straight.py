"""Issue 30 item 6 on carts pushed without turning: what the log cannot identify is null with a reason.

A straight push (studies.testbeds.rigid_sim with its yaw references removed) leaves the CoM's dx, the
yaw inertia and the yaw damping nearly collinear in the regression (paper eq. 4) while the mass and dy
stay well determined: each coordinate is judged on its own, a projection onto the physical bodies widens
the std by the distance it moved, and a log whose kept rows hold fewer independent samples than
parameters is refused instead of answered.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cart import identify_casters as icm
from cart.estimate_report import estimate_log
from cart.identify import IdentifiabilityError, _physical, _physical_std
from cart.segments import slice_log
from studies.testbeds import log_recorders as lr
from studies.testbeds import rigid_sim
from tests.cart.test_redteam_physical import COV, P_HAT


@pytest.fixture()
def straight(monkeypatch):
    """Make rigid_sim's references straight: its forward-speed steps, no yaw-rate steps."""
    orig = rigid_sim.make_references

    def no_turn(rng, duration, speed_scale):
        v, _ = orig(rng, duration, speed_scale)
        return v, rigid_sim.SmoothSteps([], [], [])

    monkeypatch.setattr(rigid_sim, "make_references", no_turn)


def test_a_straight_push_reports_dy_and_the_mass_but_not_dx(straight):
    case = rigid_sim.random_case(402, duration=40.0, lateral_std=0.0, vel_std=None)
    log, truth = rigid_sim.simulate(case)
    report = estimate_log(log)
    out = report.to_dict()
    assert out["com"] is not None and out["com"][0] is None and "dx" in out["not_identified"]
    assert "turn" in out["not_identified"]["dx"] and "com" not in out["not_identified"]
    assert abs(out["com"][1] - truth["dy"]) < 3 * out["std"]["com"][1] and out["std"]["com"][1] < 0.01
    assert abs(out["mass"] - truth["m"]) < 3 * out["std"]["mass"]
    assert out["segments"][0]["com"] == out["com"]
    assert any(w.startswith("dx not identified") for w in out["warnings"])


def test_a_log_with_fewer_independent_rows_than_parameters_is_refused(straight):
    # 500 Hz F/T with the 120 Hz pose held, three dropouts (0.78 s): each gap costs only its fill's reach through
    # the filter, the 40 s log is answered; its first 2.5 s keep about 1.3 s of rows (about 8 independent samples
    # at the cut-off for ten parameters) and are refused
    rec = lr.record(rigid_sim.random_case(401, duration=40.0), seed=401)
    log = lr.held_pose_table(rec)
    out = estimate_log(log).to_dict()
    m_true = rigid_sim.random_case(401, duration=40.0).cart.m
    assert out["streams"]["dropouts"] == 3 and abs(out["mass"] - m_true) < 3 * out["std"]["mass"]
    with pytest.raises(IdentifiabilityError, match="independent samples"):
        estimate_log(slice_log(log, log.t[0], log.t[0] + 2.5))


def test_the_projection_onto_physical_bodies_widens_the_std_by_its_move():
    # the unconstrained fit of that log (m = 92.2 kg, I about the CoM < 0) for a 93.72 kg cart
    p = np.concatenate([P_HAT, np.zeros(4)])
    cov = np.zeros((10, 10))
    cov[:6, :6] = COV
    cov[6:, 6:] = np.eye(4)
    fixed, wide, note = _physical(p, cov)
    assert note and fixed[0] != pytest.approx(P_HAT[0], rel=1e-3)
    std = _physical_std(fixed, wide)
    assert std["mass"] >= abs(fixed[0] - P_HAT[0]) and abs(fixed[0] - 93.72) < 3 * std["mass"]
    assert np.all(np.diag(wide)[:6] >= (fixed[:6] - p[:6]) ** 2)


def test_whole_turn_jumps_of_the_lanes_angle_are_no_swing():
    t = 0.01 * np.arange(4000)
    v = 0.5 * np.sin(2 * math.pi * t / 5.0)  # a straight push back and forth: 16 reversals
    om = 1e-4 * np.random.default_rng(0).standard_normal(len(t))
    reversals = int(np.sum(np.diff(np.sign(v)) != 0))
    for trail in icm.TRAILS:
        alpha, _ = icm.lanes(t, v, om, (0.6,), (trail,))
        assert icm.half_turns(alpha[:, 0, 0]) <= reversals + 1  # at most half a turn per reversal
    jump = np.zeros((10, 2))
    jump[5:] = 2 * math.pi
    assert icm.half_turns(jump) == pytest.approx(0.0, abs=1e-12)

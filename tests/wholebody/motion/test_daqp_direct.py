"""`DaqpSolver` (daqp called directly, the controller's default) against `qpsolvers`' daqp on the recorded QPs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
import qpsolvers

import robots
from wholebody.motion.experiments import initial_state
from tests.wholebody.motion.control_reference import CASES, REFERENCE, build, capture_qps
from wholebody.motion.control import ControllerConfig, ResolvedRateController
from wholebody.motion.kinematics import wholebody_for
from wholebody.motion.qp import SolverChoice
from wholebody.qp import DaqpSolver

REF = np.load(REFERENCE)


def _recorded_qps(name: str, monkeypatch) -> list[tuple]:
    """Replay case `name` with the default (daqp) solver; return each step's QP data."""
    qps = capture_qps(monkeypatch)
    ctrl = build(name)
    ctrl.config = replace(ctrl.config, solver="daqp")
    ctrl.solvers = SolverChoice(DaqpSolver(), "proxqp", ctrl.config.solver_tolerance)
    rec = {k.split("/", 1)[1]: REF[k] for k in REF.files if k.startswith(name + "/")}
    for k in range(len(rec["u"])):
        v = rec["v_des"][k]
        ctrl.step(
            rec["x"][k],
            pin.SE3(rec["T_des"][k]),
            None if np.all(np.isnan(v)) else v,
            float(rec["dt"][k]),
            band_center=rec["band_center"][k],
            band_center_velocity=rec["band_center_velocity"][k],
            base_target=rec["base_target"][k],
            base_target_velocity=rec["base_target_velocity"][k],
        )
    return qps


@pytest.mark.parametrize("name", list(CASES))
def test_direct_daqp_equals_qpsolvers_daqp(name, monkeypatch):
    """Same data layout as qpsolvers: the same solution to rounding, on every recorded step (box and rows)."""
    qps = _recorded_qps(name, monkeypatch)
    solver = DaqpSolver()
    with_rows = 0
    for H, c, G, h, lb, ub in qps:
        ours = solver.solve(H, c, G, h, lb, ub)
        theirs = qpsolvers.solve_qp(H, c, G, h, lb=lb, ub=ub, solver="daqp")
        assert (ours is None) == (theirs is None)
        if ours is not None:
            np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-11)
        with_rows += G is not None
    if CASES[name][3] is not None:  # a band: the inequality rows were exercised
        assert with_rows == len(qps)


def test_solution_satisfies_kkt_of_a_random_box_and_row_qp():
    """Independent check: KKT conditions of a strictly convex QP with one binding row and binding bounds."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(8, 6))
    H = A.T @ A + 1e-3 * np.eye(6)
    c = rng.normal(size=6) * 5
    G, h = np.ones((1, 6)), np.array([0.1])
    lb, ub = -0.3 * np.ones(6), 0.3 * np.ones(6)
    u = DaqpSolver().solve(H, c, G, h, lb, ub)
    assert u is not None
    assert np.all(u >= lb - 1e-12) and np.all(u <= ub + 1e-12) and (G @ u)[0] <= h[0] + 1e-9
    grad = H @ u + c
    # stationarity: the gradient is balanced by the active bounds and row (multipliers of the right sign)
    active_row = abs((G @ u)[0] - h[0]) < 1e-9
    free = (u > lb + 1e-9) & (u < ub - 1e-9)
    mu = -grad[free].mean() if active_row else 0.0
    np.testing.assert_allclose(grad[free] + mu, 0.0, atol=1e-8)
    assert mu >= -1e-9
    r = grad + mu * G[0]
    assert np.all(r[u <= lb + 1e-9] >= -1e-8) and np.all(r[u >= ub - 1e-9] <= 1e-8)


def test_non_finite_data_is_not_a_solution():
    """daqp reports a QP with NaN data solved; the wrapper returns None, so the controller never outputs NaN."""
    H, lb, ub = np.eye(3), -np.ones(3), np.ones(3)
    assert DaqpSolver().solve(H, np.array([np.nan, 0.0, 0.0]), None, None, lb, ub) is None
    wb = wholebody_for(robots.load("wmra"))
    ctrl = ResolvedRateController(wb, ControllerConfig(fallback_solver=None))
    x = initial_state(wb)
    T = wb.ee_placement(x)
    res = ctrl.step(x, T, np.full(6, np.nan), 0.01)
    assert not res.solver_ok and np.all(res.u == 0.0)


def test_buffers_follow_the_problem_shape():
    """The same solver object serves box-only and box + rows problems of any size in turn."""
    s = DaqpSolver()
    for n, m in ((3, 0), (5, 2), (3, 0), (5, 1)):
        H, c = np.eye(n), -np.ones(n)
        G, h = (None, None) if m == 0 else (np.ones((m, n)), np.full(m, 0.5))
        u = s.solve(H, c, G, h, -np.ones(n), np.ones(n))
        expected = np.ones(n) if m == 0 else np.full(n, 0.5 / n)
        np.testing.assert_allclose(u, expected, atol=1e-12)


def test_degenerate_band_run_does_not_depend_on_hash_seed():
    """With the default solver a band the path cannot hold gives the same run whatever PYTHONHASHSEED is."""
    argv = [sys.executable, "-m", "cartpush.cli", "track", "sine", "--band", "0.001", "--duration", "5", "--json"]
    outs = []
    for seed in ("0", "5"):
        env = {**os.environ, "PYTHONHASHSEED": seed}
        done = subprocess.run(argv, env=env, capture_output=True, text=True, check=True)
        outs.append(json.loads(done.stdout))
    assert outs[0]["band_respected"] is False
    assert outs[0] == outs[1]

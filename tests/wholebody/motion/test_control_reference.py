"""The task/limit composition of the controller reproduces the recorded monolithic controller.

`data/control_reference.npz` holds, per case of `control_reference.CASES`, the inputs, QP matrices and
outputs of the controller as it was before the QP was composed from `Task`s and `Limit`s (written by
`control_reference.py` against that code). The replay feeds the recorded inputs in order.
"""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

import qpsolvers
from scipy import sparse

import robots
from wholebody.motion.experiments import initial_state
from tests.wholebody.motion.control_reference import CASES, REFERENCE, build, capture_qps
from wholebody.motion import qp as qp_module
from wholebody.motion.control import ControllerConfig, ResolvedRateController, pose_error
from wholebody.motion.kinematics import wholebody_for
from wholebody.motion.qp import Limit, Task, stack_objective
from wholebody.qp import DaqpSolver

DT = 0.01

REF = np.load(REFERENCE)


@pytest.fixture(scope="module")
def wmra():
    return wholebody_for(robots.load("wmra"))


def _opt(a: np.ndarray) -> np.ndarray | None:
    return None if np.all(np.isnan(a)) else a


def _replay(name: str, warm_start: bool = False):
    """Yield (k, step inputs, StepResult, recorded arrays) of case `name` run by the current controller."""
    ctrl = build(name, warm_start)
    rec = {k.split("/", 1)[1]: REF[k] for k in REF.files if k.startswith(name + "/")}
    for k in range(len(rec["u"])):
        x, dt = rec["x"][k], float(rec["dt"][k])
        kw = dict(
            band_center=rec["band_center"][k],
            band_center_velocity=rec["band_center_velocity"][k],
            base_target=rec["base_target"][k],
            base_target_velocity=rec["base_target_velocity"][k],
        )
        box = ctrl.bounds(x, dt)
        ineq = ctrl.inequalities(x, dt, kw["band_center"], kw["band_center_velocity"])
        ineq_relax = ctrl.inequalities(x, dt, kw["band_center"], kw["band_center_velocity"], relax=True)
        res = ctrl.step(x, pin.SE3(rec["T_des"][k]), _opt(rec["v_des"][k]), dt, **kw)
        yield k, (box, ineq, ineq_relax), res, rec


def test_reference_file_covers_every_case():
    assert json.loads(str(REF["cases"])) == list(CASES)


@pytest.mark.parametrize("name", list(CASES))
def test_qp_matrices_match_recorded(name, monkeypatch):
    """Hessian, linear term, box and inequalities equal the monolithic controller's to rounding."""
    captured = []
    real = qp_module.QPWorkspace.objective

    def spy(self, tasks, s):
        H, c = real(self, tasks, s)
        captured.append((H.copy(), c.copy()))
        return H, c

    monkeypatch.setattr(qp_module.QPWorkspace, "objective", spy)
    for k, (box, ineq, ineq_relax), _, rec in _replay(name):
        H, c = captured[-1]
        np.testing.assert_allclose(H, rec["P"][k], rtol=1e-13, atol=1e-15)
        # the linear term sums Jacobian products whose order the locked-joint model changes: rounding of 1e-12
        np.testing.assert_allclose(c, rec["q"][k], rtol=1e-13, atol=1e-11)
        # the wheel-acceleration box is centred on the previous input, which may differ by the solver tolerance
        np.testing.assert_allclose(box[0], rec["lb"][k], rtol=1e-13, atol=1e-9)
        np.testing.assert_allclose(box[1], rec["ub"][k], rtol=1e-13, atol=1e-9)
        for (G, h), Gk, hk in ((ineq, rec["G"][k], rec["h"][k]), (ineq_relax, rec["G_relax"][k], rec["h_relax"][k])):
            if Gk.shape[0] == 0:
                assert G is None and h is None
            else:
                np.testing.assert_allclose(G, Gk, rtol=1e-14, atol=1e-15)
                np.testing.assert_allclose(h, hk, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("name", list(CASES))
def test_step_outputs_match_recorded(name):
    """Cold solves (warm_start=False): inputs within 1e-9 of the recorded ones; the flags and errors equal."""
    for k, _, res, rec in _replay(name):
        np.testing.assert_allclose(res.u, rec["u"][k], rtol=0, atol=1e-9, err_msg=f"{name} step {k}")
        for f in ("position_error", "orientation_error", "sigma_min"):
            assert getattr(res, f) == pytest.approx(float(rec[f][k]), rel=1e-12, abs=1e-14), (name, k, f)
        assert res.residual == pytest.approx(float(rec["residual"][k]), abs=1e-8), (name, k)
        for f in ("singular", "saturated", "solver_ok", "fallback_used"):
            assert getattr(res, f) == bool(rec[f][k]), (name, k, f)


def test_stack_objective_is_the_sum_of_the_tasks():
    """stack_objective adds each task's (H, c); checked against the tasks called one by one."""
    ctrl = build("ridgeback_wheels_base")
    x = REF["ridgeback_wheels_base/x"][3]
    ctrl.posture = x[3:] + 0.1  # the posture task on
    s = qp_module.StepState(
        ctrl.wb, x, 0.01, *ctrl.wb.ee_and_jacobian(x), np.ones(6), np.zeros(ctrl.wb.n_u), base_target=x[:3] + 0.1
    )
    H, c = stack_objective(ctrl.tasks, s)
    parts = [t.objective(s) for t in ctrl.tasks]
    np.testing.assert_allclose(H, sum(p[0] for p in parts if p[0] is not None), atol=1e-15)
    np.testing.assert_allclose(c, sum(p[1] for p in parts if p[1] is not None), atol=1e-15)


# ---------------------------------------------------------------- user-defined tasks and limits
class ForwardSpeedLimit(Limit):
    """User limit: the base's forward body speed vx <= vmax (one inequality row)."""

    def __init__(self, wb, vmax: float) -> None:
        self.row = np.zeros((1, wb.n_u))
        self.row[0, wb.n_arm :] = wb._wheel_map[0]
        self.vmax = vmax

    def inequality(self, s, relax=False):
        return self.row, np.array([self.vmax])


class JointRatePull(Task):
    """User task: weight (u_j - rate)^2 on one arm joint."""

    def __init__(self, wb, joint: int, rate: float, weight: float) -> None:
        self.H = np.zeros((wb.n_u, wb.n_u))
        self.H[joint, joint] = 2 * weight
        self.c = np.zeros(wb.n_u)
        self.c[joint] = -2 * weight * rate

    def objective(self, s):
        return self.H, self.c


def _far_step(ctrl):
    x = initial_state(ctrl.wb)
    T = ctrl.wb.ee_placement(x)
    return x, pin.SE3(T.rotation, T.translation + [0.5, 0.0, 0.0])


@pytest.mark.parametrize("solver", ["proxqp", "daqp"])
def test_user_limit_binds_and_the_step_is_optimal(wmra, solver):
    """An extra limit passed to the controller binds, and u is the optimum of the stacked QP (checked with osqp)."""
    cfg = ControllerConfig(solver=solver, damping=1e-3, secondary="none")
    free = ResolvedRateController(wmra, cfg)
    x, T_des = _far_step(free)
    assert (wmra._wheel_map @ free.step(x, T_des, None, DT).u[7:])[0] > 0.05  # the target pulls the base forward
    ctrl = ResolvedRateController(wmra, cfg, extra_limits=[ForwardSpeedLimit(wmra, 0.05)])
    res = ctrl.step(x, T_des, None, DT)
    assert res.solver_ok and not res.fallback_used
    assert (wmra._wheel_map @ res.u[7:])[0] <= 0.05 + 1e-7
    # independent solve of the same QP: the tasks' cost, the built-in box, the user's row
    T, J = wmra.ee_and_jacobian(x)
    e = pose_error(T, T_des)
    v_ref = cfg.gain * e
    v_ref[:3] *= min(1.0, cfg.max_linear_speed / np.linalg.norm(v_ref[:3]))
    v_ref[3:] *= min(1.0, cfg.max_angular_speed / max(np.linalg.norm(v_ref[3:]), 1e-300))
    P = J.T @ J + cfg.damping * np.eye(9)
    lb, ub = ctrl.bounds(x, DT)
    row = np.r_[np.zeros(7), wmra._wheel_map[0]][None, :]
    u_ref = qpsolvers.solve_qp(
        sparse.csc_matrix(P),
        -J.T @ v_ref,
        sparse.csc_matrix(row),
        np.array([0.05]),
        lb=lb,
        ub=ub,
        solver="osqp",
        eps_abs=1e-10,
        eps_rel=1e-10,
        max_iter=200000,
        polishing=True,
    )
    np.testing.assert_allclose(res.u, u_ref, atol=1e-5)


def test_limit_appended_between_steps_binds(wmra):
    """Editing `ctrl.limits` between steps re-sorts the workspace: the appended row binds at the next step."""
    ctrl = ResolvedRateController(wmra, ControllerConfig(secondary="none"))
    x, T_des = _far_step(ctrl)
    assert (wmra._wheel_map @ ctrl.step(x, T_des, None, DT).u[7:])[0] > 0.05
    ctrl.limits.append(ForwardSpeedLimit(wmra, 0.05))
    res = ctrl.step(x, T_des, None, DT)
    assert res.solver_ok and (wmra._wheel_map @ res.u[7:])[0] <= 0.05 + 1e-7
    ctrl.limits.pop()
    assert (wmra._wheel_map @ ctrl.step(x, T_des, None, DT).u[7:])[0] > 0.05


def test_user_task_is_added_to_the_cost(wmra):
    """An extra task pulling joint 1's rate to 0.3 rad/s with a large weight wins over the pose task."""
    x = initial_state(wmra)
    T = wmra.ee_placement(x)
    ctrl = ResolvedRateController(
        wmra, ControllerConfig(secondary="none"), extra_tasks=[JointRatePull(wmra, 0, 0.3, 1e4)]
    )
    res = ctrl.step(x, T, None, DT)
    assert res.u[0] == pytest.approx(0.3, abs=1e-3)
    assert abs(ResolvedRateController(wmra, ControllerConfig(secondary="none")).step(x, T, None, DT).u[0]) < 1e-6


def _cost(H: np.ndarray, c: np.ndarray, u: np.ndarray) -> float:
    return float(0.5 * u @ H @ u + c @ u)


@pytest.mark.parametrize("name", list(CASES))
def test_warm_start_reaches_the_optimum_of_each_step(name, monkeypatch):
    """warm_start=True (default): each step's QP cost and task velocity J u equal those of daqp's exact
    (active-set) optimum of the same QP, and the limits hold; u itself may move along the nearly free
    directions that the 1e-6 damping leaves (measured: cost within 3e-7 relative, J u within 6e-7)."""
    qps = capture_qps(monkeypatch)
    for k, _, res, rec in _replay(name, warm_start=True):
        H, c, G, h, lb, ub = qps[-1]
        exact = qpsolvers.solve_qp(H, c, G, h, lb=lb, ub=ub, solver="daqp")
        assert res.solver_ok and exact is not None, (name, k)
        f_exact = _cost(H, c, exact)
        assert _cost(H, c, res.u) == pytest.approx(f_exact, rel=1e-6, abs=1e-12), (name, k)
        J = res.jacobian
        np.testing.assert_allclose(J @ res.u, J @ exact, rtol=0, atol=1e-6, err_msg=f"{name} step {k}")
        assert np.all(res.u >= lb) and np.all(res.u <= ub), (name, k)
        if G is not None:
            assert np.all(G @ res.u <= h + 1e-8), (name, k)


def test_daqp_is_the_default_and_proxqp_warm_starts_unless_told_not_to():
    """The default primary solver is daqp called directly; ProxQP (called directly) warm-starts by default."""
    wb = wholebody_for(robots.load("wmra"))
    assert isinstance(ResolvedRateController(wb).solvers.primary, DaqpSolver)
    assert ResolvedRateController(wb).solvers.fallback == "proxqp"
    assert ResolvedRateController(wb, ControllerConfig(solver="proxqp")).solvers.primary.warm_start
    cold = ResolvedRateController(wb, ControllerConfig(solver="proxqp", warm_start=False))
    assert not cold.solvers.primary.warm_start


def test_step_result_sigma_min_is_the_smallest_singular_value(wmra):
    x = initial_state(wmra)
    res = ResolvedRateController(wmra).step(x, wmra.ee_placement(x), None, DT)
    s = np.linalg.svd(wmra.combined_jacobian(x), compute_uv=False)
    assert res.sigma_min == pytest.approx(s[-1], rel=1e-12)
    assert res.singular == (s[-1] < 1e-3)

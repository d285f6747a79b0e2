"""Wrench allocation QP: equality within 1e-8, optimality, limits, infeasibility diagnosis."""

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import LinearConstraint, minimize

import robots
from wholebody.contacts.allocation import (
    ArmLimits,
    EffortWeights,
    GraspModel,
    TorqueConstraint,
    WrenchAllocator,
    allocate,
    saturation_spans,
    saturation_summary,
)
from wholebody.contacts.handle import HandleSegment, cart_wrench, grasp_map
from wholebody.errors import InfeasibleWrenchError, WholeBodyError

HANDLE = HandleSegment.default()
SOLVERS = ["proxqp", "osqp", "daqp"]


def _contacts(n):
    return [HANDLE.point(s) for s in np.linspace(0.05, 0.45, n)]


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("n_arms", [1, 2, 3])
@pytest.mark.parametrize("fast_path", [True, False])
def test_mapped_wrenches_sum_to_request(solver, n_arms, fast_path):
    rng = np.random.default_rng(10 + n_arms)
    lim = ArmLimits(max_force=500.0, max_torque=100.0, grasp=None)
    alloc = WrenchAllocator(_contacts(n_arms), lim, solver=solver, fast_path=fast_path)
    for _ in range(10):
        gamma = rng.uniform([-60, -30, -20], [200, 30, 20])
        res = alloc.solve(gamma)
        pts = [c.point_b for c in alloc.contacts]
        assert np.max(np.abs(cart_wrench(pts, res.wrenches_ee) - gamma)) < 1e-8
        assert res.residual < 1e-8


def _scipy_reference(gamma, points, lim: ArmLimits, weights=EffortWeights()):
    """Independent solve with SLSQP on the planar variables (fx, fy, tau_z) per arm; returns its effort."""
    return _scipy_solution(gamma, points, lim, weights).fun


def _scipy_solution(gamma, points, lim: ArmLimits, weights=EffortWeights(), reference=None):
    """SLSQP on the planar variables (fx, fy, tau_z) per arm, the cost the effort plus ``weights.change`` times the
    weighted squared change from `reference` (planar variables per arm; None: zero)."""
    n = len(points)
    g = lim.grasp
    Wd = np.tile([weights.force, weights.force, weights.torque], n)
    Gp = np.hstack([grasp_map(p)[:, [0, 1, 5]] for p in points])

    def ineq(x):
        out = []
        for i in range(n):
            fx, fy, tz = x[3 * i : 3 * i + 3]
            nrm = 2 * g.grip_force + fx
            out += [g.pull_capacity + fx]
            for sgn in (1.0, -1.0):  # |v| <= c as c - v >= 0 and c + v >= 0 (smooth rows for SLSQP)
                out += [
                    lim.max_force - sgn * fx,
                    lim.max_force - sgn * fy,
                    lim.max_torque - sgn * tz,
                    g.friction * nrm - sgn * fy,
                    g.torque_arm * nrm - sgn * tz,
                ]
        return np.array(out)

    x0 = np.linalg.lstsq(Gp, gamma, rcond=None)[0]
    ref = np.zeros(3 * n) if reference is None else np.asarray(reference, dtype=float)
    lam = weights.change
    return minimize(
        lambda x: x @ (Wd * x) + lam * (x - ref) @ (Wd * (x - ref)),
        x0,
        jac=lambda x: 2 * Wd * x + 2 * lam * Wd * (x - ref),
        method="SLSQP",
        constraints=[{"type": "eq", "fun": lambda x: Gp @ x - gamma}, {"type": "ineq", "fun": ineq}],
        options={"ftol": 1e-12, "maxiter": 500},
    )


@pytest.mark.parametrize("solver", SOLVERS)
def test_optimum_matches_independent_nlp_with_active_limits(solver):
    rng = np.random.default_rng(5)
    lim = ArmLimits(max_force=60.0, max_torque=3.0, grasp=GraspModel(grip_force=40.0, friction=0.4, torque_arm=0.03))
    active = 0
    for _ in range(12):
        pts = [HANDLE.point(s) for s in np.sort(rng.uniform(0, 0.5, 2))]
        gamma = rng.uniform([0, -20, -8], [90, 20, 8])
        try:
            res = allocate(gamma, pts, lim, solver=solver)
        except InfeasibleWrenchError:
            continue
        ref = _scipy_reference(gamma, pts, lim)
        assert res.effort == pytest.approx(ref, rel=1e-5, abs=1e-6)
        alloc = WrenchAllocator(pts, lim, solver=solver)
        x = res.wrenches_ee.reshape(-1)[alloc.free]
        active += int(np.any(alloc.Gin @ x > alloc.hin - 1e-6))
    assert active >= 3  # the comparison covered cases where limits bind


def test_symmetric_two_arm_push_splits_evenly():
    pts = [HANDLE.point(0.1), HANDLE.point(0.4)]  # y = -0.15, +0.15
    for solver in SOLVERS:
        res = allocate([50.0, 0.0, 0.0], pts, solver=solver)
        w = res.wrenches_ee
        assert np.allclose(w[0], w[1], atol=1e-9)
        assert np.allclose(w[0], [25.0, 0, 0, 0, 0, 0], atol=1e-9)


def test_only_motion_directions_leaves_lateral_free_and_costs_less():
    pts = [HANDLE.point(0.3)]
    gamma = [30.0, 0.0, 2.0]
    full = allocate(gamma, pts)
    motion = allocate(gamma, pts, only_motion_directions=True)
    assert np.allclose(full.gamma_achieved, gamma, atol=1e-9)
    assert np.allclose(motion.gamma_achieved[[0, 2]], [30.0, 2.0], atol=1e-9)
    assert abs(motion.gamma_achieved[1]) > 1e-3  # uses a lateral force for the torque
    assert motion.effort < full.effort
    # closed form: min fy^2 + tz^2 s.t. px fy + tz = c, with c = tau + py fx
    px, py = pts[0][0], pts[0][1]
    c = 2.0 + py * 30.0
    assert motion.effort == pytest.approx(30.0**2 + c**2 / (px**2 + 1.0), rel=1e-10)


def test_pull_beyond_grip_is_infeasible_and_names_the_grip():
    with pytest.raises(InfeasibleWrenchError) as err:
        allocate([-250.0, 0.0, 0.0], [HANDLE.point(0.25)], ArmLimits(grasp=GraspModel(grip_force=100.0, friction=0.5)))
    assert "grip pull limit" in err.value.binding
    assert np.allclose(err.value.closest, (-100.0, 0.0, 0.0), atol=1e-4)


def test_force_bound_and_torque_limit_are_named():
    with pytest.raises(InfeasibleWrenchError) as err:
        allocate([400.0, 0.0, 0.0], [HANDLE.point(0.25)], ArmLimits(max_force=150.0))
    assert "force bound (fx <= 150 N)" in err.value.binding
    assert err.value.closest[0] == pytest.approx(150.0, abs=1e-4)
    with pytest.raises(InfeasibleWrenchError) as err:
        allocate([20.0, 0.0, 15.0], [HANDLE.point(0.25)])
    assert "grip torque limit (tau_z)" in err.value.binding or "grip friction cone" in err.value.binding
    # the closest wrench is achievable: allocating it succeeds
    res = allocate(err.value.closest, [HANDLE.point(0.25)])
    assert res.residual < 1e-6


def test_best_effort_returns_closest_instead_of_raising():
    res = allocate([400.0, 0.0, 0.0], [HANDLE.point(0.25)], raise_on_infeasible=False)
    assert res.residual == pytest.approx(250.0, abs=1e-3)


def _iiwa_jacobian():
    r = robots.load("ridgeback_iiwa")
    q = pin.neutral(r.model)
    arm = [r.model.joints[r.model.getJointId(f"iiwa_joint_{k}")] for k in range(1, 8)]
    for jnt, val in zip(arm, [0.0, 0.7, 0.0, -1.4, 0.0, 0.9, 0.0]):
        q[jnt.idx_q] = val
    fid = r.model.getFrameId("ee")
    pin.computeJointJacobians(r.model, r.data, q)
    pin.updateFramePlacements(r.model, r.data)
    J = pin.getFrameJacobian(r.model, r.data, fid, pin.LOCAL_WORLD_ALIGNED)
    cols = [jnt.idx_v for jnt in arm]
    limits = np.array([r.model.effortLimit[c] for c in cols])
    return J[:, cols], limits


def test_joint_torque_effort_uses_jacobian_transpose():
    J, tl = _iiwa_jacobian()
    pts = [HANDLE.point(0.25)]
    gamma = [40.0, 0.0, 1.0]
    res = allocate(gamma, pts, ArmLimits(planar=False), jacobians=[J], torque_limits=[tl])
    tau = res.joint_torques[0]
    assert np.allclose(tau, J.T @ res.wrenches_ee[0])
    assert res.effort == pytest.approx(tau @ tau, rel=1e-8)
    assert np.allclose(res.gamma_achieved, gamma, atol=1e-8)
    # it is no worse in joint torque than the wrench-effort optimum
    wr = allocate(gamma, pts, ArmLimits(planar=False))
    tau_wr = J.T @ wr.wrenches_ee[0]
    assert tau @ tau <= tau_wr @ tau_wr + 1e-9


def test_joint_torque_limit_binds_and_is_named():
    J, _ = _iiwa_jacobian()
    tl = np.full(7, 2.0)  # a weak arm
    with pytest.raises(InfeasibleWrenchError) as err:
        allocate([60.0, 0.0, 0.0], [HANDLE.point(0.25)], jacobians=[J], torque_limits=[tl])
    assert "joint" in err.value.binding and "torque limit" in err.value.binding
    closest = np.asarray(err.value.closest)
    assert 0.0 < closest[0] < 60.0


def test_bad_input_raises_project_errors():
    with pytest.raises(WholeBodyError):
        allocate([1.0, 2.0], [HANDLE.point(0.2)])
    with pytest.raises(WholeBodyError):
        allocate([1.0, 0.0, 0.0], [HANDLE.point(0.2)], solver="nope")
    with pytest.raises(WholeBodyError):
        GraspModel(grip_force=500.0)
    with pytest.raises(WholeBodyError):
        allocate([1.0, 0.0, 0.0], [HANDLE.point(0.2)], torque_limits=[np.ones(7)])


# ---------------------------------------------------------------------------------------------- per-step torque limits
def _torque_case(seed: int, n: int = 2):
    """Random arm Jacobians (wrench in {a} -> 7 joint torques), bias torques and limits the bias leaves room in."""
    rng = np.random.default_rng(seed)
    cons = []
    for i in range(n):
        J = rng.normal(0.0, 0.15, (6, 7))
        g = rng.uniform(-4.0, 4.0, 7)
        lim = np.abs(g) + rng.uniform(6.0, 15.0, 7)
        cons.append(TorqueConstraint(J, g, lim, tuple(f"j{i}{k}" for k in range(7))))
    return cons


def _reference_with_torques(gamma, points, cons, margin):
    """Independent optimum (scipy trust-constr): planar (fx, fy, tau_z) per arm, wrench effort, the cart wrench
    as an equality, -(1 - margin) limit <= J^T w + g <= (1 - margin) limit as linear constraints."""
    n = len(points)
    Gp = np.hstack([grasp_map(p)[:, [0, 1, 5]] for p in points])
    rows, lo, hi = [], [], []
    for i, c in enumerate(cons):
        for j in range(c.jacobian.shape[1]):
            r = np.zeros(3 * n)
            r[3 * i : 3 * i + 3] = c.jacobian[[0, 1, 5], j]
            rows.append(r)
            lo.append(-(1 - margin) * c.limit[j] - c.bias[j])
            hi.append((1 - margin) * c.limit[j] - c.bias[j])
    r = minimize(
        lambda x: x @ x,
        np.linalg.lstsq(Gp, gamma, rcond=None)[0],
        jac=lambda x: 2 * x,
        hess=lambda x: 2 * np.eye(3 * n),
        method="trust-constr",
        constraints=[LinearConstraint(Gp, gamma, gamma), LinearConstraint(np.array(rows), lo, hi)],
        options={"gtol": 1e-12, "xtol": 1e-14, "maxiter": 5000},
    )
    return r.x


@pytest.mark.parametrize("solver", ["proxqp", "daqp"])
def test_torque_limits_with_bias_match_an_independent_optimum(solver):
    pts = [HANDLE.point(0.1), HANDLE.point(0.4)]
    lim = ArmLimits(max_force=1e4, max_torque=1e4, grasp=None)
    alloc = WrenchAllocator(pts, lim, solver=solver)
    free = WrenchAllocator(pts, lim, solver=solver)
    bound = 0
    for seed in range(6):
        cons = _torque_case(seed)
        alloc.set_torque_limits(cons, margin=0.05)
        gamma = np.array([30.0, 10.0, -4.0]) * (1 + seed / 5)
        res = alloc.solve(gamma)
        x_ref = _reference_with_torques(gamma, pts, cons, 0.05)
        np.testing.assert_allclose(res.wrenches_ee[:, [0, 1, 5]].ravel(), x_ref, atol=1e-4)
        for i, c in enumerate(cons):  # every joint within its (shrunk) limit, torques reported
            np.testing.assert_allclose(res.joint_torques[i], c.jacobian.T @ res.wrenches_ee[i] + c.bias, atol=1e-12)
            assert np.all(np.abs(res.joint_torques[i]) <= 0.95 * c.limit + 1e-7)
        bound += not np.allclose(res.wrenches_ee, free.solve(gamma).wrenches_ee, atol=1e-6)
    assert bound >= 2  # the torque rows changed the optimum in some of the cases


def test_a_push_beyond_the_torque_limits_saturates_and_names_the_joint():
    pts = [HANDLE.point(0.25)]
    cons = _torque_case(3, n=1)
    alloc = WrenchAllocator(pts, ArmLimits(max_force=1e4, max_torque=1e4, grasp=None), only_motion_directions=True)
    alloc.set_torque_limits(cons)
    res = alloc.solve([500.0, 0.0, 0.0], raise_on_infeasible=False)
    assert res.residual > 1.0 and res.binding is not None
    assert res.binding.startswith("arm0 j0") and "torque limit" in res.binding
    tau = cons[0].torques(res.wrenches_ee[0])
    assert np.all(np.abs(tau) <= cons[0].limit + 1e-6)
    k = int(res.binding.split()[1][2:])  # the named joint is at its limit
    assert abs(tau[k]) == pytest.approx(cons[0].limit[k], rel=1e-5)
    with pytest.raises(InfeasibleWrenchError) as err:
        alloc.solve([500.0, 0.0, 0.0])
    assert err.value.binding == res.binding


def test_bias_beyond_a_limit_is_listed_and_no_wrench_adds_to_it():
    c = _torque_case(1, n=1)[0]
    g = c.bias.copy()
    g[2] = 1.5 * c.limit[2] * np.sign(g[2] or 1.0)
    c = TorqueConstraint(c.jacobian, g, c.limit, c.joints)
    alloc = WrenchAllocator([HANDLE.point(0.25)], ArmLimits(max_force=1e4, max_torque=1e4, grasp=None))
    alloc.set_torque_limits([c])
    assert alloc.bias_over_limit == ("arm0 j02",)
    res = alloc.solve([20.0, 0.0, 1.0], raise_on_infeasible=False)
    assert abs(c.torques(res.wrenches_ee[0])[2]) <= abs(g[2]) + 1e-7
    with pytest.raises(WholeBodyError):
        alloc.set_torque_limits([c, c])
    with pytest.raises(WholeBodyError):
        alloc.set_torque_limits([TorqueConstraint(c.jacobian, g, -c.limit)])


def test_saturation_spans_group_consecutive_binding_limits():
    t = np.arange(10) * 0.01
    b = [None, "a", "a", None, "b", "b", "b", "a", None, "a"]
    spans = saturation_spans(t, b, 0.01)
    assert [(s.limit, s.start, s.end, s.steps) for s in spans] == [
        ("a", 0.01, 0.02, 2),
        ("b", 0.04, 0.06, 3),
        ("a", 0.07, 0.07, 1),
        ("a", 0.09, 0.09, 1),
    ]
    summary = saturation_summary(spans)
    assert summary["a"]["spans"] == 3 and summary["a"]["total_s"] == pytest.approx(0.04)
    assert summary["b"]["longest_s"] == pytest.approx(0.03) and summary["b"]["first_s"] == pytest.approx(0.04)


def _planar(w):
    """Return the planar components (fx, fy, tau_z) of stacked hand wrenches (N x 6), flattened."""
    return np.asarray(w)[:, [0, 1, 5]].reshape(-1)


@pytest.mark.parametrize("solver,direct,fast_path", [("proxqp", True, True), ("proxqp", False, False), ("daqp", 0, 0)])
def test_change_weight_moves_the_free_directions_a_share_of_the_way(solver, direct, fast_path):
    # cost |w|^2 + c |w - r|^2 on the affine set G w = gamma, with r on it: (1 + c) |w - c r / (1 + c)|^2 + const,
    # whose minimum over the set is (w_min + c r) / (1 + c) (w_min the minimum-effort allocation)
    pts = _contacts(2)
    lim = ArmLimits(max_force=500.0, max_torque=100.0, grasp=None)
    gamma = np.array([60.0, 5.0, 3.0])
    w_min = allocate(gamma, pts, lim).wrenches_ee
    squeeze = np.zeros((2, 6))
    squeeze[0, 1], squeeze[1, 1] = 20.0, -20.0  # equal and opposite sideways forces on one line: no cart wrench
    reference = w_min + squeeze
    assert np.allclose(cart_wrench(pts, reference), gamma, atol=1e-12)
    c = 4.0
    alloc = WrenchAllocator(
        pts, lim, EffortWeights(change=c), solver=solver, direct=bool(direct), fast_path=bool(fast_path)
    )
    alloc.set_reference(reference)
    res = alloc.solve(gamma)
    assert np.allclose(res.wrenches_ee, (w_min + c * reference) / (1 + c), atol=1e-7)
    assert res.effort == pytest.approx(float(np.sum(res.wrenches_ee**2)), rel=1e-12)  # the effort alone
    alloc.set_reference(None)
    assert np.allclose(alloc.solve(gamma).wrenches_ee, w_min, atol=1e-7)


@pytest.mark.parametrize("solver", ["proxqp", "daqp"])
def test_change_weight_with_active_limits_matches_an_independent_optimum(solver):
    rng = np.random.default_rng(7)
    lim = ArmLimits(max_force=60.0, max_torque=3.0, grasp=GraspModel(grip_force=40.0, friction=0.4, torque_arm=0.03))
    weights = EffortWeights(torque=2.0, change=3.0)
    active = compared = 0
    for _ in range(16):
        pts = [HANDLE.point(s) for s in np.sort(rng.uniform(0, 0.5, 2))]
        gamma = rng.uniform([0, -30, -10], [100, 30, 10])
        reference = np.zeros((2, 6))
        reference[:, [0, 1, 5]] = rng.uniform([-20, -40, -6], [70, 40, 6], size=(2, 3))  # beyond some limits
        alloc = WrenchAllocator(pts, lim, weights, solver=solver)
        alloc.set_reference(reference)
        try:
            res = alloc.solve(gamma)
        except InfeasibleWrenchError:
            continue
        ref = _scipy_solution(gamma, pts, lim, weights, _planar(reference))
        assert np.allclose(_planar(res.wrenches_ee), ref.x, atol=1e-4)
        compared += 1
        x = res.wrenches_ee.reshape(-1)[alloc.free]
        active += int(np.any(alloc.Gin @ x > alloc.hin - 1e-6))
    assert compared >= 6 and active >= 3  # the comparison covered cases where limits bind


def test_change_weight_bad_input_and_minimum_effort_only_calls():
    with pytest.raises(WholeBodyError, match="change weight"):
        EffortWeights(change=-1.0)
    alloc = WrenchAllocator(_contacts(2), weights=EffortWeights(change=2.0))
    with pytest.raises(WholeBodyError, match="2 finite wrenches of 6 numbers"):
        alloc.set_reference(np.zeros((1, 6)))
    with pytest.raises(WholeBodyError, match="change = 0"):
        alloc.closed_form_batch(np.array([_contacts(2)]), np.array([[10.0, 0.0, 0.0]]))
    with pytest.raises(WholeBodyError, match="change = 0"):
        alloc.closed_form_effort(np.array(_contacts(2)), np.array([10.0, 0.0, 0.0]))


def test_a_saturated_allocation_does_not_carry_the_solvers_last_bits(monkeypatch):
    """ProxQP's last bits depend on the heap; the closest allocation is the exact KKT point on its active set, so
    two solver answers 1e-13 apart give the same wrenches to the bit (a saturated closed loop amplifies them)."""
    import qpsolvers

    from wholebody.contacts import allocation as allocation_module

    solve_problem = qpsolvers.solve_problem
    rng = np.random.default_rng(0)

    def jittered(problem, **kwargs):
        sol = solve_problem(problem, **kwargs)
        if sol.x is not None and problem.A is None:  # the closest-wrench QP (no equality rows)
            sol.x = sol.x * (1.0 + 1e-13 * rng.standard_normal(sol.x.shape))
        return sol

    monkeypatch.setattr(allocation_module.qpsolvers, "solve_problem", jittered)
    alloc = WrenchAllocator(_contacts(2), ArmLimits(max_force=60.0, max_torque=8.0))
    first, second = (alloc.solve([250.0, 40.0, 30.0], raise_on_infeasible=False) for _ in range(2))
    assert first.residual > 1.0  # saturated: the closest-wrench QP answered
    assert first.wrenches_ee.tobytes() == second.wrenches_ee.tobytes()
    lim = alloc.Gin @ np.concatenate([w for w in first.wrenches_ee])[alloc.free] - alloc.hin
    assert lim.max() <= 1e-9 * max(1.0, float(np.abs(alloc.hin).max()))

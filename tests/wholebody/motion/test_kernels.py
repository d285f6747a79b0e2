"""The compiled QP kernels (`wholebody.motion.kernels`) against independent numpy / Pinocchio computations."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import robots
from wholebody.motion.experiments import initial_state
from wholebody.errors import WholeBodyError
from wholebody.motion import kernels as K
from wholebody.motion.control import ResolvedRateController
from wholebody.motion.kinematics import wholebody_for
from wholebody.qp import DaqpSolver
from wholebody.motion.tasks import EndEffectorTask, PostureTask, pose_error

RNG = np.random.default_rng(11)


def test_weighted_gram_adds_jt_w_j_and_minus_jt_w_v():
    J, w, v = RNG.normal(size=(6, 9)), RNG.uniform(0.1, 3, 6), RNG.normal(size=6)
    H0, c0 = RNG.normal(size=(9, 9)), RNG.normal(size=9)
    H, c = H0.copy(), c0.copy()
    K.add_weighted_gram(J, w, v, H, c)
    np.testing.assert_allclose(H, H0 + J.T @ np.diag(w) @ J, rtol=0, atol=1e-12)
    np.testing.assert_allclose(c, c0 - J.T @ (w * v), rtol=0, atol=1e-12)


def test_scaled_difference_reads_the_arm_part_of_x():
    c0, target, x = RNG.normal(size=9), RNG.normal(size=7), RNG.normal(size=10)
    c = c0.copy()
    K.add_scaled_difference(c, -0.3, target, x, 3)
    np.testing.assert_allclose(c[:7], c0[:7] - 0.3 * (target - x[3:]), rtol=0, atol=1e-15)
    np.testing.assert_array_equal(c[7:], c0[7:])


def test_position_box_matches_the_numpy_formula_and_contains_zero():
    lower, upper = -np.ones(7), np.ones(7)
    x = np.r_[0.0, 0.0, 0.0, RNG.uniform(-1.5, 1.5, 7)]  # some joints outside their limits
    lb, ub = np.full(9, -50.0), np.full(9, 50.0)
    K.intersect_position_box(lower, upper, x, 3, 0.01, lb, ub)
    lo = np.minimum((lower - x[3:]) / 0.01, 0.0)
    hi = np.maximum((upper - x[3:]) / 0.01, 0.0)
    np.testing.assert_array_equal(lb[:7], np.maximum(-50.0, lo))
    np.testing.assert_array_equal(ub[:7], np.minimum(50.0, hi))
    np.testing.assert_array_equal(lb[7:], -50.0)
    assert np.all(lb <= 0) and np.all(ub >= 0)


def test_position_box_of_a_nan_joint_is_zero_rate():
    lb, ub = np.full(2, -5.0), np.full(2, 5.0)
    K.intersect_position_box(np.array([-1.0]), np.array([1.0]), np.array([0, 0, 0, np.nan]), 3, 0.1, lb, ub)
    assert lb[0] == 0.0 and ub[0] == 0.0 and lb[1] == -5.0


def test_clip_and_residual_equal_numpy():
    u, lb, ub = RNG.normal(size=9) * 3, -np.ones(9), np.ones(9)
    expected = np.clip(u, lb, ub)
    K.clip_to_box(u, lb, ub)
    np.testing.assert_array_equal(u, expected)
    J, v = RNG.normal(size=(6, 9)), RNG.normal(size=6)
    assert K.residual_norm(J, u, v) == pytest.approx(np.linalg.norm(J @ u - v), rel=1e-14)


@pytest.mark.parametrize("scale", [0.01, 1.0, 50.0])
def test_reference_twist_clips_each_half_and_returns_the_error_norms(scale):
    e, v_des = RNG.normal(size=6) * scale, RNG.normal(size=6) * scale
    v, e_lin, e_ang = K.reference_twist(e, 20.0, v_des, 1.0, 1.5)
    raw = 20.0 * e + v_des
    for half, limit in ((slice(0, 3), 1.0), (slice(3, 6), 1.5)):
        norm = np.linalg.norm(raw[half])
        np.testing.assert_allclose(v[half], raw[half] * min(1.0, limit / norm), rtol=1e-14)
    assert e_lin == pytest.approx(np.linalg.norm(e[:3])) and e_ang == pytest.approx(np.linalg.norm(e[3:]))


def test_pose_error_equals_the_rotation_matrix_formula():
    for _ in range(20):
        T, T_des = pin.SE3.Random(), pin.SE3.Random()
        e = pose_error(T, T_des)
        np.testing.assert_allclose(e[:3], T_des.translation - T.translation, atol=1e-15)
        np.testing.assert_allclose(e[3:], pin.log3(T_des.rotation @ T.rotation.T), atol=1e-12)


def test_unconstrained_solution_taken_only_when_it_is_feasible():
    A = RNG.normal(size=(8, 6))
    H, c = A.T @ A + 1e-3 * np.eye(6), RNG.normal(size=6)
    u_free = np.linalg.solve(H, -c)
    no_rows, no_rhs = np.zeros((0, 6)), np.zeros(0)
    wide = np.abs(u_free).max() + 1
    u, ok = K.unconstrained_if_feasible(H, c, no_rows, no_rhs, np.full(6, -wide), np.full(6, wide))
    assert ok
    np.testing.assert_allclose(u, u_free, rtol=1e-10, atol=1e-12)
    tight = np.abs(u_free).min() / 2  # every bound cuts the free solution
    assert not K.unconstrained_if_feasible(H, c, no_rows, no_rhs, np.full(6, -tight), np.full(6, tight))[1]
    G, h = u_free[None, :], np.array([u_free @ u_free - 1e-6])  # one row cuts it
    assert not K.unconstrained_if_feasible(H, c, G, h, np.full(6, -wide), np.full(6, wide))[1]
    H_indefinite = H - 10 * np.abs(np.linalg.eigvalsh(H)).max() * np.eye(6)
    assert not K.unconstrained_if_feasible(H_indefinite, c, no_rows, no_rhs, np.full(6, -wide), np.full(6, wide))[1]


def test_daqp_solver_uses_the_shortcut_only_on_free_steps(monkeypatch):
    """A free QP never reaches daqp; a QP with a binding bound does, and its solution meets the KKT conditions."""
    import wholebody.qp.daqp as qp

    calls = []
    real = qp.daqp.solve
    monkeypatch.setattr(qp.daqp, "solve", lambda *a: calls.append(1) or real(*a))
    H, c = np.diag([1.0, 2.0, 4.0]), np.array([-1.0, 1.0, -2.0])
    u = DaqpSolver().solve(H, c, None, None, -np.ones(3), np.ones(3))
    np.testing.assert_allclose(u, [1.0, -0.5, 0.5], atol=1e-15)
    assert calls == []
    u = DaqpSolver().solve(H, c, None, None, -np.ones(3), np.full(3, 0.25))
    np.testing.assert_allclose(u, [0.25, -0.5, 0.25], atol=1e-12)
    assert calls == [1]


def test_write_configuration_matches_pinocchio_layout():
    wb = wholebody_for(robots.load("ridgeback_iiwa"))
    x = np.r_[0.3, -0.2, 2.5, RNG.uniform(-1, 1, wb.n_arm)]
    q = wb.to_pinocchio_q(x)
    assert q[0] == 0.3 and q[1] == -0.2 and q[2] == pytest.approx(np.cos(2.5)) and q[3] == pytest.approx(np.sin(2.5))
    np.testing.assert_array_equal(q[wb.arm_idx_q], x[3:])
    pin.framesForwardKinematics(wb.model, wb.data, q)
    T = wb.data.oMf[wb.ee_frame_id]
    np.testing.assert_allclose(wb.ee_placement(x).homogeneous, T.homogeneous, atol=1e-15)


def test_an_index_out_of_range_raises_instead_of_reading_past_the_array():
    """A hand-built `StepState` with a short state reaches the kernels unchecked: bounds checking stops it."""
    lb, ub = np.full(9, -1.0), np.full(9, 1.0)
    with pytest.raises(IndexError):
        K.intersect_position_box(-np.ones(7), np.ones(7), np.zeros(5), 3, 0.01, lb, ub)


def test_bad_shapes_are_rejected_before_the_kernels():
    wb = wholebody_for(robots.load("wmra"))
    x = initial_state(wb)
    ctrl = ResolvedRateController(wb)
    T = wb.ee_placement(x)
    with pytest.raises(WholeBodyError, match="state x must have shape"):
        ctrl.step(x[:-1], T, None, 0.01)
    with pytest.raises(WholeBodyError, match="state x must have shape"):
        wb.ee_and_jacobian(np.r_[x, 0.0])
    with pytest.raises(WholeBodyError, match="v_des must have 6 entries"):
        ctrl.step(x, T, np.zeros(5), 0.01)
    with pytest.raises(WholeBodyError, match="posture must have 7"):
        PostureTask(wb, 1e-3, 1.0, np.zeros(6))
    with pytest.raises(WholeBodyError, match="weights must have 6 entries"):
        EndEffectorTask(np.ones(3))

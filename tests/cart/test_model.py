"""Cart model: Pinocchio cross-check, exact vs projected constraint, wrenches, parameters."""

import math

import numpy as np
import pinocchio as pin
import pytest

from cart import model
from cart.errors import ParameterError
from cart.params import CartParams, project_phi
from cart.simulate import rk4_step

PARAMS = CartParams(m=20.0, dx=0.3, dy=0.15, I=2.27, sigma=4.0)


def planar_body_model(p: CartParams) -> pin.Model:
    """Rigid body on PX + PY + RZ joints (nq = nv = 3), CoM at (dx, dy), inertia I about the CoM."""
    mdl = pin.Model()
    j = mdl.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
    j = mdl.addJoint(j, pin.JointModelPY(), pin.SE3.Identity(), "y")
    j = mdl.addJoint(j, pin.JointModelRZ(), pin.SE3.Identity(), "theta")
    inertia = pin.Inertia(p.m, np.array([p.dx, p.dy, 0.0]), np.diag([1.0, 1.0, p.I]))
    mdl.appendBodyToJoint(j, inertia, pin.SE3.Identity())
    mdl.gravity.linear[:] = 0.0
    return mdl


def test_mass_and_coriolis_match_pinocchio_crba_and_nle():
    rng = np.random.default_rng(0)
    for _ in range(20):
        p = CartParams(rng.uniform(5, 60), rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(0.2, 5))
        mdl = planar_body_model(p)
        data = mdl.createData()
        q = rng.uniform(-4, 4, 3)
        qd = rng.normal(size=3)
        m_pin = pin.crba(mdl, data, q)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        nle = pin.nonLinearEffects(mdl, data, q, qd)
        np.testing.assert_allclose(model.mass_matrix(q, p), m_pin, atol=1e-9, rtol=0)
        np.testing.assert_allclose(model.coriolis_matrix(q, qd, p) @ qd, nle, atol=1e-9, rtol=0)


def test_exact_dynamics_satisfy_rnea_with_a_lateral_constraint_force():
    """M qdd + C qd (Pinocchio RNEA) equals gamma - N - Lambda^T lambda, and the constraint holds at acceleration level."""
    rng = np.random.default_rng(1)
    mdl = planar_body_model(PARAMS)
    data = mdl.createData()
    for _ in range(10):
        q, gamma = rng.normal(size=3), rng.normal(size=3) * 20
        qd = rng.normal(size=3)
        qdd = model.forward_dynamics(q, qd, gamma, PARAMS)
        lam = model.constraint_force(q, qd, gamma, PARAMS)
        tau = pin.rnea(mdl, data, q, qd, qdd)
        np.testing.assert_allclose(tau, gamma - PARAMS.sigma * qd - model.constraint_matrix(q)[0] * lam, atol=1e-9)
        acc_constraint = model.constraint_matrix(q) @ qdd + model.constraint_matrix_dot(q, qd) @ qd
        assert abs(acc_constraint.item()) < 1e-12
        fast = model.forward_dynamics_fast(q[2], *qd, *gamma, *PARAMS.phi, PARAMS.sigma)
        np.testing.assert_allclose(fast, qdd, atol=1e-12)


def test_constraint_matrix_dot_matches_finite_difference():
    q, qd = np.array([0.3, -1.0, 0.7]), np.array([0.5, 0.2, -0.8])
    h = 1e-6
    fd = (model.constraint_matrix(q + h * qd) - model.constraint_matrix(q - h * qd)) / (2 * h)
    np.testing.assert_allclose(model.constraint_matrix_dot(q, qd), fd, atol=1e-9)


def test_projection_annihilates_constraint_direction_and_has_rank_two():
    q = np.array([1.0, 2.0, 0.4])
    proj = model.projection(q, PARAMS)
    np.testing.assert_allclose(proj @ model.constraint_matrix(q).T, 0.0, atol=1e-12)
    np.testing.assert_allclose(proj @ proj, proj, atol=1e-12)
    assert np.linalg.matrix_rank(proj, tol=1e-9) == 2


def test_paper_projection_drifts_sideways_while_exact_form_keeps_the_constraint():
    """30 s of a turning push: lateral speed of the b origin < 1e-9 (exact) but large (paper eq. 5-7)."""

    def gamma_of(q):
        c, s = math.cos(q[2]), math.sin(q[2])
        return np.array([25.0 * c, 25.0 * s, 4.0])  # forward push + steady turning torque

    lateral = {}
    for exact in (True, False):
        q, qd = np.zeros(3), np.zeros(3)
        worst = 0.0
        for k in range(3000):
            q, qd = rk4_step(k * 0.01, q, qd, gamma_of(q), PARAMS, 0.01, exact=exact)
            worst = max(worst, abs(model.lateral_speed(q, qd)))
            if worst > 1.0:  # the projected form has visibly broken the constraint
                break
        lateral[exact] = worst
        if exact:
            assert abs(qd[2]) > 0.05 and abs(q[2]) > 1.0  # it really turned
    assert lateral[True] < 1e-9
    assert lateral[False] > 0.1


def test_contact_wrench_matches_adjoint_grasp_map():
    """Paper eq. (22-24): Gamma = Ad_{g_ab}^T B_a Gamma_ee restricted to (fx, fy, tau_z), then rotated to {s}."""
    rng = np.random.default_rng(2)
    for _ in range(10):
        q = rng.normal(size=3)
        p_b = rng.normal(size=2)
        f_b, tau_a = rng.normal(size=2), rng.normal()
        # wrench at {a} (same orientation as {b}) -> wrench at {b}: f unchanged, n_b = n_a + p x f
        g_ab = pin.SE3(np.eye(3), np.array([p_b[0], p_b[1], 0.0]))
        w_a = pin.Force(np.array([f_b[0], f_b[1], 0.0]), np.array([0.0, 0.0, tau_a]))
        w_b = g_ab.act(w_a)
        rot = np.array([[math.cos(q[2]), -math.sin(q[2])], [math.sin(q[2]), math.cos(q[2])]])
        expected = np.r_[rot @ w_b.linear[:2], w_b.angular[2]]
        np.testing.assert_allclose(model.contact_wrench_to_generalized(q, p_b, f_b, tau_a), expected, atol=1e-12)


def test_params_phi_roundtrip_and_validation():
    p2 = CartParams.from_phi(PARAMS.phi, PARAMS.sigma)
    for name in ("m", "dx", "dy", "I", "sigma"):
        assert getattr(p2, name) == pytest.approx(getattr(PARAMS, name), abs=1e-12)
    assert PARAMS.phi[3] == pytest.approx(2.27 + 20 * (0.09 + 0.0225))
    with pytest.raises(ParameterError):
        CartParams(-1.0, 0, 0, 1.0)
    with pytest.raises(ParameterError):
        CartParams.from_phi([20.0, 6.0, 0.0, 1.0])  # I = 1 - 36/20 < 0
    clipped = project_phi(np.array([-3.0, 6.0, 0.0, 1.0]))
    assert clipped[0] > 0 and CartParams.from_phi(clipped).I > 0


def test_simulate_fast_path_equals_the_generic_rk4_step_path():
    """simulate's float RK4 (exact dynamics, no extra force) is bit for bit the generic `rk4_step` loop."""
    from cart.simulate import MeasurementNoise, ParameterChange, simulate

    def ctrl(t, q, qd):
        return np.array([15.0 * math.cos(q[2]), 15.0 * math.sin(q[2]), 2.0 * math.sin(t)])

    kw = dict(
        noise=MeasurementNoise.from_level(0.005), changes=[ParameterChange(2.0, PARAMS.with_mass(1.5 * PARAMS.m))]
    )
    fast = simulate(PARAMS, ctrl, 5.0, rng=np.random.default_rng(2), **kw)
    generic = simulate(PARAMS, ctrl, 5.0, rng=np.random.default_rng(2), extra_force=lambda *a: np.zeros(3), **kw)
    np.testing.assert_array_equal(fast.true.q, generic.true.q)
    np.testing.assert_array_equal(fast.true.qd, generic.true.qd)
    assert np.ptp(fast.true.q[:, 2]) > 0.5  # the cart turned: the test exercises every state

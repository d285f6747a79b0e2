"""The whole-body QP's joint torque limit (`JointTorqueLimit`): its linear torque model against Pinocchio's RNEA,
and a step that would need more torque than a joint has is held to its limit."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import robots
from wholebody.motion.control import ControllerConfig, ResolvedRateController
from wholebody.motion.experiments import initial_state
from wholebody.motion.kinematics import wholebody_for
from wholebody.motion.limits import JointTorqueLimit
from wholebody.motion.qp import StepState


@pytest.fixture(scope="module")
def wb():
    return wholebody_for(robots.load("wmra"), "wheels")


def rnea_torque(wb, x, u, u_prev, dt, wrenches):
    """Return the arm torques Pinocchio gives for input u after u_prev (over dt) and the hands' wrenches."""
    q, S = wb.to_pinocchio_q(x), wb.input_map
    data = wb.model.createData()
    tau = pin.rnea(wb.model, data, q, S @ u, S @ (u - u_prev) / dt)[wb.arm_idx_v]
    for fid, w in wrenches:
        tau += pin.computeFrameJacobian(wb.model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)[:, wb.arm_idx_v].T @ w
    return tau


def test_the_linear_torque_model_is_rnea_to_first_order(wb):
    rng = np.random.default_rng(3)
    x = initial_state(wb)
    u_prev = rng.uniform(-0.5, 0.5, wb.n_u)
    limit = JointTorqueLimit(wb)
    limit.wrenches = [(wb.ee_frame_id, np.array([30.0, -5.0, 10.0, 1.0, 0.5, -2.0]))]
    dt = 0.01
    G, h = limit.inequality(StepState(wb, x, dt, u_prev=u_prev))
    n = wb.n_arm
    step = rng.uniform(-1.0, 1.0, wb.n_u)
    errors = []
    for scale in (0.1, 0.05):
        u = u_prev + scale * step
        model = G[:n] @ u + (limit.limit - h[:n])  # tau = Ma u + bias, with h = limit - bias
        errors.append(np.abs(model - rnea_torque(wb, x, u, u_prev, dt, limit.wrenches)).max())
    assert errors[0] < 1e-2
    assert errors[1] < 0.3 * errors[0]  # the error of a first-order model shrinks with the square of the step


def test_a_step_needing_more_torque_than_a_joint_has_is_held_to_its_limit(wb):
    x = initial_state(wb)
    T = wb.ee_placement(x)
    target = pin.SE3(T.rotation, T.translation + np.array([0.0, 0.0, 0.3]))  # 0.3 m up at once
    cfg = ControllerConfig(gain=50.0, max_linear_speed=5.0)
    free = ResolvedRateController(wb, cfg).step(x, target, None, 0.01)
    zero = np.zeros(wb.n_u)
    tau_free = rnea_torque(wb, x, free.u, zero, 0.01, [])
    limit = JointTorqueLimit(wb)
    limit.limit = 0.5 * np.abs(tau_free).max() * np.ones(wb.n_arm)  # half of what the free step asks for
    held = ResolvedRateController(wb, cfg, extra_limits=[limit]).step(x, target, None, 0.01)
    tau_held = rnea_torque(wb, x, held.u, zero, 0.01, [])
    assert np.abs(tau_free).max() > 1.5 * limit.limit[0]  # without the limit the step asks for more ...
    assert np.abs(tau_held).max() <= limit.limit[0] * (1 + 1e-3)  # ... with it, no joint exceeds it
    assert held.solver_ok and held.position_error == pytest.approx(free.position_error)

"""The base plan's exact Jacobians (`wholebody.push.base_plan.WindowProblem`) against central finite differences."""

import numpy as np
import pytest
from scipy.optimize._numdiff import approx_derivative

from wholebody.push.base_plan import ArmReach, BaseWheels, WindowProblem
from wholebody.push.base_settings import BasePlanSettings


def _problem(nonholonomic: bool) -> tuple[WindowProblem, np.ndarray]:
    rng = np.random.default_rng(7)
    t = np.arange(14) * 0.1
    cart = np.c_[0.8 * t, 0.1 * np.sin(t), 0.9 * t]
    footprint = np.array([[0.5, 0.3], [0.5, -0.3], [-0.5, 0.3], [-0.5, -0.3]])
    reach = ArmReach(np.array([0.3, 0.1]), np.array([-0.2, 0.15]), footprint, 0.7)
    blocked = np.array([[0.0], [1.0], [0.0]]) if nonholonomic else np.zeros((3, 0))
    wheels = BaseWheels(rng.standard_normal((4, 3)), np.ones(4), blocked, 3.0 if nonholonomic else None)
    front = 0.4 if nonholonomic else None
    w = WindowProblem(cart, cart + [-0.9, 0.05, 0.1], reach, wheels, BasePlanSettings(), front, nonholonomic)
    return w, w.z0 + 0.05 * rng.standard_normal(len(w.z0))


@pytest.mark.parametrize("nonholonomic", [False, True])
def test_the_jacobians_match_finite_differences(nonholonomic):
    w, z = _problem(nonholonomic)
    pairs = [(w.objective, w.gradient), (w.constraints, w.constraints_jacobian)]
    if nonholonomic:  # the blocked twist's equality rows, the footprint and the wheel acceleration rows
        pairs.append((w.sideways, w.sideways_jacobian))
    for fun, jac in pairs:
        fd = approx_derivative(fun, z, method="3-point")
        assert np.abs(jac(z) - fd).max() < 1e-7 * max(1.0, np.abs(fd).max())


def test_the_rows_are_the_module_docstring_s_at_the_nominal_place():
    w, _ = _problem(False)
    n, nw = len(w.cart), 4
    g = w.constraints(w.z0)
    rho_row = g[2 * (n - 1) * nw : 2 * (n - 1) * nw + n]  # rho - |mount - wrist|: rho is the nominal reach
    mount = (
        w.nominal[:, :2]
        + np.array(
            [
                np.cos(w.nominal[:, 2]) * 0.3 - np.sin(w.nominal[:, 2]) * 0.1,
                np.sin(w.nominal[:, 2]) * 0.3 + np.cos(w.nominal[:, 2]) * 0.1,
            ]
        ).T
    )
    assert np.allclose(rho_row, 0.7 - np.linalg.norm(w.wrist - mount, axis=1))


def test_the_rows_left_out_change_nothing_on_traj_2_s_first_turn():
    """SLSQP on the screened rows (`WindowProblem.screened`) gives the plan of SLSQP on every row."""
    import math

    import robots
    from cart.trajectories import Turn, UnicycleTrajectory
    from wholebody.push.base_plan import _slsqp, arm_reach, base_wheels, rigid_poses, rim_rates, wheel_windows
    from wholebody.push.robot import make_robots

    turn = UnicycleTrajectory(duration=13.0, stop_start=13.0, turns=(Turn(7.0, 3.0, math.pi / 2),))
    s = BasePlanSettings(step=0.2, lead=1.0, tail=2.0)
    mm = make_robots(robots.load("ridgeback_iiwa"), np.zeros(3), [-0.2])[0]
    reach, wheels = arm_reach(mm, -0.2), base_wheels(mm)
    t = np.arange(0.0, turn.duration + 0.5 * s.step, s.step)
    cart = np.array([turn.sample(float(v))[0] for v in t])
    nominal = rigid_poses(cart, mm.base_offset_b)
    (i0, i1), *_ = wheel_windows(t, rim_rates(nominal, s.step, wheels.H), wheels.limit, s)
    w = WindowProblem(cart[i0 : i1 + 1], nominal[i0 : i1 + 1], reach, wheels, s, None, False)
    kept = w.screened()
    assert len(kept) < 0.75 * len(w.constraints(w.z0))
    screened, full = _slsqp(w, kept), _slsqp(w, None)
    assert w.worst(screened.x) < 1e-3
    assert np.abs(w.poses(screened.x) - w.poses(full.x)).max() < 1e-6

"""The WMRA (differential-drive wheelchair + 7-DoF arm) pushes the cart: nonholonomic base, reach, limits."""

from __future__ import annotations

import numpy as np
import pytest

import robots
from wholebody.contacts.allocation import ArmLimits
from wholebody.contacts.placement import REACH_JOINT_MARGIN, optimal_contact_points, robot_contact_point
from wholebody.errors import InfeasibleWrenchError, WholeBodyError
from wholebody.motion.kinematics import wholebody_for
from wholebody.push import PushConfig, run_push
from wholebody.push.loop import make_reach_map


@pytest.fixture(scope="module")
def wmra_run():
    """A short WMRA push along the turning Traj. 2 with estimation and re-planned contacts."""
    return run_push(PushConfig(robot="wmra", trajectory=2, duration=8.0))


@pytest.fixture(scope="module")
def reach():
    return make_reach_map(PushConfig(robot="wmra"))


def test_base_never_slides_sideways(wmra_run):
    twist = wmra_run.base_twist[:, 0]
    assert np.abs(twist[:, 1]).max() < 1e-9  # lateral body velocity, every step
    # and on the integrated path: each step's chord points along the mean heading (a unicycle arc)
    pose = wmra_run.robot_x[:, 0, :3]
    d = np.diff(pose, axis=0)
    mid = pose[:-1, 2] + d[:, 2] / 2
    lateral = -np.sin(mid) * d[:, 0] + np.cos(mid) * d[:, 1]
    assert np.abs(lateral).max() / wmra_run.config.dt < 1e-9
    assert np.abs(twist[:, 0]).max() > 0.3  # it did drive


def test_arm_joint_and_wheel_limits_hold_at_every_step(wmra_run):
    wb = wholebody_for(robots.load("wmra"), base_input="wheels")
    q = wmra_run.robot_x[:, 0, 3:]
    assert np.all(q >= wb.arm_lower - 1e-9) and np.all(q <= wb.arm_upper + 1e-9)
    qdot = np.diff(q, axis=0) / wmra_run.config.dt
    assert np.all(np.abs(qdot) <= wb.arm_velocity_limit + 1e-6)
    w = wmra_run.wheel_rates[:, 0]
    assert np.all(np.abs(w) <= wb.wheel_velocity_limit + 1e-9)
    acc = np.abs(np.diff(w, axis=0)) / wmra_run.config.dt
    from robots.profiles import profile

    assert acc.max() <= profile("wmra").wheel_acceleration_limit + 1e-6
    m = wmra_run.metrics
    assert m.tracking_max_mm < 20.0 and m.base_lateral_speed_max_m_s < 1e-9


def test_chosen_contacts_are_reachable_with_margin(wmra_run, reach):
    ok = reach.y[reach.reachable]
    ys = wmra_run.contact_y[:, 0]
    assert ys.min() >= ok.min() - 1e-9 and ys.max() <= ok.max() + 1e-9
    for y in np.unique(np.round(ys, 3))[::20]:
        i = reach.index(y)
        assert reach.joint_margin[i] >= REACH_JOINT_MARGIN - 1e-9  # IK converged inside the limits with margin


def test_wmra_contact_differs_from_ridgeback_where_reach_binds(reach):
    gamma = np.array([40.0, 0.0, 8.0])  # a turn whose minimum-effort point lies far right on the handle (y < 0)
    rb = optimal_contact_points(gamma, limits=ArmLimits())
    y_rb = float(rb.points_b[0, 1])
    assert y_rb < reach.y[reach.reachable].min()  # the Ridgeback's point is out of the WMRA's reach
    y_wmra, alloc = robot_contact_point(gamma, reach, torque_fraction=10.0)
    assert reach.is_reachable(y_wmra) and abs(y_wmra - y_rb) > 0.05
    assert alloc.residual < 1e-6
    # harder still: the Ridgeback grips at the end, the WMRA cannot produce it from where it reaches: grip binds
    with pytest.raises(InfeasibleWrenchError) as err:
        robot_contact_point([40.0, 0.0, 12.0], reach, torque_fraction=10.0)
    assert "grip" in err.value.binding


def test_infeasible_requests_name_what_binds(reach):
    with pytest.raises(InfeasibleWrenchError) as err:
        run_push(PushConfig(robot="wmra", contact="fixed", fixed_contact_y=(-0.25,), duration=8.0))
    assert err.value.binding == "reach" and "reaches" in str(err.value)
    with pytest.raises(InfeasibleWrenchError) as err:
        robot_contact_point([140.0, 0.0, 0.0], reach, limits=ArmLimits(max_force=400.0))
    assert err.value.binding.startswith("joint torque")
    with pytest.raises(WholeBodyError):
        PushConfig(robot="shopping_cart")


def test_cli_push_robot_option(capsys):
    from cartpush.cli.app import main

    assert main(["push", "--robot", "nope", "--duration", "8", "--json"]) == 2
    assert "--robot" in capsys.readouterr().err

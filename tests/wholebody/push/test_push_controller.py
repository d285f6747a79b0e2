"""The push controller driven by recorded measurements alone: no plant, no simulated truth."""

from __future__ import annotations

import numpy as np
import pytest

from wholebody.errors import WholeBodyError
from wholebody.push import Measurement, PushConfig, RobotReading, build_controller, kinematic_plant

CONFIG = PushConfig(trajectory=2, duration=3.0, contact="fixed", fixed_contact_y=(0.0,))


@pytest.fixture(scope="module")
def recorded():
    """Measurements and commands of a live run on the kinematic plant."""
    setup = build_controller(CONFIG)
    plant = kinematic_plant(CONFIG, setup)
    measurements, commands = [], []
    for _ in range(int(round(CONFIG.duration / CONFIG.dt))):
        m = plant.measure()
        cmds = setup.controller.step(m)
        measurements.append(m)
        commands.append(cmds)
        plant.step(cmds)
    return measurements, commands, setup.controller.estimator.params()


def test_replayed_measurements_give_the_same_commands(recorded):
    measurements, commands, final = recorded
    ctrl = build_controller(CONFIG).controller  # a fresh controller; no plant exists
    for m, live in zip(measurements, commands):
        out = ctrl.step(m)
        for a, b in zip(out, live):
            np.testing.assert_array_equal(a.arm_torque, b.arm_torque)
            np.testing.assert_array_equal(a.base_twist, b.base_twist)
            np.testing.assert_array_equal(a.hand_wrench, b.hand_wrench)
    assert ctrl.estimator.params().m == final.m
    # from 16 kg, the recorded pushes alone move the estimate towards the 20 kg cart
    assert abs(final.m - CONFIG.true_params.m) < abs(CONFIG.initial_mass - CONFIG.true_params.m)


def test_the_estimate_follows_the_measured_wrench_not_a_truth(recorded):
    """Doubling every F/T reading doubles the mass the controller estimates: it reads only measurements."""
    measurements, _, final = recorded
    ctrl = build_controller(CONFIG).controller
    for m in measurements:
        robots = tuple(RobotReading(r.base_pose, r.base_twist, r.q_arm, r.v_arm, 2.0 * r.ft) for r in m.robots)
        ctrl.step(Measurement(m.t, m.cart_pose, m.cart_velocity, robots))
    assert ctrl.estimator.params().m > 1.5 * final.m


def test_a_measurement_with_the_wrong_number_of_robots_is_refused(recorded):
    m = recorded[0][0]
    ctrl = build_controller(CONFIG).controller
    with pytest.raises(WholeBodyError, match="robots"):
        ctrl.step(Measurement(m.t, m.cart_pose, m.cart_velocity, m.robots * 2))


def test_a_user_path_through_waypoints_is_pushed():
    from cart.trajectories import WaypointTrajectory
    from wholebody.push import run_push

    traj = WaypointTrajectory(((0.0, 0.0), (1.5, 0.0), (2.5, 0.8)), speed=0.4)
    r = run_push(PushConfig(trajectory=traj, duration=traj.duration + 0.5, contact="fixed", fixed_contact_y=(0.0,)))
    end = traj.sample(traj.duration)[0]
    assert r.metrics.tracking_max_mm < 20.0
    assert np.hypot(*(r.q_true[-1, :2] - end[:2])) < 0.02  # the cart reached the last waypoint
    with pytest.raises(WholeBodyError, match="trajectory"):
        PushConfig(trajectory=3)


def test_a_run_says_when_it_lost_the_cart():
    from wholebody.push.loop import _lost_at

    err = np.r_[np.zeros(100), np.linspace(0.0, 1.0, 101)]
    assert _lost_at(err, 0.01) == pytest.approx(1.26)  # the first sample beyond 0.25 m
    assert _lost_at(np.zeros(10), 0.01) is None

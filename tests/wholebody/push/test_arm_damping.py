"""The torque law's joint impedance on a light null-space motion, integrated as the physics step does.

A straight iiwa elbow adds the counter-rotation of joints 3 and 5 to the hand's null space: a motion of a few
hundredths of kg m^2. Held explicitly, the impedance's damping (20 N m s/rad) over a 2 ms step flips that motion's
velocity every step and grows (`TorqueArmGains.implicit_damping`).
"""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from wholebody.push.arm_control import TorqueArmGains, TorqueArmLaw, implicit_impedance, null_space_projector_T

LIMIT = np.array([320.0, 320.0, 176.0, 176.0, 110.0, 40.0, 40.0])
DT = 0.002


def _held_arm(light: float) -> tuple[np.ndarray, np.ndarray]:
    """Return (J, M): a hand Jacobian whose null space is joint 3's motion alone, of inertia `light` (kg m^2)."""
    rng = np.random.default_rng(5)
    J = rng.normal(size=(6, 7))
    J[:, 2] = 0.0  # joint 3 does not move the hand: the null space
    M = np.diag([3.0, 3.0, light, 2.0, 1.0, 0.5, 0.5])
    return J, M


def _run(gains: TorqueArmGains, light: float, steps: int = 100) -> np.ndarray:
    """Return the joint velocities over `steps` physics steps (semi-implicit Euler, the torque held over each step)
    of an arm whose null-space joint starts at 0.1 rad/s, the plan at rest."""
    J, M = _held_arm(light)
    law = TorqueArmLaw(LIMIT, gains, DT)
    z = np.zeros(7)
    law.begin(np.zeros(6), z, z, z, J, M, t_end=steps * DT, dt=steps * DT)
    q, v = np.zeros(7), np.zeros(7)
    v[2] = 0.1
    NT = null_space_projector_T(J, M)
    out = []
    for k in range(steps):
        tau = law.torque(k * DT, q, v, np.zeros(7))
        v = v + DT * np.linalg.solve(M, NT @ tau)  # the held hand: only the null space moves
        q = q + DT * v
        out.append(v[2])
    return np.array(out)


@pytest.mark.parametrize("light", [0.01, 0.015])
def test_the_impedance_damps_a_light_null_space_motion(light):
    explicit = _run(TorqueArmGains(implicit_damping=False), light)
    implicit = _run(TorqueArmGains(), light)
    assert np.abs(explicit[-10:]).max() > 1.0  # the inertia below D dt / 2 = 0.02: grows every step
    assert np.abs(implicit).max() <= 0.1  # never above the start
    assert np.abs(implicit[10:]).max() < 0.01  # damped within a few steps


def test_implicit_impedance_is_the_explicit_one_on_a_heavy_motion_and_stays_in_the_null_space():
    J, M = _held_arm(light=0.01)
    NT = null_space_projector_T(J, M)
    A = implicit_impedance(NT, M, damping=20.0, dt=DT)
    x = np.random.default_rng(1).normal(size=7)
    assert np.allclose(J @ np.linalg.solve(M, A @ x), 0.0, atol=1e-6)  # no force on a held hand
    heavy = np.diag([3.0, 3.0, 50.0, 2.0, 1.0, 0.5, 0.5])
    NT_h = null_space_projector_T(J, heavy)
    assert np.allclose(implicit_impedance(NT_h, heavy, 20.0, DT) @ x, NT_h @ x, rtol=2e-3, atol=2e-3 * np.abs(x).max())


@pytest.fixture(scope="module")
def setup():
    from wholebody.push import PushConfig, build_controller

    return build_controller(PushConfig(trajectory=2, duration=2.0, contact="fixed"))


@pytest.mark.parametrize("implicit", [True, False])
def test_a_straight_iiwa_elbow_in_mujoco_stays_still_with_the_implicit_damping(setup, implicit):
    """The iiwa in MuJoCo, hand released, elbow (joint 4) 0.02 rad from straight, joints 3 and 5 counter-rotating at
    0.5 rad/s (a motion of the hand's null space there): the law holding the posture damps it, or, held explicitly,
    drives it to the torque limits."""
    from tests.wholebody.push.mujoco_hold import hold_commands, quiet_plant
    from wholebody.push.mujoco_plant import MujocoPlantConfig

    gains = TorqueArmGains(force_feedback=0.0, implicit_damping=implicit)
    plant = quiet_plant(setup, config=MujocoPlantConfig(torque_gains=gains))
    m, d, r = plant.scene.model, plant.scene.data, plant.scene.robots[0]
    d.eq_active[r.weld] = 0  # the hand let go
    q = d.qpos[r.arm_qpos]
    q[3] = 0.02
    d.qpos[r.arm_qpos] = q
    d.qvel[r.arm_dof] = 0.0
    d.qvel[r.arm_dof[2]], d.qvel[r.arm_dof[4]] = 0.5, -0.5
    mujoco.mj_forward(m, d)
    hold = replace(hold_commands(plant)[0], arm_position=q.copy())  # the straight elbow's posture
    speeds = []
    for _ in range(20):
        plant.step([hold])
        speeds.append(float(np.abs(d.qvel[r.arm_dof[[2, 4]]]).max()))
    if implicit:
        assert max(speeds[5:]) < 0.05 and plant.report()["plant_arm_torque_limit_ratio"] < 0.5
    else:  # measured: 4-6 rad/s alternating from the first period
        assert plant.report()["plant_arm_torque_limit_ratio"] >= 1.0 and max(speeds) > 2.0

"""Robots known only by a profile file enter the MuJoCo plant: TIAGo from example-robot-data (COLLADA meshes MuJoCo
cannot read, a torso held by the profile, fixed ball casters), and the URDF rewriting that makes any robot compile."""

from __future__ import annotations

import math
import warnings

import mujoco
import numpy as np
import pinocchio as pin
import pytest

import robots
from robots.checks import reference_configuration
from robots.urdf_text import matrix_from_rpy
from tests.robots.profile_files import need_example_robot_data, tiago_profile
from wholebody.push import PushConfig, build_controller
from wholebody.push.mujoco_plant import MujocoPlant
from wholebody.push.cart_file import cart_source
from wholebody.push.config import TRUE_CART
from wholebody.push.mujoco_scene import ARM_TORQUE, ARM_VELOCITY, MujocoSceneWarning, RobotSetup, compose
from wholebody.push.mujoco_urdf import equivalent_box, mujoco_urdf, physical_inertia

ARM = tuple(f"arm_{i}_joint" for i in range(1, 8))


@pytest.fixture(scope="module")
def tiago(tmp_path_factory):
    path = tiago_profile(tmp_path_factory.mktemp("tiago"))
    return str(path), robots.load(str(path))


def _tiago_scene(loaded, x):
    prof = loaded.profile
    setup = RobotSetup(
        name="tiago",
        urdf=str(loaded.urdf),
        base="differential",
        arm_joints=ARM,
        wheel_joints=tuple(prof.wheel_joints),
        x=x,
        arm_mode=ARM_VELOCITY,
        ee_link="arm_tool_link",
        ft_link="wrist_ft_link",
        package_dirs=tuple(str(d) for d in prof.package_dirs),
        locked=tuple(prof.locked),
    )
    cart = cart_source(TRUE_CART)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = compose(cart.spec(), (2.0, 0.0, 0.0), cart.z, [setup], 0.002)
    return scene, [w for w in caught if issubclass(w.category, MujocoSceneWarning)]


def test_tiago_composes_with_its_meshes_replaced_its_mass_and_its_torso_kept(tiago):
    _, loaded = tiago
    x = np.r_[0.3, -0.1, 0.4, 0.2, -0.5, 0.1, 1.2, -0.3, 0.4, 0.2]  # base pose, 7 arm joints
    scene, caught = _tiago_scene(loaded, x)
    m, d, r = scene.model, scene.data, scene.robots[0]
    # the COLLADA collision meshes are replaced, said in a warning and on the robot's index
    assert r.replaced_meshes and all(".dae" in s and "box" in s for s in r.replaced_meshes)
    assert len(caught) == 1 and "arm_1_collision.dae" in str(caught[0].message)
    listed = str(caught[0].message).split("collide): ")[1].split(", ")
    assert len(listed) == len(set(listed))  # a link's visual and collision shapes naming one file: listed once
    assert f"{len(listed)} meshes MuJoCo cannot read" in str(caught[0].message)
    # the URDF's mass, as Pinocchio sums it
    bodies = [b for b in range(m.nbody) if mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b).startswith("r0/")]
    assert m.body_mass[bodies].sum() == pytest.approx(pin.computeTotalMass(loaded.model), rel=1e-6)
    # the torso held at the profile's 0.2 m: the hand where Pinocchio puts it (torso locked, same base and arm)
    q = reference_configuration(loaded.profile, loaded.model)
    q[:4] = (x[0], x[1], math.cos(x[2]), math.sin(x[2]))
    for name, v in zip(ARM, x[3:]):
        q[loaded.model.joints[loaded.model.getJointId(name)].idx_q] = v
    pin.framesForwardKinematics(loaded.model, loaded.data, q)
    hand = loaded.data.oMf[loaded.model.getFrameId("arm_tool_link")]
    np.testing.assert_allclose(d.site_xpos[r.hand_site], hand.translation, atol=1e-9)
    np.testing.assert_allclose(d.site_xmat[r.hand_site].reshape(3, 3), hand.rotation, atol=1e-9)
    # only the arm, the wheels and the base move; the F/T sensor holds the hand and the tool beyond its frame
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "r0/torso_lift_joint") < 0
    assert mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.site_bodyid[r.ft_site]) == "r0/arm_tool_link"
    assert r.tool_mass == pytest.approx(0.3)


def test_tiago_stands_on_its_wheels_and_casters(tiago):
    _, loaded = tiago
    scene, _ = _tiago_scene(loaded, np.r_[0.0, 0.0, 0.0, 0.2, -0.5, 0.1, 1.2, -0.3, 0.4, 0.2])
    m, d, r = scene.model, scene.data, scene.robots[0]
    assert r.base == "differential" and r.base_model == "wheels" and r.wheel_radius == pytest.approx(0.0985)
    z0 = float(d.qpos[r.base_qpos[2]])
    d.eq_active[r.weld] = 0  # no cart in hand: the robot alone on the floor, arm and wheels held by their servos
    for _ in range(250):
        mujoco.mj_step(m, d)
    touching = {
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, int(c.geom[i])) for c in d.contact[: d.ncon] for i in (0, 1)
    }
    assert {"r0/wheel_left_link_tyre", "r0/wheel_right_link_tyre"} <= touching
    assert sum("caster" in str(n) for n in touching) >= 3  # a two-wheel base rests on its casters
    assert abs(float(d.qpos[r.base_qpos[2]]) - z0) < 2e-3  # neither sinking nor tipping


@pytest.mark.filterwarnings("ignore::wholebody.push.mujoco_scene.MujocoSceneWarning")
def test_tiagos_ft_sensor_reads_the_grasps_constraint_force(tiago):
    """TIAGo's hand frame comes before its F/T frame: the sensor on the hand's body reads what holds the handle."""
    from cart.simulate import MeasurementNoise
    from tests.wholebody.push.test_mujoco_plant import _weld_wrench_on_cart
    from wholebody.push.arm_control import TorqueArmGains
    from wholebody.push.mujoco_plant import MujocoPlantConfig
    from wholebody.push.plant import RobotCommand

    config = PushConfig(robot=tiago[0], trajectory=1, plant="mujoco", contact="fixed")
    setup = build_controller(config)
    gains = MujocoPlantConfig(torque_gains=TorqueArmGains(feedforward="bias", force_feedback=0.0))
    plant = MujocoPlant(
        setup.controller.robots, setup.q0, TRUE_CART, noise=MeasurementNoise(), config=gains, arm_modes=[ARM_TORQUE]
    )
    push = np.array([12.0, -4.0, 0.0, 0.0, 0.0, 0.5])  # world-aligned at the grasp, on the cart
    errors = []
    for _ in range(40):
        q = plant.measure().robots[0].q_arm
        z = np.zeros(q.size)
        plant.step([RobotCommand(z, q.copy(), z, np.zeros(3), np.zeros(2), push)])
        d, r = plant.scene.data, plant.scene.robots[0]
        mujoco.mj_forward(plant.scene.model, d)
        w = plant._hand_wrench_world(0, plant._sensor_wrench(0))
        arm = d.site_xpos[r.hand_site] - d.xpos[plant.scene.cart_body]
        errors.append(np.r_[w[:3], w[3:] + np.cross(arm, w[:3])] - _weld_wrench_on_cart(plant))
    assert np.abs(np.array(errors)[:, :3]).max() < 1.0  # up to the 0.3 kg tool's inertia beyond the sensor


@pytest.mark.filterwarnings("ignore::wholebody.push.mujoco_scene.MujocoSceneWarning")
def test_a_short_mujoco_push_with_tiagos_profile(tiago):
    """Traj. 1's first 1.5 s on the MuJoCo plant, the arm torque-controlled: the cart follows, the hand holds, the
    base rolls with it."""
    path, _ = tiago
    config = PushConfig(robot=path, trajectory=1, plant="mujoco", contact="fixed")
    setup = build_controller(config)
    plant = MujocoPlant(setup.controller.robots, setup.q0, config.true_params, arm_modes=[ARM_TORQUE])
    traj = config.make_trajectory()
    base0, errors = plant.robot_states()[0][:2].copy(), []
    for _ in range(150):
        m = plant.measure()
        errors.append(np.hypot(*(m.cart_pose[:2] - traj.sample(m.t)[0][:2])))
        plant.step(setup.controller.step(m))
    report = plant.report()
    cart, _ = plant.cart_state()
    moved = np.hypot(*(traj.sample(1.5)[0][:2] - traj.sample(0.0)[0][:2]))
    assert moved > 0.05 and max(errors) < 0.02  # the cart moved and followed the plan
    assert report["grasp_slip_max_m"] < 0.005 and report["base_wheel_slip_max_m_s"] is not None
    base_moved = np.hypot(*(plant.robot_states()[0][:2] - base0))
    assert base_moved == pytest.approx(moved, abs=0.02)  # the base rolled along with the cart


@pytest.mark.filterwarnings("ignore::wholebody.push.mujoco_scene.MujocoSceneWarning")
def test_tiagos_velocity_servos_take_their_gains_from_the_arms_limits(tiago):
    """The default arm law of a profile robot: each servo's damping is its joint's effort over its speed limit (TIAGo's
    3 N m wrist: 1.5 N m s/rad, not the WMRA's 80) and the admittance's loop gain is the same in every direction."""
    from wholebody.push.admittance_tuning import LOOP_GAIN, loop_admittance, loop_gains
    from wholebody.push.admittance_law import AdmittanceGains
    from wholebody.push.mujoco_plant import MujocoPlantConfig

    path, loaded = tiago
    config = PushConfig(robot=path, trajectory=1, plant="mujoco", contact="fixed")
    setup = build_controller(config)
    plant = MujocoPlant(setup.controller.robots, setup.q0, config.true_params)
    r, law = plant.scene.robots[0], plant._laws[0]
    kv = plant.scene.model.actuator_gainprm[r.arm_actuators, 0]
    wb = setup.controller.robots[0].wb
    assert kv == pytest.approx(np.minimum(wb.arm_effort_limit / wb.arm_velocity_limit, 80.0))
    assert kv[4] == pytest.approx(3.0 / 1.95)
    assert np.asarray(law.gains.servo_kv) == pytest.approx(kv) and law.gains.loop_gain == LOOP_GAIN
    J, _ = plant._arm_jacobian_inertia(r)
    assert loop_gains(J, kv, loop_admittance(J, kv, LOOP_GAIN)) == pytest.approx(np.full(6, LOOP_GAIN))
    fixed = MujocoPlant(
        setup.controller.robots,
        setup.q0,
        config.true_params,
        config=MujocoPlantConfig(admittance=AdmittanceGains(from_arm=False, loop_gain=None)),
    )
    assert np.all(fixed.scene.model.actuator_gainprm[r.arm_actuators, 0] == 80.0)
    assert fixed._laws[0].gains.loop_gain is None


@pytest.mark.filterwarnings("ignore::wholebody.push.mujoco_scene.MujocoSceneWarning")
def test_a_short_mujoco_push_with_tiagos_default_velocity_servos(tiago):
    """Traj. 1's first 3 s on the MuJoCo plant with TIAGo's default arm law (velocity servos, gains from its limits):
    the cart follows and no servo drives its joint far past the effort limit (the WMRA's gains: 100x within 0.5 s)."""
    path, _ = tiago
    config = PushConfig(robot=path, trajectory=1, plant="mujoco", contact="fixed")
    setup = build_controller(config)
    plant = MujocoPlant(setup.controller.robots, setup.q0, config.true_params)
    traj = config.make_trajectory()
    errors = []
    for _ in range(300):
        m = plant.measure()
        errors.append(np.hypot(*(m.cart_pose[:2] - traj.sample(m.t)[0][:2])))
        plant.step(setup.controller.step(m))
    report = plant.report()
    # 4.8 cm at most with the tip-over bound's margin (the prior's CoM std leaves the hands less sideways push at
    # the start), under 3 cm without it; the WMRA's gains lose the cart at 3.16 s
    assert max(errors) < 0.06 and report["grasp_slip_max_m"] < 0.005
    # the velocity errors of the start ask TIAGo's servos for up to 2.2x a joint's limit before clipping
    assert report["plant_arm_torque_limit_ratio"] < 2.5


URDF = """<robot name="r">
  <link name="a"><inertial><origin xyz="0.1 0 0" rpy="0 0 0.5"/><mass value="2"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.06"/></inertial>
    <visual><geometry><mesh filename="a.dae"/></geometry></visual>
    <collision><geometry><mesh filename="missing.stl"/></geometry></collision></link>
  <link name="b"><collision><geometry><mesh filename="b.stl"/></geometry></collision></link>
  <link name="c"><inertial><mass value="1e-6"/>
    <inertia ixx="2e-8" ixy="6e-8" ixz="1e-8" iyy="3e-8" iyz="1e-8" izz="4e-8"/></inertial></link>
  <joint name="ab" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="bc" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0 0 1"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
</robot>"""


def test_the_urdf_rewriting_replaces_meshes_fixes_inertias_and_locks_joints(tmp_path):
    (tmp_path / "a.dae").write_text("<COLLADA/>")
    path = tmp_path / "r.urdf"
    path.write_text(URDF)
    out = mujoco_urdf(path, locked={"ab": 0.3, "bc": 0.5})
    assert len(out.replaced_meshes) == 3  # a.dae (format), missing.stl (not found), b.stl (not found; b massless)
    assert [m.reason for m in out.replaced_meshes] == ["MuJoCo does not read .dae meshes", "not found", "not found"]
    assert "dropped" in out.replaced_meshes[2].replacement and out.fixed_inertias == ("c",)
    assert out.fixed_joints == ("ab = 0.3", "bc = 0.5")
    model = mujoco.MjSpec.from_string(out.text)
    model.compiler.fusestatic = False
    compiled = model.compile()
    d = mujoco.MjData(compiled)
    mujoco.mj_kinematics(compiled, d)
    c = mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_BODY, "c")
    np.testing.assert_allclose(d.xpos[c], [0, 0, 1.3], atol=1e-12)  # 0.3 m up the slide, then 1 m
    np.testing.assert_allclose(d.xmat[c].reshape(3, 3)[:, 0], [math.cos(0.5), 0, -math.sin(0.5)], atol=1e-12)
    assert compiled.body_mass.sum() == pytest.approx(2.0 + 1e-6)  # b has no <inertial>: massless, as in Pinocchio


def test_the_equivalent_box_has_the_links_inertia():
    import xml.etree.ElementTree as ET

    T, sides = equivalent_box(ET.fromstring(URDF).find("link"))
    a, b, c = sides
    moments = 2.0 / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    Rz = matrix_from_rpy(0.0, 0.0, 0.5)  # the inertial's frame in the link's
    expected = Rz @ np.diag([0.02, 0.05, 0.06]) @ Rz.T
    np.testing.assert_allclose(T[:3, :3] @ np.diag(moments) @ T[:3, :3].T, expected, atol=1e-12)
    assert T[:3, 3] == pytest.approx([0.1, 0, 0])
    assert physical_inertia(np.diag([1.0, 1.0, 3.0])) == pytest.approx(np.eye(3) * 5 / 3)
    assert physical_inertia(np.diag([1.0, 2.0, 2.5])) is None and physical_inertia(np.zeros((3, 3))) is None
    assert np.diag(physical_inertia(np.diag([1.0, 1.0, 0.0]))) == pytest.approx([1.0, 1.0, 1e-6])  # a thin rod


def _two_wheeler(tmp_path, caster: bool) -> str:
    """Return the path of a two-wheeled base with a one-joint arm, with or without a ball caster under its nose."""
    from robots.urdf_text import Inertial, Shape, joint, link, robot

    wheel = (Shape("cylinder", (0.1, 0.04), rpy=(math.pi / 2, 0, 0)),)
    parts = [
        link("root"),
        link("base", Inertial(20.0, (0, 0, 0), 0.5, 0.5, 0.5), (Shape("box", (0.5, 0.4, 0.1)),)),
        joint("root_base", "fixed", "root", "base", xyz=(0, 0, 0.2)),
        link("wheel_l", Inertial(1.0, (0, 0, 0), 0.003, 0.005, 0.003), wheel),
        link("wheel_r", Inertial(1.0, (0, 0, 0), 0.003, 0.005, 0.003), wheel),
        joint("wl", "continuous", "base", "wheel_l", xyz=(0, 0.25, -0.1), axis=(0, 1, 0), limit=(0, 0, 10, 10)),
        joint("wr", "continuous", "base", "wheel_r", xyz=(0, -0.25, -0.1), axis=(0, 1, 0), limit=(0, 0, 10, 10)),
        link("arm", Inertial(2.0, (0.2, 0, 0), 0.01, 0.03, 0.03), (Shape("box", (0.4, 0.05, 0.05), xyz=(0.2, 0, 0)),)),
        joint("a1", "revolute", "base", "arm", xyz=(0, 0, 0.3), axis=(0, 0, 1), limit=(-2, 2, 50, 1)),
        link("hand", Inertial(0.5, (0, 0, 0), 0.001, 0.001, 0.001)),
        joint("a_hand", "fixed", "arm", "hand", xyz=(0.4, 0, 0)),
    ]
    if caster:
        parts += [
            link("ball", None, (Shape("sphere", (0.05,)),)),
            joint("b", "fixed", "base", "ball", xyz=(0.2, 0, -0.15)),
        ]
    path = tmp_path / f"two_wheeler_{caster}.urdf"
    path.write_text(robot("two_wheeler", "".join(parts)))
    return str(path)


@pytest.mark.parametrize("caster", [True, False])
def test_a_differential_base_rolls_on_its_wheels_and_what_else_is_on_the_floor(tmp_path, caster):
    setup = RobotSetup(
        name="two_wheeler",
        urdf=_two_wheeler(tmp_path, caster),
        base="differential",
        arm_joints=("a1",),
        wheel_joints=("wl", "wr"),
        x=np.zeros(4),
        arm_mode=ARM_TORQUE,
        ee_link="hand",
        ft_link="hand",
    )
    cart = cart_source(TRUE_CART)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = compose(cart.spec(), (2.0, 0.0, 0.0), cart.z, [setup], 0.002).robots[0]
    notes = [str(w.message) for w in caught if issubclass(w.category, MujocoSceneWarning)]
    if caster:  # on its wheels and the ball; a base without anything else on the floor would tip over
        assert (r.base, r.base_model, r.wheel_radius, notes) == ("differential", "wheels", pytest.approx(0.1), [])
    else:
        assert (r.base, r.base_model) == ("planar", "planar") and "planar base under velocity servos" in notes[0]


def test_every_example_robot_data_urdf_compiles_in_mujoco():
    """Robots we did not write: every URDF example-robot-data installs (COLLADA meshes, invalid inertias) compiles."""
    from pathlib import Path

    from robots.checks import package_search_dirs

    need_example_robot_data()
    share = [Path(d) / "example-robot-data" for d in package_search_dirs((), Path(__file__))]
    files = sorted(f for d in share if d.is_dir() for f in d.glob("robots/*/robots/*.urdf"))
    assert len(files) >= 10
    failed = {}
    for f in files:
        spec = mujoco.MjSpec.from_string(mujoco_urdf(f, locked={}).text)
        spec.compiler.fusestatic = False
        try:
            spec.compile()
        except ValueError as exc:
            failed[f.name] = str(exc).splitlines()[0]
    assert not failed


def test_a_moving_link_without_mass_is_named_when_mujoco_refuses_it(tmp_path):
    """The WMRA's left wheel (a continuous joint) without <inertial>: MuJoCo refuses a moving body without mass;
    the error names the link and the fix. Without the wheel's mass the URDF is fine for Pinocchio."""
    import re

    from wholebody.push.mujoco_scene import SceneCompositionError, _compile_urdf, massless_moving_links

    text = (robots.DATA_DIR / "wmra.urdf").read_text()
    wheel = re.search(r'(<link name="wheel_left">\s*)<inertial>.*?</inertial>', text, re.S)
    assert wheel is not None
    bare = text[: wheel.start()] + wheel.group(1) + text[wheel.end() :]
    assert massless_moving_links(text) == [] and massless_moving_links(bare) == ["wheel_left"]
    (tmp_path / "wmra.urdf").write_text(text)
    (tmp_path / "bare.urdf").write_text(bare)
    _compile_urdf(mujoco_urdf(tmp_path / "wmra.urdf").text, "wmra")
    with pytest.raises(SceneCompositionError, match=r"without mass: wheel_left; give each an <inertial>"):
        _compile_urdf(mujoco_urdf(tmp_path / "bare.urdf").text, "wmra")

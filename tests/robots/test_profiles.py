"""Robot profiles (TOML): format, one registry, `robots.load(NAME | PROFILE.toml)`, meshes, one-line errors."""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import robots
from robots.errors import ProfileError, RobotError, UnknownRobotError
from robots.profiles import PROFILES, profile
from tests.robots.profile_files import TIAGO_ARM, tiago_profile, write_profile
from wholebody.motion.kinematics import wholebody_for

WMRA = robots.DATA_DIR / "wmra.urdf"
WMRA_ARM = [f"arm_joint{i}" for i in range(1, 8)]


def wmra_text(arm: str | None = None, **over: str | None) -> str:
    """Return a minimal WMRA profile (URDF next to it: 'wmra.urdf'): top-level keys replaced by `over`, the
    [[arms]] table's body by `arm`."""
    keys = {
        "name": '"wmra_copy"',
        "urdf": '"wmra.urdf"',
        "base": '"differential"',
        "wheel_joints": '["wheel_left_joint", "wheel_right_joint"]',
    }
    keys.update(over)
    keys = {k: v for k, v in keys.items() if v is not None}  # None: the key left out
    joints = ", ".join(f'"{j}"' for j in WMRA_ARM)
    body = arm if arm is not None else f'joints = [{joints}]\ngripper_frame = "ee"\n'
    return "".join(f"{k} = {v}\n" for k, v in keys.items()) + "[[arms]]\n" + body


@pytest.fixture
def wmra_dir(tmp_path):
    shutil.copy(WMRA, tmp_path / "wmra.urdf")
    return tmp_path


def test_builtin_robots_are_profiles_in_one_registry():
    assert robots.available() == ("ridgeback_iiwa", "shopping_cart", "wmra")
    assert set(PROFILES) == set(robots.available())
    for name in robots.available():
        path = robots.DATA_DIR / f"{name}.toml"
        assert profile(name) == robots.read_profile(path)  # the shipped file is the registry's entry
        assert tomllib.loads(path.read_text())["name"] == name
    rb = profile("ridgeback_iiwa")
    assert rb.base == "holonomic" and rb.arm_joints == tuple(f"iiwa_joint_{i}" for i in range(1, 8))
    assert rb.ft_frame == "ft_sensor" and rb.push_arm_seed is not None and rb.tuned


def test_load_a_profile_file_with_a_relative_urdf(wmra_dir):
    path = write_profile(wmra_dir, wmra_text())
    r = robots.load(path)
    assert r.name == "wmra_copy" and r.urdf == wmra_dir / "wmra.urdf"
    assert r.profile.source == path and r.frames["ee"] == "ee" and r.frames["base"] == "base_footprint"
    assert robots.load(str(path)).model.nv == robots.load("wmra").model.nv
    # the base read off the URDF: the WMRA's track and wheel radius (robots/wmra.py constants)
    wb = wholebody_for(r)
    assert wb.base.track == pytest.approx(robots.wmra.WMRA_TRACK, abs=1e-12)
    assert wb.base.wheel_radius == pytest.approx(robots.wmra.WMRA_WHEEL_RADIUS, abs=1e-12)


def test_register_makes_a_name_and_unregister_removes_it(wmra_dir):
    path = write_profile(wmra_dir, wmra_text(name='"wmra_registered"'))
    try:
        prof = robots.register(path)
        assert "wmra_registered" in robots.available() and robots.load("wmra_registered").profile == prof
        with pytest.raises(ProfileError, match="registered"):
            other = write_profile(wmra_dir, wmra_text(name='"wmra_registered"', wheel_radius="0.2"), "b.toml")
            robots.register(other)
    finally:
        robots.unregister("wmra_registered")
    assert "wmra_registered" not in robots.available()
    with pytest.raises(ProfileError, match="built-in"):
        robots.unregister("wmra")
    with pytest.raises(UnknownRobotError, match=r"ridgeback_iiwa, shopping_cart, wmra, or the path of a robot profile"):
        robots.load("tiago")


def test_tiago_from_example_robot_data_loads_with_its_meshes(tmp_path):
    path = tiago_profile(tmp_path)
    r = robots.load(path)
    assert r.name == "tiago" and r.urdf.name == "tiago_no_hand.urdf"
    meshes = [Path(g.meshPath) for g in r.visual_model.geometryObjects if g.meshPath.lower().endswith((".stl", ".dae"))]
    assert len(meshes) > 20 and all(p.is_file() for p in meshes)  # resolved to files of example-robot-data
    # wheel radius and separation read off the URDF = the values of its wheel joints (0.0985 m, 2 x 0.2022 m)
    wb = wholebody_for(r)
    assert wb.base.wheel_radius == pytest.approx(0.0985, abs=1e-9)
    assert wb.base.track == pytest.approx(0.4044, abs=1e-9)
    assert wb.n_arm == 7 and wb.arm_joints == tuple(TIAGO_ARM)
    # urdf_text of the same robot finds the meshes through the profile's package folders as well
    text = r.urdf.read_text()
    again = robots.load(path, urdf_text=text)
    assert len(again.visual_model.geometryObjects) == len(r.visual_model.geometryObjects)


def test_locked_joints_hold_their_value(tmp_path):
    r = robots.load(tiago_profile(tmp_path))
    wb = wholebody_for(r)
    x = np.r_[0.3, -0.2, 0.4, np.full(7, 0.3)]
    q = wb.to_pinocchio_q(x)
    torso = r.model.joints[r.model.getJointId("torso_lift_joint")]
    assert q[torso.idx_q] == pytest.approx(0.2)
    # independent: Pinocchio's FK of a configuration written by hand
    q2 = pin.neutral(r.model)
    q2[:4] = [0.3, -0.2, np.cos(0.4), np.sin(0.4)]
    q2[torso.idx_q] = 0.2
    for name in TIAGO_ARM:
        q2[r.model.joints[r.model.getJointId(name)].idx_q] = 0.3
    pin.framesForwardKinematics(r.model, r.data, q2)
    np.testing.assert_allclose(
        wb.ee_placement(x).homogeneous, r.data.oMf[r.frame_id("arm_tool_link")].homogeneous, atol=1e-12
    )


@pytest.mark.parametrize(
    "over, key, fix",
    [
        ({"urdf": '"missing.urdf"'}, "urdf", "not found"),
        ({"base": '"tracked"'}, "base", "must be one of"),
        ({"wheel_joints": '["wheel_left_joint"]'}, "wheel_joints", "needs 2 wheel joints"),
        ({"wheel_joints": '["wheel_left_joint", "arm_joint1"]'}, "wheel_joints[1]", "not a continuous joint"),
        ({"colour": '"red"'}, "colour", "unknown key"),
        (
            {"arm": 'joints = ["arm_joint1", "elbow"]\ngripper_frame = "ee"\n'},
            "arms[0].joints[1]",
            "not a movable joint",
        ),
        (
            {"arm": 'joints = ["arm_joint1"]\ngripper_frame = "hand"\n'},
            "arms[0].gripper_frame",
            "frame 'hand' is not in",
        ),
        ({"arm": 'joints = ["arm_joint1"]\ngripper_frame = "ee"\nft_frame = "wrist"\n'}, "arms[0].ft_frame", "not in"),
        (
            {"arm": 'joints = ["arm_joint1"]\ngripper_frame = "ee"\n\n[locked]\narm_joint2 = 9.0\n'},
            "locked.arm_joint2",
            "outside",
        ),
        (
            {"arm": 'joints = ["arm_joint1"]\ngripper_frame = "ee"\n\n[locked]\nneck = 0.0\n'},
            "locked.neck",
            "not a movable",
        ),
        ({"arm": 'joints = []\ngripper_frame = "ee"\n'}, "arms[0].joints", "is empty"),
        (
            {"arm": 'joints = ["arm_joint1"]\ngripper_frame = "ee"\npush_seed = [0.1, 0.2]\n'},
            "arms[0].push_seed",
            "1 numbers",
        ),
        (
            {"arm": 'joints = ["arm_joint1"]\ngripper_frame = "ee"\ngrip_force = 300.0\n'},
            "arms[0].grip_force",
            "within [20, 235]",
        ),
        (
            {"arm": 'joints = ["arm_joint1"]\ngripper_frame = "ee"\ngrip_force = "strong"\n'},
            "arms[0].grip_force",
            "number",
        ),
        (
            {"wheel_joints": '["wheel_right_joint", "wheel_left_joint"]'},
            "wheel_joints",
            "list the left wheel (+y) first",
        ),
        (  # `name` written below [locked]: TOML puts it in that table
            {"name": None, "arm": 'joints = ["arm_joint1"]\ngripper_frame = "ee"\n\n[locked]\nname = "wmra_copy"\n'},
            "name",
            "found in [locked]",
        ),
        ({"arm": 'joints = ["arm_joint2", "arm_joint1"]\ngripper_frame = "ee"\n'}, "arms[0].joints[1]", "base to tip"),
        (
            {"arm": 'joints = ["arm_joint1"]\ngripper_frame = "wheel_left"\n'},
            "arms[0].joints[0]",
            "does not move the gripper frame 'wheel_left'",
        ),
        (
            {"arm": 'joints = ["arm_joint1", "arm_joint2"]\ngripper_frame = "ee"\nft_frame = "arm_link1"\n'},
            "arms[0].ft_frame",
            "not carried by the arm's joint 'arm_joint2'",
        ),
        (
            {"arm": 'joints = ["arm_joint1"]\ngripper_frame = "ee"\n\n[push]\nbase_twist_limit = [0, 0, 0]\n'},
            "push.base_twist_limit",
            "vx and wz above 0",
        ),
        (
            {"arm": 'joints = ["arm_joint1"]\ngripper_frame = "ee"\n\n[push]\nbase_twist_limit = [1.0, 0, 0]\n'},
            "push.base_twist_limit",
            "vx and wz above 0",
        ),
        (
            {"arm": 'joints = ["arm_joint1"]\ngripper_frame = "ee"\n\n[push]\nbase_x = 0.5\n'},
            "push.base_x",
            "give a negative value",
        ),
    ],
)
def test_a_bad_profile_is_one_line_naming_the_key(wmra_dir, over, key, fix):
    path = write_profile(wmra_dir, wmra_text(**over))
    with pytest.raises(ProfileError) as err:
        robots.load(path)
    msg = str(err.value)
    assert err.value.key == key and f": {key}: " in msg and fix in msg and "\n" not in msg
    assert isinstance(err.value, RobotError)


@pytest.mark.parametrize(
    "old, new, key, fix",
    [
        (  # the left wheel's axle along z of the base: a wheel lying flat
            '<origin xyz="0 0.25 0" rpy="-1.570796326795 0 0"/>',
            '<origin xyz="0 0.25 0" rpy="0 0 0"/>',
            "wheel_joints[0]",
            "90 deg off its y axis",
        ),
        (
            'upper="2.96705972839" effort="60" velocity="0.9"/>',
            'upper="2.96705972839" effort="0" velocity="0.9"/>',
            "arms[0].joints[0]",
            "positive effort",
        ),
        (  # a finger's range
            'lower="-2.96705972839" upper="2.96705972839" effort="60" velocity="0.9"',
            'lower="0" upper="0.04" effort="60" velocity="0.9"',
            "arms[0].joints[0]",
            "moves only 0.04",
        ),
        (  # the root link 0.3 m under the floor: axles 0.47 m above it, the wheels' cylinders 0.17 m
            '<origin xyz="0 0 0.17" rpy="0 0 0"/>\n  </joint>\n  <link name="wheel_left">',
            '<origin xyz="0 0 0.47" rpy="0 0 0"/>\n  </joint>\n  <link name="wheel_left">',
            "wheel_radius",
            'a new root link with a fixed joint to the old one at xyz="0 0 -0.3"',
        ),
        (  # the left wheel without a speed limit: Pinocchio reads it as unlimited, so would the base's twist
            '<limit effort="60" velocity="8.8"/>',
            "",
            "wheel_joints[0]",
            "give its <limit velocity> in rad/s, or the profile's [push] base_twist_limit",
        ),
        (  # a planar joint inside the URDF (the base's motion belongs to the profile's base key)
            '<joint name="base_joint" type="fixed">',
            '<joint name="base_joint" type="planar">',
            "urdf",
            "make it fixed",
        ),
    ],
)
def test_a_urdf_the_profile_cannot_drive_is_one_line_naming_the_key(wmra_dir, old, new, key, fix):
    text = WMRA.read_text()
    assert old in text  # its first occurrence: the left wheel, arm_joint1, the base
    (wmra_dir / "wmra.urdf").write_text(text.replace(old, new, 1))
    path = write_profile(wmra_dir, wmra_text(arm='joints = ["arm_joint1", "arm_joint2"]\ngripper_frame = "ee"\n'))
    with pytest.raises(ProfileError) as err:
        robots.load(path)
    msg = str(err.value)
    assert err.value.key == key and fix in msg and "\n" not in msg, msg


@pytest.mark.parametrize("radius, fix", [("0.17", "fixed joint to 'base_footprint' at xyz=\"0 0 -0.3\""), ("0.47", "")])
def test_a_given_wheel_radius_must_stand_the_root_link_on_the_floor(wmra_dir, radius, fix):
    """The root link 0.3 m under the floor (axles 0.47 m above it) with wheel_radius = 0.17 given: the robot would be
    modelled 0.3 m too high; a radius that is the axle's height stands the root on the floor."""
    text = WMRA.read_text()
    old = '<origin xyz="0 0 0.17" rpy="0 0 0"/>\n  </joint>\n  <link name="wheel_left">'
    new = old.replace("0.17", "0.47")
    text = text.replace(old, new, 1)
    (wmra_dir / "wmra.urdf").write_text(text)
    arm = 'joints = ["arm_joint1", "arm_joint2"]\ngripper_frame = "ee"\n'
    path = write_profile(wmra_dir, wmra_text(arm=arm, wheel_radius=radius))
    if not fix:
        assert robots.load(path).profile.wheel_radius == 0.47
        return
    with pytest.raises(ProfileError) as err:
        robots.load(path)
    assert err.value.key == "wheel_radius" and fix in str(err.value), str(err.value)


def test_a_wrong_wheel_radius_with_the_root_on_the_floor_names_the_radius_not_a_new_root(wmra_dir):
    """The WMRA's tyres (0.17 m collision cylinders) agree with their axles' height: the root link stands on the
    floor, so a wheel_radius of 0.3 is the profile's mistake, not the URDF's."""
    arm = 'joints = ["arm_joint1", "arm_joint2"]\ngripper_frame = "ee"\n'
    path = write_profile(wmra_dir, wmra_text(arm=arm, wheel_radius="0.3"))
    with pytest.raises(ProfileError) as err:
        robots.load(path)
    msg = str(err.value)
    assert err.value.key == "wheel_radius" and "correct wheel_radius to 0.17" in msg and "new root link" not in msg


def test_a_continuous_arm_joint_names_the_urdf_fix(wmra_dir):
    text = WMRA.read_text()
    start = text.index('<joint name="arm_joint1" type="revolute">')
    (wmra_dir / "wmra.urdf").write_text(text[:start] + text[start:].replace('type="revolute"', 'type="continuous"', 1))
    path = write_profile(wmra_dir, wmra_text(arm='joints = ["arm_joint1", "arm_joint2"]\ngripper_frame = "ee"\n'))
    with pytest.raises(ProfileError) as err:
        robots.load(path)
    assert err.value.key == "arms[0].joints[0]" and 'make it type="revolute" with <limit lower=' in str(err.value)


def test_a_frame_named_like_a_joint_is_the_link(wmra_dir):
    """A URDF link and joint sharing a name (Unitree Z1's gripperStator, SO-100's gripper): the link's frame."""
    from robots.checks import frame_id

    text = (
        WMRA.read_text().replace('<link name="ee">', '<link name="ee_joint">').replace('link="ee"', 'link="ee_joint"')
    )
    (wmra_dir / "wmra.urdf").write_text(text)
    arm = 'joints = ["arm_joint1", "arm_joint2"]\ngripper_frame = "ee_joint"\n'
    loaded = robots.load(write_profile(wmra_dir, wmra_text(arm=arm)))
    fid = frame_id(loaded.model, "ee_joint")
    assert loaded.model.frames[fid].type == pin.FrameType.BODY and loaded.frame_id("ee_joint") == fid
    with pytest.raises(ValueError, match="Several frames"):  # what the profile checks called and crashed on
        loaded.model.getFrameId("ee_joint")


def test_missing_meshes_name_package_dirs(tmp_path):
    urdf = tmp_path / "one.urdf"
    urdf.write_text(
        '<robot name="one"><link name="base_footprint"><visual><geometry>'
        '<mesh filename="package://no_such_package/meshes/base.stl"/></geometry></visual></link></robot>'
    )
    path = write_profile(tmp_path, 'name = "one"\nurdf = "one.urdf"\n')
    with pytest.raises(ProfileError, match=r"package_dirs: mesh package://no_such_package/meshes/base.stl not found"):
        robots.load(path)
    mesh = tmp_path / "pkgs" / "no_such_package" / "meshes" / "base.stl"
    mesh.parent.mkdir(parents=True)
    mesh.write_bytes(b"solid empty\nendsolid empty\n")  # an ASCII STL without facets
    ok = write_profile(tmp_path, 'name = "one"\nurdf = "one.urdf"\npackage_dirs = ["pkgs"]\n', "ok.toml")
    try:
        robots.load(ok)
    except RobotError as err:  # found now: whatever the mesh reader says, the mesh is not reported missing
        assert "package_dirs" not in str(err)
    typo = tmp_path / "typo.urdf"
    typo.write_text(urdf.read_text().replace("base.stl", "bsae.stl"))
    bad = write_profile(tmp_path, 'name = "one"\nurdf = "typo.urdf"\npackage_dirs = ["pkgs"]\n', "typo.toml")
    with pytest.raises(
        ProfileError, match=r": urdf: mesh .*bsae.stl not found; its package is at .*check the file name"
    ):
        robots.load(bad)


def test_not_toml_and_missing_file(tmp_path):
    bad = write_profile(tmp_path, "name = \n")
    with pytest.raises(ProfileError, match="file: is not valid TOML"):
        robots.load(bad)
    with pytest.raises(ProfileError, match="file: not found"):
        robots.load(tmp_path / "nope.toml")


def test_resolved_urdf_names_mesh_files(tmp_path):
    r = robots.load(tiago_profile(tmp_path))
    text = r.resolved_urdf().read_text()
    assert "package://" not in text
    import re

    files = re.findall(r'<mesh filename="([^"]+)"', text)
    assert len(files) > 20 and all(Path(f).is_file() for f in files)
    assert robots.load("wmra").resolved_urdf() == robots.load("wmra").urdf  # nothing to resolve

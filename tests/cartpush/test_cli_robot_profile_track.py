"""`--robot PROFILE.toml` on `track` (a differential and a holonomic base described only by a profile file) and on
`plan-contacts` (not taken: one line naming why, exit 2)."""

from __future__ import annotations

import json

import pytest

import robots
from cartpush.cli.app import main
from tests.robots.profile_files import UNTUNED_RIDGEBACK, write_profile

#: the shipped URDFs described anew by the keys a new user writes (no [push] table)
DIFFERENTIAL = """\
name = "my_wheelchair"
urdf = "{urdf}"
base = "differential"
wheel_joints = ["wheel_left_joint", "wheel_right_joint"]
[[arms]]
joints = [{arm}]
gripper_frame = "ee"
"""


def _profile(tmp_path, text: str, urdf: str, joint: str) -> str:
    arm = ", ".join(f'"{joint}{i}"' for i in range(1, 8))
    return str(write_profile(tmp_path, text.format(urdf=robots.DATA_DIR / urdf, arm=arm)))


@pytest.mark.parametrize(
    ("text", "urdf", "joint", "name"),
    [
        (DIFFERENTIAL, "wmra.urdf", "arm_joint", "my_wheelchair"),
        (UNTUNED_RIDGEBACK, "ridgeback_iiwa.urdf", "iiwa_joint_", "untuned_rb"),
    ],
)
def test_track_takes_a_profile_file(tmp_path, capsys, text, urdf, joint, name):
    path = _profile(tmp_path, text, urdf, joint)
    assert main(["track", "line", "--robot", path, "--duration", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["robot"] == name and out["steps"] == 300 and out["solver_failures"] == 0
    assert out["rms_position_error_m"] < 0.005  # the hand follows 90 mm/s along X from a mid-range posture
    assert out["max_wheel_speed_ratio"] <= 1.0 + 1e-9 and out["max_joint_speed_ratio"] <= 1.0 + 1e-9


def test_track_names_a_robot_that_cannot_track(capsys):
    assert main(["track", "line", "--robot", "shopping_cart", "--duration", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no arm on a wheeled base" in err


def test_track_with_a_bad_profile_is_one_line(tmp_path, capsys):
    path = _profile(
        tmp_path, DIFFERENTIAL.replace('gripper_frame = "ee"', 'gripper_frame = "hand"'), "wmra.urdf", "arm_joint"
    )
    assert main(["track", "line", "--robot", path, "--duration", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "arms[0].gripper_frame" in err and "'hand'" in err


def test_plan_contacts_says_why_it_takes_no_robot(capsys):
    assert main(["plan-contacts", "--wrench", "40", "0", "-2", "--robot", "my_robot.toml"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--max-force" in err and "cartpush push --robot my_robot.toml" in err


def test_a_run_near_a_singular_pose_warns():
    from cartpush.cli.track import SINGULAR_SHARE, _singular_warnings

    assert _singular_warnings({"steps": 6000, "singular_steps": 0}) == []
    assert _singular_warnings({"steps": 6000, "singular_steps": int(SINGULAR_SHARE * 6000)}) == []
    (w,) = _singular_warnings({"steps": 6000, "singular_steps": 6000})
    assert "6000 of 6000 steps" in w and "push_seed" in w


def test_track_warns_when_a_stretched_start_leaves_the_motion_to_the_base(tmp_path, capsys):
    """The WMRA's arm started stretched (every joint at 0: the shoulder, elbow and wrist in line): the hand
    follows the path with the base alone, and the output says so instead of an empty warning list."""
    text = DIFFERENTIAL.replace('gripper_frame = "ee"', 'gripper_frame = "ee"\npush_seed = [0, 0, 0, 0, 0, 0, 0]')
    path = _profile(tmp_path, text, "wmra.urdf", "arm_joint")
    assert main(["track", "line", "--robot", path, "--duration", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["singular_steps"] > 0.5 * out["steps"]
    assert len(out["warnings"]) == 1 and "near a singular pose" in out["warnings"][0]


def test_push_says_why_a_profile_is_no_mobile_manipulator(tmp_path, capsys):
    assert main(["push", "--robot", "shopping_cart", "--duration", "8"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "'shopping_cart' is not, it has no arm ([[arms]])" in err
    armed = DIFFERENTIAL.replace('base = "differential"\nwheel_joints = ["wheel_left_joint", "wheel_right_joint"]', "")
    assert "base" not in armed  # an arm without a base (base "none", the default without wheels)
    assert main(["push", "--robot", _profile(tmp_path, armed, "wmra.urdf", "arm_joint"), "--duration", "8"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'its base is "none" (give base and wheel_joints)' in err, err

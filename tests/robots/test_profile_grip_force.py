"""A profile's ``grip_force`` (N per finger) is its arm's squeeze in the push loop's allocation."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from robots.profiles import read_profile
from wholebody.contacts.allocation import WrenchAllocator
from wholebody.errors import InfeasibleWrenchError
from wholebody.push.config import PUSH_GRIP_FORCE, PushConfig

WMRA = Path(__file__).resolve().parents[2] / "robots" / "wmra.urdf"
ARM = ", ".join(f'"arm_joint{i}"' for i in range(1, 8))


def _profile(tmp_path: Path, grip: str) -> Path:
    shutil.copy(WMRA, tmp_path / "wmra.urdf")
    text = (
        'name = "wmra_grip"\nurdf = "wmra.urdf"\nbase = "differential"\n'
        'wheel_joints = ["wheel_left_joint", "wheel_right_joint"]\n'
        f'[[arms]]\njoints = [{ARM}]\ngripper_frame = "ee"\n{grip}'
    )
    path = tmp_path / "wmra_grip.toml"
    path.write_text(text)
    return path


def test_grip_force_is_read_and_optional(tmp_path):
    assert read_profile(_profile(tmp_path, "grip_force = 60\n")).arms[0].grip_force == 60.0
    assert read_profile(_profile(tmp_path, "")).arms[0].grip_force is None


def test_each_hand_takes_its_arms_grip_force(tmp_path):
    own = PushConfig(robot=str(_profile(tmp_path, "grip_force = 60.0\n")), n_arms=2).hand_limits()
    assert [lim.grasp.grip_force for lim in own if lim.grasp] == [60.0, 60.0]
    default = PushConfig(robot=str(_profile(tmp_path, ""))).hand_limits()
    assert default[0].grasp is not None and default[0].grasp.grip_force == PUSH_GRIP_FORCE


def test_a_weaker_grip_pulls_less_in_the_allocation(tmp_path):
    """60 N per finger at friction 0.5 holds a 60 N pull; the default 200 N grip holds the 100 N one."""
    weak = PushConfig(robot=str(_profile(tmp_path, "grip_force = 60.0\n"))).hand_limits()
    strong = PushConfig(robot=str(_profile(tmp_path, ""))).hand_limits()
    pull = np.array([-100.0, 0.0, 0.0])
    point = [(0.0, 0.0, 0.0)]
    res = WrenchAllocator(point, strong, only_motion_directions=True).solve(pull)
    assert res.wrenches_ee[0, 0] == pytest.approx(-100.0)
    with pytest.raises(InfeasibleWrenchError, match="grip pull limit"):
        WrenchAllocator(point, weak, only_motion_directions=True).solve(pull)

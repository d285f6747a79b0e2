"""The profile's `arm_control` key: read, checked, and what the MuJoCo plant drives the arm with."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from robots.errors import ProfileError
from robots.profiles import parse_profile
from wholebody.push.mujoco_plant import arm_mode_of

BASE = {"name": "x", "urdf": "a.urdf"}


@pytest.mark.parametrize("mode", ["torque", "velocity"])
def test_arm_control_is_read_and_chooses_the_arm_law(mode):
    prof = parse_profile({**BASE, "arm_control": mode}, Path("."))
    assert prof.arm_control == mode
    mm = SimpleNamespace(profile=prof, wb=SimpleNamespace(robot=SimpleNamespace(name="x")))
    assert arm_mode_of(mm) == mode


def test_without_arm_control_the_plant_default_applies():
    prof = parse_profile(dict(BASE), Path("."))
    assert prof.arm_control is None
    assert arm_mode_of(SimpleNamespace(profile=prof, wb=SimpleNamespace(robot=SimpleNamespace(name="x")))) == "velocity"


def test_bad_arm_control_names_the_key():
    with pytest.raises(ProfileError, match="arm_control: must be 'torque' or 'velocity'"):
        parse_profile({**BASE, "arm_control": "force"}, Path("."))

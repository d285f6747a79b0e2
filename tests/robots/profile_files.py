"""Robot profiles the tests write: TIAGo from example-robot-data (one arm, torso locked) and variants."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path

from tests.optional import missing

TIAGO_ARM = [f"arm_{i}_joint" for i in range(1, 8)]

#: TIAGo's profile: the URDF and its meshes resolve through the cmeel prefix (no path of this machine in it).
TIAGO = """\
name = "tiago"
urdf = "package://example-robot-data/robots/tiago_description/robots/tiago_no_hand.urdf"
base = "differential"
wheel_joints = ["wheel_left_joint", "wheel_right_joint"]

[[arms]]
joints = {arm}
gripper_frame = "arm_tool_link"
ft_frame = "wrist_ft_link"
"""
#: the Ridgeback + iiwa described only by the keys a new user writes (no [push] table, no push_seed); format with
#: ``urdf`` and ``arm`` (the quoted joint names)
UNTUNED_RIDGEBACK = """\
name = "untuned_rb"
urdf = "{urdf}"
base = "holonomic"
wheel_joints = ["front_left_wheel_joint", "front_right_wheel_joint", "rear_left_wheel_joint", "rear_right_wheel_joint"]
wheel_radius = 0.0759
[[arms]]
joints = [{arm}]
gripper_frame = "ee"
ft_frame = "ft_sensor"
"""
#: TIAGo's torso, held at 0.2 m when it is not one of the arm's joints.
TORSO_LOCK = """
[locked]
torso_lift_joint = 0.2
"""


def need_example_robot_data() -> None:
    """Skip (or fail under CARTPUSH_REQUIRE_EXTRAS=1) when example-robot-data is not installed."""
    try:
        distribution("example-robot-data")
    except PackageNotFoundError:
        missing("example-robot-data", "pip install -e '.[dev]'")


def write_profile(folder: Path, text: str, name: str = "robot.toml") -> Path:
    """Return the path of a profile file with `text` written in `folder`."""
    path = folder / name
    path.write_text(text)
    return path


def tiago_profile(folder: Path, arm: list[str] | None = None, extra: str = "") -> Path:
    """Return the path of TIAGo's profile written in `folder` (arm joints `arm`, default the 7 arm joints; the
    torso locked at 0.2 m unless it is one of them)."""
    need_example_robot_data()
    arm = arm or TIAGO_ARM
    joints = "[" + ", ".join(f'"{j}"' for j in arm) + "]"
    lock = "" if "torso_lift_joint" in arm else TORSO_LOCK
    return write_profile(folder, TIAGO.format(arm=joints) + lock + extra, "tiago.toml")


def wmra_variant(folder: Path, name: str, urdf_text: str) -> str:
    """Write the WMRA's profile renamed `name`, pointing at `urdf_text` written beside it; return the profile's path
    (a variant of the shipped robot: its URDF edited, its tuned [push] settings kept)."""
    robots_dir = Path(__file__).resolve().parents[2] / "robots"
    urdf = folder / f"{name}.urdf"
    urdf.write_text(urdf_text)
    prof = (robots_dir / "wmra.toml").read_text()
    prof = prof.replace('name = "wmra"', f'name = "{name}"').replace('urdf = "wmra.urdf"', f'urdf = "{urdf}"')
    (folder / f"{name}.toml").write_text(prof)
    return str(folder / f"{name}.toml")

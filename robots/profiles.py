"""Robot profiles: everything generic code needs to know about a robot, read from a TOML file.

A profile names the URDF, the base (differential or holonomic) and its wheel joints, one table per
arm (joints base to tip, the frame that holds the handle, the F/T frame) and the value every other
movable joint is held at. Everything else (joint and torque limits, wheel radius and separation,
push posture and base placement) comes from the URDF or is computed. The built-in robots are
profiles in this format (``robots/*.toml``); their tuned push settings are optional keys of the
``[push]`` table. The format is documented in docs/robots.md.

>>> from robots.profiles import profile
>>> profile("ridgeback_iiwa").base
'holonomic'
>>> profile("wmra").arms[0].joints[:2]
('arm_joint1', 'arm_joint2')
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, cast, overload

from robots.errors import ProfileError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

#: Base kinematics: a differential drive (two driven wheels, left then right), a holonomic base with
#: mecanum wheels, or none (a cart, a fixed arm).
BaseType = Literal["differential", "holonomic", "none"]
BASE_TYPES = ("differential", "holonomic", "none")
#: Axes a gripper frame's tool axis may point along (the direction from the wrist to the fingertips).
TOOL_AXES = ("x", "y", "z", "-x", "-y", "-z")
#: Grip forces (N per finger) a profile's ``grip_force`` may give: the Robotiq 2F-85's range (20-235 N, its
#: manual), which the allocation's grasp model (`wholebody.contacts.allocation.GraspModel`) also takes.
GRIP_FORCE_RANGE = (20.0, 235.0)

_TOP_KEYS = (
    "name",
    "urdf",
    "package_dirs",
    "base",
    "wheel_joints",
    "wheel_radius",
    "wheel_separation",
    "wheel_positions",
    "arms",
    "locked",
    "frames",
    "push",
    "arm_control",
)
_ARM_KEYS = ("joints", "gripper_frame", "ft_frame", "tool_axis", "push_seed", "grip_force")
_PUSH_KEYS = (
    "grasp_pitch",
    "grasp_roll",
    "base_x",
    "base_y",
    "base_dy",
    "contact_y",
    "base_twist_limit",
    "wheel_acceleration_limit",
    "base_lookahead",
)


@dataclass(frozen=True)
class ArmProfile:
    """One arm: its joints (base to tip), the frame that holds the handle and the F/T sensor's frame."""

    joints: tuple[str, ...]
    gripper_frame: str
    #: frame of the F/T sensor; None = the gripper frame
    ft_frame: str | None = None
    #: the gripper frame's axis pointing from the wrist to the fingertips; None = computed from the URDF
    tool_axis: str | None = None
    #: arm posture holding the handle (the grasp IK's seed); None = computed by IK
    push_seed: tuple[float, ...] | None = None
    #: the gripper's squeeze on the handle (N per finger, its rated grip force, within `GRIP_FORCE_RANGE`); it sets
    #: how hard the hand may pull and how much torque the grip holds; None = the push loop's default
    #: (`wholebody.push.config.PUSH_GRIP_FORCE`)
    grip_force: float | None = None

    @property
    def sensor_frame(self) -> str:
        """Return the F/T frame (the gripper frame when the profile names none)."""
        return self.ft_frame if self.ft_frame is not None else self.gripper_frame


@dataclass(frozen=True)
class RobotProfile:
    """One robot: URDF, base, arms, locked joints and optional tuned push settings (docs/robots.md).

    ``None`` in an optional field means "computed": from the URDF (wheel radius, separation and
    positions, base twist limits) or by the push posture's IK (`wholebody.push.robot.push_profile`).
    """

    name: str
    urdf: Path
    base: BaseType = "none"
    package_dirs: tuple[Path, ...] = ()
    wheel_joints: tuple[str, ...] = ()
    wheel_radius: float | None = None
    wheel_separation: float | None = None
    #: holonomic bases: wheel (x, y) in the base frame, in `wheel_joints` order; () = from the URDF
    wheel_positions: tuple[tuple[float, float], ...] = ()
    arms: tuple[ArmProfile, ...] = ()
    #: joint name -> value (rad or m) every movable joint outside the arms and wheels is held at (else 0)
    locked: tuple[tuple[str, float], ...] = ()
    #: frame roles: role -> frame name (``"ee"``, ``"ft_sensor"``, ``"base"`` ... ; defaults from the arms)
    frames: tuple[tuple[str, str], ...] = ()
    #: the TOML file this profile was read from (None: built in code)
    source: Path | None = None
    #: grasp pitch (rad about y_b): the tool points forward and this much down onto the handle bar
    grasp_pitch: float | None = None
    #: grasp roll (rad) about the tool axis
    grasp_roll: float | None = None
    #: base x relative to the handle, in {b} (m, negative = behind it)
    push_base_x: float | None = None
    #: base y in {b} (m); None = behind its contact point (a base that follows the contact sideways)
    push_base_y: float | None = None
    #: lateral offset of the base from its contact point when it follows the contact (m)
    push_base_dy: float = 0.0
    #: contact point y (m) on the handle when the contact is fixed and none is given
    push_contact_y: float | None = None
    #: base body-twist limits (vx m/s, vy m/s, wz rad/s); None = from the wheel speed limits
    base_twist_limit: tuple[float, float, float] | None = None
    #: wheel angular acceleration limit (rad/s^2), None = not enforced
    wheel_acceleration_limit: float | None = None
    #: look-ahead distance (m) of a differential base's tracker; None = 0.3 m differential, 0 holonomic
    base_lookahead: float | None = None
    #: how a physics plant drives the arms: "torque" (joint torques: the arm applies its wrench through its
    #: dynamics) or "velocity" (joint velocity servos with an admittance); None = the plant's default
    arm_control: Literal["torque", "velocity"] | None = None
    #: whether the push settings came from the profile (True) or still need the IK (False)
    tuned: bool = field(default=False, compare=False)

    # ------------------------------------------------------------------ derived
    @property
    def is_mobile_manipulator(self) -> bool:
        """Return True when the robot has an arm on a wheeled base (a whole-body model can be built)."""
        return bool(self.arms) and self.base != "none"

    @property
    def base_input(self) -> Literal["wheels", "twist"]:
        """Return the whole-body base input: a body twist for a holonomic base, wheel rates for a differential
        drive (its lateral velocity is then zero by construction, paper 2 eq. 11-21)."""
        return "twist" if self.base == "holonomic" else "wheels"

    @property
    def arm_joints(self) -> tuple[str, ...]:
        """Return the first arm's joints (base to tip)."""
        return self.arms[0].joints if self.arms else ()

    @property
    def ee_frame(self) -> str:
        """Return the first arm's gripper frame."""
        return self.arms[0].gripper_frame if self.arms else "ee"

    @property
    def ft_frame(self) -> str | None:
        """Return the first arm's F/T frame (its gripper frame when the profile names none)."""
        return self.arms[0].sensor_frame if self.arms else None

    @property
    def push_arm_seed(self) -> tuple[float, ...] | None:
        """Return the first arm's push posture (None until computed, `wholebody.push.robot.push_profile`)."""
        return self.arms[0].push_seed if self.arms else None

    @property
    def locked_joints(self) -> dict[str, float]:
        """Return the locked joints as a dict."""
        return dict(self.locked)

    @property
    def frame_roles(self) -> dict[str, str]:
        """Return role -> frame name: the profile's `frames`, and ``ee``/``ft_sensor`` from the first arm."""
        roles: dict[str, str] = {}
        if self.arms:
            roles["ee"] = self.arms[0].gripper_frame
            if self.arms[0].ft_frame is not None:
                roles["ft_sensor"] = self.arms[0].ft_frame
        roles.update(dict(self.frames))
        return roles


# ---------------------------------------------------------------------------------------------- parsing
class _Reader:
    """Typed access to a profile's TOML tables; every problem is a `ProfileError` naming the key."""

    def __init__(self, source: object) -> None:
        self.source = source

    def fail(self, key: str, problem: str) -> ProfileError:
        return ProfileError(self.source, key, problem)

    def only(self, table: Mapping, allowed: tuple[str, ...], prefix: str = "") -> None:
        for k in table:
            if k not in allowed:
                raise self.fail(f"{prefix}{k}", f"unknown key; valid keys here: {', '.join(allowed)}")

    @overload
    def string(self, table: Mapping, key: str, prefix: str = "", required: Literal[True] = True) -> str: ...

    @overload
    def string(self, table: Mapping, key: str, prefix: str = "", *, required: bool) -> str | None: ...

    def string(self, table: Mapping, key: str, prefix: str = "", required: bool = True) -> str | None:
        if key not in table:
            if required:
                raise self.fail(f"{prefix}{key}", "missing; give a string")
            return None
        v = table[key]
        if not isinstance(v, str) or not v.strip():
            raise self.fail(f"{prefix}{key}", f"must be a non-empty string, got {v!r}")
        return v

    def number(self, table: Mapping, key: str, prefix: str = "", positive: bool = False) -> float | None:
        if key not in table:
            return None
        v = table[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise self.fail(f"{prefix}{key}", f"must be a finite number, got {v!r}")
        if positive and v <= 0:
            raise self.fail(f"{prefix}{key}", f"must be positive, got {v!r}")
        return float(v)

    def strings(self, table: Mapping, key: str, prefix: str = "", required: bool = False) -> tuple[str, ...]:
        if key not in table:
            if required:
                raise self.fail(f"{prefix}{key}", "missing; give a list of joint names")
            return ()
        v = table[key]
        if not isinstance(v, list) or not all(isinstance(s, str) and s for s in v):
            raise self.fail(f"{prefix}{key}", f"must be a list of names (strings), got {v!r}")
        if len(set(v)) != len(v):
            raise self.fail(f"{prefix}{key}", f"lists a name twice: {v!r}")
        return tuple(v)

    def numbers(self, table: Mapping, key: str, size: int | None = None, prefix: str = "") -> tuple[float, ...] | None:
        if key not in table:
            return None
        v = table[key]
        ok = isinstance(v, list) and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v
        )
        if not ok or (size is not None and len(v) != size):
            want = f"{size} numbers" if size is not None else "a list of numbers"
            raise self.fail(f"{prefix}{key}", f"must be {want}, got {v!r}")
        return tuple(float(x) for x in v)

    def table(self, table: Mapping, key: str) -> Mapping:
        v = table.get(key, {})
        if not isinstance(v, dict):
            raise self.fail(key, f"must be a table ([{key}]), got {v!r}")
        return v


def _resolve_path(text: str, base_dir: Path) -> Path:
    """Return a profile path: absolute, ``~``-expanded, or relative to the profile's folder."""
    p = Path(text).expanduser()
    return p if p.is_absolute() else (base_dir / p)


def _arm(r: _Reader, i: int, table: object) -> ArmProfile:
    prefix = f"arms[{i}]."
    if not isinstance(table, dict):
        raise r.fail(f"arms[{i}]", "must be a table ([[arms]])")
    r.only(table, _ARM_KEYS, prefix)
    joints = r.strings(table, "joints", prefix, required=True)
    if not joints:
        raise r.fail(f"{prefix}joints", "is empty; list the arm's joints from its base to its tip")
    axis = r.string(table, "tool_axis", prefix, required=False)
    if axis is not None and axis not in TOOL_AXES:
        raise r.fail(f"{prefix}tool_axis", f"must be one of {', '.join(TOOL_AXES)}, got {axis!r}")
    return ArmProfile(
        joints=joints,
        gripper_frame=r.string(table, "gripper_frame", prefix),
        ft_frame=r.string(table, "ft_frame", prefix, required=False),
        tool_axis=axis,
        push_seed=r.numbers(table, "push_seed", len(joints), prefix),
        grip_force=_grip_force(r, table, prefix),
    )


def _grip_force(r: _Reader, table: Mapping, prefix: str) -> float | None:
    """Return an arm's ``grip_force`` (N per finger), None when not given; outside `GRIP_FORCE_RANGE` is an error."""
    force = r.number(table, "grip_force", prefix, positive=True)
    lo, hi = GRIP_FORCE_RANGE
    if force is not None and not lo <= force <= hi:
        raise r.fail(
            f"{prefix}grip_force",
            f"must be the gripper's squeeze in N per finger within [{lo:g}, {hi:g}] (the grasp model's range), "
            f"got {force:g}",
        )
    return force


def _base(r: _Reader, data: Mapping) -> tuple[BaseType, tuple[str, ...]]:
    wheels = r.strings(data, "wheel_joints")
    base = data.get("base", "none" if not wheels else None)
    if base not in BASE_TYPES:
        raise r.fail("base", f"must be one of {', '.join(repr(b) for b in BASE_TYPES)}, got {base!r}")
    if base == "differential" and len(wheels) != 2:
        raise r.fail("wheel_joints", f"a differential base needs 2 wheel joints (left, right), got {len(wheels)}")
    if base == "holonomic" and len(wheels) < 3:
        raise r.fail("wheel_joints", f"a holonomic base needs at least 3 wheel joints, got {len(wheels)}")
    if base == "none" and wheels:
        raise r.fail("base", "is 'none' but wheel_joints are given; set base = 'differential' or 'holonomic'")
    return cast(BaseType, base), wheels  # checked against BASE_TYPES above


def _push(r: _Reader, data: Mapping) -> dict:
    push = r.table(data, "push")
    r.only(push, _PUSH_KEYS, "push.")
    out = {k: r.number(push, k, "push.") for k in ("grasp_pitch", "grasp_roll", "base_x", "base_y", "contact_y")}
    lim = r.numbers(push, "base_twist_limit", 3, "push.")
    if lim is not None and (any(v < 0 for v in lim) or lim[0] <= 0 or lim[2] <= 0):
        raise r.fail(
            "push.base_twist_limit",
            f"must be 3 non-negative numbers (vx, vy, wz) with vx and wz above 0 (the base must drive and turn to "
            f"push), got {list(lim)}",
        )
    if out["base_x"] is not None and out["base_x"] >= 0.0:
        raise r.fail(
            "push.base_x",
            f"{out['base_x']:g} m puts the base at or ahead of the handle (inside the cart's footprint); the base "
            "stands behind the handle: give a negative value (e.g. -0.7)",
        )
    return dict(
        grasp_pitch=out["grasp_pitch"],
        grasp_roll=out["grasp_roll"],
        push_base_x=out["base_x"],
        push_base_y=out["base_y"],
        push_base_dy=r.number(push, "base_dy", "push.") or 0.0,
        push_contact_y=out["contact_y"],
        base_twist_limit=lim,
        wheel_acceleration_limit=r.number(push, "wheel_acceleration_limit", "push.", positive=True),
        base_lookahead=r.number(push, "base_lookahead", "push."),
    )


def _top_keys_in_tables(r: _Reader, data: Mapping) -> None:
    """Raise `ProfileError` for a required top-level key written below a table header (TOML then puts it in that
    table: ``name = ...`` after ``[locked]`` is a locked joint called name)."""
    for key in ("name", "urdf"):
        if key in data:
            continue
        tables = [("locked", data.get("locked")), ("frames", data.get("frames")), ("push", data.get("push"))]
        arms = data.get("arms")
        tables += [(f"arms[{i}]", t) for i, t in enumerate(arms)] if isinstance(arms, list) else []
        for where, table in tables:
            if isinstance(table, Mapping) and key in table:
                raise r.fail(
                    key,
                    f"missing at the top level, found in [{where}]: a key written below a table header belongs "
                    "to that table; move it above the first table",
                )


def parse_profile(data: Mapping, base_dir: Path, source: object = "<profile>") -> RobotProfile:
    """Return the profile of a parsed TOML document; relative paths are taken from `base_dir`.

    Checks the profile on its own (keys, types, base and wheel counts); `robots.load` checks it against
    its URDF (joints, frames, wheel joint types, meshes). Raises `ProfileError` naming the key.
    """
    r = _Reader(source)
    r.only(data, _TOP_KEYS)
    _top_keys_in_tables(r, data)
    name = r.string(data, "name")
    urdf_text = r.string(data, "urdf")
    base, wheels = _base(r, data)
    arms_raw = data.get("arms", [])
    if not isinstance(arms_raw, list):
        raise r.fail("arms", "must be an array of tables ([[arms]])")
    arms = tuple(_arm(r, i, t) for i, t in enumerate(arms_raw))
    locked = r.table(data, "locked")
    for k in locked:
        r.number(locked, k, "locked.")
    frames = r.table(data, "frames")
    for k in frames:
        r.string(frames, k, "frames.")
    positions = data.get("wheel_positions", [])
    if not (isinstance(positions, list) and all(isinstance(p, list) and len(p) == 2 for p in positions)):
        raise r.fail("wheel_positions", "must be a list of [x, y] pairs (m), one per wheel joint")
    if positions and len(positions) != len(wheels):
        raise r.fail("wheel_positions", f"gives {len(positions)} positions for {len(wheels)} wheel joints")
    push = _push(r, data)
    arm_control = r.string(data, "arm_control", required=False)
    if arm_control not in (None, "torque", "velocity"):
        raise r.fail("arm_control", f"must be 'torque' or 'velocity', got {arm_control!r}")
    urdf = Path(urdf_text) if urdf_text.startswith("package://") else _resolve_path(urdf_text, base_dir)
    return RobotProfile(
        name=name,
        urdf=urdf,
        base=base,
        package_dirs=tuple(_resolve_path(p, base_dir) for p in r.strings(data, "package_dirs")),
        arm_control=cast(Literal["torque", "velocity"] | None, arm_control),
        wheel_joints=wheels,
        wheel_radius=r.number(data, "wheel_radius", positive=True),
        wheel_separation=r.number(data, "wheel_separation", positive=True),
        wheel_positions=tuple((float(x), float(y)) for x, y in positions),
        arms=arms,
        locked=tuple((k, float(v)) for k, v in locked.items()),
        frames=tuple((k, str(v)) for k, v in frames.items()),
        source=Path(source) if isinstance(source, Path) else None,
        tuned=all(a.push_seed is not None for a in arms) and push["push_base_x"] is not None,
        **push,
    )


def read_profile(path: str | Path) -> RobotProfile:
    """Return the profile in a TOML file (docs/robots.md); raise `ProfileError` naming the bad key."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise ProfileError(p, "file", "not found; give the path of a robot profile (.toml)")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ProfileError(p, "file", f"is not valid TOML ({exc})") from None
    return parse_profile(data, p.resolve().parent, p)


# ---------------------------------------------------------------------------------------------- registry
def profile(name_or_path: str | Path | RobotProfile) -> RobotProfile:
    """Return a registered robot's profile, or read a profile file (a path ending in ``.toml``).

    Raises `UnknownRobotError` naming the known robots for an unknown name, `ProfileError` for a bad file.
    """
    from robots.registry import resolve

    return resolve(name_or_path)


def mobile_manipulators() -> tuple[str, ...]:
    """Return the names of the registered robots with an arm on a wheeled base."""
    from robots.registry import registered

    return tuple(sorted(n for n, p in registered().items() if p.is_mobile_manipulator))


class _RegistryView(Mapping):
    """Read-only name -> profile view of the registry (`robots.register` adds to it)."""

    def _all(self) -> dict[str, RobotProfile]:
        from robots.registry import registered

        return registered()

    def __getitem__(self, name: str) -> RobotProfile:
        return self._all()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._all())

    def __len__(self) -> int:
        return len(self._all())


#: name -> profile of every registered robot (a live view of `robots.registry`).
PROFILES: Mapping[str, RobotProfile] = _RegistryView()

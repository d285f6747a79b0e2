"""The one robot registry: name -> profile, seeded with the built-in profiles (``robots/*.toml``).

>>> import robots
>>> "wmra" in robots.available()
True

`register` adds a robot (a `RobotProfile` or the path of a profile file) so that every command and
function taking a robot name accepts it; `resolve` also takes a profile file's path directly.
"""

from __future__ import annotations

import threading
from pathlib import Path

from robots.errors import ProfileError, UnknownRobotError
from robots.profiles import RobotProfile, read_profile

DATA_DIR = Path(__file__).resolve().parent
#: Example profiles of robots from other packages (``robots/examples/*.toml``), read by path, never registered.
EXAMPLES_DIR = DATA_DIR / "examples"

_LOCK = threading.Lock()
_REGISTRY: dict[str, RobotProfile] = {}
_BUILTIN: tuple[str, ...] = ()


def _seed() -> None:
    """Read the built-in profiles once (``robots/*.toml``)."""
    global _BUILTIN
    if _BUILTIN:
        return
    with _LOCK:
        if _BUILTIN:
            return
        found = {}
        for path in sorted(DATA_DIR.glob("*.toml")):
            prof = read_profile(path)
            found[prof.name] = prof
        for name, prof in found.items():
            _REGISTRY.setdefault(name, prof)
        _BUILTIN = tuple(sorted(found))


def builtin() -> tuple[str, ...]:
    """Return the names of the robots shipped with the package."""
    _seed()
    return _BUILTIN


def registered() -> dict[str, RobotProfile]:
    """Return a copy of the registry (name -> profile)."""
    _seed()
    return dict(_REGISTRY)


def available() -> tuple[str, ...]:
    """Return the registered robot names, sorted."""
    return tuple(sorted(registered()))


def register(robot: RobotProfile | str | Path, replace: bool = False) -> RobotProfile:
    """Register a robot (a profile, or the path of a profile file) under its profile's name; return the profile.

    A name already taken raises `ProfileError` unless ``replace``; the built-in robots are never replaced.
    """
    prof = robot if isinstance(robot, RobotProfile) else read_profile(robot)
    _seed()
    with _LOCK:
        if prof.name in _BUILTIN and _REGISTRY[prof.name] != prof:
            raise ProfileError(prof.source or prof.name, "name", f"{prof.name!r} is a built-in robot; pick another")
        if prof.name in _REGISTRY and not replace and _REGISTRY[prof.name] != prof:
            raise ProfileError(
                prof.source or prof.name, "name", f"a robot {prof.name!r} is registered; pass replace=True"
            )
        _REGISTRY[prof.name] = prof
    return prof


def unregister(name: str) -> None:
    """Remove a registered robot (not a built-in one)."""
    _seed()
    with _LOCK:
        if name in _BUILTIN:
            raise ProfileError(name, "name", f"{name!r} is a built-in robot and cannot be removed")
        _REGISTRY.pop(name, None)


def examples() -> tuple[str, ...]:
    """Return the names of the example profiles shipped in ``robots/examples`` (`example_profile` gives their paths)."""
    return tuple(sorted(p.stem for p in EXAMPLES_DIR.glob("*.toml")))


def example_profile(name: str) -> Path:
    """Return the path of an example profile (``robots/examples/NAME.toml``), e.g. ``"tiago_dual"`` (TIAGo++).

    Examples describe robots of other packages (example-robot-data); they are not registered, so that the
    package works without them: pass the path wherever a robot is taken.
    """
    path = EXAMPLES_DIR / f"{name}.toml"
    if not path.is_file():
        raise UnknownRobotError(f"no example profile {name!r}; examples: {', '.join(examples())}")
    return path


def is_profile_path(text: str | Path) -> bool:
    """Return True when `text` names a profile file rather than a registered robot (``.toml`` or a path)."""
    s = str(text)
    return s.endswith(".toml") or "/" in s or "\\" in s


def resolve(robot: str | Path | RobotProfile) -> RobotProfile:
    """Return the profile of a robot name, a profile file's path, or a profile (returned as is)."""
    if isinstance(robot, RobotProfile):
        return robot
    if isinstance(robot, Path) or is_profile_path(robot):
        return read_profile(robot)
    known = registered()
    if robot not in known:
        raise UnknownRobotError(
            f"unknown robot {robot!r}; valid names: {', '.join(sorted(known))}, or the path of a robot profile (.toml)"
        )
    return known[robot]

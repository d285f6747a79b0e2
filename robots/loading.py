"""Load a robot (a registered name, a profile file or a profile) into Pinocchio with a planar root joint (x, y, yaw)."""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import sys
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Iterator

import pinocchio as pin

from robots import registry
from robots.checks import check_profile, check_wheel_radius, frame_id, package_search_dirs, resolve_package_uri
from robots.errors import ProfileError, RobotError, UnknownRobotError
from robots.profiles import RobotProfile

DATA_DIR = Path(__file__).resolve().parent


@dataclass
class LoadedRobot:
    """A robot loaded into Pinocchio: models, data, its named frames and its profile.

    Attributes:
        name: the robot's name (its profile's `name`).
        urdf: path of the URDF file.
        model, data: Pinocchio kinematic/dynamic model (planar root joint `root_joint`) and its data.
        visual_model, collision_model, visual_data, collision_data: geometry models.
        frames: role -> frame name, e.g. ``{"ee": "ee", "ft_sensor": "ft_sensor"}``.
        profile: the robot's profile (`robots.profiles.RobotProfile`); None for a model built by hand.
    """

    name: str
    urdf: Path
    model: pin.Model
    data: pin.Data
    visual_model: pin.GeometryModel
    collision_model: pin.GeometryModel
    visual_data: pin.GeometryData
    collision_data: pin.GeometryData
    frames: dict[str, str] = field(default_factory=dict)
    profile: RobotProfile | None = None

    def resolved_urdf(self) -> Path:
        """Return a copy of the URDF with every ``package://`` URI replaced by the absolute path it resolves to.

        For readers without package folders (MuJoCo's URDF compiler, placo); the copy is content-addressed in
        the temporary folder. The URDF itself when it has no ``package://`` URI.
        """
        text = self.urdf.read_text(encoding="utf-8")
        if "package://" not in text:
            return self.urdf
        dirs = package_search_dirs(self.profile.package_dirs if self.profile is not None else (), self.urdf)

        def sub(m: re.Match) -> str:
            found = resolve_package_uri(m.group(0), dirs)
            return str(found) if found is not None else m.group(0)

        resolved = re.sub(r"package://[^\"'<>\s]+", sub, text)
        digest = hashlib.sha256(resolved.encode()).hexdigest()[:16]
        path = Path(tempfile.gettempdir()) / "cartpush_urdf" / f"{self.name}_{digest}_resolved.urdf"
        if not path.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{self.name}_", suffix=".urdf", dir=path.parent)
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(resolved)
            os.replace(tmp, path)
        return path

    def frame_id(self, role_or_name: str) -> int:
        """Return the Pinocchio frame id of a role (``"ee"``) or a frame name."""
        name = self.frames.get(role_or_name, role_or_name)
        if not self.model.existFrame(name):
            raise UnknownRobotError(f"robot {self.name!r} has no frame {role_or_name!r}; roles: {sorted(self.frames)}")
        return frame_id(self.model, name)


def available() -> tuple[str, ...]:
    """Return the names `load` accepts, sorted (the registry's: built-in and registered robots)."""
    return registry.available()


def urdf_path(robot: str | Path | RobotProfile) -> Path:
    """Return the path of a robot's URDF file (a registered name, a profile file or a profile)."""
    prof = registry.resolve(robot)
    return _urdf_file(prof)


def _urdf_file(prof: RobotProfile) -> Path:
    """Return the profile's URDF file; a ``package://`` URI resolves through the package search folders."""
    text = str(prof.urdf)
    src = prof.source or prof.name
    if text.startswith("package:/"):
        uri = "package://" + text[len("package:/") :].lstrip("/")
        found = resolve_package_uri(uri, package_search_dirs(prof.package_dirs, Path.cwd()))
        if found is None:
            raise ProfileError(src, "urdf", f"{uri} is in none of the package folders; add its folder to package_dirs")
        return found
    if not prof.urdf.is_file():
        raise ProfileError(src, "urdf", f"file {prof.urdf} not found; give a path absolute or relative to the profile")
    return prof.urdf


@contextlib.contextmanager
def _captured_stderr_fd(lines: list[str]) -> Iterator[None]:
    """Capture what C++ code (urdfdom) writes to file descriptor 2 into `lines` (best effort)."""
    try:
        fd = sys.stderr.fileno() if hasattr(sys.stderr, "fileno") else 2
    except (OSError, ValueError):
        fd = 2
    try:
        saved = os.dup(2)
    except OSError:
        yield
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        try:
            sys.stderr.flush()
        except (OSError, ValueError):
            pass
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            text = tmp.read().decode("utf-8", "replace")
            lines.extend(ln.strip() for ln in text.splitlines() if ln.strip())
    del fd


def check_urdf_text(urdf_text: object) -> None:
    """Raise RobotError naming the problem if `urdf_text` is not well-formed URDF XML (a <robot> root)."""
    if not isinstance(urdf_text, str):
        raise RobotError(f"urdf_text must be a string of URDF XML, got {type(urdf_text).__name__}")
    if not urdf_text.strip():
        raise RobotError("urdf_text is empty")
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as exc:
        raise RobotError(f"urdf_text is not well-formed XML: {exc}") from None
    if root.tag != "robot":
        raise RobotError(f"urdf_text must have a <robot> root element, got <{root.tag}>")


def _parser_message(exc: Exception, messages: list[str], path: Path, label: str | None) -> str:
    detail = "; ".join(
        m[len("Error:") :].strip() if m.startswith("Error:") else m
        for m in messages
        if not re.match(r"^at line \d+ in ", m)
    )
    text = str(exc) if label is None else str(exc).replace(f"The file {path}", label).replace(str(path), label)
    return f"invalid URDF: {text}" + (f" ({detail})" if detail else "")


def _build(path: Path, root: pin.JointModel, label: str | None = None, prof: RobotProfile | None = None):
    """Return (model, visual, collision) of a URDF file.

    A URDF the parser rejects is a RobotError with the parser's message; a mesh that is in none of the
    package folders is a `ProfileError` on ``package_dirs``.
    """
    messages: list[str] = []
    try:
        with _captured_stderr_fd(messages):
            model = pin.buildModelFromUrdf(str(path), root)
    except (ValueError, RuntimeError, OSError) as exc:
        raise RobotError(_parser_message(exc, messages, path, label)) from None
    dirs = package_search_dirs(prof.package_dirs if prof is not None else (), path) + [str(DATA_DIR)]
    try:
        with _captured_stderr_fd(messages):
            visual = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.VISUAL, package_dirs=dirs)
            collision = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.COLLISION, package_dirs=dirs)
    except (ValueError, RuntimeError, OSError) as exc:
        text = str(exc)
        if "could not be found" in text or "package://" in text:
            mesh = re.search(r"(package://\S+|\S+\.(?:stl|dae|obj|STL|DAE|OBJ))", text)
            where = mesh.group(1) if mesh else text
            package = _package_dir(where, dirs)
            fix = (
                f"its package is at {package}, which has no such file: check the file name in the URDF"
                if package is not None
                else "add the folder that holds its package to package_dirs"
            )
            raise ProfileError(
                (prof.source or prof.name) if prof is not None else path,
                "package_dirs" if package is None else "urdf",
                f"mesh {where} not found; {fix}",
            ) from None
        raise RobotError(_parser_message(exc, messages, path, label)) from None
    return model, visual, collision


def _package_dir(uri: str, dirs: list[str]) -> Path | None:
    """Return the folder of a ``package://pkg/...`` URI's package under one of `dirs`, or None."""
    if not uri.startswith("package://"):
        return None
    package = uri[len("package://") :].split("/", 1)[0]
    return next((Path(d) / package for d in dirs if package and (Path(d) / package).is_dir()), None)


def _root_link(model: pin.Model) -> str:
    """Return the name of the body frame carried by the root joint (the URDF's root link)."""
    for f in model.frames:
        if f.type == pin.FrameType.BODY and f.parentJoint == 1:
            return f.name
    return "root_joint"


def _build_text(name: str, urdf_text: str, root: pin.JointModel, prof: RobotProfile):
    """Return (path, model, visual, collision) of URDF text kept in a content-addressed file."""
    check_urdf_text(urdf_text)
    # Keep the text in a content-addressed file so `LoadedRobot.urdf` stays valid (placo reads it);
    # it is written under a private name first and kept only if Pinocchio accepts it.
    digest = hashlib.sha256(urdf_text.encode()).hexdigest()[:16]
    path = Path(tempfile.gettempdir()) / "cartpush_urdf" / f"{name}_{digest}.urdf"
    if path.exists():
        return (path, *_build(path, root, prof=prof))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{name}_", suffix=".urdf", dir=path.parent)
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(urdf_text)
        built = _build(tmp, root, label="urdf_text", prof=prof)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return (path, *built)


def load(robot: str | Path | RobotProfile, urdf_text: str | None = None) -> LoadedRobot:
    """Return a robot loaded into Pinocchio with a planar root joint, its profile checked against its URDF.

    Args:
        robot: a registered name (`available()`), the path of a robot profile (.toml), or a profile.
        urdf_text: optional URDF text to load instead of the profile's file (e.g. another WMRA build from
            `robots.wmra_urdf(...)`); meshes resolve through the profile's package folders, and the
            joints and frames are those of the profile.

    Raises `UnknownRobotError` (unknown name), `ProfileError` (a profile its URDF contradicts, a missing
    URDF or mesh) or `RobotError` (a URDF the parser rejects).
    """
    prof = registry.resolve(robot)
    root = pin.JointModelPlanar()
    if urdf_text is None:
        path = _urdf_file(prof)
        model, visual, collision = _build(path, root, prof=prof)
    else:
        path, model, visual, collision = _build_text(prof.name, urdf_text, root, prof)
    check_profile(prof, model)
    check_wheel_radius(prof, model, collision)
    roles = prof.frame_roles
    roles.setdefault("base", _root_link(model))
    return LoadedRobot(
        name=prof.name,
        urdf=path,
        model=model,
        data=model.createData(),
        visual_model=visual,
        collision_model=collision,
        visual_data=visual.createData() if hasattr(visual, "createData") else pin.GeometryData(visual),
        collision_data=collision.createData() if hasattr(collision, "createData") else pin.GeometryData(collision),
        frames=roles,
        profile=prof,
    )

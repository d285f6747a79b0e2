"""Load the shipped URDFs into Pinocchio with a planar root joint (x, y, yaw)."""

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

from robots.errors import RobotError, UnknownRobotError

DATA_DIR = Path(__file__).resolve().parent

#: name -> (URDF file, named frames: role -> frame name)
_ROBOTS: dict[str, tuple[str, dict[str, str]]] = {
    "ridgeback_iiwa": (
        "ridgeback_iiwa.urdf",
        {"base": "base_link", "arm_base": "iiwa_link_0", "flange": "iiwa_flange", "ft_sensor": "ft_sensor", "ee": "ee"},
    ),
    "shopping_cart": ("shopping_cart.urdf", {"base": "b", "b": "b", "handle": "handle"}),
    "wmra": ("wmra.urdf", {"base": "base_link", "arm_base": "arm_mount", "ee": "ee"}),
}


@dataclass
class LoadedRobot:
    """A robot loaded into Pinocchio: models, data, and its named frames.

    Attributes:
        name: the robot's name in `available()`.
        urdf: path of the URDF file.
        model, data: Pinocchio kinematic/dynamic model (planar root joint `root_joint`) and its data.
        visual_model, collision_model, visual_data, collision_data: geometry models (primitives).
        frames: role -> frame name, e.g. ``{"ee": "ee", "ft_sensor": "ft_sensor"}``.
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

    def frame_id(self, role_or_name: str) -> int:
        """Return the Pinocchio frame id of a role (``"ee"``) or a frame name."""
        name = self.frames.get(role_or_name, role_or_name)
        if not self.model.existFrame(name):
            raise UnknownRobotError(f"robot {self.name!r} has no frame {role_or_name!r}; roles: {sorted(self.frames)}")
        return self.model.getFrameId(name)


def available() -> tuple[str, ...]:
    """Return the names `load` accepts, sorted."""
    return tuple(sorted(_ROBOTS))


def urdf_path(name: str) -> Path:
    """Return the path of a shipped URDF by robot name."""
    if name not in _ROBOTS:
        raise UnknownRobotError(f"unknown robot {name!r}; valid names: {', '.join(available())}")
    return DATA_DIR / _ROBOTS[name][0]


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


def _build(path: Path, root: pin.JointModel, label: str | None = None):
    """Return (model, visual, collision) of a URDF file; RobotError with the parser's message when it fails."""
    messages: list[str] = []
    try:
        with _captured_stderr_fd(messages):
            model = pin.buildModelFromUrdf(str(path), root)
            visual = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.VISUAL, package_dirs=[str(DATA_DIR)])
            collision = pin.buildGeomFromUrdf(
                model, str(path), pin.GeometryType.COLLISION, package_dirs=[str(DATA_DIR)]
            )
    except (ValueError, RuntimeError, OSError) as exc:
        detail = "; ".join(
            m[len("Error:") :].strip() if m.startswith("Error:") else m
            for m in messages
            if not re.match(r"^at line \d+ in ", m)
        )
        text = str(exc) if label is None else str(exc).replace(f"The file {path}", label).replace(str(path), label)
        raise RobotError(f"invalid URDF: {text}" + (f" ({detail})" if detail else "")) from None
    return model, visual, collision


def load(name: str, urdf_text: str | None = None) -> LoadedRobot:
    """Return the robot `name` loaded into Pinocchio with a planar root joint.

    Args:
        name: one of `available()`.
        urdf_text: optional URDF text to load instead of the shipped file (e.g.
            another WMRA build from `robots.wmra_urdf(...)`); frame roles are those of `name`.
    """
    path = urdf_path(name)
    roles = dict(_ROBOTS[name][1])
    root = pin.JointModelPlanar()
    if urdf_text is None:
        model, visual, collision = _build(path, root)
    else:
        check_urdf_text(urdf_text)
        # Keep the text in a content-addressed file so `LoadedRobot.urdf` stays valid (placo reads it);
        # it is written under a private name first and kept only if Pinocchio accepts it.
        digest = hashlib.sha256(urdf_text.encode()).hexdigest()[:16]
        path = Path(tempfile.gettempdir()) / "cartpush_urdf" / f"{name}_{digest}.urdf"
        if path.exists():
            model, visual, collision = _build(path, root)
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp_name = tempfile.mkstemp(prefix=f".{name}_", suffix=".urdf", dir=path.parent)
            tmp = Path(tmp_name)
            try:
                with os.fdopen(fd, "w", encoding="utf-8") as fh:
                    fh.write(urdf_text)
                model, visual, collision = _build(tmp, root, label="urdf_text")
                os.replace(tmp, path)
            finally:
                if tmp.exists():
                    tmp.unlink()
    return LoadedRobot(
        name=name,
        urdf=path,
        model=model,
        data=model.createData(),
        visual_model=visual,
        collision_model=collision,
        visual_data=visual.createData() if hasattr(visual, "createData") else pin.GeometryData(visual),
        collision_data=collision.createData() if hasattr(collision, "createData") else pin.GeometryData(collision),
        frames=roles,
    )

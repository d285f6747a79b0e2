"""Load the shipped URDFs into Pinocchio with a planar root joint (x, y, yaw)."""
from __future__ import annotations

import hashlib
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import pinocchio as pin

from robots.errors import UnknownRobotError

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
            raise UnknownRobotError(
                f"robot {self.name!r} has no frame {role_or_name!r}; roles: {sorted(self.frames)}"
            )
        return self.model.getFrameId(name)


def available() -> tuple[str, ...]:
    """Return the names `load` accepts, sorted."""
    return tuple(sorted(_ROBOTS))


def urdf_path(name: str) -> Path:
    """Return the path of a shipped URDF by robot name."""
    if name not in _ROBOTS:
        raise UnknownRobotError(f"unknown robot {name!r}; valid names: {', '.join(available())}")
    return DATA_DIR / _ROBOTS[name][0]


def load(name: str, urdf_text: str | None = None) -> LoadedRobot:
    """Return the robot `name` loaded into Pinocchio with a planar root joint.

    Args:
        name: one of `available()`.
        urdf_text: optional URDF text to load instead of the shipped file (e.g.
            another WMRA build from `robots.wmra_urdf(...)`); frame roles are those of `name`.
    """
    path = urdf_path(name)
    roles = dict(_ROBOTS[name][1])
    if urdf_text is not None:
        # Keep the text in a content-addressed file so `LoadedRobot.urdf` stays valid (placo reads it).
        digest = hashlib.sha256(urdf_text.encode()).hexdigest()[:16]
        path = Path(tempfile.gettempdir()) / "cartpush_urdf" / f"{name}_{digest}.urdf"
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists():
            path.write_text(urdf_text)
    root = pin.JointModelPlanar()
    model = pin.buildModelFromUrdf(str(path), root)
    visual = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.VISUAL, package_dirs=[str(DATA_DIR)])
    collision = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.COLLISION, package_dirs=[str(DATA_DIR)])
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

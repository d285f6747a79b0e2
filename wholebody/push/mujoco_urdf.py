"""A robot's URDF as text MuJoCo compiles, for any robot: meshes resolved or replaced, inertias made physical,
locked joints fixed.

MuJoCo's URDF compiler reads STL, OBJ and MSH meshes by file path; it knows no ``package://`` folders and
no COLLADA (``.dae``). This module rewrites the URDF text (the file itself is never changed):

- every mesh is resolved (``package://`` through the package folders, relative paths against the URDF's
  folder) to an absolute path; a mesh MuJoCo cannot read (missing, or a format it does not know) is
  replaced by the box with the link's inertia (the solid box with the same principal moments, at the
  link's centre of mass, along its principal axes), or dropped when the link has no inertia. The link's
  mass and inertia stay the URDF's (its ``<inertial>``): robot geoms do not collide in the scene, so
  only their inertia matters. Each replacement is listed (`MujocoUrdf.replaced_meshes`);
- a link without ``<inertial>`` gets an explicit zero one (URDF semantics, Pinocchio's: massless;
  MuJoCo would otherwise give it the mass of its geoms at the density of water);
- an inertia tensor MuJoCo refuses (a principal moment <= 0, a thin rod's included, or one above the sum of
  the other two) gets its principal moments clipped at 1e-6 of the largest, then balanced to their mean if
  still not physical (MuJoCo's ``balanceinertia``); its link is listed (`MujocoUrdf.fixed_inertias`);
- with `locked` given, every movable joint outside `free` becomes a fixed joint at its locked value
  (0 when not listed), its motion folded into the joint's origin: the rigid robot Pinocchio's locked
  joints give (a torso held at 0.2 m, a head, fingers).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robots.checks import package_search_dirs, resolve_package_uri
from robots.urdf_text import matrix_from_rpy, rpy_from_matrix, vec

#: mesh formats MuJoCo's compiler reads
MUJOCO_MESH_SUFFIXES = (".stl", ".obj", ".msh")
#: smallest side (m) of a box that replaces a mesh
MIN_BOX_SIDE = 1e-3
MOVABLE = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class ReplacedMesh:
    """A mesh MuJoCo cannot read and what stands for it."""

    link: str
    #: the mesh's file name as the URDF gives it
    mesh: str
    #: why MuJoCo cannot read it ("not found", "MuJoCo does not read .dae meshes")
    reason: str
    #: "box a x b x c m" (the link's equivalent box) or "dropped (the link has no mass)"
    replacement: str

    def __str__(self) -> str:
        return f"{self.link}: {self.mesh} ({self.reason}) -> {self.replacement}"


@dataclass(frozen=True)
class MujocoUrdf:
    """URDF text MuJoCo compiles, and what was changed to make it so."""

    text: str
    #: the meshes MuJoCo cannot read, each with what stands for it
    replaced_meshes: tuple[ReplacedMesh, ...] = ()
    #: links whose inertia tensor was made physical
    fixed_inertias: tuple[str, ...] = ()
    #: "joint = value" per movable joint made fixed
    fixed_joints: tuple[str, ...] = ()


def _origin(elem: ET.Element | None) -> np.ndarray:
    """Return the (4, 4) pose of an `<origin>` element (identity when absent)."""
    T = np.eye(4)
    if elem is not None:
        T[:3, :3] = matrix_from_rpy(*[float(v) for v in elem.get("rpy", "0 0 0").split()])
        T[:3, 3] = [float(v) for v in elem.get("xyz", "0 0 0").split()]
    return T


def _set_origin(parent: ET.Element, T: np.ndarray) -> None:
    """Set (or add as first child) `parent`'s `<origin>` to pose `T`."""
    elem = parent.find("origin")
    if elem is None:
        elem = ET.Element("origin")
        parent.insert(0, elem)
    elem.set("xyz", vec(*T[:3, 3]))
    elem.set("rpy", vec(*rpy_from_matrix(T[:3, :3])))


def _inertia_matrix(inertia: ET.Element) -> np.ndarray:
    a = {k: float(inertia.get(k, "0")) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    return np.array([[a["ixx"], a["ixy"], a["ixz"]], [a["ixy"], a["iyy"], a["iyz"]], [a["ixz"], a["iyz"], a["izz"]]])


def physical_inertia(inertia: np.ndarray) -> np.ndarray | None:
    """Return a physical inertia tensor near `inertia`, or None when MuJoCo takes `inertia` as it is.

    MuJoCo takes a zero tensor, or principal moments > 0 (here at least 1e-6 of the largest and 1e-12 kg m^2: a
    thin rod's zero moment is refused) each at most the sum of the other two. Otherwise the moments are clipped at that floor, then set to
    their mean if the triangle inequality still fails (MuJoCo's ``balanceinertia``).
    """
    w, V = np.linalg.eigh(0.5 * (inertia + inertia.T))
    scale = float(np.abs(w).max())
    floor = max(1e-6 * scale, 1e-12)  # above the precision of MuJoCo's own eigen-decomposition
    if scale == 0.0 or (w.min() >= floor and w[0] + w[1] >= w[2] * (1.0 - 1e-12)):
        return None
    w = np.clip(w, floor, None)
    if w[0] + w[1] < w[2]:
        w = np.full(3, w.mean())
    return V @ np.diag(w) @ V.T


def _fix_inertials(root: ET.Element) -> list[str]:
    """Give links without `<inertial>` a zero one; make non-physical inertias physical; return those links."""
    fixed = []
    for link in root.findall("link"):
        inertial = link.find("inertial")
        if inertial is None:
            inertial = ET.SubElement(link, "inertial")
            ET.SubElement(inertial, "mass", value="0")
            ET.SubElement(inertial, "inertia", {k: "0" for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")})
            continue
        inertia = inertial.find("inertia")
        if inertia is None:
            continue
        better = physical_inertia(_inertia_matrix(inertia))
        if better is not None:
            for k, (i, j) in {
                "ixx": (0, 0),
                "ixy": (0, 1),
                "ixz": (0, 2),
                "iyy": (1, 1),
                "iyz": (1, 2),
                "izz": (2, 2),
            }.items():
                inertia.set(k, repr(float(better[i, j])))  # not `fmt`: it rounds to 1e-12
            fixed.append(str(link.get("name")))
    return fixed


def equivalent_box(link: ET.Element) -> tuple[np.ndarray, np.ndarray] | None:
    """Return (pose (4, 4) in the link frame, sides (3,)) of the solid box with the link's mass and inertia.

    None when the link has no mass. The box is centred at the centre of mass along the principal axes;
    sides come from the principal moments (I_x = m (b^2 + c^2) / 12, ...), at least `MIN_BOX_SIDE`.
    """
    inertial = link.find("inertial")
    mass_el = inertial.find("mass") if inertial is not None else None
    inertia = inertial.find("inertia") if inertial is not None else None
    if inertial is None or mass_el is None or inertia is None:
        return None
    mass = float(mass_el.get("value", "0"))
    if not mass > 0.0:
        return None
    T_com = _origin(inertial.find("origin"))
    w, V = np.linalg.eigh(T_com[:3, :3] @ _inertia_matrix(inertia) @ T_com[:3, :3].T)
    if np.linalg.det(V) < 0:
        V[:, 2] = -V[:, 2]
    sides = np.sqrt(np.clip(6.0 * (w.sum() - 2.0 * w) / mass, MIN_BOX_SIDE**2, None))
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = V, T_com[:3, 3]
    return T, sides


def resolve_mesh(filename: str, urdf: Path, dirs: Sequence[str]) -> Path | None:
    """Return the file a URDF mesh `filename` names (``package://``, ``file://``, absolute or relative), or None."""
    if filename.startswith("package://"):
        return resolve_package_uri(filename, list(dirs))
    path = Path(filename[len("file://") :] if filename.startswith("file://") else filename)
    path = path if path.is_absolute() else urdf.parent / path
    return path if path.is_file() else None


def _fix_meshes(root: ET.Element, urdf: Path, dirs: Sequence[str]) -> list[ReplacedMesh]:
    """Point readable meshes at absolute paths; replace the others by the link's equivalent box; return them."""
    replaced = []
    for link in root.findall("link"):
        for kind in ("visual", "collision"):
            for shape in link.findall(kind):
                geometry = shape.find("geometry")
                mesh = geometry.find("mesh") if geometry is not None else None
                if geometry is None or mesh is None:
                    continue
                name = mesh.get("filename", "")
                path = resolve_mesh(name, urdf, dirs)
                if path is not None and path.suffix.lower() in MUJOCO_MESH_SUFFIXES:
                    mesh.set("filename", str(path.resolve()))
                    continue
                why = "not found" if path is None else f"MuJoCo does not read {path.suffix} meshes"
                box = equivalent_box(link)
                if box is None:
                    link.remove(shape)
                    replaced.append(ReplacedMesh(str(link.get("name")), name, why, "dropped (the link has no mass)"))
                    continue
                geometry.remove(mesh)
                ET.SubElement(geometry, "box", size=vec(*box[1]))
                _set_origin(shape, box[0])
                sides = " x ".join(f"{s:.3f}" for s in box[1])
                replaced.append(ReplacedMesh(str(link.get("name")), name, why, f"box {sides} m"))
    return replaced


def _joint_motion(joint: ET.Element, value: float) -> np.ndarray:
    """Return the (4, 4) motion of a 1-DoF joint at `value` (rad or m) about/along its axis."""
    axis_el = joint.find("axis")
    axis = np.array([float(v) for v in (axis_el.get("xyz", "1 0 0") if axis_el is not None else "1 0 0").split()])
    axis = axis / np.linalg.norm(axis)
    M = np.eye(4)
    if joint.get("type") == "prismatic":
        M[:3, 3] = axis * value
        return M
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    M[:3, :3] = np.eye(3) + math.sin(value) * K + (1.0 - math.cos(value)) * (K @ K)
    return M


def _lock_joints(root: ET.Element, locked: Mapping[str, float], free: Sequence[str]) -> list[str]:
    """Make every movable joint outside `free` fixed at its locked value (0 when unlisted); return them."""
    fixed = []
    for joint in root.findall("joint"):
        name = str(joint.get("name"))
        if joint.get("type") not in MOVABLE or name in free:
            continue
        value = float(locked.get(name, 0.0))
        T = _origin(joint.find("origin")) @ _joint_motion(joint, value)
        for child in list(joint):
            if child.tag not in ("origin", "parent", "child"):
                joint.remove(child)
        joint.set("type", "fixed")
        _set_origin(joint, T)
        fixed.append(f"{name} = {value:g}")
    return fixed


def mujoco_urdf(
    urdf: str | Path,
    package_dirs: Sequence[str | Path] = (),
    locked: Mapping[str, float] | None = None,
    free: Sequence[str] = (),
) -> MujocoUrdf:
    """Return the URDF at `urdf` as text MuJoCo compiles (see the module doc).

    Args:
        urdf: the URDF file.
        package_dirs: extra folders where ``package://`` meshes resolve (the profile's); also searched: the
            URDF's folder and its parents, ``$ROS_PACKAGE_PATH`` and the cmeel prefix (`package_search_dirs`).
        locked: joint -> value for the joints to hold; None: no joint is fixed.
        free: the joints that stay movable when `locked` is given (arms, wheels, casters).
    """
    path = Path(urdf)
    root = ET.fromstring(path.read_text(encoding="utf-8"))
    dirs = package_search_dirs(tuple(Path(p) for p in package_dirs), path)
    replaced = _fix_meshes(root, path, dirs)
    inertias = _fix_inertials(root)
    joints = _lock_joints(root, locked, free) if locked is not None else []
    return MujocoUrdf(ET.tostring(root, encoding="unicode"), tuple(replaced), tuple(inertias), tuple(joints))

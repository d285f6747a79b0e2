"""Small helpers that write URDF XML text with physically consistent inertials."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def fmt(x: float) -> str:
    """Return a float as compact, round-trippable text."""
    return repr(float(round(x, 12))).rstrip("0").rstrip(".") if x != 0 else "0"


def vec(*xs: float) -> str:
    """Return a space separated vector for URDF attributes."""
    return " ".join(fmt(x) for x in xs)


def matrix_from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Return the rotation matrix of URDF ``rpy`` angles (fixed axes x, y, z: R = Rz(yaw) Ry(pitch) Rx(roll))."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def rpy_from_matrix(R: np.ndarray) -> tuple[float, float, float]:
    """Return URDF ``rpy`` angles (roll, pitch, yaw) of a rotation matrix (the inverse of `matrix_from_rpy`)."""
    pitch = float(np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0])))
    if np.hypot(R[0, 0], R[1, 0]) < 1e-9:  # gimbal lock: yaw and roll share one axis; put it all in roll
        return float(np.arctan2(-R[1, 2], R[1, 1])), pitch, 0.0
    return float(np.arctan2(R[2, 1], R[2, 2])), pitch, float(np.arctan2(R[1, 0], R[0, 0]))


@dataclass(frozen=True)
class Inertial:
    """A body's mass, CoM (in the link frame) and inertia about the CoM (link axes)."""

    mass: float
    com: tuple[float, float, float]
    ixx: float
    iyy: float
    izz: float
    ixy: float = 0.0
    ixz: float = 0.0
    iyz: float = 0.0

    def xml(self) -> str:
        """Return the `<inertial>` element."""
        return (
            f'    <inertial>\n      <origin xyz="{vec(*self.com)}" rpy="0 0 0"/>\n'
            f'      <mass value="{fmt(self.mass)}"/>\n'
            f'      <inertia ixx="{fmt(self.ixx)}" ixy="{fmt(self.ixy)}" ixz="{fmt(self.ixz)}" '
            f'iyy="{fmt(self.iyy)}" iyz="{fmt(self.iyz)}" izz="{fmt(self.izz)}"/>\n    </inertial>\n'
        )


def box_inertial(mass: float, size: tuple[float, float, float], com=(0.0, 0.0, 0.0)) -> Inertial:
    """Return the inertial of a solid box of the given size (x, y, z) centred at `com`."""
    a, b, c = size
    k = mass / 12.0
    return Inertial(mass, tuple(com), k * (b * b + c * c), k * (a * a + c * c), k * (a * a + b * b))


def cylinder_inertial(mass: float, radius: float, length: float, com=(0.0, 0.0, 0.0), axis: str = "z") -> Inertial:
    """Return the inertial of a solid cylinder along `axis` ('x', 'y' or 'z')."""
    axial = 0.5 * mass * radius**2
    radial = mass * (3 * radius**2 + length**2) / 12.0
    d = {"x": (axial, radial, radial), "y": (radial, axial, radial), "z": (radial, radial, axial)}[axis]
    return Inertial(mass, tuple(com), *d)


def combine(parts: list[Inertial]) -> Inertial:
    """Return the inertial of several rigid parts (parallel-axis theorem)."""
    m = sum(p.mass for p in parts)
    c = sum((p.mass * np.asarray(p.com) for p in parts), np.zeros(3)) / m
    inertia = np.zeros((3, 3))
    for p in parts:
        ip = np.array([[p.ixx, p.ixy, p.ixz], [p.ixy, p.iyy, p.iyz], [p.ixz, p.iyz, p.izz]])
        r = np.asarray(p.com) - c
        inertia += ip + p.mass * (r @ r * np.eye(3) - np.outer(r, r))
    return Inertial(
        m, tuple(c), inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]
    )


def geometry(shape: str, dims: tuple[float, ...]) -> str:
    """Return a `<geometry>` element: box (x, y, z), cylinder (radius, length) or sphere (radius)."""
    if shape == "box":
        g = f'<box size="{vec(*dims)}"/>'
    elif shape == "cylinder":
        g = f'<cylinder radius="{fmt(dims[0])}" length="{fmt(dims[1])}"/>'
    elif shape == "sphere":
        g = f'<sphere radius="{fmt(dims[0])}"/>'
    else:
        raise ValueError(f"unknown primitive {shape!r}")
    return f"<geometry>{g}</geometry>"


@dataclass(frozen=True)
class Shape:
    """A primitive visual/collision shape placed in a link frame."""

    shape: str
    dims: tuple[float, ...]
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    material: str = "grey"


def link(name: str, inertial: Inertial | None = None, shapes: tuple[Shape, ...] = ()) -> str:
    """Return a `<link>` with visual and identical collision geometry."""
    out = [f'  <link name="{name}">\n']
    if inertial is not None:
        out.append(inertial.xml())
    for s in shapes:
        origin = f'<origin xyz="{vec(*s.xyz)}" rpy="{vec(*s.rpy)}"/>'
        geom = geometry(s.shape, s.dims)
        out.append(f'    <visual>{origin}{geom}<material name="{s.material}"/></visual>\n')
        out.append(f"    <collision>{origin}{geom}</collision>\n")
    out.append("  </link>\n")
    return "".join(out)


def joint(
    name: str,
    kind: str,
    parent: str,
    child: str,
    xyz=(0.0, 0.0, 0.0),
    rpy=(0.0, 0.0, 0.0),
    axis=(0.0, 0.0, 1.0),
    limit: tuple[float, float, float, float] | None = None,
    damping: float | None = None,
) -> str:
    """Return a `<joint>`; `limit` is (lower, upper, effort, velocity)."""
    out = [
        f'  <joint name="{name}" type="{kind}">\n    <parent link="{parent}"/>\n    <child link="{child}"/>\n'
        f'    <origin xyz="{vec(*xyz)}" rpy="{vec(*rpy)}"/>\n'
    ]
    if kind != "fixed":
        out.append(f'    <axis xyz="{vec(*axis)}"/>\n')
    if limit is not None:
        lo, hi, effort, vel = limit
        if kind == "continuous":
            out.append(f'    <limit effort="{fmt(effort)}" velocity="{fmt(vel)}"/>\n')
        else:
            out.append(
                f'    <limit lower="{fmt(lo)}" upper="{fmt(hi)}" effort="{fmt(effort)}" velocity="{fmt(vel)}"/>\n'
            )
    if damping is not None:
        out.append(f'    <dynamics damping="{fmt(damping)}"/>\n')
    out.append("  </joint>\n")
    return "".join(out)


MATERIALS = {
    "grey": (0.6, 0.6, 0.62, 1.0),
    "dark": (0.15, 0.15, 0.17, 1.0),
    "orange": (1.0, 0.45, 0.0, 1.0),
    "blue": (0.1, 0.3, 0.8, 1.0),
    "silver": (0.8, 0.8, 0.82, 1.0),
    "red": (0.8, 0.1, 0.1, 1.0),
    "yellow": (0.95, 0.8, 0.1, 1.0),
}


def robot(name: str, body: str) -> str:
    """Return a whole URDF document around `body` (links and joints)."""
    mats = "".join(f'  <material name="{k}"><color rgba="{vec(*v)}"/></material>\n' for k, v in MATERIALS.items())
    return f'<?xml version="1.0"?>\n<!-- Generated by cartpush robots/; see robots/README.md for every number\'s source. -->\n<robot name="{name}">\n{mats}{body}</robot>\n'

"""A MuJoCo cart drawn in a Meshcat scene: its own bodies, joints and geoms, as Pinocchio models (`Scene` draws those).

`cart_robot` turns the body ``cart`` of a compiled MuJoCo model (a cart file, `wholebody.push.cart_file`) and
everything below it into a `robots.LoadedRobot`: a planar root on the floor, {b} (frame ``b``) at the height the
file puts the body at, one Pinocchio joint per hinge, slide and ball joint of the file (caster swivels, wheel axles,
a wobbling stem), and each visible geom as the primitive it is (box, sphere, capsule, cylinder; an ellipsoid, a mesh
or a height field as the box around it). The handle sites (``handle``, ``handle_*``) are drawn too. A `Scene` shows it
like any robot (``Scene([robot_name, cart.robot])``); `MjcfCart.joints_from_record` turns the angles a MuJoCo run
recorded (`wholebody.push.mujoco_cart.CartJointRecord`) into the model's joint configurations.

Not drawn: other free bodies of the file (a loose load beside the cart), the floor, geoms in MuJoCo's hidden groups
(3 to 5).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import coal
import mujoco
import numpy as np
import pinocchio as pin

import robots
from wholebody.errors import SceneError

#: MuJoCo's geom groups shown by default (its viewer hides 3, 4 and 5: helpers such as contact spheres)
VISIBLE_GROUPS = (0, 1, 2)
_T = mujoco.mjtGeom


@dataclass(frozen=True)
class MjcfCart:
    """A MuJoCo cart as a Pinocchio model (`robot`), and where each of the file's joints is in its configuration.

    ``joints``: label (`wholebody.push.mujoco_cart.joint_label`) -> (index in q after the 4 planar-root entries,
    kind ``hinge``/``slide``/``ball``, the joint's reference qpos in the file: MuJoCo turns a hinge by qpos - qpos0).
    """

    robot: robots.LoadedRobot
    joints: dict[str, tuple[int, str, float]]

    def joints_from_record(self, names: tuple[str, ...], kinds: tuple[str, ...], q: np.ndarray) -> np.ndarray:
        """Return joint configurations (N, nq - 4) of `robot` from recorded qpos rows q (N, sum of the joints' nq).

        Joints of the record the model does not have are skipped; the model's joints the record lacks stay at rest.
        """
        from wholebody.push.mujoco_cart import JOINT_NQ

        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.tile(pin.neutral(self.robot.model)[4:], (len(q), 1))
        col = 0
        for name, kind in zip(names, kinds):
            width = JOINT_NQ[kind]
            if name in self.joints and self.joints[name][1] == kind:
                k, _, ref = self.joints[name]
                if kind == "ball":  # MuJoCo (w, x, y, z) -> Pinocchio (x, y, z, w)
                    out[:, k : k + 4] = q[:, [col + 1, col + 2, col + 3, col]]
                else:
                    out[:, k] = q[:, col] - ref
            col += width
        return out


def _se3(quat_wxyz: Any, pos: Any) -> pin.SE3:
    """Return the SE3 of a MuJoCo (quaternion w, x, y, z; position) pair."""
    w, x, y, z = (float(v) for v in quat_wxyz)
    return pin.SE3(pin.Quaternion(w, x, y, z).normalized().matrix(), np.asarray(pos, dtype=float).copy())


def _shape(kind: int, size: np.ndarray, aabb: np.ndarray) -> tuple[Any, pin.SE3] | None:
    """Return (coal shape, its offset in the geom frame) of a MuJoCo geom or site; None for a plane."""
    if kind == int(_T.mjGEOM_PLANE):
        return None
    if kind == int(_T.mjGEOM_SPHERE):
        return coal.Sphere(float(size[0])), pin.SE3.Identity()
    if kind == int(_T.mjGEOM_CAPSULE):
        return coal.Capsule(float(size[0]), 2.0 * float(size[1])), pin.SE3.Identity()
    if kind == int(_T.mjGEOM_CYLINDER):
        return coal.Cylinder(float(size[0]), 2.0 * float(size[1])), pin.SE3.Identity()
    if kind == int(_T.mjGEOM_BOX):
        return coal.Box(*(2.0 * np.asarray(size[:3], dtype=float))), pin.SE3.Identity()
    centre, half = np.asarray(aabb[:3], dtype=float), np.asarray(aabb[3:], dtype=float)
    if not np.all(half > 0.0):
        return None
    return coal.Box(*(2.0 * half)), pin.SE3(np.eye(3), centre)  # the box around an ellipsoid, a mesh, a height field


def _inertia(model: mujoco.MjModel, b: int) -> pin.Inertia:
    """Return body b's inertia in its body frame (MuJoCo's principal axes rotated back)."""
    mass = float(model.body_mass[b])
    if mass <= 0.0:
        return pin.Inertia.Zero()
    R = _se3(model.body_iquat[b], model.body_ipos[b])
    return pin.Inertia(mass, R.translation, R.rotation @ np.diag(model.body_inertia[b]) @ R.rotation.T)


def _colour(model: mujoco.MjModel, g: int) -> np.ndarray:
    """Return a geom's RGBA: its material's when it has one, else its own."""
    mat = int(model.geom_matid[g])
    return np.asarray(model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g], dtype=float).copy()


def _joint_model(kind: str, axis: np.ndarray) -> Any:
    """Return the Pinocchio joint of a MuJoCo hinge, slide or ball joint with `axis` in the body frame."""
    if kind == "hinge":
        return pin.JointModelRevoluteUnaligned(*axis)
    if kind == "slide":
        return pin.JointModelPrismaticUnaligned(*axis)
    return pin.JointModelSpherical()


@dataclass
class _Builder:
    """Pinocchio model and geometry grown body by body from a MuJoCo subtree."""

    mj: mujoco.MjModel
    model: pin.Model
    geoms: pin.GeometryModel
    joints: dict[str, tuple[int, str, float]]

    def add_joints(self, b: int, parent: int, M: pin.SE3) -> tuple[int, pin.SE3]:
        """Add body b's joints below Pinocchio joint `parent` (body frame at M in it); return (its joint, frame in it)."""
        from wholebody.push.mujoco_cart import JOINT_KINDS, joint_label

        mj = self.mj
        for j in range(int(mj.body_jntadr[b]), int(mj.body_jntadr[b] + mj.body_jntnum[b])):
            kind = JOINT_KINDS.get(int(mj.jnt_type[j]))
            if kind is None:
                continue
            pos = np.asarray(mj.jnt_pos[j], dtype=float)
            axis = np.asarray(mj.jnt_axis[j], dtype=float)
            label = joint_label(mj, j)
            parent = self.model.addJoint(parent, _joint_model(kind, axis), M * pin.SE3(np.eye(3), pos), label)
            ref = float(mj.qpos0[int(mj.jnt_qposadr[j])]) if kind != "ball" else 0.0
            self.joints[label] = (int(self.model.idx_qs[parent]) - 4, kind, ref)
            M = pin.SE3(np.eye(3), -pos)
        return parent, M

    def add_body(self, b: int, joint: int, M: pin.SE3) -> None:
        """Add body b's inertia, frame, visible geoms and handle sites on Pinocchio joint `joint` (body frame at M)."""
        mj = self.mj
        name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}"
        self.model.appendBodyToJoint(joint, _inertia(mj, b), M)
        frame = self.model.addFrame(pin.Frame(name, joint, M, pin.FrameType.BODY))
        for g in range(int(mj.body_geomadr[b]), int(mj.body_geomadr[b] + mj.body_geomnum[b])):
            rgba = _colour(mj, g)
            if int(mj.geom_group[g]) not in VISIBLE_GROUPS or rgba[3] <= 0.0:
                continue
            shape = _shape(int(mj.geom_type[g]), mj.geom_size[g], mj.geom_aabb[g])
            label = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_GEOM, g) or f"{name}_geom{g - int(mj.body_geomadr[b])}"
            if shape is not None:
                self._add(label, joint, frame, M, g, shape, rgba, "geom")
        for s in range(mj.nsite):
            site = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_SITE, s) or ""
            if int(mj.site_bodyid[s]) == b and (site == "handle" or site.startswith("handle_")):
                size = np.array(mj.site_size[s], dtype=float)
                size[0] = max(size[0], HANDLE_MIN_RADIUS)  # a 5 mm point hid inside the posts around it
                shape = _shape(int(mj.site_type[s]), size, np.zeros(6))
                if shape is not None:
                    self._add(site, joint, frame, M, s, shape, np.array(HANDLE_RGBA), "site")

    def _add(self, name: str, joint: int, frame: int, M: pin.SE3, i: int, shape: tuple, rgba: np.ndarray, of: str):
        """Add one geometry object: geom or site `i` of the body whose frame is at M on `joint`."""
        mj = self.mj
        quat, pos = (mj.geom_quat[i], mj.geom_pos[i]) if of == "geom" else (mj.site_quat[i], mj.site_pos[i])
        placement = M * _se3(quat, pos) * shape[1]
        obj = pin.GeometryObject(name, joint, frame, placement, shape[0])
        obj.meshColor = rgba
        self.geoms.addGeometryObject(obj)


def cart_robot(mj: mujoco.MjModel, body: str = "cart", name: str = "cart", source: str | Path = "") -> MjcfCart:
    """Return the body `body` of a compiled MuJoCo model and its subtree as a Pinocchio cart named `name`.

    The planar root (``root_joint``) stands on the floor under {b}; frame ``b`` is {b}, as high as the body's
    ``pos`` puts it (the cart-file contract: its height when the cart stands); frame ``handle`` is the first
    handle site's centre. `source` is the file it came from (`robots.LoadedRobot.urdf`: only a label here).
    """
    root = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, body)
    if root < 0:
        raise SceneError(f"the MuJoCo model has no body {body!r}")
    from wholebody.push.mujoco_cart import subtree_bodies

    model, geoms = pin.Model(), pin.GeometryModel()
    model.name = name
    top = model.addJoint(0, pin.JointModelPlanar(), pin.SE3.Identity(), "root_joint")
    b_frame = pin.SE3(np.eye(3), np.array([0.0, 0.0, float(mj.body_pos[root][2])]))
    builder = _Builder(mj, model, geoms, {})
    placed: dict[int, tuple[int, pin.SE3]] = {root: (top, b_frame)}
    for b in subtree_bodies(mj, root):
        b = int(b)
        if b != root:
            joint, M = placed[int(mj.body_parentid[b])]
            placed[b] = builder.add_joints(b, joint, M * _se3(mj.body_quat[b], mj.body_pos[b]))
        builder.add_body(b, *placed[b])
    model.addFrame(pin.Frame("b", top, b_frame, pin.FrameType.OP_FRAME))
    frames = {"b": "b"}
    handle = next((g for g in geoms.geometryObjects if g.name.startswith("handle")), None)
    if handle is not None:
        model.addFrame(pin.Frame("handle", top, handle.placement, pin.FrameType.OP_FRAME))
        frames["handle"] = "handle"
    robot = robots.LoadedRobot(
        name, Path(source), model, model.createData(), geoms, geoms, pin.GeometryData(geoms), pin.GeometryData(geoms)
    )
    robot.frames.update(frames)
    return MjcfCart(robot, builder.joints)


def cart_file_robot(path: str | Path, name: str = "cart") -> MjcfCart:
    """Return the cart of a cart file (`wholebody.push.cart_file.load_cart_file`) as a Pinocchio cart (`cart_robot`)."""
    from wholebody.push.cart_file import load_cart_file

    return cart_robot(load_cart_file(path).spec().compile(), name=name, source=path)


#: handle sites are drawn in this colour (the file's site colour, grey by default, read as one more post) and at
#: least this radius (m)
HANDLE_RGBA = (1.0, 0.55, 0.0, 1.0)
HANDLE_MIN_RADIUS = 0.02
#: the legend line of a cart file's scene on its handle sites
HANDLE_LEGEND = "orange bars and points: the file's handle sites (named handle*), where hands may hold"


def cart_file_scene(path: str | Path, serve: bool = False) -> Any:
    """Return a `wholebody.viz.Scene` of a cart file's cart (`cart_file_robot`) at the origin, framed by the camera."""
    from wholebody.viz.scene import Scene

    cart = cart_file_robot(path)
    scene = Scene([cart.robot], serve=serve)
    handles = [g for g in cart.robot.visual_model.geometryObjects if g.name.startswith("handle")]
    if handles:
        rgba = np.clip(np.asarray(handles[0].meshColor[:3], dtype=float), 0.0, 1.0)
        scene.add_legend("handles", int("".join(f"{int(round(255 * c)):02x}" for c in rgba), 16), "line", HANDLE_LEGEND)
    scene.frame_robots(margin=0.4)
    return scene

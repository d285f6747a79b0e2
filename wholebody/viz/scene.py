"""Meshcat scenes: robots and cart (Pinocchio's visualizer), contacts, wrench arrows, CoM, traces, animations.

A `Scene` records every Meshcat command in-process, so `save_html` writes a
self-contained static page (viewer JavaScript inlined, works offline) without
any server. With ``serve=True`` it also starts a local Meshcat server and
forwards the commands to it (open `Scene.url` in a browser); `close()` (or a
``with`` block) stops that server.

>>> with Scene(["ridgeback_iiwa", "shopping_cart"]) as scene:
...     scene.set_robot_pose("shopping_cart", (0.9, 0.0, 0.0))
...     scene.save_html("scene.html")
"""

from __future__ import annotations

import contextlib
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from collections.abc import Mapping, Sequence

import meshcat
import meshcat.geometry as mg
import meshcat.transformations as tf
import numpy as np
import numpy.typing as npt
import pinocchio as pin
import umsgpack
from meshcat.animation import Animation, AnimationClip
from meshcat.commands import SetProperty
from meshcat.path import Path as PathOf
from meshcat.servers.tree import SceneTree, find_node, walk
from pinocchio.visualize import MeshcatVisualizer

import robots
from robots.shopping_cart import CART_HANDLE_X, CART_HANDLE_Z_B, CART_WHEEL_RADIUS
from wholebody.errors import SceneError
from wholebody.motion.bases import planar_pose_matrix
from wholebody.viz.lowering import Lowered, lower_command
from wholebody.viz.page import MARKS, Chart, LegendEntry, Readout, compressed_iframe, nice_scale, static_html

#: Colours (0xRRGGBB) of the overlays.
COLORS = {
    "applied": 0x1565C0,  # blue: wrench the manipulator applies
    "desired": 0x2E7D32,  # green: wrench the planner/controller asked for
    "measured": 0x1565C0,  # blue: a physics run's hand force from its F/T sensor
    "allocated": 0x2E7D32,  # green: the hand force the allocation asked for
    "contact": 0x111111,
    "com_true": 0x1F3FBF,
    "com_est": 0xE040FB,
    "trace": 0x00E5FF,
}
#: Height (m above the floor) at which CoM markers are drawn (just above the basket).
COM_MARKER_Z = 0.95
#: Default floor grid (xmin, xmax, ymin, ymax), metres.
FLOOR = (-2.0, 6.0, -3.0, 3.0)
#: Most grid lines per axis of the floor (the spacing grows from 0.5 m to 1-2-5 steps to respect it).
MAX_FLOOR_LINES = 120
#: Most keyframes of one animation (longer runs are decimated; playback stays in real time).
MAX_FRAMES = 3000
#: Default arrow scale of static scenes: metres of arrow per newton (and per newton-metre for torques).
#: Animations choose theirs from the forces they draw (`wholebody.viz.page.nice_scale`); the legend says it.
FORCE_SCALE = 0.03
#: Radius and head length (m) of force arrows (torque arrows: half the radius, 2/3 of the head).
ARROW_RADIUS, ARROW_HEAD = 0.018, 0.08
#: Longest animated force arrow (m): longer ones are drawn this long (the legend says so, the read-out gives |f|).
ARROW_MAX = 1.5
#: Where a scene with the cart and another robot puts the cart by default: ahead of the robot at the origin.
DEFAULT_CART_POSE = (0.9, 0.0, 0.0)
#: What each overlay colour means, for the page's legend (kind -> (shape, text)).
LEGEND_TEXT = {
    "applied": ("arrow", "blue arrow: force the hand applies"),
    "desired": ("arrow", "green arrow: force the controller asked for"),
    "measured": ("arrow", "blue arrow: the hand's horizontal force its F/T sensor measured"),
    "allocated": ("arrow", "green arrow: the horizontal force the allocation asked of the hand"),
    "torque": ("arrow", "thin vertical arrow: yaw torque, up = counter-clockwise"),
    "contact": ("dot", "black dot: contact point on the handle"),
    "com_true": ("sphere", "blue sphere (large, see-through): the cart's true CoM"),
    "com_est": ("sphere", "magenta sphere (small): the estimated CoM"),
}

#: the kinds of force arrow (`LEGEND_TEXT`): what the hand applied or was asked for, a physics run's measured
#: and allocated hand force
ARROW_KINDS = ("applied", "desired", "measured", "allocated")


class _OnTopMesh(mg.Mesh):
    """A mesh drawn over everything else (no depth test, rendered last): arrows stay visible inside cart and hand."""

    def __init__(self, geometry: Any, color: int) -> None:
        super().__init__(geometry, mg.MeshLambertMaterial(color=color, depthTest=False, depthWrite=False))

    def lower(self) -> dict:
        data = super().lower()
        data["object"]["renderOrder"] = 10
        return data


@dataclass(frozen=True)
class Camera:
    """A perspective camera looking from `eye` at `target` (world, z up), vertical field of view `fov_deg`.

    This is Meshcat's default camera (three.js PerspectiveCamera, fov 75 deg,
    orbit controls around `target`); `project` maps world points to pixels.
    """

    target: tuple[float, float, float] = (0.45, 0.0, 0.55)
    eye: tuple[float, float, float] = (2.1, -2.3, 1.9)
    fov_deg: float = 50.0

    @staticmethod
    def framing(points: Any, elevation: float = 0.65) -> Camera:
        """Return a camera that sees the world points (N, 3) from the -y side, looking down by about `elevation` rad."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        lo, hi = p.min(axis=0), p.max(axis=0)
        centre = (lo + hi) / 2
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1.0)
        dist = 0.95 * radius / math.tan(math.radians(25.0))
        d = np.array([0.55, -0.85 * math.cos(elevation), math.sin(elevation)])
        d /= np.linalg.norm(d)
        return Camera(target=tuple(centre), eye=tuple(centre + dist * d), fov_deg=50.0)

    def project(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """Return pixel coordinates (u right, v down), shape (N, 2), of world points (N, 3)."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        eye, target = np.asarray(self.eye, float), np.asarray(self.target, float)
        fwd = (target - eye) / np.linalg.norm(target - eye)
        right = np.cross(fwd, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        d = p - eye
        zc = d @ fwd
        t = math.tan(math.radians(self.fov_deg) / 2)
        ndc_x = (d @ right) / (zc * t * width / height)
        ndc_y = (d @ up) / (zc * t)
        return np.column_stack(((ndc_x + 1) / 2 * width, (1 - ndc_y) / 2 * height))


class _RecordingWindow:
    """A Meshcat window that keeps the scene tree in-process and optionally forwards to a live server."""

    def __init__(self, live: Any | None = None) -> None:
        self.tree = SceneTree()
        self.animation: bytes | None = None
        self.live = live

    def send(self, command: Any) -> None:
        """Record a Meshcat command (same tree semantics as meshcat's zmq server) and forward it.

        The command is lowered once, meshes in the viewer's current form (`lowering.lower_command`).
        """
        data = lower_command(command.lower())
        path = [p for p in data["path"].split("/") if p]
        packed = umsgpack.packb(data)
        kind = data["type"]
        if kind == "set_object":
            node = find_node(self.tree, path)
            node.object, node.properties = packed, []
        elif kind == "set_transform":
            find_node(self.tree, path).transform = packed
        elif kind == "set_property":
            find_node(self.tree, path).properties.append(packed)
        elif kind == "set_animation":
            self.animation = packed
        elif kind == "delete":
            if path:
                parent = find_node(self.tree, path[:-1])
                parent.pop(path[-1], None)
            else:
                self.tree, self.animation = SceneTree(), None
        if self.live is not None:
            self.live.send(Lowered(data))

    def commands(self) -> list[bytes]:
        """Return the recorded scene as msgpack commands, animation last."""
        out: list[bytes] = []
        for node in walk(self.tree):
            if node.object is not None:
                out.append(node.object)
            out.extend(node.properties)
            if node.transform is not None:
                out.append(node.transform)
        if self.animation is not None:
            out.append(self.animation)
        return out

    def local_transform(self, path: Sequence[str]) -> np.ndarray:
        """Return the recorded transform (4x4) of the node at `path` (identity when none was set)."""
        node = self.tree
        for part in path:
            if part not in node:
                raise SceneError(f"scene has no node /{'/'.join(path)}")
            node = node[part]
        if node.transform is None:
            return np.eye(4)
        return np.array(umsgpack.unpackb(node.transform)["matrix"], dtype=float).reshape(4, 4).T

    def get_image(self):  # pinocchio checks that the viewer can capture images
        raise SceneError("image capture needs a browser; use Scene.save_html and a headless browser")


def _grid_step(span: float, step: float) -> float:
    """Return `step`, or the smallest 1-2-5 x 10^k spacing above it that keeps a grid over `span` within MAX_FLOOR_LINES."""
    if span / step <= MAX_FLOOR_LINES - 1:
        return step
    raw = span / (MAX_FLOOR_LINES - 1)
    base = 10.0 ** math.floor(math.log10(raw))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * base >= raw:
            return m * base
    return 10.0 * base


def _start_server() -> tuple[Any, Any]:
    """Return (meshcat ViewerWindow connected to a new local server, server process)."""
    with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL on stdout
        window = meshcat.visualizer.ViewerWindow(zmq_url=None, start_server=True, server_args=[])
    return window, window.server_proc


def _planar_q(model: pin.Model, planar_pose: Sequence[float], q_joints: Any) -> np.ndarray:
    """Return a full configuration: planar root (x, y, theta) + the other joints (array or name -> angle)."""
    pose = np.asarray(planar_pose, dtype=float).ravel()
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise SceneError(f"planar pose must be 3 finite numbers (x, y, theta), got {planar_pose!r}")
    q = pin.neutral(model)
    q[:4] = pose[0], pose[1], math.cos(pose[2]), math.sin(pose[2])
    if q_joints is None:
        return q
    if isinstance(q_joints, Mapping):
        for name, angle in q_joints.items():
            if not model.existJointName(name):
                raise SceneError(f"model has no joint {name!r}")
            j = model.joints[model.getJointId(name)]
            if j.nq != 1:
                raise SceneError(f"joint {name!r} has nq={j.nq}; give it in the array form of q_joints")
            q[j.idx_q] = float(angle)
        return q
    rest = np.asarray(q_joints, dtype=float).ravel()
    if rest.shape != (model.nq - 4,) or not np.all(np.isfinite(rest)):
        raise SceneError(f"q_joints must have {model.nq - 4} finite entries (nq - 4), got shape {rest.shape}")
    q[4:] = rest
    return q


def _js_pose(T: np.ndarray) -> tuple[list[float], list[float]]:
    """Return (position, quaternion x y z w) of a rigid 4x4 transform, as three.js animation keys want them."""
    quat = pin.Quaternion(np.ascontiguousarray(T[:3, :3])).coeffs()  # (x, y, z, w)
    return [float(v) for v in T[:3, 3]], [float(v) for v in quat]


def _set_key(anim: Animation, path: Any, frame: int, T: np.ndarray, scale: np.ndarray | None = None) -> None:
    """Add position/quaternion (and scale) keys of the node at `path` to `anim` at `frame`."""
    if path not in anim.clips:
        anim.clips[path] = AnimationClip(fps=anim.default_framerate)
    clip = anim.clips[path]
    pos, quat = _js_pose(T)
    clip.set_property(frame, "position", "vector3", pos)
    clip.set_property(frame, "quaternion", "quaternion", quat)
    if scale is not None:
        clip.set_property(frame, "scale", "vector3", [float(v) for v in scale])


def _points3(points: Any, z: float) -> np.ndarray:
    """Return points as (N, 3); 2-D points get height `z`."""
    p = np.atleast_2d(np.asarray(points, dtype=float))
    if p.ndim != 2 or p.shape[1] not in (2, 3) or not np.all(np.isfinite(p)):
        raise SceneError(f"points must be finite (N, 2) or (N, 3), got shape {np.shape(points)}")
    if p.shape[1] == 2:
        p = np.column_stack((p, np.full(len(p), z)))
    return p


def _rotation_x_to(direction: np.ndarray) -> np.ndarray:
    """Return a rotation matrix whose x axis is the unit vector `direction`."""
    x = direction / np.linalg.norm(direction)
    helper = np.array([0.0, 0.0, 1.0]) if abs(x[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    y = np.cross(helper, x)
    y /= np.linalg.norm(y)
    return np.column_stack((x, y, np.cross(x, y)))


def _arrow_parts(origin: np.ndarray, vector: np.ndarray, head: float) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Return [(part, rigid transform, scale)] for the group, shaft and head of an arrow from `origin` along `vector`.

    The group carries position and direction; the unit shaft (along x) is
    stretched to length |vector| - head; the head sits at the tip. A zero
    vector collapses the group (scale 1e-6), i.e. the arrow is invisible.
    """
    length = float(np.linalg.norm(vector))
    group = np.eye(4)
    group[:3, 3] = origin
    if length < 1e-9:
        return [("", group, np.full(3, 1e-6)), ("shaft", np.eye(4), np.ones(3)), ("head", np.eye(4), np.ones(3))]
    group[:3, :3] = _rotation_x_to(vector)
    h = min(head, 0.5 * length)
    shaft, tip = tf.translation_matrix([(length - h) / 2, 0, 0]), tf.translation_matrix([length - h / 2, 0, 0])
    return [
        ("", group, np.ones(3)),
        ("shaft", shaft, np.array([length - h, 1.0, 1.0])),
        ("head", tip, np.full(3, h / head)),
    ]


def _per_unit(scale: float, unit: str) -> str:
    """Return an arrow scale in words, e.g. '3 cm per N (10 N = 30 cm)'."""
    return f"{100 * scale:.3g} cm per {unit} (10 {unit} = {1000 * scale:.3g} cm)"


def _set_arrow(node: Any, parts: list[tuple[str, np.ndarray, np.ndarray]]) -> None:
    """Set the (scaled) arrow transforms on the Visualizer `node`."""
    for part, T, scale in parts:
        S = T.copy()
        S[:3, :3] = T[:3, :3] * scale
        (node[part] if part else node).set_transform(S)


def _frame_schedule(t: np.ndarray, fps: int) -> tuple[np.ndarray, np.ndarray]:
    """Return (keyed frame numbers, index of the sample shown at each) for sample times `t` played at `fps`.

    Each frame shows the latest sample at or before its time; beyond MAX_FRAMES
    frames only every k-th frame is keyed (three.js interpolates between them).
    """
    if len(t) < 2 or not np.all(np.diff(t) > 0) or not np.all(np.isfinite(t)):
        raise SceneError("animation times must be finite and strictly increasing, at least 2 samples")
    span_frames = (t[-1] - t[0]) * fps
    if not span_frames < 1e12:
        raise SceneError(f"animation spans {t[-1] - t[0]:.3g} s: too long to animate")
    total = int(math.floor(span_frames)) + 1
    stride = max(1, int(math.ceil(total / MAX_FRAMES)))
    frame_numbers = np.arange(0, total, stride)
    idx = np.searchsorted(t, t[0] + frame_numbers / fps, side="right") - 1
    return frame_numbers, idx


class Scene:
    """A Meshcat scene of robots (by `robots.load` name) with contacts, wrenches, CoM markers, traces and animations."""

    def __init__(
        self,
        robot_names: Sequence[str | robots.LoadedRobot] = ("ridgeback_iiwa", "shopping_cart"),
        serve: bool = False,
        camera: Camera | None = None,
        floor: tuple[float, float, float, float] = FLOOR,
    ) -> None:
        """Load the robots (each under its own node `/meshcat/<name>`); optionally start a server.

        A robot is a `robots.load` name or a model loaded already (`robots.LoadedRobot`, shown under its
        ``name``; e.g. a cart file's cart, `wholebody.viz.mjcf.cart_robot`). The first robot with a frame ``b``
        is the scene's cart (`Scene.cart`; the shopping cart's {b}). Robots stand at the origin, except the cart
        next to another robot: it stands ahead of it at `DEFAULT_CART_POSE`. Without `camera` the page's
        camera frames every robot as displayed when the page is written
        (`set_camera` or `frame_robots` fix it). `floor` (xmin, xmax, ymin,
        ymax) is drawn as a 0.5 m grid of short segments instead of Meshcat's
        20 m grid (whose long lines software renderers drop when they pass
        behind the camera); Meshcat's axes at the origin are hidden.
        """
        entries = list(robot_names)
        names = [e if isinstance(e, str) else e.name for e in entries]
        if len(set(names)) != len(names):
            raise SceneError(f"robot names must be unique, got {names}")
        self._server = None
        live = None
        if serve:
            live, self._server = _start_server()
        self.window = _RecordingWindow(live)
        self.viewer = meshcat.Visualizer(window=self.window)
        self.url: str | None = live.web_url if live is not None else None
        self.robots: dict[str, robots.LoadedRobot] = {}
        self._viz: dict[str, MeshcatVisualizer] = {}
        self._q: dict[str, np.ndarray] = {}
        self.follow: tuple[str, ...] = ()
        self._camera: Camera | None = None
        self._legend: dict[str, LegendEntry] = {}
        self._readouts: list[Readout] = []
        self._charts: list[Chart] = []
        self._autoplay = True
        try:
            for name, entry in zip(names, entries):
                robot = robots.load(entry) if isinstance(entry, str) else entry  # UnknownRobotError for bad names
                viz = MeshcatVisualizer(
                    robot.model, None, robot.visual_model, data=robot.data, visual_data=robot.visual_data
                )
                viz.initViewer(viewer=self.viewer)
                viz.loadViewerModel(rootNodeName=name)
                self.robots[name], self._viz[name] = robot, viz
                pose = DEFAULT_CART_POSE if robot.model.existFrame("b") and len(names) > 1 else (0.0, 0.0, 0.0)
                self.set_robot_pose(name, pose)
            if camera is not None:
                self.set_camera(camera)
            self.set_floor(floor)
        except BaseException:
            self.close()
            raise

    # -- lifecycle -----------------------------------------------------------------
    def close(self) -> None:
        """Stop the Meshcat server started by ``serve=True`` (no-op otherwise)."""
        if self._server is not None:
            self._server.kill()
            self._server.wait()
            for stream in (self._server.stdout, self._server.stderr):
                if stream is not None:
                    stream.close()
            if self.window.live is not None:  # the live window of the server started with it
                self.window.live.zmq_socket.close(linger=0)
            self._server = None

    def __enter__(self) -> Scene:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -- robots ----------------------------------------------------------------------
    def _robot(self, name: str) -> robots.LoadedRobot:
        if name not in self.robots:
            raise SceneError(f"scene has no robot {name!r}; robots: {', '.join(self.robots)}")
        return self.robots[name]

    def set_robot_pose(self, name: str, planar_pose: Sequence[float], q_joints: Any = None) -> np.ndarray:
        """Place robot `name` at planar pose (x, y, theta) with joints `q_joints`; return its full configuration.

        `q_joints` is either the nq - 4 entries after the planar root (Pinocchio
        order) or a mapping joint name -> angle for 1-dof joints (others neutral).
        """
        robot = self._robot(name)
        self.set_robot_q(name, _planar_q(robot.model, planar_pose, q_joints))
        return self._q[name].copy()

    def set_robot_q(self, name: str, q: np.ndarray) -> None:
        """Display robot `name` at full Pinocchio configuration `q` (nq entries).

        The planar root goes to the transform of node `/meshcat/<name>`; the
        geometry below it is placed by Pinocchio with the root at the origin.
        """
        robot = self._robot(name)
        q = np.asarray(q, dtype=float).ravel()
        if q.shape != (robot.model.nq,) or not np.all(np.isfinite(q)):
            raise SceneError(f"q of {name!r} must have {robot.model.nq} finite entries, got shape {q.shape}")
        q_local = q.copy()
        q_local[:4] = 0.0, 0.0, 1.0, 0.0
        self._viz[name].display(q_local)
        self.viewer[name].set_transform(planar_pose_matrix(q[0], q[1], math.atan2(q[3], q[2])))
        self._q[name] = q.copy()

    def robot_q(self, name: str) -> np.ndarray:
        """Return the configuration robot `name` is displayed at."""
        self._robot(name)
        return self._q[name].copy()

    def frame_position(self, name: str, role: str) -> np.ndarray:
        """Return the world position of frame `role` (or frame name) of robot `name` as displayed."""
        robot = self._robot(name)
        pin.framesForwardKinematics(robot.model, robot.data, self._q[name])
        return robot.data.oMf[robot.frame_id(role)].translation.copy()

    @property
    def cart(self) -> str | None:
        """Return the name of the scene's cart: its first robot with a frame ``b`` ({b}); None without one."""
        return next((name for name, r in self.robots.items() if r.model.existFrame("b")), None)

    def cart_heights(self, cart: str | None = None) -> tuple[float, float]:
        """Return (height of {b} above the floor, height of the handle above {b}) of the cart (default `cart`).

        From the cart model's frames ``b`` and ``handle`` at rest (no ``handle`` frame: the shopping cart's).
        """
        robot = self._robot(self._cart_name(cart))
        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, pin.neutral(robot.model))
        z_b = float(data.oMf[robot.model.getFrameId("b")].translation[2])
        handle = robot.frames.get("handle", "handle")
        if not robot.model.existFrame(handle):
            return z_b, CART_HANDLE_Z_B
        return z_b, float(data.oMf[robot.model.getFrameId(handle)].translation[2]) - z_b

    def _cart_name(self, cart: str | None) -> str:
        name = cart if cart is not None else self.cart
        if name is None:
            raise SceneError(f"scene has no cart (a robot with a frame 'b'); robots: {', '.join(self.robots)}")
        return name

    def cart_to_world(self, points_b: Any, cart: str | None = None) -> np.ndarray:
        """Return world positions (N, 3) of points given in the cart frame {b} (2-D points lie at the handle height).

        `cart`: the robot whose {b} they are in (default: the scene's `cart`).
        """
        name = self._cart_name(cart)
        q = self._q[self._robot(name).name]
        z_b, z_handle = self.cart_heights(name)
        p = _points3(points_b, z_handle)
        c, s = q[2], q[3]
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return p @ rot.T + np.array([q[0], q[1], z_b])

    # -- overlays --------------------------------------------------------------------
    def show_contact(
        self, name: str, points: Any, frame: str = "world", radius: float = 0.025, color: int = COLORS["contact"]
    ) -> np.ndarray:
        """Draw contact points as spheres under `/meshcat/contacts/<name>`; return their world positions.

        `frame` is ``"world"`` (2-D points lie on the floor) or ``"b"`` (cart
        frame; 2-D points lie at the handle height, like LOG_FORMAT's contact_x/y).
        """
        world = self._to_world(points, frame)
        if color == COLORS["contact"]:
            self.add_legend("contact", color, *LEGEND_TEXT["contact"])
        node = self.viewer["contacts"][name]
        node.delete()
        for i, p in enumerate(world):
            node[str(i)].set_object(mg.Sphere(radius), mg.MeshLambertMaterial(color=color))
            node[str(i)].set_transform(tf.translation_matrix(p))
        return world

    def _to_world(self, points: Any, frame: str) -> np.ndarray:
        if frame == "world":
            return _points3(points, 0.0)
        if frame == "b":
            return self.cart_to_world(points)
        raise SceneError(f"frame must be 'world' or 'b', got {frame!r}")

    def _arrow_node(self, name: str, kind: str, radius: float, head: float) -> Any:
        if kind not in ARROW_KINDS:
            raise SceneError(f"wrench kind must be one of {', '.join(map(repr, ARROW_KINDS))}, got {kind!r}")
        node = self.viewer["wrenches"][kind][name]
        shaft_rot = tf.rotation_matrix(-math.pi / 2, [0, 0, 1])  # meshcat cylinders lie along y
        node["shaft"]["geom"].set_object(_OnTopMesh(mg.Cylinder(1.0, radius), COLORS[kind]))
        node["shaft"]["geom"].set_transform(shaft_rot)
        node["head"]["geom"].set_object(
            _OnTopMesh(mg.Cylinder(head, radiusTop=0.0, radiusBottom=2.2 * radius), COLORS[kind])
        )
        node["head"]["geom"].set_transform(shaft_rot)
        return node

    def show_wrench(
        self,
        name: str,
        origin: Any,
        force: Any,
        kind: str = "applied",
        torque: float | None = None,
        frame: str = "world",
        scale: float = FORCE_SCALE,
    ) -> float:
        """Draw a force arrow (length `scale` * |force| m) at `origin`; return the arrow length.

        `kind` ``"applied"`` (blue) or ``"desired"`` (green). `force` is (fx, fy)
        or (fx, fy, fz) in world axes. A vertical torque `torque` (N m) is drawn
        as a thinner vertical arrow (right-hand rule) at the same origin.
        `frame` says where `origin` is given (``"world"`` or cart ``"b"``).
        Arrows are drawn over the robots and the cart (never hidden by them);
        the page's legend states the scale.
        """
        o = self._to_world(origin, frame)[0]
        f = np.asarray(force, dtype=float).ravel()
        if f.shape not in ((2,), (3,)) or not np.all(np.isfinite(f)):
            raise SceneError(f"force must be 2 or 3 finite numbers, got {force!r}")
        f = np.append(f, 0.0) if f.size == 2 else f
        node = self._arrow_node(name, kind, ARROW_RADIUS, ARROW_HEAD)
        _set_arrow(node, _arrow_parts(o, scale * f, ARROW_HEAD))
        self._legend_arrow(kind, scale, torque is not None)
        if torque is not None:
            tnode = self._arrow_node(f"{name}_torque", kind, ARROW_RADIUS / 2, 0.04)
            _set_arrow(tnode, _arrow_parts(o, np.array([0.0, 0.0, scale * float(torque)]), 0.04))
        return float(scale * np.linalg.norm(f))

    def show_allocation(
        self,
        points_b: Any,
        wrenches_ee: Any,
        name: str = "arm",
        scale: float = FORCE_SCALE,
        cart: str | None = None,
    ) -> np.ndarray:
        """Draw planned contact points (N, 2|3) in the cart frame {b} and each hand's wrench (N, 6) as arrows.

        The wrenches are the allocation's end-effector wrenches ``[f; tau]`` in
        the contact frames {a} (orientation of {b}, `wholebody.contacts.handle`):
        force arrows (blue, `scale` m per N) at the points, the vertical torque
        as a thinner arrow. Return the points' world positions (N, 3).
        """
        pts = np.atleast_2d(np.asarray(points_b, dtype=float))
        w = np.atleast_2d(np.asarray(wrenches_ee, dtype=float))
        if w.shape != (len(pts), 6) or not np.all(np.isfinite(w)):
            raise SceneError(f"wrenches_ee must be finite, shape ({len(pts)}, 6), got {w.shape}")
        q = self._q[self._robot(self._cart_name(cart)).name]
        rot = np.array([[q[2], -q[3], 0.0], [q[3], q[2], 0.0], [0.0, 0.0, 1.0]])
        world = self.show_contact(name, pts, frame="b")
        for i, (p, wi) in enumerate(zip(world, w)):
            self.show_wrench(f"{name}{i}", [p], rot @ wi[:3], torque=float(wi[5]), scale=scale)
        return world

    def show_com(self, true_b: Any, est_b: Any, radius: float = 0.04) -> np.ndarray:
        """Draw the cart's true and estimated CoM (dx, dy) in {b} as two spheres; return their world positions (2, 3).

        The true CoM is a larger see-through blue sphere (1.6 `radius`), the
        estimate a smaller solid magenta one inside it: both stay visible when
        the estimate has converged. The legend says which is which.
        """
        pts = np.vstack((_points3(true_b, 0.0), _points3(est_b, 0.0)))[:, :2]
        world = self.cart_to_world(np.column_stack((pts, np.full(2, COM_MARKER_Z - self.cart_heights()[0]))))
        materials = {
            "com_true": (1.6 * radius, mg.MeshLambertMaterial(color=COLORS["com_true"], opacity=0.4, depthWrite=False)),
            "com_est": (0.8 * radius, mg.MeshLambertMaterial(color=COLORS["com_est"])),
        }
        for key, p in zip(("com_true", "com_est"), world):
            r, material = materials[key]
            self.viewer["com"][key].set_object(mg.Sphere(r), material)
            self.viewer["com"][key].set_transform(tf.translation_matrix(p))
            self.add_legend(key, COLORS[key], *LEGEND_TEXT[key])
        return world

    def show_trace(
        self, name: str, points: Any, color: int = COLORS["trace"], z: float = 0.005, label: str | None = None
    ) -> np.ndarray:
        """Draw a polyline through `points` ((N, 2) on the floor at height `z`, or (N, 3)); return them as (N, 3).

        `label` is its legend line (default: ``"line: path <name>"``).
        """
        p = _points3(points, z)
        if len(p) < 2:
            raise SceneError("a trace needs at least 2 points")
        self.add_legend(f"trace_{name}", color, "line", label or f"line: path {name}")
        geom = mg.PointsGeometry(p.T.astype(np.float32))
        self.viewer["traces"][name].set_object(mg.Line(geom, mg.LineBasicMaterial(color=color, linewidth=3)))
        return p

    def set_floor(self, floor: tuple[float, float, float, float], step: float = 0.5) -> int:
        """Draw a floor grid over (xmin, xmax, ymin, ymax) at `step` spacing, hiding Meshcat's grid; return #segments."""
        x0, x1, y0, y1 = (float(v) for v in floor)
        if not (x1 > x0 and y1 > y0 and all(math.isfinite(v) for v in (x0, x1, y0, y1))):
            raise SceneError(f"floor must be (xmin, xmax, ymin, ymax) with xmin < xmax, ymin < ymax, got {floor!r}")
        step = _grid_step(max(x1 - x0, y1 - y0), float(step))
        x0, y0 = math.floor(x0 / step) * step, math.floor(y0 / step) * step
        xs, ys = np.arange(x0, x1 + 1e-9, step), np.arange(y0, y1 + 1e-9, step)
        segs = [((a, y), (b, y)) for y in ys for a, b in zip(xs[:-1], xs[1:])]
        segs += [((x, a), (x, b)) for x in xs for a, b in zip(ys[:-1], ys[1:])]
        pts = np.array([p for seg in segs for p in seg])
        pts = np.column_stack((pts, np.zeros(len(pts)))).T.astype(np.float32)
        self.viewer["/Grid"].set_property("visible", False)
        self.viewer["/Axes"].set_property("visible", False)  # its blue z axis at the origin read as a torque arrow
        self.viewer["floor"].set_object(mg.LineSegments(mg.PointsGeometry(pts), mg.LineBasicMaterial(color=0x9AA4B0)))
        return len(segs)

    def set_camera(self, camera: Camera) -> None:
        """Use `camera` for the static page (exact) and, approximately, for a live viewer.

        Meshcat 0.3 has no command for the orbit target, so the static page sets
        it with a script (`_camera_js`); a live viewer only gets the camera
        position and orbits around the world origin.
        """
        self._camera = camera
        if self.window.live is not None:
            d = np.asarray(camera.eye, float)  # the camera node is rotated +90 deg about x: (x, y, z) -> (x, z, -y)
            self.window.live.send(
                SetProperty("position", [d[0], d[2], -d[1]], PathOf("/Cameras/default/rotated/<object>"))
            )

    @property
    def camera(self) -> Camera:
        """The page's camera: the one set (`set_camera`, `frame_robots`), else one framing the robots as displayed."""
        if self._camera is not None:
            return self._camera
        return self._framing(list(self.robots), margin=0.3) if self.robots else Camera()

    def _framing(self, names: Sequence[str], margin: float) -> Camera:
        """Return a camera seeing every frame of the robots `names` as displayed, `margin` m around them."""
        pts: list[np.ndarray] = []
        for name in names:
            robot = self._robot(name)
            pin.framesForwardKinematics(robot.model, robot.data, self._q[name])
            pts.extend(f.translation for f in robot.data.oMf)
        p = np.array(pts)
        return Camera.framing(np.vstack((p, p.min(axis=0) - margin, p.max(axis=0) + margin)))

    # -- legend ----------------------------------------------------------------------
    def add_legend(self, key: str, color: int, shape: str, text: str) -> None:
        """Add (or replace) the legend line `key` of the page: a `shape` swatch in `color` and `text`."""
        self._legend[key] = LegendEntry(int(color), shape, text)

    def legend_entry(self, key: str) -> LegendEntry:
        """Return the legend line `key` (e.g. ``"arrow_applied"``); SceneError when the page has none."""
        if key not in self._legend:
            raise SceneError(f"no legend line {key!r}; the page has {', '.join(self._legend) or 'none'}")
        return self._legend[key]

    def legend(self) -> list[LegendEntry]:
        """Return the page's legend lines, in the order they were first added."""
        return list(self._legend.values())

    def add_readout(self, label: str, unit: str, t: Any, values: Any, digits: int = 1) -> None:
        """Show ``label: value unit`` live on the animated page (the latest of samples (t, values) at the page's time)."""
        t, v = np.asarray(t, dtype=float).ravel(), np.asarray(values, dtype=float).ravel()
        if t.shape != v.shape or len(t) < 1 or not np.all(np.isfinite(t)):
            raise SceneError(f"readout {label!r}: t and values must have the same length, got {t.shape}, {v.shape}")
        self._readouts.append(Readout(label, unit, t, v, digits))

    def add_chart(
        self,
        title: str,
        unit: str,
        t: Any,
        estimate: Any,
        std: Any = None,
        truth: Any = None,
        marks: Sequence[tuple[float, str]] = (),
        settle: float = 0.0,
        until: float = math.inf,
    ) -> Chart:
        """Plot an estimate over time on the animated page (bottom right), with its band (+-`std`) against the
        `truth` (a number or samples), time marks ((t, kind), kinds of `wholebody.viz.page.MARKS`) and a cursor at
        the page's time; the y range covers the truth and the estimate from `settle` s after the start to `until`.
        Return the chart."""
        t = np.asarray(t, dtype=float).ravel()
        est = np.asarray(estimate, dtype=float).ravel()
        if len(t) < 2 or est.shape != t.shape or not np.all(np.isfinite(t)):
            raise SceneError(f"chart {title!r}: t must be finite, at least 2 samples, as many as the estimate")
        band = None if std is None else np.broadcast_to(np.asarray(std, dtype=float), t.shape).copy()
        true = None if truth is None else np.broadcast_to(np.asarray(truth, dtype=float), t.shape).copy()
        bad = [kind for _, kind in marks if kind not in MARKS]
        if bad:
            raise SceneError(f"chart {title!r}: unknown mark kinds {bad}; kinds: {', '.join(MARKS)}")
        chart = Chart(title, unit, t, est, band, true, tuple((float(a), k) for a, k in marks), settle, until)
        self._charts.append(chart)
        return chart

    def add_event_readout(
        self,
        label: str,
        unit: str,
        t: Any,
        event_times: Sequence[float],
        event_values: Sequence[float],
        digits: int = 1,
    ) -> None:
        """Show ``label: value unit`` live: the value of the latest event at the page's time ("-" before the first).

        E.g. the load changes an estimator detected (detection times, new masses) on the time samples ``t``.
        """
        t = np.asarray(t, dtype=float).ravel()
        times, vals = np.asarray(event_times, dtype=float).ravel(), np.asarray(event_values, dtype=float).ravel()
        if times.shape != vals.shape:
            raise SceneError(f"event readout {label!r}: {len(times)} times for {len(vals)} values")
        order = np.argsort(times, kind="stable")
        idx = np.searchsorted(times[order], t, side="right") - 1
        values = np.where(idx >= 0, vals[order][np.maximum(idx, 0)] if len(vals) else np.nan, np.nan)
        self.add_readout(label, unit, t, values, digits)

    def _legend_arrow(self, kind: str, scale: float, torque: bool = False, clipped: bool = False) -> None:
        shape, text = LEGEND_TEXT[kind]
        clip = f"; at most {ARROW_MAX:g} m" if clipped else ""
        self.add_legend(f"arrow_{kind}", COLORS[kind], shape, f"{text}, {_per_unit(scale, 'N')}{clip}")
        if torque:
            shape, text = LEGEND_TEXT["torque"]
            self.add_legend(f"torque_{kind}", COLORS[kind], shape, f"{text}, {_per_unit(scale, 'N m')}")

    # -- animation -------------------------------------------------------------------
    def animate(
        self,
        t: npt.ArrayLike,
        poses: Mapping[str, Any],
        q_joints: Mapping[str, Any] | None = None,
        wrenches: Mapping[str, tuple[Any, Any]] | None = None,
        kind: str | Mapping[str, str] = "applied",
        markers: Mapping[str, Any] | None = None,
        scale: float | None = None,
        fps: int = 30,
        play: bool = True,
        repetitions: int = 10**6,
        follow: Sequence[str] = (),
    ) -> int:
        """Animate robots, force arrows and markers over times `t`; return the number of animation frames.

        The scene's static state is the first frame. The page plays when opened
        and loops (``play=False``: it opens paused, ``#play`` starts it); its
        overlay has a pause button and the legend. `repetitions` is for a live
        viewer (``serve=True``). `follow`: robot names whose mean root position
        the page's camera follows (see `camera_at`). `scale` (m per N) of the
        force arrows: by default the largest of 0.1, 0.05, 0.03, 0.02, 0.01
        that draws the median force at most 30 cm long; animated arrows are at
        most `ARROW_MAX` m long (the legend says when some were clipped).

        poses: robot name -> (N, 3) planar poses. q_joints: robot name -> (N, nq-4).
        wrenches: arrow name -> ((N, 3) world origins, (N, 2|3) forces); `kind`: their colour and legend
        (`LEGEND_TEXT`), one for all or arrow name -> kind (``"applied"`` for the others).
        markers: node path under /meshcat (e.g. ``"com/com_est"``, made by
        `show_com` / `show_contact`) -> (N, 3) world positions. Samples are
        resampled at `fps` (latest sample at or before each frame time) so
        playback runs in real time; beyond MAX_FRAMES frames only every k-th
        frame gets keys (three.js interpolates between them), so the page stays small.
        """
        times = np.asarray(t, dtype=float).ravel()
        frame_numbers, idx = _frame_schedule(times, fps)
        keys = list(zip(frame_numbers.tolist(), idx))
        anim = Animation(default_framerate=fps)
        for name in follow:
            if name not in poses:
                raise SceneError(f"follow: robot {name!r} is not animated; animated: {', '.join(poses)}")
        for name, traj in poses.items():
            self._animate_robot(anim, keys, name, traj, (q_joints or {}).get(name), len(times))
        if scale is None:
            norms = [np.linalg.norm(np.asarray(f, dtype=float), axis=-1) for _, f in (wrenches or {}).values()]
            scale = nice_scale(np.concatenate(norms)) if norms else FORCE_SCALE
        for name, (origins, forces) in (wrenches or {}).items():
            k = kind if isinstance(kind, str) else kind.get(name, "applied")
            self._animate_arrow(anim, keys, name, origins, forces, k, scale, len(times))
        for path, pts in (markers or {}).items():
            self._animate_marker(anim, keys, path, pts, len(times))
        self.viewer.set_animation(anim, play=play, repetitions=repetitions)
        self.follow = tuple(follow)
        self._fps = fps
        self._autoplay = bool(play)
        self.arrow_scale = float(scale)
        return len(frame_numbers)

    def _animate_robot(
        self, anim: Animation, keys: list[tuple[int, int]], name: str, traj: Any, joints: Any, n: int
    ) -> None:
        """Add the root keys (and geometry keys when joints move) of robot `name`; show its first frame."""
        traj = np.asarray(traj, dtype=float)
        if traj.shape != (n, 3):
            raise SceneError(f"poses[{name!r}] must have shape ({n}, 3), got {traj.shape}")
        robot = self._robot(name)
        if joints is not None:
            joints = np.asarray(joints, dtype=float)
            if joints.shape != (n, robot.model.nq - 4):
                raise SceneError(f"q_joints[{name!r}] must have shape ({n}, {robot.model.nq - 4})")
        moving = joints is not None and np.ptp(joints, axis=0).max() > 0
        root = self.viewer[name]
        for k, i in keys:
            _set_key(anim, root.path, k, planar_pose_matrix(*traj[i]))
            if moving:
                self._animate_geometry(anim, name, k, _planar_q(robot.model, (0.0, 0.0, 0.0), joints[i]))
        first = keys[0][1]
        self.set_robot_pose(name, traj[first], None if joints is None else joints[first])

    def _animate_arrow(
        self,
        anim: Animation,
        keys: list[tuple[int, int]],
        name: str,
        origins: Any,
        forces: Any,
        kind: str,
        scale: float,
        n: int,
    ) -> None:
        """Add the keys of force arrow `name` (world origins (n, 3), forces (n, 2|3)); show its first frame."""
        origins, forces = _points3(origins, 0.0), np.asarray(forces, dtype=float)
        if len(origins) != n or len(forces) != n:
            raise SceneError(f"wrenches[{name!r}] must have {n} origins and forces")
        forces = forces if forces.shape[1] == 3 else np.column_stack((forces, np.zeros(n)))
        node = self._arrow_node(name, kind, ARROW_RADIUS, ARROW_HEAD)
        vectors = scale * forces
        lengths = np.linalg.norm(vectors, axis=1)
        vectors *= np.minimum(1.0, ARROW_MAX / np.maximum(lengths, 1e-12))[:, None]
        for k, i in keys:
            for part, T, sc in _arrow_parts(origins[i], vectors[i], ARROW_HEAD):
                _set_key(anim, (node[part] if part else node).path, k, T, sc)
        first = keys[0][1]
        _set_arrow(node, _arrow_parts(origins[first], vectors[first], ARROW_HEAD))
        self._legend_arrow(kind, scale, clipped=bool(np.any(lengths > ARROW_MAX)))

    def _animate_marker(self, anim: Animation, keys: list[tuple[int, int]], path: str, pts: Any, n: int) -> None:
        """Add the position keys of the marker node `path` (world positions (n, 3)); show its first frame."""
        pts = _points3(pts, 0.0)
        if len(pts) != n:
            raise SceneError(f"markers[{path!r}] must have {n} positions")
        node = self.viewer[path]
        for k, i in keys:
            _set_key(anim, node.path, k, tf.translation_matrix(pts[i]))
        node.set_transform(tf.translation_matrix(pts[keys[0][1]]))

    def _animate_geometry(self, anim: Animation, name: str, frame: int, q: np.ndarray) -> None:
        """Add keys at `frame` placing every visual geometry of robot `name` at configuration `q`."""
        viz = self._viz[name]
        pin.forwardKinematics(viz.model, viz.data, q)
        pin.updateGeometryPlacements(viz.model, viz.data, viz.visual_model, viz.visual_data)
        for gid, geom in enumerate(viz.visual_model.geometryObjects):
            node = self.viewer[viz.getViewerNodeName(geom, pin.GeometryType.VISUAL)]
            _set_key(anim, node.path, frame, viz.visual_data.oMg[gid].homogeneous)

    def animate_cart_log(
        self, log: Any, cart: str = "shopping_cart", fps: int = 30, play: bool = True, follow: bool = True
    ) -> int:
        """Animate a cart log (`cart.logs.CartLog`: t, q, gamma, optional contact_b); return the number of frames.

        The cart follows `q`; the applied force (fx, fy) is an arrow at the
        contact point (`contact_b`, else the handle midpoint); the path is a
        trace; the page shows the force in N live and (`follow`) its camera
        follows the cart.
        """
        self._robot(cart)
        t, q, gamma = np.asarray(log.t, float), np.asarray(log.q, float), np.asarray(log.gamma, float)
        contact_b = getattr(log, "contact_b", None)
        if contact_b is None:
            contact_b = np.tile([CART_HANDLE_X, 0.0], (len(t), 1))
        contact_b = np.asarray(contact_b, dtype=float)
        origins = cart_to_world_traj(q, contact_b, CART_HANDLE_Z_B + CART_WHEEL_RADIUS)
        self.show_trace(f"{cart}_path", q[:, :2], label="cyan line: the cart's path in the log")
        self.show_contact(cart, origins[:1])
        self.add_readout("force on the cart |f|", "N", t, np.hypot(gamma[:, 0], gamma[:, 1]))
        return self.animate(
            t,
            {cart: q},
            wrenches={f"{cart}_force": (origins, gamma[:, :2])},
            markers={f"contacts/{cart}/0": origins},
            fps=fps,
            play=play,
            follow=(cart,) if follow else (),
        )

    def world_transform(self, path: str) -> np.ndarray:
        """Return the recorded world transform (4x4) of a node, e.g. ``"/meshcat/shopping_cart/visuals/handle_0"``."""
        parts = [p for p in path.split("/") if p]
        T = np.eye(4)
        for k in range(1, len(parts) + 1):
            T = T @ self.window.local_transform(parts[:k])
        return T

    def animation_keys(self) -> dict[str, dict[str, np.ndarray]]:
        """Return the recorded animation: node path -> track name (``"position"`` ...) -> (frames, k) values."""
        if self.window.animation is None:
            return {}
        out: dict[str, dict[str, np.ndarray]] = {}
        for item in umsgpack.unpackb(self.window.animation)["animations"]:
            tracks = out.setdefault(item["path"], {})
            for track in item["clip"]["tracks"]:
                tracks[track["name"].lstrip(".")] = np.array([key["value"] for key in track["keys"]], dtype=float)
        return out

    def animation_duration(self) -> float:
        """Return the animation's length in s (0 without animation)."""
        if self.window.animation is None:
            return 0.0
        clips = [item["clip"] for item in umsgpack.unpackb(self.window.animation)["animations"]]
        return max(
            (float(k["time"]) / clip["fps"] for clip in clips for tr in clip["tracks"] for k in tr["keys"]), default=0.0
        )

    def camera_at(self, time: float) -> Camera:
        """Return the page's camera at animation time `time` (s): `self.camera` moved with the followed robots.

        Without `follow` (see `animate`) the camera does not move. The page keeps
        the camera's offset to the mean root position of the followed robots;
        three.js interpolates keys linearly, as done here.
        """
        if not self.follow:
            return self.camera
        keys = self.animation_keys()
        anims = {item["path"]: item["clip"] for item in umsgpack.unpackb(self.window.animation)["animations"]}
        shift = np.zeros(3)
        for name in self.follow:
            path = self.viewer[name].path.lower()
            clip = anims[path]
            frames = (
                np.array(
                    [k["time"] for tr in clip["tracks"] if tr["name"].lstrip(".") == "position" for k in tr["keys"]],
                    dtype=float,
                )
                / clip["fps"]
            )
            pos = keys[path]["position"]
            at = np.array([np.interp(time, frames, pos[:, j]) for j in range(3)])
            shift += (at - pos[0]) / len(self.follow)
        eye, target = np.asarray(self.camera.eye) + shift, np.asarray(self.camera.target) + shift
        return Camera(target=tuple(target), eye=tuple(eye), fov_deg=self.camera.fov_deg)

    def frame_robots(self, names: Sequence[str] | None = None, margin: float = 0.3) -> Camera:
        """Point the camera at the robots `names` (default: all) as displayed now; return the camera."""
        camera = self._framing(list(names or self.robots), margin)
        self.set_camera(camera)
        return camera

    # -- output ----------------------------------------------------------------------
    def static_html(self, controls: bool = True) -> str:
        """Return the scene as a self-contained HTML page (works offline; `controls=False` hides the GUI panel).

        An animated page plays when opened and loops (unless `animate` got
        ``play=False``); its overlay has a pause button (or the space bar),
        the time, the read-outs and the legend. ``#t=<seconds>`` in its URL
        opens it paused at that time, ``#pause`` paused at the start,
        ``#t=<s>&play`` plays from there; its camera follows the robots named
        by `animate`'s `follow`. A static page shows the legend only.
        """
        follow = [self.viewer[name].path.lower() for name in self.follow]
        return static_html(
            self.window.commands(),
            controls=controls,
            camera=self.camera,
            follow=follow,
            animated=self.window.animation is not None,
            legend=self.legend(),
            autoplay=self._autoplay,
            readouts=self._readouts,
            charts=self._charts,
        )

    def iframe(self, height: int = 420, controls: bool = True) -> str:
        """Return the static page in an ``<iframe>`` (stored gzipped, inflated by the browser), for a notebook's output.

        Use ``IPython.display.HTML(scene.iframe())``; about a third of the
        page's size (the viewer's JavaScript, 0.9 MB, becomes ~0.3 MB).
        """
        return compressed_iframe(self.static_html(controls=controls), height)

    def _repr_html_(self) -> str:
        """Show the scene inline in Jupyter (the static page in an iframe)."""
        return self.iframe()

    def save_html(self, path: str | Path, controls: bool = True) -> Path:
        """Write the static page to `path`; return the path."""
        path = Path(path)
        path.write_text(self.static_html(controls=controls), encoding="utf-8")
        return path


def add_estimator_events(
    scene: Scene, report: Mapping[str, Any] | None, t: Any, masses: Sequence[float] | None = None
) -> None:
    """Add read-outs of what an online estimator reported (`cart.online_estimator.OnlineLSEstimator.report`).

    The detected load changes (``load detected at t: new mass``, from each change's detection time) and the
    run-off episodes flagged so far (a count, from each flag's time); nothing for an estimator that reports none.
    ``masses``: the mass to show per change (a run's estimate at each detection, known then); None: the report's
    ``mass_after`` (for the last change the estimator's estimate at the report's time, which a page would show
    before it was known).
    """
    report = report or {}
    changes = list(report.get("load_changes") or [])
    flags = list(report.get("runoff_flags") or [])
    if changes:
        times = [c["t_detected"] for c in changes]
        label, values = ("load change detected (new mass)", [c["mass_after"] for c in changes])
        if masses is not None:
            label, values = "load change detected (mass at detection)", list(masses)
        scene.add_event_readout(label, "kg", t, times, values)
        scene.add_event_readout("  ... its onset", "s", t, times, [c["t_change"] for c in changes], digits=2)
    if flags:
        kinds = sorted({f["kind"] for f in flags})
        scene.add_event_readout(
            f"run-off flags so far ({', '.join(kinds)})",
            "",
            t,
            [f["t"] for f in flags],
            [float(k) for k in range(1, len(flags) + 1)],
            0,
        )


def frame_points(points: np.ndarray, scene: Scene) -> None:
    """Frame `points` (N, 3) with the camera and cover them with the floor grid."""
    scene.set_camera(Camera.framing(points))
    cover_floor(points, scene)


def cover_floor(points: np.ndarray, scene: Scene, border: float = 2.0) -> None:
    """Draw the floor grid under `points` (N, 2|3) with `border` m around them."""
    lo, hi = np.min(points, axis=0), np.max(points, axis=0)
    scene.set_floor(
        (math.floor(lo[0]) - border, math.ceil(hi[0]) + border, math.floor(lo[1]) - border, math.ceil(hi[1]) + border)
    )


def robot_scene(name: str, serve: bool = False) -> Scene:
    """Return a scene of one robot at the origin (its profile's push posture when it has one, else neutral joints)."""
    from robots.profiles import profile

    scene = Scene([name], serve=serve)
    prof = profile(name)
    if prof.push_arm_seed is not None and prof.arm_joints:  # its pushing posture, arm held up, not folded flat
        scene.set_robot_pose(name, (0.0, 0.0, 0.0), dict(zip(prof.arm_joints, prof.push_arm_seed)))
    robot = scene.robots[name]
    pin.framesForwardKinematics(robot.model, robot.data, scene.robot_q(name))
    pts = np.array([f.translation for f in robot.data.oMf])
    scene.set_camera(Camera.framing(np.vstack((pts, pts.min(axis=0) - 0.4, pts.max(axis=0) + 0.4))))
    return scene


def log_scene(log: Any, serve: bool = False, fps: int = 30) -> Scene:
    """Return a scene animating a cart log (`cart.logs.CartLog`, or a path read with `cart.logs.read_log`)."""
    from cart.logs import read_log

    if isinstance(log, (str, Path)):
        if not Path(log).is_file():
            raise SceneError(f"log file {str(log)!r} not found")
        log = read_log(log)
    scene = Scene(["shopping_cart"], serve=serve)
    scene.animate_cart_log(log, fps=fps)  # the camera follows the cart
    cover_floor(np.asarray(log.q, float)[:, :2], scene)
    scene.frame_robots(margin=0.8)  # the cart at its first sample, large on screen
    return scene


def cart_to_world_traj(q: np.ndarray, points_b: np.ndarray, z: float) -> np.ndarray:
    """Return world points (N, 3) of per-sample points (N, 2) in {b} of the cart poses q (N, 3), at height z."""
    c, s = np.cos(q[:, 2]), np.sin(q[:, 2])
    return np.column_stack(
        (
            q[:, 0] + c * points_b[:, 0] - s * points_b[:, 1],
            q[:, 1] + s * points_b[:, 0] + c * points_b[:, 1],
            np.full(len(q), z),
        )
    )

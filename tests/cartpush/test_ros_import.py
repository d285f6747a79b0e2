"""Issue 15: ROS 1 bags, ROS 2 bags (sqlite3, MCAP) and .mcap files as cart logs (cartpush.ros, `cartpush import`).

The bags are written with rosbags' own writers from a simulated push with known truth
(studies.testbeds.rigid_sim). The F/T sensor sits on a moving arm link four TF links from the
world frame (world -> odom -> base_link -> arm_link, dynamic, then arm_link -> ft_sensor, static);
the wrench is written in the sensor frame and the pose by motion capture with a small tilt. The
expected sensor-frame values are computed here independently (scipy rotations, matrix products),
so the import must undo them back to the simulator's log within float precision.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from cart.logs import CartLog, read_log, write_log
from studies.testbeds import rigid_sim
from cartpush.ros import (
    BagImportError,
    TransformBuffer,
    TransformLookupError,
    import_bag,
    list_bag,
    load_any,
)

NS = 1_000_000_000
T0_NS = 1_700_000_000 * NS  # a wall-clock epoch, as real recordings have
LATENCY_NS = 2_000_000  # the recorder receives each message 2 ms after its header stamp
CUSTOM_MSG = "std_msgs/Header header\nstring body\ngeometry_msgs/Pose pose\ncart_msgs/Quality quality\n"
QUALITY_MSG = "float64 residual\nuint8 markers\n"


# -- the scenario: truth and what the sensors report ------------------------------------------------
def _rz(a):
    a = np.asarray(a, dtype=float)
    return Rotation.from_euler("z", a[:, None] if a.ndim else a).as_matrix()


def _links(t):
    """Return {(parent, child): (R, p)} of the dynamic links at times t (s) and the static sensor mount."""
    n = len(t)
    one = np.ones(n)
    R_wo = _rz(0.05 * np.sin(0.3 * t))
    p_wo = np.column_stack([0.3 + 0.01 * t, -0.2 * one, 0 * one])
    R_ob = _rz(0.2 * t - 1.0)
    p_ob = np.column_stack([1.0 + 0.1 * np.sin(t), 0.5 * np.cos(0.7 * t), 0 * one])
    R_ba = Rotation.from_euler("ZYX", np.column_stack([0.5 * np.sin(t), 0.3 + 0.1 * np.cos(t), 0.2 * one])).as_matrix()
    p_ba = np.column_stack([0.4 * one, 0.1 * one, 0.8 + 0.05 * np.sin(2 * t)])
    R_as = Rotation.from_euler("XZ", [np.pi, 0.3]).as_matrix()
    p_as = np.array([0.0, 0.02, 0.12])
    return {
        ("world", "odom"): (R_wo, p_wo),
        ("odom", "base_link"): (R_ob, p_ob),
        ("base_link", "arm_link"): (R_ba, p_ba),
        ("arm_link", "ft_sensor"): (R_as, p_as),
    }


def _sensor_in_world(t):
    """Return R_ws (n, 3, 3), p_ws (n, 3): the sensor frame in the world, composed link by link."""
    L = _links(t)
    R = np.broadcast_to(np.eye(3), (len(t), 3, 3)).copy()
    p = np.zeros((len(t), 3))
    for key in (("world", "odom"), ("odom", "base_link"), ("base_link", "arm_link"), ("arm_link", "ft_sensor")):
        Rl, pl = L[key]
        Rl = np.broadcast_to(Rl, (len(t), 3, 3))
        p = p + np.einsum("nij,nj->ni", R, np.broadcast_to(pl, (len(t), 3)))
        R = np.einsum("nij,njk->nik", R, Rl)
    return R, p


def _cart_orientation(t, theta):
    """Return R_wc: yaw theta with a tilt of up to ~2 degrees (ZYX Euler: yaw stays theta exactly)."""
    tilt_y = np.radians(1.5) * np.sin(0.9 * t)
    tilt_x = np.radians(1.0) * np.cos(0.4 * t)
    return Rotation.from_euler("ZYX", np.column_stack([theta, tilt_y, tilt_x])).as_matrix()


def _scenario(log: CartLog, rng_seed: int = 0):
    """Return the sensor streams of the push in ``log``: pose at the log's stamps, wrench and TF at twice the rate."""
    rng = np.random.default_rng(rng_seed)
    t = log.t
    x, y, theta = log.q.T
    z = 0.35 + 0.0 * t
    R_wc = _cart_orientation(t, theta)
    p_b = np.column_stack([x, y, z])
    # world wrench on the cart at the pose stamps: (fx, fy, fz), torque about the {b} origin (mx, my, tau)
    f = np.column_stack([log.gamma[:, 0], log.gamma[:, 1], 5.0 * np.sin(1.3 * t)])
    m_b = np.column_stack([2.0 * np.cos(0.7 * t), -1.5 * np.sin(0.5 * t), log.gamma[:, 2]])
    m_o = m_b + np.cross(p_b, f)  # about the world origin
    # the wrench stream: the pose stamps and the midpoints (arbitrary values there: interpolation must not use them
    # at the pose stamps)
    t_mid = 0.5 * (t[1:] + t[:-1])
    tw = np.sort(np.concatenate([t, t_mid]))
    is_pose = np.isin(tw, t)
    f_all = np.empty((len(tw), 3))
    m_all = np.empty((len(tw), 3))
    f_all[is_pose], m_all[is_pose] = f, m_o
    f_all[~is_pose] = 0.5 * (f[1:] + f[:-1]) + rng.normal(0, 3.0, (len(t_mid), 3))
    m_all[~is_pose] = 0.5 * (m_o[1:] + m_o[:-1]) + rng.normal(0, 1.0, (len(t_mid), 3))
    R_ws, p_ws = _sensor_in_world(tw)
    m_s_world = m_all - np.cross(p_ws, f_all)  # about the sensor origin
    f_sensor = np.einsum("nji,nj->ni", R_ws, f_all)  # R^T f
    m_sensor = np.einsum("nji,nj->ni", R_ws, m_s_world)
    return {"t": t, "R_wc": R_wc, "p_c": p_b, "tw": tw, "f_sensor": f_sensor, "m_sensor": m_sensor, "links": _links(tw)}


def _ns(t):
    return T0_NS + np.round(np.asarray(t) * 1e9).astype(np.int64)


def _quat(R):
    return Rotation.from_matrix(R).as_quat()  # x, y, z, w


# -- writing bags with rosbags' writers -------------------------------------------------------------
class _Msgs:
    """Message constructors for one typestore (ROS 1 headers carry `seq`)."""

    def __init__(self, store):
        self.s = store
        self.T = store.types
        self.ros1 = "seq" in self.T["std_msgs/msg/Header"].__dataclass_fields__

    def header(self, ns, frame):
        H, Time = self.T["std_msgs/msg/Header"], self.T["builtin_interfaces/msg/Time"]
        kw = {"stamp": Time(sec=int(ns) // NS, nanosec=int(ns) % NS), "frame_id": frame}
        if self.ros1:
            kw["seq"] = 0
        return H(**kw)

    def vec(self, v, name="geometry_msgs/msg/Vector3"):
        return self.T[name](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def quat(self, q):
        return self.T["geometry_msgs/msg/Quaternion"](x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))

    def pose(self, p, q):
        return self.T["geometry_msgs/msg/Pose"](
            position=self.vec(p, "geometry_msgs/msg/Point"), orientation=self.quat(q)
        )

    def transform_stamped(self, ns, parent, child, p, q):
        tr = self.T["geometry_msgs/msg/Transform"](translation=self.vec(p), rotation=self.quat(q))
        return self.T["geometry_msgs/msg/TransformStamped"](
            header=self.header(ns, parent), child_frame_id=child, transform=tr
        )

    def tf(self, transforms):
        return self.T["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def pose_stamped(self, ns, frame, p, q):
        return self.T["geometry_msgs/msg/PoseStamped"](header=self.header(ns, frame), pose=self.pose(p, q))

    def odometry(self, ns, frame, child, p, q, v, w):
        T = self.T
        cov = np.zeros(36)
        pwc = T["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(p, q), covariance=cov)
        twist = T["geometry_msgs/msg/Twist"](linear=self.vec(v), angular=self.vec(w))
        twc = T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov)
        return T["nav_msgs/msg/Odometry"](header=self.header(ns, frame), child_frame_id=child, pose=pwc, twist=twc)

    def wrench(self, ns, frame, f, m):
        W = self.T["geometry_msgs/msg/Wrench"](force=self.vec(f), torque=self.vec(m))
        return self.T["geometry_msgs/msg/WrenchStamped"](header=self.header(ns, frame), wrench=W)

    def custom(self, ns, frame, p, q, residual):
        Q = self.T["cart_msgs/msg/Quality"](residual=float(residual), markers=5)
        return self.T["cart_msgs/msg/MocapBody"](
            header=self.header(ns, frame), body="cart", pose=self.pose(p, q), quality=Q
        )


def _store(fmt, custom=False):
    store = get_typestore(Stores.ROS1_NOETIC if fmt == "ros1" else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in store.types:  # rosbags' ROS 1 store lacks tf2_msgs (bags carry it)
        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    if custom:
        types = get_types_from_msg(QUALITY_MSG, "cart_msgs/msg/Quality")
        types.update(get_types_from_msg(CUSTOM_MSG, "cart_msgs/msg/MocapBody"))
        store.register(types)
    return store


def _write_bag(path, fmt, messages, store):
    """Write (topic, msgtype, record ns, message) tuples, sorted by record time, as a ROS 1 / sqlite3 / MCAP bag."""
    messages = sorted(messages, key=lambda m: m[2])
    if fmt == "ros1":
        writer = Writer1(path)
    else:
        writer = Writer2(
            path, version=9, storage_plugin=StoragePlugin.SQLITE3 if fmt == "sqlite3" else StoragePlugin.MCAP
        )
    conns = {}
    with writer:
        for topic, msgtype, record_ns, msg in messages:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
            data = store.serialize_ros1(msg, msgtype) if fmt == "ros1" else store.serialize_cdr(msg, msgtype)
            writer.write(conns[topic], int(record_ns), data)
    return path


def _tf_messages(M, sc, slash, drop_link=None, topic_link=None):
    """Return the /tf (one message per wrench stamp, three dynamic links) and /tf_static messages.

    ``drop_link``: a link left out; ``topic_link``: a link published as a TransformStamped topic instead of /tf
    (as motion capture does for the robot's base).
    """
    fr = lambda name: ("/" if slash else "") + name  # noqa: E731
    links = sc["links"]
    tw_ns = _ns(sc["tw"])
    quats = {k: _quat(links[k][0]) for k in links if k != ("arm_link", "ft_sensor")}
    out = []
    for i, ns in enumerate(tw_ns):
        transforms = [
            M.transform_stamped(ns, fr(a), fr(b), links[(a, b)][1][i], quats[(a, b)][i])
            for (a, b) in quats
            if (a, b) not in (drop_link, topic_link)
        ]
        out.append(("/tf", "tf2_msgs/msg/TFMessage", ns + LATENCY_NS, M.tf(transforms)))
        if topic_link:
            a, b = topic_link
            out.append(
                (
                    "/mocap/robot",
                    "geometry_msgs/msg/TransformStamped",
                    ns + LATENCY_NS,
                    M.transform_stamped(ns, fr(a), fr(b), links[topic_link][1][i], quats[topic_link][i]),
                )
            )
    R_as, p_as = links[("arm_link", "ft_sensor")]
    static = M.transform_stamped(T0_NS, fr("arm_link"), fr("ft_sensor"), p_as, _quat(R_as))
    out.append(("/tf_static", "tf2_msgs/msg/TFMessage", T0_NS, M.tf([static])))
    return out


def _wrench_messages(M, sc, frame, sign=1.0):
    return [
        (
            "/ft_sensor/wrench",
            "geometry_msgs/msg/WrenchStamped",
            ns + LATENCY_NS,
            M.wrench(ns, frame, sign * sc["f_sensor"][i], sign * sc["m_sensor"][i]),
        )
        for i, ns in enumerate(_ns(sc["tw"]))
    ]


@pytest.fixture(scope="module")
def push():
    """Return the simulated push (a CartLog with velocities) and its truth."""
    log, truth = rigid_sim.simulate(rigid_sim.random_case(3, duration=12.0, rate_hz=100.0, vel_std=0.005))
    return log, truth


@pytest.fixture(scope="module")
def bags(push, tmp_path_factory):
    """Write the push as a ROS 1 bag, a ROS 2 sqlite3 bag and a ROS 2 MCAP bag (three pose sources)."""
    log, _ = push
    sc = _scenario(log)
    root = tmp_path_factory.mktemp("bags")
    pose_ns = _ns(sc["t"])
    q_wc = _quat(sc["R_wc"])
    out = {"scenario": sc}

    # ROS 1: mocap TransformStamped /world -> /cart, leading slashes everywhere, one duplicate and one
    # out-of-order pose message
    s1 = _store("ros1")
    M = _Msgs(s1)
    msgs = _tf_messages(M, sc, slash=True) + _wrench_messages(M, sc, "/ft_sensor")
    for i, ns in enumerate(pose_ns):
        msgs.append(
            (
                "/mocap/cart",
                "geometry_msgs/msg/TransformStamped",
                ns + LATENCY_NS,
                M.transform_stamped(ns, "/world", "/cart", sc["p_c"][i], q_wc[i]),
            )
        )
    k = len(pose_ns) // 2
    msgs.append(
        (
            "/mocap/cart",
            "geometry_msgs/msg/TransformStamped",
            pose_ns[k] + LATENCY_NS + 1000,
            M.transform_stamped(pose_ns[k], "/world", "/cart", sc["p_c"][k] + 1.0, q_wc[k]),
        )
    )  # duplicate
    msgs.append(
        (
            "/mocap/cart",
            "geometry_msgs/msg/TransformStamped",
            pose_ns[k + 5] + LATENCY_NS + 1000,
            M.transform_stamped(pose_ns[k - 3], "/world", "/cart", sc["p_c"][k] + 2.0, q_wc[k]),
        )
    )  # late
    out["ros1"] = _write_bag(root / "push.bag", "ros1", msgs, s1)

    # ROS 2 sqlite3: PoseStamped in a 'mocap' frame, static world -> mocap; the sensor reports the negated wrench
    s2 = _store("ros2")
    M = _Msgs(s2)
    R_wm, p_wm = _rz(0.4), np.array([2.0, -1.0, 0.1])
    R_mc = np.einsum("ij,njk->nik", R_wm.T, sc["R_wc"])
    p_mc = (sc["p_c"] - p_wm) @ R_wm  # R_wm^T (p - p_wm)
    msgs = _tf_messages(M, sc, slash=False) + _wrench_messages(M, sc, "ft_sensor", sign=-1.0)
    msgs.append(
        (
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            T0_NS,
            M.tf([M.transform_stamped(T0_NS, "world", "mocap", p_wm, _quat(R_wm))]),
        )
    )
    q_mc = _quat(R_mc)
    for i, ns in enumerate(pose_ns):
        msgs.append(
            (
                "/mocap/cart_pose",
                "geometry_msgs/msg/PoseStamped",
                ns + LATENCY_NS,
                M.pose_stamped(ns, "mocap", p_mc[i], q_mc[i]),
            )
        )
    out["sqlite3"] = _write_bag(root / "push_sqlite3", "sqlite3", msgs, s2)

    # ROS 2 MCAP: nav_msgs/Odometry world -> cart with the twist in the child frame; the robot's base
    # (world -> odom) from a motion-capture TransformStamped topic, not /tf
    msgs = _tf_messages(M, sc, slash=False, topic_link=("world", "odom")) + _wrench_messages(M, sc, "ft_sensor")
    for i, ns in enumerate(pose_ns):
        R = sc["R_wc"][i]
        v_c = R.T @ np.array([log.qd[i, 0], log.qd[i, 1], 0.0])
        w_c = R.T @ np.array([0.0, 0.0, log.qd[i, 2]])
        msgs.append(
            (
                "/odom",
                "nav_msgs/msg/Odometry",
                ns + LATENCY_NS,
                M.odometry(ns, "world", "cart", sc["p_c"][i], q_wc[i], v_c, w_c),
            )
        )
    out["mcap"] = _write_bag(root / "push_mcap", "mcap", msgs, s2)
    return out


def _assert_same_log(got: CartLog, want: CartLog, shift: float = 0.0):
    np.testing.assert_allclose(got.t, want.t + shift, rtol=0, atol=2e-9)
    np.testing.assert_allclose(got.q[:, :2], want.q[:, :2], rtol=0, atol=1e-9)
    dtheta = np.angle(np.exp(1j * (got.q[:, 2] - want.q[:, 2])))
    np.testing.assert_allclose(dtheta, 0.0, atol=1e-9)
    np.testing.assert_allclose(got.gamma, want.gamma, rtol=0, atol=1e-8)


# -- the imported log equals the simulator's ----------------------------------------------------------
def test_ros1_bag_with_slashes_duplicates_and_a_four_link_chain(push, bags):
    log, _ = push
    got, report = import_bag(bags["ros1"], pose_topic="/mocap/cart", wrench_topic="/ft_sensor/wrench")
    _assert_same_log(got, log)
    assert report.world_frame == "world" and report.cart_frame == "cart"
    assert report.tf_chains["ft_sensor"] == ["ft_sensor", "arm_link", "base_link", "odom", "world"]
    assert report.dropped["pose_duplicate_stamp"] == 1 and report.dropped["pose_out_of_order"] == 1
    assert any("repeating the previous stamp" in w for w in report.warnings) and any(
        "stamped earlier" in w for w in report.warnings
    )
    assert report.clock == "header" and report.t0_ns == T0_NS
    assert 1.0 < report.tilt_max_deg < 2.5 and not any("tilt" in w for w in report.warnings)
    assert got.qd is None
    # the same chain given with slashes, and a window in seconds from the start of the recording
    win, rep = import_bag(
        bags["ros1"],
        pose_topic="mocap/cart",
        wrench_topic="/ft_sensor/wrench",
        world_frame="/world",
        start=2.0,
        end=5.0,
    )
    sel = (log.t >= 2.0) & (log.t <= 5.0)
    _assert_same_log(win, CartLog(t=log.t[sel], q=log.q[sel], gamma=log.gamma[sel]))
    assert rep.window == (2.0, 5.0)


def test_ros2_sqlite3_pose_in_another_frame_negated_wrench_and_record_time(push, bags):
    log, _ = push
    got, report = import_bag(
        bags["sqlite3"],
        pose_topic="/mocap/cart_pose",
        wrench_topic="/ft_sensor/wrench",
        world_frame="world",
        negate_wrench=True,
    )
    _assert_same_log(got, log)
    assert report.storage == "ROS 2 bag (sqlite3)" and report.negate_wrench
    assert not any(report.dropped.values())
    # without --negate-wrench the force comes out reversed
    raw, _ = import_bag(
        bags["sqlite3"], pose_topic="/mocap/cart_pose", wrench_topic="/ft_sensor/wrench", world_frame="world"
    )
    np.testing.assert_allclose(raw.gamma, -log.gamma, atol=1e-8)
    # the recorder's clock: every stream (and TF) 2 ms later, the same values
    rec, rep = import_bag(
        bags["sqlite3"],
        pose_topic="/mocap/cart_pose",
        wrench_topic="/ft_sensor/wrench",
        world_frame="world",
        negate_wrench=True,
        use_record_time=True,
    )
    assert rep.clock == "record"
    _assert_same_log(rec, log, shift=LATENCY_NS / 1e9)


def test_ros2_mcap_odometry_gives_velocities_and_the_single_mcap_file_reads_the_same(push, bags):
    log, _ = push
    got, report = import_bag(bags["mcap"], pose_topic="/odom", wrench_topic="/ft_sensor/wrench")
    _assert_same_log(got, log)
    assert (
        report.storage == "ROS 2 bag (MCAP)" and report.has_velocities and report.pose_type == "nav_msgs/msg/Odometry"
    )
    np.testing.assert_allclose(got.qd, log.qd, atol=1e-9)
    assert report.tf_chains["ft_sensor"][-2:] == ["odom", "world"]
    assert any("world -> odom from /mocap/robot" in n for n in report.notes)
    mcap_file = next(bags["mcap"].glob("*.mcap"))
    single, rep = import_bag(mcap_file, pose_topic="/odom", wrench_topic="/ft_sensor/wrench")
    assert rep.storage == "MCAP file"
    np.testing.assert_array_equal(single.gamma, got.gamma)


def test_pose_from_a_tf_frame_and_a_cart_frame_attached_by_tf(push, bags, tmp_path):
    """--pose-frame: the pose of base_link (three links from world) read from TF equals the scenario's."""
    log, _ = push
    sc = bags["scenario"]
    got, report = import_bag(bags["ros1"], pose_frame="/base_link", wrench_topic="/ft_sensor/wrench")
    assert report.world_frame == "world" and report.pose_source == "TF frame base_link"
    L = _links(got.t)
    R = np.einsum("nij,njk->nik", L[("world", "odom")][0], L[("odom", "base_link")][0])
    p = L[("world", "odom")][1] + np.einsum("nij,nj->ni", L[("world", "odom")][0], L[("odom", "base_link")][1])
    np.testing.assert_allclose(got.q[:, :2], p[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (got.q[:, 2] - np.arctan2(R[:, 1, 0], R[:, 0, 0])))), 0, atol=1e-9)
    assert len(got) == len(sc["tw"])  # the stamps of the nearest dynamic link (odom -> base_link)
    # cart_frame: {b} 0.4 m ahead of the tracked 'cart' frame (a static TF link), the wrench about its origin
    s2 = _store("ros2")
    M = _Msgs(s2)
    t = log.t[:300]
    R_wc, p_c = sc["R_wc"][:300], sc["p_c"][:300]
    off = np.array([0.4, 0.0, 0.0])
    f = np.column_stack([log.gamma[:300, :2], 0 * t])
    msgs = [
        (
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            T0_NS,
            M.tf([M.transform_stamped(T0_NS, "cart", "axle", off, [0, 0, 0, 1])]),
        )
    ]
    for i, ns in enumerate(_ns(t)):
        msgs.append(
            (
                "/mocap",
                "geometry_msgs/msg/TransformStamped",
                ns,
                M.transform_stamped(ns, "world", "cart", p_c[i], _quat(R_wc[i])),
            )
        )
        # the wrench in the axle frame itself: TF reaches it through the pose (world -> cart) and the static link
        msgs.append(
            (
                "/w",
                "geometry_msgs/msg/WrenchStamped",
                ns,
                M.wrench(ns, "axle", R_wc[i].T @ f[i], R_wc[i].T @ [0, 0, 1.0]),
            )
        )
    bag = _write_bag(tmp_path / "offset_mcap", "mcap", msgs, s2)
    got, rep = import_bag(bag, pose_topic="/mocap", wrench_topic="/w", cart_frame="axle")
    p_b = p_c + np.einsum("nij,j->ni", R_wc, off)
    np.testing.assert_allclose(got.q[:, :2], p_b[:, :2], atol=1e-9)
    np.testing.assert_allclose(got.gamma, np.column_stack([f[:, :2], 1.0 + 0 * t]), atol=1e-9)
    assert rep.cart_frame == "axle" and rep.tf_chains["axle"] == ["axle", "cart", "world"]


@pytest.mark.parametrize("fmt", ["ros1", "mcap"])
def test_custom_message_definition_carried_in_the_bag(fmt, push, tmp_path):
    """A mocap message type known only from the bag (nested custom type) serves as the pose source."""
    log, _ = push
    assert "cart_msgs/msg/MocapBody" not in get_typestore(Stores.ROS1_NOETIC).types
    assert "cart_msgs/msg/MocapBody" not in get_typestore(Stores.ROS2_HUMBLE).types
    store = _store("ros1" if fmt == "ros1" else "ros2", custom=True)
    M = _Msgs(store)
    n = 200
    t, q = log.t[:n], log.q[:n]
    msgs = []
    for i, ns in enumerate(_ns(t)):
        quat = _quat(_rz(q[i, 2]))
        msgs.append(
            ("/mocap/body", "cart_msgs/msg/MocapBody", ns, M.custom(ns, "map", [q[i, 0], q[i, 1], 0.0], quat, 0.001))
        )
        msgs.append(
            (
                "/wrench",
                "geometry_msgs/msg/WrenchStamped",
                ns,
                M.wrench(
                    ns,
                    "map",
                    [log.gamma[i, 0], log.gamma[i, 1], 0.0],
                    [0.0, 0.0, log.gamma[i, 2] + q[i, 0] * log.gamma[i, 1] - q[i, 1] * log.gamma[i, 0]],
                ),
            )
        )
    path = tmp_path / ("custom.bag" if fmt == "ros1" else "custom_mcap")
    _write_bag(path, fmt, msgs, store)
    if fmt == "mcap":
        path = next(path.glob("*.mcap"))  # the single file carries the definitions too
    summary = list_bag(path)
    uses = {tp.name: (tp.msgtype, tp.use) for tp in summary.topics}
    assert uses["/mocap/body"][1] == "pose" and uses["/mocap/body"][0].endswith("MocapBody")
    got, report = import_bag(path, pose_topic="/mocap/body", wrench_topic="/wrench")
    assert report.world_frame == "map" and report.tf_chains == {"map": ["map"]}  # no TF needed
    _assert_same_log(got, CartLog(t=t, q=q, gamma=log.gamma[:n]))
    same = load_any(path, pose_topic="/mocap/body", wrench_topic="/wrench", pose_frame=None, negate_wrench=False)
    np.testing.assert_array_equal(same.gamma, got.gamma)


def test_tilt_warning_wrench_gap_and_stream_ends_are_reported(push, tmp_path):
    """A cart tilted 8 deg is warned about (its yaw still read exactly); pose samples in a wrench gap are dropped."""
    log, _ = push
    store = _store("ros2")
    M = _Msgs(store)
    n = 300
    t, q = log.t[:n], log.q[:n]
    R = Rotation.from_euler("ZYX", np.column_stack([q[:, 2], 0 * t, np.radians(8.0) + 0 * t])).as_matrix()
    msgs = [
        ("/pose", "geometry_msgs/msg/PoseStamped", ns, M.pose_stamped(ns, "world", [q[i, 0], q[i, 1], 0], _quat(R[i])))
        for i, ns in enumerate(_ns(t))
    ]
    gap = (t > 1.0) & (t < 1.5)
    tw = t[~gap][5:-5]  # the wrench starts later, ends earlier, and pauses for 0.5 s
    msgs += [
        ("/w", "geometry_msgs/msg/WrenchStamped", ns, M.wrench(ns, "world", [1.0, 0, 0], [0, 0, 0])) for ns in _ns(tw)
    ]
    got, report = import_bag(
        _write_bag(tmp_path / "tilted", "sqlite3", msgs, store), pose_topic="/pose", wrench_topic="/w"
    )
    assert report.tilt_max_deg == pytest.approx(8.0, abs=1e-6)
    assert any("tilts up to 8.0 deg" in w for w in report.warnings)
    np.testing.assert_allclose(np.angle(np.exp(1j * (got.q[:, 2] - q[np.isin(t, got.t), 2]))), 0, atol=1e-9)
    assert report.dropped["pose_in_wrench_gap"] == int(np.count_nonzero(gap))
    assert report.dropped["pose_outside_wrench"] == 10
    assert len(got) == n - 10 - int(np.count_nonzero(gap))
    assert any("inside a gap of the wrench stream" in w for w in report.warnings)
    # a publisher that does not stamp its messages: header stamps all zero -> use the record time
    msgs = [m for m in msgs if m[0] == "/pose"] + [
        ("/w", "geometry_msgs/msg/WrenchStamped", ns, M.wrench(0, "world", [1.0, 0, 0], [0, 0, 0])) for ns in _ns(t)
    ]
    bag = _write_bag(tmp_path / "unstamped", "sqlite3", msgs, store)
    with pytest.raises(BagImportError, match="header stamps are zero.*record time"):
        import_bag(bag, pose_topic="/pose", wrench_topic="/w")
    got, report = import_bag(bag, pose_topic="/pose", wrench_topic="/w", use_record_time=True)
    assert len(got) == n and report.clock == "record"
    # header stamps on a simulated clock (from 0 s), recorded on the wall clock: t = 0 at the first pose stamp
    sim = [(topic, typ, ns, msg) for topic, typ, ns, msg in msgs[:n]]
    for i, (_, _, ns, msg) in enumerate(sim):
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(ns - T0_NS + 5 * NS), NS)
    wrench = [
        ("/w", "geometry_msgs/msg/WrenchStamped", ns, M.wrench(ns - T0_NS + 5 * NS, "world", [1.0, 0, 0], [0, 0, 0]))
        for ns in _ns(t)
    ]
    got, report = import_bag(
        _write_bag(tmp_path / "simtime", "sqlite3", sim + wrench, store), pose_topic="/pose", wrench_topic="/w"
    )
    np.testing.assert_allclose(got.t, t - t[0], atol=2e-9)
    assert report.t0_ns == 5 * NS + int(round(t[0] * 1e9)) and any("another clock" in note for note in report.notes)


# -- the TF buffer on its own -----------------------------------------------------------------------
def test_tf_buffer_interpolates_along_the_chain_and_inverts():
    buf = TransformBuffer()
    ts = np.array([0.0, 1.0])
    buf.add_many("/world", "base", ts, [[0, 0, 0], [2, 0, 0]], Rotation.from_euler("z", [[0.0], [1.0]]).as_quat())
    buf.add_static("base", "/sensor", [0, 1, 0], [0, 0, 0, 1])
    R, p, ok = buf.lookup("world", "sensor", [0.25, 1.0, 1.5])
    assert ok.tolist() == [True, True, False]  # no extrapolation past the last sample
    np.testing.assert_allclose(R[0], _rz(0.25), atol=1e-12)  # slerp
    np.testing.assert_allclose(p[0], [0.5, 0, 0] + _rz(0.25) @ [0, 1, 0], atol=1e-12)
    Ri, pi, _ = buf.lookup("sensor", "world", [0.25])
    np.testing.assert_allclose(Ri[0] @ R[0], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(Ri[0] @ p[0] + pi[0], 0, atol=1e-12)
    buf.add_static("odom", "wheel", [0, 0, 0], [0, 0, 0, 1])
    with pytest.raises(TransformLookupError, match="'sensor'.*'wheel'") as exc:
        buf.lookup("wheel", "/sensor", [0.5])
    assert exc.value.source == "sensor" and exc.value.target == "wheel" and "rooted at 'world'" in str(exc.value)


# -- bad input: one line, exit 2 ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def small_bags(push, tmp_path_factory):
    """A short ROS 1 bag like the big one, and the same with the base_link -> arm_link link missing."""
    log, _ = push
    n = 120
    short = CartLog(t=log.t[:n], q=log.q[:n], gamma=log.gamma[:n])
    sc = _scenario(short)
    root = tmp_path_factory.mktemp("small")
    s1 = _store("ros1")
    M = _Msgs(s1)
    q_wc = _quat(sc["R_wc"])
    pose = [
        (
            "/mocap/cart",
            "geometry_msgs/msg/TransformStamped",
            ns,
            M.transform_stamped(ns, "/world", "/cart", sc["p_c"][i], q_wc[i]),
        )
        for i, ns in enumerate(_ns(sc["t"]))
    ]
    imu = [
        (
            "/imu",
            "sensor_msgs/msg/Imu",
            T0_NS + 5,
            s1.types["sensor_msgs/msg/Imu"](
                header=M.header(T0_NS, "/imu"),
                orientation=M.quat([0, 0, 0, 1]),
                orientation_covariance=np.zeros(9),
                angular_velocity=M.vec([0, 0, 0]),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=M.vec([0, 0, 0]),
                linear_acceleration_covariance=np.zeros(9),
            ),
        )
    ]
    ok = _write_bag(
        root / "ok.bag", "ros1", _tf_messages(M, sc, True) + _wrench_messages(M, sc, "/ft_sensor") + pose + imu, s1
    )
    broken = _write_bag(
        root / "broken.bag",
        "ros1",
        _tf_messages(M, sc, True, drop_link=("base_link", "arm_link")) + _wrench_messages(M, sc, "/ft_sensor") + pose,
        s1,
    )
    write_log(root / "short.csv", short)
    return {"ok": ok, "broken": broken, "log": short, "csv": root / "short.csv"}


def _cli(capsys, argv):
    from cartpush.cli import main

    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


BASE = ["--pose-topic", "/mocap/cart", "--wrench-topic", "/ft_sensor/wrench"]


@pytest.mark.parametrize(
    "bag, extra, fragments",
    [
        (
            "ok",
            ["--pose-topic", "/mocap/nope", "--wrench-topic", "/ft_sensor/wrench"],
            ["no pose topic '/mocap/nope'", "/mocap/cart (geometry_msgs/TransformStamped)", "/ft_sensor/wrench", "/tf"],
        ),
        ("ok", ["--pose-topic", "/mocap/cart", "--wrench-topic", "/wrench"], ["no wrench topic '/wrench'", "/imu"]),
        (
            "ok",
            ["--pose-topic", "/imu", "--wrench-topic", "/ft_sensor/wrench"],
            ["sensor_msgs/Imu", "geometry_msgs/PoseStamped", "geometry_msgs/TransformStamped", "nav_msgs/Odometry"],
        ),
        (
            "ok",
            ["--pose-topic", "/mocap/cart", "--wrench-topic", "/mocap/cart"],
            ["geometry_msgs/TransformStamped", "which carries no stamped wrench", "geometry_msgs/WrenchStamped"],
        ),
        ("broken", BASE, ["cannot connect frame 'ft_sensor' to frame 'world'", "rooted at 'arm_link'"]),
        ("ok", BASE + ["--world-frame", "map"], ["'map'", "does not appear"]),
        ("ok", BASE + ["--start", "100", "--end", "200"], ["empty time window", "pose stamps span"]),
        ("ok", BASE + ["--start", "0.5", "--end", "0.2"], ["empty time window"]),
        ("ok", BASE + ["--start", "nan"], ["--start"]),
        ("ok", ["--wrench-topic", "/ft_sensor/wrench"], ["--pose-topic"]),
        ("ok", ["--pose-topic", "/mocap/cart"], ["--wrench-topic"]),
    ],
)
def test_bad_input_is_one_line_and_exit_2(small_bags, tmp_path, capsys, bag, extra, fragments):
    code, out, err = _cli(capsys, ["import", small_bags[bag], "-o", tmp_path / "out.csv"] + extra)
    assert code == 2, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cartpush import: error:"), err
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    assert not (tmp_path / "out.csv").exists()


def test_not_a_bag_and_missing_paths_exit_2(tmp_path, capsys, small_bags):
    for path in (tmp_path / "nope.bag", tmp_path, small_bags["csv"]):
        code, _, err = _cli(capsys, ["import", path, "--list"])
        assert code == 2 and len(err.strip().splitlines()) == 1, err
    (tmp_path / "corrupt.bag").write_bytes(b"#ROSBAG V2.0\n" + b"\x00" * 50)
    code, _, err = _cli(capsys, ["import", tmp_path / "corrupt.bag", "--list"])
    assert code == 2 and "cannot read the bag" in err
    with pytest.raises(BagImportError, match="apply to ROS bags only"):
        load_any(small_bags["csv"], pose_topic="/mocap/cart")


# -- end to end: cartpush import, then estimate ---------------------------------------------------------
def test_cartpush_import_list_and_convert_then_estimate_as_on_the_csv(push, bags, tmp_path, capsys):
    log, truth = push
    code, out, _ = _cli(capsys, ["import", bags["ros1"], "--list", "--json"])
    assert code == 0
    listing = json.loads(out)
    topics = {tp["name"]: tp for tp in listing["topics"]}
    assert topics["/mocap/cart"]["type"] == "geometry_msgs/TransformStamped" and topics["/mocap/cart"]["use"] == "pose"
    assert topics["/ft_sensor/wrench"]["use"] == "wrench" and topics["/tf"]["use"] == "tf"
    assert topics["/mocap/cart"]["count"] == len(log) + 2
    assert abs(topics["/ft_sensor/wrench"]["rate_hz"] - 200.0) < 5.0
    assert listing["tf_frames"] == ["arm_link", "base_link", "ft_sensor", "odom", "world"]
    static = [(e["parent"], e["child"]) for e in listing["tf_links"] if e["static"]]
    assert static == [("arm_link", "ft_sensor")]
    code, out, _ = _cli(capsys, ["import", bags["ros1"], "--list"])
    assert code == 0 and "arm_link -> ft_sensor  (static)" in out

    csv = tmp_path / "run.csv"
    code, out, err = _cli(
        capsys,
        [
            "import",
            bags["ros1"],
            "-o",
            csv,
            "--pose-topic",
            "/mocap/cart",
            "--wrench-topic",
            "/ft_sensor/wrench",
            "--json",
        ],
    )
    assert code == 0, err
    report = json.loads(out, parse_constant=lambda c: pytest.fail(f"non-strict JSON {c}"))
    assert report["samples"] == len(log) and report["output"] == str(csv)
    assert report["dropped"]["pose_duplicate_stamp"] == 1
    _assert_same_log(read_log(csv), log)
    assert read_log(csv).metadata["world_frame"] == "world"

    original = tmp_path / "sim.csv"
    write_log(original, CartLog(t=log.t, q=log.q, gamma=log.gamma))
    estimates = []
    topics = ["--pose-topic", "/mocap/cart", "--wrench-topic", "/ft_sensor/wrench"]
    for argv in ([csv], [original], [bags["ros1"]] + topics):  # the bag directly: converted in memory
        code, out, err = _cli(capsys, ["estimate", *argv, "--json"])
        assert code == 0, err
        estimates.append(json.loads(out))
    a, b, c = estimates
    for key in ("mass", "inertia", "sigma"):
        assert c[key] == pytest.approx(a[key], rel=1e-9), key
    for key in ("mass", "inertia", "sigma"):
        assert a[key] == pytest.approx(b[key], rel=1e-6), key
    assert abs(a["mass"] - truth["m"]) < 3 * a["std"]["mass"]
    assert abs(a["com"][0] - truth["dx"]) < 3 * a["std"]["com"][0]

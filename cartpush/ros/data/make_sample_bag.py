"""Write cartpush/ros/data/sample_push.bag: a ROS 1 bag of a simulated push, for trying `cartpush import`.

The push is the project's closed loop (`wholebody.push.run_push`, `SAMPLE_CONFIG`: the Ridgeback + iiwa
pushes the 20 kg cart along 16 s of Traj. 2, hand fixed at y = -0.2 m on the handle) and the bag carries
what its sensors measured (`wholebody.push.report.push_log`: motion capture with 3 mm noise, F/T with 3 N):

* ``/mocap/cart``, ``geometry_msgs/TransformStamped``: the cart frame ``cart`` ({b}, the rear-axle midpoint)
  in ``world``, 100 Hz;
* ``/ft_sensor/wrench``, ``geometry_msgs/WrenchStamped``: the hand's wrench in the sensor frame
  ``ft_sensor`` (on the handle at the contact, rotated 90 deg about z), 100 Hz;
* ``/tf_static``: ``cart -> ft_sensor``, so the import moves the wrench into the world frame.

Run from the repository root: ``.venv/bin/python cartpush/ros/data/make_sample_bag.py`` (about 300 kB,
deterministic). The test ``tests/cartpush/test_sample_bag.py`` imports the bag and compares it with
the same push recomputed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parent / "sample_push.bag"
#: One second of 10^9 ns; the bag's clock starts at a wall-clock epoch, as real recordings do.
NS, T0_NS = 1_000_000_000, 1_700_000_000_000_000_000
#: The sensor's place on the handle in {b} (m) and its yaw relative to {b} (rad).
SENSOR_B, SENSOR_YAW = np.array([-0.15, -0.2, 0.85]), np.pi / 2
TOPICS = {"pose": "/mocap/cart", "wrench": "/ft_sensor/wrench"}


def sample_config():
    """Return the `PushConfig` of the sample push (16 s of Traj. 2, fixed contact y = -0.2 m, the paper's EKF, seed 0)."""
    from wholebody.push import PushConfig

    return PushConfig(
        trajectory=2, duration=16.0, contact="fixed", fixed_contact_y=(-0.2,), estimation=True, estimator="ekf", seed=0
    )


def sample_log():
    """Return the measured log (`cart.logs.CartLog`) of the sample push."""
    from wholebody.push import run_push
    from wholebody.push.report import push_log

    return push_log(run_push(sample_config()))


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def sensor_wrench(theta: float, gamma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (force, moment) in the sensor frame producing the log's (fx, fy in {s}, tau about {b})."""
    R_s_sensor = _rz(theta) @ _rz(SENSOR_YAW)
    f_s = np.array([gamma[0], gamma[1], 0.0])
    r = _rz(theta) @ SENSOR_B  # sensor relative to the {b} origin, world axes
    m_s = np.array([0.0, 0.0, gamma[2] - np.cross(r, f_s)[2]])  # tau = [R m + (r - p_b) x f_s]_z
    return R_s_sensor.T @ f_s, R_s_sensor.T @ m_s


def _messages(log, store) -> list[tuple[str, str, int, object]]:
    """Return (topic, type, record ns, message) of the pose, wrench and static TF streams."""
    T = store.types
    vec = lambda v, kind="Vector3": T[f"geometry_msgs/msg/{kind}"](x=float(v[0]), y=float(v[1]), z=float(v[2]))  # noqa: E731

    def header(ns: int, frame: str):
        stamp = T["builtin_interfaces/msg/Time"](sec=ns // NS, nanosec=ns % NS)
        return T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)

    def transform(ns: int, parent: str, child: str, p, yaw: float):
        q = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=float(np.sin(yaw / 2)), w=float(np.cos(yaw / 2)))
        tr = T["geometry_msgs/msg/Transform"](translation=vec(p), rotation=q)
        return T["geometry_msgs/msg/TransformStamped"](header=header(ns, parent), child_frame_id=child, transform=tr)

    tf = T["tf2_msgs/msg/TFMessage"](transforms=[transform(T0_NS, "cart", "ft_sensor", SENSOR_B, SENSOR_YAW)])
    out = [("/tf_static", "tf2_msgs/msg/TFMessage", T0_NS, tf)]
    for t, (x, y, theta), gamma in zip(log.t, log.q, log.gamma):
        ns = T0_NS + int(round(t * 1e9))
        out.append(
            (
                TOPICS["pose"],
                "geometry_msgs/msg/TransformStamped",
                ns + 1_000_000,
                transform(ns, "world", "cart", (x, y, 0.0), theta),
            )
        )
        f, m = sensor_wrench(theta, gamma)
        wrench = T["geometry_msgs/msg/Wrench"](force=vec(f), torque=vec(m))
        msg = T["geometry_msgs/msg/WrenchStamped"](header=header(ns, "ft_sensor"), wrench=wrench)
        out.append((TOPICS["wrench"], "geometry_msgs/msg/WrenchStamped", ns + 2_000_000, msg))
    return sorted(out, key=lambda m: m[2])


def write_sample_bag(path: Path = OUT) -> Path:
    """Write the sample bag (ROS 1) to `path` (replaced if it exists); return the path."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    if "tf2_msgs/msg/TFMessage" not in store.types:  # rosbags' ROS 1 store lacks tf2_msgs
        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    path = Path(path)
    path.unlink(missing_ok=True)
    connections = {}
    with Writer(path) as writer:
        for topic, msgtype, ns, msg in _messages(sample_log(), store):
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(connections[topic], ns, store.serialize_ros1(msg, msgtype))
    return path


if __name__ == "__main__":
    out = write_sample_bag(Path(sys.argv[1]) if len(sys.argv) > 1 else OUT)
    print(f"wrote {out} ({out.stat().st_size / 1e3:.0f} kB)")

"""Turn a ROS recording (ROS 1 ``.bag``, ROS 2 bag folder with sqlite3 or MCAP storage, ``.mcap``/``.db3`` file)
into a cart log (docs/log_format.md), with `rosbags` (pure Python, no ROS installation).

- :func:`list_bag`: what the bag holds (topics, types, counts, rates, the TF links).
- :func:`import_bag`: the cart log and an :class:`ImportReport` saying what was done and dropped.
- :func:`load_any`: a cart log from a CSV or a bag, for commands that accept both.

Semantics (docs/ros_import.md):

- Pose: ``geometry_msgs/PoseStamped``, ``PoseWithCovarianceStamped``, ``TransformStamped``,
  ``nav_msgs/Odometry`` (or any message with the same fields, e.g. a custom type whose definition the
  bag carries), or a TF child frame (``pose_frame``). The planar pose is the position's x, y and the
  yaw of the 3-D orientation (``atan2(R[1,0], R[0,0])``); a tilt beyond `TILT_WARNING_DEG` is reported.
  The world frame {s} is the pose messages' frame unless ``world_frame`` names another one (then TF
  connects them). ``cart_frame``: a TF frame rigidly attached to the tracked body that is the cart
  frame {b} (axle midpoint), when the tracked body's own frame is not.
- Wrench: ``geometry_msgs/WrenchStamped`` (or the same fields) in the frame its header names (or
  ``wrench_frame``), transformed into {s} with ``/tf`` and ``/tf_static`` at its own stamps
  (`tf_tree.TransformBuffer`: any chain, interpolated in time), its torque re-expressed about the {b}
  origin: ``tau = m_z + ((r_sensor - p_b) x f)_z``. ``negate_wrench`` flips the sign (a sensor that
  reports the force on the tool rather than on the cart). A wrench in the world frame needs no TF.
- Time: header stamps (``use_record_time``: the recorder's receive times), zero at the start of the
  recording; streams are aligned on the pose stamps with the wrench interpolated linearly; duplicate
  or out-of-order stamps are dropped and counted (``ImportReport.dropped``), never silently.
"""

from __future__ import annotations

import errno
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple
from collections.abc import Iterator, Sequence

import numpy as np

from cart.logs import CartLog, file_kind, plausibility_warnings, read_log
from cartpush.ros.errors import BagImportError, TransformLookupError
from cartpush.ros.tf_tree import EdgeInfo, TransformBuffer, normalize_frame, quaternion_to_matrix

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

#: Pose message types read (ROS 1 names; ROS 2 adds ``/msg/``); messages with the same fields are read too.
POSE_TYPES = (
    "geometry_msgs/PoseStamped",
    "geometry_msgs/PoseWithCovarianceStamped",
    "geometry_msgs/TransformStamped",
    "nav_msgs/Odometry",
)
#: Wrench message types read (and messages with the same fields).
WRENCH_TYPES = ("geometry_msgs/WrenchStamped",)
#: Topics holding TF links (with or without a leading slash).
TF_TOPIC = "tf"
TF_STATIC_TOPIC = "tf_static"
#: A tilt of the cart's orientation beyond this (degrees) is reported: the planar model may not hold.
TILT_WARNING_DEG = 5.0
#: Header stamps within this many seconds of the recorder's clock count as the same clock (t = 0 at the bag start).
SAME_CLOCK_S = 60.0
#: A pose sample between two wrench samples further apart than this many median wrench periods is dropped.
WRENCH_GAP_PERIODS = 5.0
#: Bag file suffixes `load_any` sends to `import_bag` (a folder is a ROS 2 bag).
BAG_SUFFIXES = (".bag", ".mcap", ".db3")

_NS = 1_000_000_000


# -- results -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TopicSummary:
    """One topic of a bag: name, message type, count, mean rate over the bag, and what it can serve as."""

    name: str
    msgtype: str
    count: int
    rate_hz: float
    use: str  # "pose", "wrench", "tf", "" (none), "?" (its first message could not be decoded)

    def to_dict(self) -> dict:
        """Return the topic as a JSON-ready dict."""
        return {"name": self.name, "type": self.msgtype, "count": self.count, "rate_hz": self.rate_hz, "use": self.use}


@dataclass(frozen=True)
class BagSummary:
    """What a bag holds: storage, span, topics and the TF links (frames normalized, without leading slashes)."""

    path: str
    storage: str
    start_ns: int
    duration: float
    message_count: int
    topics: tuple[TopicSummary, ...]
    tf_links: tuple[EdgeInfo, ...]

    @property
    def tf_frames(self) -> list[str]:
        """Return every frame named by the bag's TF links, sorted."""
        return sorted({e.parent for e in self.tf_links} | {e.child for e in self.tf_links})

    def to_dict(self) -> dict:
        """Return the summary as a JSON-ready dict."""
        return {
            "bag": self.path,
            "storage": self.storage,
            "start_unix_ns": self.start_ns,
            "duration": self.duration,
            "message_count": self.message_count,
            "topics": [t.to_dict() for t in self.topics],
            "tf_frames": self.tf_frames,
            "tf_links": [e.to_dict() for e in self.tf_links],
        }

    def summary(self) -> str:
        """Return a human-readable table of the topics and TF links."""
        lines = [f"bag       {self.path} ({self.storage}, {self.duration:.2f} s, {self.message_count} messages)"]
        w = max([5] + [len(t.name) for t in self.topics])
        wt = max([4] + [len(t.msgtype) for t in self.topics])
        lines.append(f"{'topic':<{w}}  {'type':<{wt}}  {'count':>7}  {'rate_hz':>8}  use")
        for t in self.topics:
            rate = f"{t.rate_hz:8.1f}" if math.isfinite(t.rate_hz) else f"{'-':>8}"
            lines.append(f"{t.name:<{w}}  {t.msgtype:<{wt}}  {t.count:>7}  {rate}  {t.use}")
        if self.tf_links:
            lines.append("TF links (parent -> child):")
            for e in self.tf_links:
                kind = "static" if e.static else f"dynamic, {e.count} samples"
                lines.append(f"  {e.parent} -> {e.child}  ({kind})")
        else:
            lines.append("TF links: none (no /tf or /tf_static messages)")
        return "\n".join(lines)


@dataclass(frozen=True)
class ImportReport:
    """What `import_bag` did: sources, frames, clock, TF chains, samples kept and dropped (by reason), warnings."""

    bag: str
    storage: str
    samples: int
    duration: float
    t0_ns: int
    clock: str
    pose_source: str
    pose_type: str
    wrench_topic: str
    wrench_type: str
    world_frame: str
    cart_frame: str
    wrench_frames: tuple[str, ...]
    tf_chains: dict[str, list[str]]
    negate_wrench: bool
    window: tuple[float | None, float | None]
    dropped: dict[str, int]
    tilt_max_deg: float
    has_velocities: bool
    warnings: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """Return the report as a JSON-ready dict."""
        return {
            "bag": self.bag,
            "storage": self.storage,
            "samples": self.samples,
            "duration": self.duration,
            "t0_unix_ns": self.t0_ns,
            "clock": self.clock,
            "pose_source": self.pose_source,
            "pose_type": self.pose_type,
            "wrench_topic": self.wrench_topic,
            "wrench_type": self.wrench_type,
            "world_frame": self.world_frame,
            "cart_frame": self.cart_frame,
            "wrench_frames": list(self.wrench_frames),
            "tf_chains": dict(self.tf_chains),
            "negate_wrench": self.negate_wrench,
            "window": list(self.window),
            "dropped": dict(self.dropped),
            "tilt_max_deg": self.tilt_max_deg,
            "has_velocities": self.has_velocities,
            "warnings": list(self.warnings),
            "notes": list(self.notes),
        }

    def summary(self) -> str:
        """Return a few human-readable lines."""
        lines = [
            f"bag        {self.bag} [{self.storage}]",
            f"samples    {self.samples} over {self.duration:.2f} s ({self.clock} stamps, t = 0 at "
            f"{self.t0_ns} ns since the Unix epoch)",
            f"pose       {self.pose_source} ({self.pose_type}); world frame '{self.world_frame}', cart frame "
            f"'{self.cart_frame or '-'}'; max tilt {self.tilt_max_deg:.2f} deg",
            f"wrench     {self.wrench_topic} ({self.wrench_type}) in {', '.join(self.wrench_frames)}"
            f"{' (negated)' if self.negate_wrench else ''}",
        ]
        for frame, chain in self.tf_chains.items():
            lines.append(f"TF chain   {' -> '.join(chain)}" if len(chain) > 1 else f"TF chain   {frame} (world frame)")
        lost = {k: v for k, v in self.dropped.items() if v}
        lines.append("dropped    " + (", ".join(f"{k} {v}" for k, v in lost.items()) if lost else "nothing"))
        lines.append(f"velocities {'from the odometry twist' if self.has_velocities else 'not in the log'}")
        lines.extend(f"note: {n}" for n in self.notes)
        return "\n".join(lines)


# -- reading a bag -------------------------------------------------------------------------------
def _ros1_name(msgtype: str) -> str:
    return msgtype.replace("/msg/", "/")


def _storage_of(path: Path) -> str:
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            raise BagImportError(f"{path}: a folder, but not a ROS 2 bag (it has no metadata.yaml)")
        return "ROS 2 bag (MCAP)" if any(path.glob("*.mcap")) else "ROS 2 bag (sqlite3)"
    kind = file_kind(path)
    if kind is not None:  # a FIFO would wait for a writer forever, a device never end
        raise BagImportError(f"{path}: is {kind}, not a bag file; save the recording to a file and give that")
    suffix = path.suffix.lower()
    if suffix == ".bag":
        return "ROS 1 bag"
    if suffix == ".mcap":
        return "MCAP file"
    if suffix == ".db3":
        return "ROS 2 sqlite3 file"
    raise BagImportError(f"{path}: not a bag (expected a ROS 1 .bag file, a ROS 2 bag folder, or a .mcap or .db3 file)")


def is_bag(path: str | os.PathLike) -> bool:
    """Return True when ``path`` names a bag (a folder, or a .bag/.mcap/.db3 file) rather than a cart log."""
    p = Path(path)
    return p.is_dir() or p.suffix.lower() in BAG_SUFFIXES


class _Bag:
    """An open bag: topics, raw messages in record order, messages decoded with the bag's own definitions."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise FileNotFoundError(errno.ENOENT, "No such file or directory", str(path))
        self.storage = _storage_of(self.path)
        self.ros1 = self.storage == "ROS 1 bag"
        self._stores: dict[tuple[str, Any, str], Any] = {}
        self._default_store: Typestore | None = None
        self.reader: Any = None

    def __enter__(self) -> _Bag:
        from rosbags.rosbag1 import Reader as Reader1
        from rosbags.rosbag2 import Reader as Reader2

        try:
            self.reader = (Reader1 if self.ros1 else Reader2)(self.path)
            self.reader.open()
        except (FileNotFoundError, PermissionError, IsADirectoryError):
            raise
        except Exception as exc:  # noqa: BLE001 - any failure to parse the container is bad input
            hint = " (run `rosbag reindex` on it)" if "index" in str(exc).lower() and self.ros1 else ""
            raise BagImportError(f"{self.path}: cannot read the bag: {' '.join(str(exc).split())}{hint}") from None
        return self

    def __exit__(self, *exc: object) -> None:
        try:
            self.reader.close()
        except Exception:  # noqa: BLE001 - closing a reader that failed half-way
            pass

    # topics ---------------------------------------------------------------------------------
    @property
    def topics(self) -> dict[str, Any]:
        return self.reader.topics

    @property
    def start_ns(self) -> int:
        return int(self.reader.start_time) if self.message_count else 0

    @property
    def end_ns(self) -> int:
        return int(self.reader.end_time) if self.message_count else 0

    @property
    def message_count(self) -> int:
        return int(self.reader.message_count)

    def type_name(self, msgtype: str | None) -> str:
        if msgtype is None:
            return "(several types)"
        return _ros1_name(msgtype) if self.ros1 else msgtype

    def topic_list(self) -> str:
        return (
            ", ".join(f"{name} ({self.type_name(info.msgtype)})" for name, info in sorted(self.topics.items()))
            or "none"
        )

    def find_topic(self, name: str, what: str) -> str:
        """Return the bag's name of topic ``name`` (leading slash optional); raise BagImportError listing topics."""
        if name in self.topics:
            return name
        wanted = "/" + name.strip().lstrip("/")
        for topic in self.topics:
            if "/" + topic.lstrip("/") == wanted:
                return topic
        raise BagImportError(f"{self.path}: no {what} topic '{name}' in the bag; its topics are: {self.topic_list()}")

    def tf_topics(self) -> list[str]:
        return [t for t in self.topics if t.lstrip("/") in (TF_TOPIC, TF_STATIC_TOPIC)]

    # messages -------------------------------------------------------------------------------
    def raw(self, topics: Sequence[str]) -> Iterator[tuple[str, int, bytes, Any]]:
        """Yield (topic, record time ns, raw bytes, connection) of the topics, in record order."""
        conns = [c for t in topics for c in self.topics[t].connections]
        if not conns:
            return
        try:
            for conn, stamp, data in self.reader.messages(connections=conns):
                yield conn.topic, int(stamp), data, conn
        except BagImportError:
            raise
        except Exception as exc:  # noqa: BLE001 - a truncated or corrupt bag
            raise BagImportError(
                f"{self.path}: cannot read the messages of {', '.join(topics)}: {' '.join(str(exc).split())}"
            ) from None

    def _default(self) -> Any:
        from rosbags.typesys import Stores, get_typestore

        if self._default_store is None:
            name = Stores.ROS1_NOETIC
            if not self.ros1:
                distro = str(getattr(self.reader, "ros_distro", None) or "").lower()
                name = {s.value: s for s in Stores}.get(f"ros2_{distro}", Stores.LATEST)
            self._default_store = get_typestore(name)
        return self._default_store

    def store(self, conn: Any) -> Any:
        """Return a typestore that knows ``conn.msgtype``: from the definition the bag carries, else the defaults."""
        from rosbags.interfaces import MessageDefinitionFormat
        from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

        fmt, text = conn.msgdef.format, conn.msgdef.data
        key = (conn.msgtype, fmt, text)
        if key in self._stores:
            return self._stores[key]
        if fmt == MessageDefinitionFormat.NONE or not str(text).strip():
            store = self._default()
            if conn.msgtype not in store.types:
                raise BagImportError(
                    f"{self.path}: topic {conn.topic}: the bag carries no definition of "
                    f"{self.type_name(conn.msgtype)} and it is not a standard ROS message"
                )
        else:
            try:
                if fmt == MessageDefinitionFormat.MSG:
                    types = get_types_from_msg(text, conn.msgtype)
                else:
                    types = {}
                    sep = "=" * 80 + "\n"
                    parts = text.split(sep)[1:] if text.startswith(f"{sep}IDL: ") else [text]
                    for part in parts:
                        types.update(get_types_from_idl(part.split("\n", 1)[1] if part.startswith("IDL: ") else part))
                store = get_typestore(Stores.EMPTY)
                store.register(types)
            except Exception as exc:  # noqa: BLE001 - a definition rosbags cannot parse
                raise BagImportError(
                    f"{self.path}: topic {conn.topic}: cannot parse the definition of "
                    f"{self.type_name(conn.msgtype)} carried in the bag: "
                    f"{' '.join(str(exc).split())}"
                ) from None
        self._stores[key] = store
        return store

    def decode(self, data: bytes, conn: Any) -> Any:
        """Return the message object of raw ``data`` on connection ``conn``."""
        store = self.store(conn)
        ros1_encoded = self.ros1 or getattr(conn.ext, "serialization_format", "cdr") == "ros1"
        try:
            if ros1_encoded:
                return store.deserialize_ros1(data, conn.msgtype)
            return store.deserialize_cdr(data, conn.msgtype)
        except Exception as exc:  # noqa: BLE001 - corrupt data or a definition that does not match it
            raise BagImportError(
                f"{self.path}: topic {conn.topic}: cannot decode a {self.type_name(conn.msgtype)} "
                f"message: {' '.join(str(exc).split())}"
            ) from None


# -- message shapes ------------------------------------------------------------------------------
def _has(obj: Any, *names: str) -> bool:
    return all(hasattr(obj, n) for n in names)


def _is_header(obj: Any) -> bool:
    return _has(obj, "stamp", "frame_id") and _has(obj.stamp, "sec", "nanosec")


def _is_pose(obj: Any) -> bool:
    return (
        _has(obj, "position", "orientation")
        and _has(obj.position, "x", "y", "z")
        and _has(obj.orientation, "x", "y", "z", "w")
    )


def _is_transform(obj: Any) -> bool:
    return (
        _has(obj, "translation", "rotation")
        and _has(obj.translation, "x", "y", "z")
        and _has(obj.rotation, "x", "y", "z", "w")
    )


def pose_kind(msg: Any) -> str | None:
    """Return how a message carries a pose ("odometry", "pose_cov", "pose", "transform") or None when it does not."""
    if not (_has(msg, "header") and _is_header(msg.header)):
        return None
    if _has(msg, "pose", "twist", "child_frame_id") and _has(msg.pose, "pose") and _is_pose(msg.pose.pose):
        return "odometry"
    if _has(msg, "pose") and _has(msg.pose, "pose") and _is_pose(msg.pose.pose):
        return "pose_cov"
    if _has(msg, "pose") and _is_pose(msg.pose):
        return "pose"
    if _has(msg, "transform") and _is_transform(msg.transform):
        return "transform"
    return None


def is_wrench(msg: Any) -> bool:
    """Return True when a message carries a stamped wrench (header + wrench.force + wrench.torque)."""
    return (
        _has(msg, "header", "wrench")
        and _is_header(msg.header)
        and _has(msg.wrench, "force", "torque")
        and _has(msg.wrench.force, "x", "y", "z")
        and _has(msg.wrench.torque, "x", "y", "z")
    )


def is_tf(msg: Any) -> bool:
    """Return True when a message is a list of transforms (tf2_msgs/TFMessage)."""
    return _has(msg, "transforms")


def _stamp_ns(stamp: Any) -> int:
    return int(stamp.sec) * _NS + int(stamp.nanosec)


def _xyz(v: Any) -> tuple[float, float, float]:
    return (float(v.x), float(v.y), float(v.z))


def _xyzw(q: Any) -> tuple[float, float, float, float]:
    return (float(q.x), float(q.y), float(q.z), float(q.w))


def _topic_use(msg: Any) -> str:
    if is_tf(msg):
        return "tf"
    if pose_kind(msg):
        return "pose"
    if is_wrench(msg):
        return "wrench"
    return ""


def _supported(kind: str) -> str:
    types = POSE_TYPES if kind == "pose" else WRENCH_TYPES
    shape = (
        "a std_msgs/Header header and a geometry_msgs/Pose pose (or a Transform transform)"
        if kind == "pose"
        else "a std_msgs/Header header and a geometry_msgs/Wrench wrench"
    )
    return f"supported: {', '.join(types)}, or a message with the same fields ({shape})"


# -- streams -------------------------------------------------------------------------------------
@dataclass
class _Stream:
    """Decoded samples of one topic, in record order: record and header times (ns), frames, values."""

    record_ns: list[int] = field(default_factory=list)
    stamp_ns: list[int] = field(default_factory=list)
    frames: list[str] = field(default_factory=list)
    children: list[str] = field(default_factory=list)
    values: list[tuple[float, ...]] = field(default_factory=list)
    msgtype: str = ""
    kind: str = ""


def _pose_values(msg: Any, kind: str) -> tuple[tuple[float, ...], str]:
    if kind == "transform":
        return _xyz(msg.transform.translation) + _xyzw(msg.transform.rotation), str(getattr(msg, "child_frame_id", ""))
    pose = msg.pose.pose if kind in ("odometry", "pose_cov") else msg.pose
    values = _xyz(pose.position) + _xyzw(pose.orientation)
    if kind == "odometry":
        tw = msg.twist.twist
        return values + _xyz(tw.linear) + _xyz(tw.angular), str(msg.child_frame_id)
    return values, ""


class _TFSample(NamedTuple):
    """One transform read from the bag: kind "static" (/tf_static), "dynamic" (/tf) or the TransformStamped topic."""

    kind: str
    record_ns: int
    stamp_ns: int
    parent: str
    child: str
    values: tuple


def _tf_sample(kind: str, record_ns: int, tr: Any) -> _TFSample:
    return _TFSample(
        kind,
        record_ns,
        _stamp_ns(tr.header.stamp),
        normalize_frame(tr.header.frame_id),
        normalize_frame(tr.child_frame_id),
        _xyz(tr.transform.translation) + _xyzw(tr.transform.rotation),
    )


def _read_streams(
    bag: _Bag, pose_topic: str | None, wrench_topic: str, extra_tf: bool = True
) -> tuple[_Stream | None, _Stream, list[_TFSample]]:
    """Return (pose stream, wrench stream, transforms of /tf, /tf_static and, with ``extra_tf``, of the other
    geometry_msgs/TransformStamped topics (motion capture publishes them))."""
    pose = _Stream() if pose_topic else None
    wrench = _Stream()
    tf: list[_TFSample] = []
    tf_topics = bag.tf_topics()
    extra = [
        t
        for t, info in bag.topics.items()
        if extra_tf and str(info.msgtype).endswith("/TransformStamped") and t not in (pose_topic, wrench_topic)
    ]
    topics = [t for t in dict.fromkeys([pose_topic, wrench_topic, *tf_topics, *extra]) if t]
    for topic, record_ns, data, conn in bag.raw(topics):
        msg = bag.decode(data, conn)
        if topic in tf_topics and topic not in (pose_topic, wrench_topic):
            if is_tf(msg):
                kind = "static" if topic.lstrip("/") == TF_STATIC_TOPIC else "dynamic"
                tf.extend(_tf_sample(kind, record_ns, tr) for tr in msg.transforms)
            continue
        if topic in extra:
            if pose_kind(msg) == "transform" and _has(msg, "child_frame_id"):
                tf.append(_tf_sample(topic, record_ns, msg))
            continue
        if topic == pose_topic and pose is not None:
            if not pose.kind:
                msg_kind = pose_kind(msg)
                if msg_kind is None:
                    raise BagImportError(
                        f"{bag.path}: pose topic {topic} has type {bag.type_name(conn.msgtype)}, "
                        f"which carries no stamped pose; {_supported('pose')}"
                    )
                pose.kind, pose.msgtype = msg_kind, bag.type_name(conn.msgtype)
            values, child = _pose_values(msg, pose.kind)
            pose.record_ns.append(record_ns)
            pose.stamp_ns.append(_stamp_ns(msg.header.stamp))
            pose.frames.append(normalize_frame(msg.header.frame_id))
            pose.children.append(normalize_frame(child))
            pose.values.append(values)
        if topic == wrench_topic:
            if not wrench.kind:
                if not is_wrench(msg):
                    raise BagImportError(
                        f"{bag.path}: wrench topic {topic} has type {bag.type_name(conn.msgtype)}, "
                        f"which carries no stamped wrench; {_supported('wrench')}"
                    )
                wrench.kind, wrench.msgtype = "wrench", bag.type_name(conn.msgtype)
            wrench.record_ns.append(record_ns)
            wrench.stamp_ns.append(_stamp_ns(msg.header.stamp))
            wrench.frames.append(normalize_frame(msg.header.frame_id))
            wrench.values.append(_xyz(msg.wrench.force) + _xyz(msg.wrench.torque))
    return pose, wrench, tf


def _ordered(t_ns: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Return (keep mask, duplicates, out of order): a sample is kept when its time exceeds every earlier one."""
    keep = np.ones(len(t_ns), dtype=bool)
    if len(t_ns) < 2:
        return keep, 0, 0
    before = np.maximum.accumulate(t_ns)[:-1]
    keep[1:] = t_ns[1:] > before
    dup = int(np.count_nonzero(t_ns[1:] == before))
    back = int(np.count_nonzero(t_ns[1:] < before))
    return keep, dup, back


def _seconds(t_ns: np.ndarray, t0_ns: int) -> np.ndarray:
    return (np.asarray(t_ns, dtype=np.int64) - np.int64(t0_ns)).astype(float) / 1e9


def _build_tf(tf: list[_TFSample], t0_ns: int, use_record_time: bool) -> tuple[TransformBuffer, list[str]]:
    """Return the TF buffer and the links taken from TransformStamped topics (for frames without a TF parent)."""
    buf = TransformBuffer()
    links: dict[tuple[str, str, str], list[tuple[int, tuple]]] = {}
    for s in tf:
        if s.parent == s.child or not s.parent or not s.child:
            continue
        if s.kind == "static":
            buf.add_static(s.parent, s.child, s.values[:3], s.values[3:])
        else:
            links.setdefault((s.kind, s.parent, s.child), []).append(
                (s.record_ns if use_record_time else s.stamp_ns, s.values)
            )
    # a TransformStamped topic may give a frame its parent (e.g. the robot's base in the motion-capture world),
    # never a second one
    has_parent = {child for (kind, _, child) in links if kind == "dynamic"} | {e.child for e in buf.edges()}
    extra: list[str] = []
    for (kind, parent, child), samples in sorted(links.items(), key=lambda kv: kv[0][0] != "dynamic"):
        if kind != "dynamic":
            if child in has_parent:
                continue
            has_parent.add(child)
            extra.append(f"{parent} -> {child} from {kind}")
        t = _seconds(np.array([s[0] for s in samples], dtype=np.int64), t0_ns)
        v = np.array([s[1] for s in samples], dtype=float)
        buf.add_many(parent, child, t, v[:, :3], v[:, 3:7])
    return buf, extra


# -- public API ----------------------------------------------------------------------------------
def list_bag(path: str | os.PathLike) -> BagSummary:
    """Return what a bag holds: topics (type, count, mean rate, use as pose/wrench/tf) and its TF links."""
    with _Bag(path) as bag:
        duration = max(bag.end_ns - bag.start_ns, 0) / 1e9
        topics = []
        for name, info in sorted(bag.topics.items()):
            use = ""
            try:
                for _, _, data, conn in bag.raw([name]):
                    use = _topic_use(bag.decode(data, conn))
                    break
            except BagImportError:
                use = "?"
            latched = name.lstrip("/") == TF_STATIC_TOPIC
            rate = info.msgcount / duration if duration > 0 and info.msgcount > 1 and not latched else float("nan")
            topics.append(TopicSummary(name, bag.type_name(info.msgtype), int(info.msgcount), rate, use))
        _, _, tf = _read_streams(bag, None, "", extra_tf=False) if bag.tf_topics() else (None, None, [])
        links = tuple(_build_tf(tf, bag.start_ns, False)[0].edges())
        return BagSummary(str(path), bag.storage, bag.start_ns, duration, bag.message_count, tuple(topics), links)


def _check_window(start: float | None, end: float | None) -> None:
    for name, v in (("start", start), ("end", end)):
        if v is not None and not math.isfinite(float(v)):
            raise BagImportError(f"the window's {name} must be a finite number of seconds, got {v}")
    if start is not None and end is not None and not float(end) > float(start):
        raise BagImportError(f"empty time window: end {end} s is not after start {start} s")


@dataclass
class _Poses:
    """Pose samples of the tracked frame C in the pose messages' frame H (R_hc, p_hc), twist (Odometry) or None."""

    t: np.ndarray
    R_hc: np.ndarray
    p_hc: np.ndarray
    twist: np.ndarray | None
    header_frame: str
    child: str
    source: str
    msgtype: str

    def subset(self, mask: np.ndarray) -> _Poses:
        return _Poses(
            self.t[mask],
            self.R_hc[mask],
            self.p_hc[mask],
            None if self.twist is None else self.twist[mask],
            self.header_frame,
            self.child,
            self.source,
            self.msgtype,
        )


#: How the report's warnings name each reason for dropping samples.
_DROP_REASONS = {
    "pose_duplicate_stamp": "pose message(s) repeating the previous stamp",
    "pose_out_of_order": "pose message(s) stamped earlier than a previous one",
    "pose_invalid": "pose message(s) with non-finite values or a zero quaternion",
    "pose_outside_tf": "pose sample(s) outside the time span of the TF links they need",
    "pose_in_wrench_gap": "pose sample(s) inside a gap of the wrench stream",
    "wrench_duplicate_stamp": "wrench message(s) repeating the previous stamp",
    "wrench_out_of_order": "wrench message(s) stamped earlier than a previous one",
    "wrench_invalid": "wrench message(s) with non-finite values",
    "wrench_outside_tf": "wrench sample(s) outside the time span of the TF links to the world frame",
}


def _poses_from_topic(
    pose: _Stream,
    name: str,
    t_ns: np.ndarray,
    t0_ns: int,
    world: str,
    tf_buf: TransformBuffer,
    dropped: dict[str, int],
    notes: list[str],
) -> _Poses:
    keep, dropped["pose_duplicate_stamp"], dropped["pose_out_of_order"] = _ordered(t_ns)
    values = np.array(pose.values, dtype=float)[keep]
    t = _seconds(t_ns[keep], t0_ns)
    frames = sorted(set(np.array(pose.frames, dtype=object)[keep]))
    if len(frames) > 1:
        raise BagImportError(
            f"{name}: the pose messages change frame ({', '.join(map(repr, frames))}); import one "
            f"stretch at a time (--start/--end)"
        )
    header_frame = frames[0] if frames else ""
    if not header_frame:
        header_frame = world or "world"
        notes.append(f"the pose messages name no frame: taken to be in the world frame '{header_frame}'")
    children = sorted(set(np.array(pose.children, dtype=object)[keep]) - {""})
    child = children[0] if len(children) == 1 else ""
    finite = np.all(np.isfinite(values), axis=1) & (np.linalg.norm(values[:, 3:7], axis=1) > 1e-6)
    dropped["pose_invalid"] = int(np.count_nonzero(~finite))
    t, values = t[finite], values[finite]
    if child and not tf_buf.has_parent(child) and len(t):
        # the pose is a TF link too (unless TF already places C): a wrench may be given in C or a frame on it
        tf_buf.add_many(header_frame, child, t, values[:, :3], values[:, 3:7])
    return _Poses(
        t,
        quaternion_to_matrix(values[:, 3:7]),
        values[:, :3],
        values[:, 7:13] if pose.kind == "odometry" else None,
        header_frame,
        child,
        name,
        pose.msgtype,
    )


def _poses_from_tf(frame: str, world: str, tf_buf: TransformBuffer) -> _Poses:
    child = normalize_frame(frame)
    if not tf_buf.has_frame(child):
        raise TransformLookupError(
            f"pose frame '{child}' does not appear in /tf or /tf_static (frames present: "
            f"{', '.join(tf_buf.frames) or 'none'})",
            source=child,
            target=world,
        )
    world = world or tf_buf.root_of(child)
    t = tf_buf.dynamic_stamps(world, child)
    if not len(t):
        raise BagImportError(
            f"pose frame '{child}' does not move relative to '{world}' (every TF link between them "
            f"is static): no pose samples"
        )
    R, p, ok = tf_buf.lookup(world, child, t)
    return _Poses(t[ok], R[ok], p[ok], None, world, child, f"TF frame {child}", "tf2_msgs/TFMessage")


def _window(poses: _Poses, start: float | None, end: float | None, path: Any) -> _Poses:
    t = poses.t
    if len(t) == 0:
        raise BagImportError(f"{path}: no valid pose samples on {poses.source}")
    lo = -np.inf if start is None else float(start)
    hi = np.inf if end is None else float(end)
    inside = (t >= lo) & (t <= hi)
    if not np.any(inside):
        raise BagImportError(
            f"{path}: empty time window: no pose sample between {start if start is not None else '-'}"
            f" s and {end if end is not None else '-'} s (the pose stamps span {t[0]:.3f} s to "
            f"{t[-1]:.3f} s from the start of the recording)"
        )
    return poses.subset(inside)


def _cart_in_world(
    poses: _Poses, world: str, cart: str, tf_buf: TransformBuffer
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (R_wc, p_wc, R_wb, p_wb, valid): the tracked frame C and the cart frame {b} in the world frame."""
    t = poses.t
    ok = np.ones(len(t), dtype=bool)
    R_wc, p_wc = poses.R_hc, poses.p_hc
    if poses.header_frame != world:
        R_wh, p_wh, ok = tf_buf.lookup(world, poses.header_frame, t)
        R_wc = np.einsum("nij,njk->nik", R_wh, poses.R_hc)
        p_wc = np.einsum("nij,nj->ni", R_wh, poses.p_hc) + p_wh
    if not cart or cart == poses.child:
        return R_wc, p_wc, R_wc, p_wc, ok
    if not poses.child:
        raise BagImportError(
            f"cart frame '{cart}': the pose messages ({poses.msgtype}) name no child frame to "
            f"attach it to; use a TransformStamped or Odometry pose, or a TF frame (pose_frame)"
        )
    R_ck, p_ck, ok_k = tf_buf.lookup(poses.child, cart, t)
    return R_wc, p_wc, np.einsum("nij,njk->nik", R_wc, R_ck), np.einsum("nij,nj->ni", R_wc, p_ck) + p_wc, ok & ok_k


def _wrench_in_world(
    wrench: _Stream,
    name: str,
    t_ns: np.ndarray,
    t0_ns: int,
    world: str,
    wrench_frame: str | None,
    tf_buf: TransformBuffer,
    dropped: dict[str, int],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, list[str]]]:
    """Return (t, force in {s}, torque about the world origin in {s}, TF chain of each wrench frame)."""
    keep, dropped["wrench_duplicate_stamp"], dropped["wrench_out_of_order"] = _ordered(t_ns)
    tw = _seconds(t_ns[keep], t0_ns)
    wv = np.array(wrench.values, dtype=float)[keep]
    frames = np.array(wrench.frames, dtype=object)[keep]
    if wrench_frame:
        frames[:] = normalize_frame(wrench_frame)
    if np.any(frames == ""):
        raise BagImportError(
            f"{name}: the wrench messages name no frame (empty header frame_id): give the sensor frame (--wrench-frame)"
        )
    fin = np.all(np.isfinite(wv), axis=1)
    dropped["wrench_invalid"] = int(np.count_nonzero(~fin))
    f_w = np.zeros((len(tw), 3))
    m_o = np.zeros((len(tw), 3))
    ok = fin.copy()
    chains: dict[str, list[str]] = {}
    for frame in sorted(set(frames)):
        sel = frames == frame
        n = int(np.count_nonzero(sel))
        if frame == world:
            R, p, ok_s = np.broadcast_to(np.eye(3), (n, 3, 3)), np.zeros((n, 3)), np.ones(n, dtype=bool)
        else:
            R, p, ok_s = tf_buf.lookup(world, frame, tw[sel])
        chains[frame] = tf_buf.chain(world, frame) if frame != world else [frame]
        f = np.einsum("nij,nj->ni", R, wv[sel, :3])
        f_w[sel] = f
        m_o[sel] = np.einsum("nij,nj->ni", R, wv[sel, 3:]) + np.cross(p, f)  # about the world origin
        ok[sel] &= ok_s
    dropped["wrench_outside_tf"] = int(np.count_nonzero(fin & ~ok))
    if int(np.count_nonzero(ok)) < 2:
        raise BagImportError(
            f"{name}: fewer than 2 usable wrench samples (dropped: { {k: v for k, v in dropped.items() if v} })"
        )
    return tw[ok], f_w[ok], m_o[ok], chains


def _aligned(t: np.ndarray, valid: np.ndarray, tw: np.ndarray, dropped: dict[str, int], path: Any) -> np.ndarray:
    """Return the mask of pose samples the wrench covers (inside its span, not inside a gap of it)."""
    covered = (t >= tw[0]) & (t <= tw[-1])
    dropped["pose_outside_wrench"] = int(np.count_nonzero(valid & ~covered))
    j = np.clip(np.searchsorted(tw, t, side="left"), 1, len(tw) - 1)
    exact = tw[np.clip(np.searchsorted(tw, t), 0, len(tw) - 1)] == t
    gap = (tw[j] - tw[j - 1]) > WRENCH_GAP_PERIODS * float(np.median(np.diff(tw)))
    in_gap = gap & ~exact & covered & valid
    dropped["pose_in_wrench_gap"] = int(np.count_nonzero(in_gap))
    use = valid & covered & ~in_gap
    if int(np.count_nonzero(use)) < 3:
        lost = {k: v for k, v in dropped.items() if v}
        raise BagImportError(
            f"{path}: only {int(np.count_nonzero(use))} pose sample(s) left in the window once "
            f"aligned with the wrench (a log needs 3; dropped: {lost or 'nothing'}; wrench stamps "
            f"span {tw[0]:.3f} s to {tw[-1]:.3f} s, pose stamps {t[0]:.3f} s to {t[-1]:.3f} s)"
        )
    return use


class _Recording(NamedTuple):
    """What `import_bag` reads off the bag: resolved topic names, decoded streams, TF samples, start and storage."""

    pose_name: str | None
    wrench_name: str
    pose: _Stream | None
    wrench: _Stream
    tf: list[_TFSample]
    start_ns: int
    storage: str


def _check_request(
    path: Any,
    pose_topic: str | None,
    pose_frame: str | None,
    wrench_topic: str | None,
    start: float | None,
    end: float | None,
) -> str:
    """Raise BagImportError unless exactly one pose source, a wrench topic and a valid window are given.

    Return the wrench topic.
    """
    if (pose_topic is None) == (pose_frame is None):
        raise BagImportError(
            f"{path}: give the cart's pose as exactly one of a pose topic or a TF frame "
            f"(--pose-topic / --pose-frame), got {'both' if pose_topic else 'neither'}"
        )
    if not wrench_topic:
        raise BagImportError(f"{path}: give the wrench topic (--wrench-topic, a geometry_msgs/WrenchStamped topic)")
    _check_window(start, end)
    return wrench_topic


def _read_recording(bag: _Bag, pose_topic: str | None, wrench_topic: str) -> _Recording:
    """Return the pose (None with a TF pose frame) and wrench streams and the TF samples; close the bag."""
    with bag:
        pose_name = bag.find_topic(pose_topic, "pose") if pose_topic else None
        wrench_name = bag.find_topic(wrench_topic, "wrench")
        for name in (pose_name, wrench_name):
            if name and bag.topics[name].msgcount == 0:
                raise BagImportError(f"{bag.path}: topic {name} has no messages")
        pose, wrench, tf = _read_streams(bag, pose_name, wrench_name)
        return _Recording(pose_name, wrench_name, pose, wrench, tf, bag.start_ns, bag.storage)


def _clock(rec: _Recording, use_record_time: bool, notes: list[str]) -> tuple[np.ndarray, np.ndarray, int]:
    """Return (pose times, wrench times (ns), t0_ns): t = 0 at the start of the recording, or at the first pose
    stamp when the header stamps use another clock."""
    if not use_record_time:
        for name, stream in ((rec.pose_name, rec.pose), (rec.wrench_name, rec.wrench)):
            if stream is not None and 2 * stream.stamp_ns.count(0) > len(stream.stamp_ns):
                raise BagImportError(
                    f"{name}: the header stamps are zero (its publisher does not stamp the "
                    f"messages): use the record time (--record-time)"
                )
    wrench_t_ns = np.array(rec.wrench.record_ns if use_record_time else rec.wrench.stamp_ns, dtype=np.int64)
    pose_t_ns = np.zeros(0, dtype=np.int64)
    if rec.pose is not None:
        pose_t_ns = np.array(rec.pose.record_ns if use_record_time else rec.pose.stamp_ns, dtype=np.int64)
        first_ns = int(pose_t_ns.min())
    else:
        first_ns = min(
            [s.record_ns if use_record_time else s.stamp_ns for s in rec.tf if s.kind != "static"] or [rec.start_ns]
        )
    t0_ns = rec.start_ns
    if not use_record_time and abs(first_ns - rec.start_ns) > SAME_CLOCK_S * _NS:
        t0_ns = first_ns
        notes.append(
            "the header stamps are on another clock than the recorder's (simulated time?): t = 0 at the "
            "first pose stamp; use the record time to window by the recorder's clock"
        )
    return pose_t_ns, wrench_t_ns, t0_ns


def _tracked_poses(
    rec: _Recording,
    pose_frame: str | None,
    world: str,
    pose_t_ns: np.ndarray,
    t0_ns: int,
    tf_buf: TransformBuffer,
    dropped: dict[str, int],
    notes: list[str],
) -> tuple[_Poses, str]:
    """Return (pose samples of the tracked frame, the world frame) from the pose topic or the TF frame."""
    if rec.pose is not None and rec.pose_name is not None:  # a pose topic (the stream exists with its name)
        poses = _poses_from_topic(rec.pose, rec.pose_name, pose_t_ns, t0_ns, world, tf_buf, dropped, notes)
        return poses, world or poses.header_frame
    if pose_frame is None:  # _check_request asks for exactly one of a pose topic and a pose frame
        raise BagImportError("give the cart's pose as exactly one of a pose topic or a TF frame")
    poses = _poses_from_tf(pose_frame, world, tf_buf)
    return poses, poses.header_frame


def _planar_pose(t: np.ndarray, R_wb: np.ndarray, warns: list[str]) -> tuple[np.ndarray, float]:
    """Return (unwrapped yaw of {b}, largest tilt in degrees); warn beyond TILT_WARNING_DEG."""
    theta = np.unwrap(np.arctan2(R_wb[:, 1, 0], R_wb[:, 0, 0]))
    tilt = np.degrees(np.arccos(np.clip(R_wb[:, 2, 2], -1.0, 1.0)))
    tilt_max = float(np.max(tilt))
    if tilt_max > TILT_WARNING_DEG:
        warns.append(
            f"the cart frame tilts up to {tilt_max:.1f} deg from the vertical (at t = "
            f"{t[int(np.argmax(tilt))]:.2f} s): a planar cart stays within a few degrees; check the world "
            f"frame and the pose source"
        )
    return theta, tilt_max


def _odometry_velocities(
    poses: _Poses,
    use: np.ndarray,
    world: str,
    tf_buf: TransformBuffer,
    R_wc: np.ndarray,
    p_wc: np.ndarray,
    p_wb: np.ndarray,
    notes: list[str],
) -> np.ndarray | None:
    """Return the cart rates (vx, vy, wz of {b} in {s}) of an odometry pose, None without a usable twist."""
    if poses.twist is None:
        return None
    if not (poses.header_frame == world or tf_buf.is_static(world, poses.header_frame)):
        notes.append(
            f"velocities omitted: the odometry frame '{poses.header_frame}' moves relative to the world frame '{world}'"
        )
        return None
    # nav_msgs/Odometry: the twist is in the child frame C; R_wc includes the (static) R_wh
    twist = poses.twist[use]
    v_w = np.einsum("nij,nj->ni", R_wc, twist[:, :3])
    w_w = np.einsum("nij,nj->ni", R_wc, twist[:, 3:])
    v_b = v_w + np.cross(w_w, p_wb - p_wc)
    return np.column_stack([v_b[:, 0], v_b[:, 1], w_w[:, 2]])


def _cart_wrench(t: np.ndarray, tw: np.ndarray, f_w: np.ndarray, m_o: np.ndarray, p_wb: np.ndarray) -> np.ndarray:
    """Return (fx, fy, tau) at the pose times: the wrench interpolated, its torque about the {b} origin."""
    F = np.column_stack([np.interp(t, tw, f_w[:, k]) for k in range(3)])
    M = np.column_stack([np.interp(t, tw, m_o[:, k]) for k in range(3)])
    tau = M[:, 2] - (p_wb[:, 0] * F[:, 1] - p_wb[:, 1] * F[:, 0])  # torque about the {b} origin, z component
    return np.column_stack([F[:, 0], F[:, 1], tau])


def _report_drops(dropped: dict[str, int], warns: list[str], notes: list[str]) -> None:
    """Add a warning per reason samples were dropped, and a note on poses outside the wrench's span."""
    warns.extend(f"dropped {n} {_DROP_REASONS[key]}" for key, n in dropped.items() if n and key in _DROP_REASONS)
    if dropped.get("pose_outside_wrench"):
        notes.append(
            f"{dropped['pose_outside_wrench']} pose sample(s) before the first or after the last wrench "
            f"sample were left out"
        )


def _tf_buffer(rec: _Recording, t0_ns: int, use_record_time: bool, notes: list[str]) -> TransformBuffer:
    """Return the TF buffer of the recording; note the links taken from TransformStamped topics."""
    tf_buf, extra_links = _build_tf(rec.tf, t0_ns, use_record_time)
    if extra_links:
        notes.append(f"TF links taken from TransformStamped topics: {'; '.join(extra_links)}")
    return tf_buf


class _CartPoses(NamedTuple):
    """The windowed pose samples, the world and cart frames, and the tracked and cart frames in the world."""

    poses: _Poses
    world: str
    cart: str
    R_wc: np.ndarray
    p_wc: np.ndarray
    R_wb: np.ndarray
    p_wb: np.ndarray
    valid: np.ndarray


def _cart_poses(
    rec: _Recording,
    pose_frame: str | None,
    world_frame: str | None,
    cart_frame: str | None,
    window: tuple[float | None, float | None],
    path: Any,
    pose_t_ns: np.ndarray,
    t0_ns: int,
    tf_buf: TransformBuffer,
    dropped: dict[str, int],
    notes: list[str],
) -> _CartPoses:
    """Return the pose samples in the window with {b} in the world frame; count those TF cannot place."""
    world = normalize_frame(world_frame) if world_frame else ""
    poses, world = _tracked_poses(rec, pose_frame, world, pose_t_ns, t0_ns, tf_buf, dropped, notes)
    poses = _window(poses, *window, path)
    cart = normalize_frame(cart_frame) if cart_frame else poses.child
    R_wc, p_wc, R_wb, p_wb, valid = _cart_in_world(poses, world, cart, tf_buf)
    dropped["pose_outside_tf"] = int(np.count_nonzero(~valid))
    return _CartPoses(poses, world, cart, R_wc, p_wc, R_wb, p_wb, valid)


def _wrench_on_cart(
    rec: _Recording,
    wrench_t_ns: np.ndarray,
    t0_ns: int,
    world: str,
    wrench_frame: str | None,
    tf_buf: TransformBuffer,
    dropped: dict[str, int],
    negate_wrench: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, list[str]]]:
    """Return `_wrench_in_world` of the wrench stream, its sign flipped with ``negate_wrench``."""
    tw, f_w, m_o, chains = _wrench_in_world(
        rec.wrench, rec.wrench_name, wrench_t_ns, t0_ns, world, wrench_frame, tf_buf, dropped
    )
    if negate_wrench:
        f_w, m_o = -f_w, -m_o
    return tw, f_w, m_o, chains


class _Samples(NamedTuple):
    """The cart log's columns at the kept pose stamps, and the largest tilt of {b} (degrees)."""

    t: np.ndarray
    q: np.ndarray
    gamma: np.ndarray
    qd: np.ndarray | None
    tilt_max: float


def _cart_samples(
    cp: _CartPoses,
    wrench: tuple[np.ndarray, np.ndarray, np.ndarray],
    tf_buf: TransformBuffer,
    dropped: dict[str, int],
    warns: list[str],
    notes: list[str],
    path: Any,
) -> _Samples:
    """Return the pose, wrench and (odometry) rates of {b} at the pose stamps the wrench covers."""
    tw, f_w, m_o = wrench
    use = _aligned(cp.poses.t, cp.valid, tw, dropped, path)
    t, R_wb, p_wb, R_wc, p_wc = cp.poses.t[use], cp.R_wb[use], cp.p_wb[use], cp.R_wc[use], cp.p_wc[use]
    gamma = _cart_wrench(t, tw, f_w, m_o, p_wb)
    theta, tilt_max = _planar_pose(t, R_wb, warns)
    qd = _odometry_velocities(cp.poses, use, cp.world, tf_buf, R_wc, p_wc, p_wb, notes)
    return _Samples(t, np.column_stack([p_wb[:, 0], p_wb[:, 1], theta]), gamma, qd, tilt_max)


def _import_report(
    path: Any,
    rec: _Recording,
    cp: _CartPoses,
    s: _Samples,
    t0_ns: int,
    clock: str,
    chains: dict[str, list[str]],
    negate_wrench: bool,
    window: tuple[float | None, float | None],
    dropped: dict[str, int],
    notes: list[str],
) -> ImportReport:
    """Return the report of an import, without warnings (the log's are added once it exists)."""
    return ImportReport(
        bag=str(path),
        storage=rec.storage,
        samples=len(s.t),
        duration=float(s.t[-1] - s.t[0]),
        t0_ns=int(t0_ns),
        clock=clock,
        pose_source=cp.poses.source,
        pose_type=cp.poses.msgtype,
        wrench_topic=rec.wrench_name,
        wrench_type=rec.wrench.msgtype,
        world_frame=cp.world,
        cart_frame=cp.cart,
        wrench_frames=tuple(chains),
        tf_chains=chains,
        negate_wrench=bool(negate_wrench),
        window=window,
        dropped=dropped,
        tilt_max_deg=s.tilt_max,
        has_velocities=s.qd is not None,
        notes=tuple(notes),
    )


def _cart_log(report: ImportReport, t0_ns: int, cart: str, s: _Samples) -> CartLog:
    """Return the cart log of an import, its metadata (docs/log_format.md) taken from `report`."""
    metadata = {
        "source": "ROS bag",
        "bag": report.bag,
        "pose": report.pose_source,
        "wrench": report.wrench_topic,
        "world_frame": report.world_frame,
        "cart_frame": cart or "-",
        "clock": report.clock,
        "t0_unix_ns": str(t0_ns),
        "negate_wrench": str(report.negate_wrench).lower(),
    }
    return CartLog(t=s.t, q=s.q, gamma=s.gamma, qd=s.qd, metadata=metadata, source=report.bag)


def import_bag(
    path: str | os.PathLike,
    pose_topic: str | None = None,
    wrench_topic: str | None = None,
    pose_frame: str | None = None,
    world_frame: str | None = None,
    negate_wrench: bool = False,
    start: float | None = None,
    end: float | None = None,
    use_record_time: bool = False,
    cart_frame: str | None = None,
    wrench_frame: str | None = None,
) -> tuple[CartLog, ImportReport]:
    """Return (cart log, report) of a bag: the pose of {b} and the wrench on the cart, aligned on the pose stamps.

    ``pose_topic`` or ``pose_frame`` (a TF child frame) gives the pose; ``wrench_topic`` the wrench,
    in its header's frame (``wrench_frame`` overrides it, e.g. when the header names none);
    ``world_frame`` the world frame {s} (default: the pose messages' frame, or the root of
    ``pose_frame``'s TF tree); ``cart_frame`` the TF frame that is {b} when the tracked body's frame
    is not; ``start``/``end`` a window in seconds from the start of the recording;
    ``use_record_time`` the recorder's receive times instead of header stamps.
    Raises BagImportError (TransformLookupError for TF) on bad input, FileNotFoundError for a missing path.
    """
    bag = _Bag(path)  # a bag at all? (before the options, which only make sense for one)
    wrench_topic = _check_request(path, pose_topic, pose_frame, wrench_topic, start, end)
    clock = "record" if use_record_time else "header"
    notes: list[str] = []
    warns: list[str] = []
    dropped: dict[str, int] = {}
    rec = _read_recording(bag, pose_topic, wrench_topic)
    pose_t_ns, wrench_t_ns, t0_ns = _clock(rec, use_record_time, notes)
    tf_buf = _tf_buffer(rec, t0_ns, use_record_time, notes)
    cp = _cart_poses(
        rec, pose_frame, world_frame, cart_frame, (start, end), path, pose_t_ns, t0_ns, tf_buf, dropped, notes
    )
    tw, f_w, m_o, chains = _wrench_on_cart(
        rec, wrench_t_ns, t0_ns, cp.world, wrench_frame, tf_buf, dropped, negate_wrench
    )
    s = _cart_samples(cp, (tw, f_w, m_o), tf_buf, dropped, warns, notes, path)
    _report_drops(dropped, warns, notes)
    report = _import_report(path, rec, cp, s, t0_ns, clock, chains, negate_wrench, (start, end), dropped, notes)
    log = _cart_log(report, t0_ns, cp.cart, s)
    warns.extend(plausibility_warnings(log))
    object.__setattr__(log, "warnings", tuple(warns))
    return log, replace(report, warnings=tuple(warns))


def load_any(path: str | os.PathLike, **topic_options: Any) -> CartLog:
    """Return the cart log of ``path``: a bag converted in memory (`import_bag` with ``topic_options``), else a CSV.

    Options that are None are ignored, so a command can pass all of its topic options through.
    """
    options = {k: v for k, v in topic_options.items() if v is not None and v is not False}
    if is_bag(path):
        return import_bag(path, **options)[0]
    if options:
        raise BagImportError(
            f"{path}: {', '.join(sorted(options))} apply to ROS bags only; this is a cart log "
            f"(a .bag, .mcap or .db3 file or a ROS 2 bag folder is converted)"
        )
    return read_log(path)

"""ROS recordings as cart logs: ROS 1 bags, ROS 2 bags (sqlite3, MCAP) and .mcap files, read with `rosbags`.

``import_bag(path, pose_topic=..., wrench_topic=...)`` returns ``(CartLog, ImportReport)``;
``list_bag(path)`` what a bag holds; ``load_any(path, **topic_options)`` a CSV or a bag;
``TransformBuffer`` the TF tree (static + dynamic links, interpolated along chains of any length).
See docs/ros_import.md.
"""

from __future__ import annotations

from cartpush.ros.bag_import import (
    POSE_TYPES,
    WRENCH_TYPES,
    BagSummary,
    ImportReport,
    TopicSummary,
    import_bag,
    is_bag,
    list_bag,
    load_any,
)
from cartpush.ros.errors import BagImportError, TransformLookupError
from cartpush.ros.tf_tree import EdgeInfo, TransformBuffer, normalize_frame

__all__ = [
    "BagImportError",
    "BagSummary",
    "EdgeInfo",
    "ImportReport",
    "POSE_TYPES",
    "TopicSummary",
    "TransformBuffer",
    "TransformLookupError",
    "WRENCH_TYPES",
    "import_bag",
    "is_bag",
    "list_bag",
    "load_any",
    "normalize_frame",
]

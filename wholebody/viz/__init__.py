"""Meshcat scenes: robots, the cart, contacts, wrenches, CoM markers, traces, animations, offline pages.

>>> from wholebody.viz import Scene
>>> scene = Scene(["ridgeback_iiwa", "shopping_cart"])    # doctest: +SKIP
>>> scene.save_html("push.html")                          # doctest: +SKIP
"""

from __future__ import annotations

from wholebody.viz.scene import (
    COLORS,
    COM_MARKER_Z,
    DEFAULT_CART_POSE,
    FLOOR,
    FORCE_SCALE,
    MAX_FLOOR_LINES,
    MAX_FRAMES,
    Camera,
    Scene,
    SceneError,
    cart_to_world_traj,
    cover_floor,
    frame_points,
    log_scene,
    robot_scene,
)

__all__ = [
    "COLORS",
    "COM_MARKER_Z",
    "DEFAULT_CART_POSE",
    "FLOOR",
    "FORCE_SCALE",
    "MAX_FLOOR_LINES",
    "MAX_FRAMES",
    "Camera",
    "Scene",
    "SceneError",
    "cart_to_world_traj",
    "cover_floor",
    "frame_points",
    "log_scene",
    "robot_scene",
]

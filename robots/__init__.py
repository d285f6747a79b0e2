"""Robot and cart models: profiles (TOML), one registry, and `load(name | profile.toml)` -> Pinocchio model.

>>> import robots
>>> robots.available()
('ridgeback_iiwa', 'shopping_cart', 'wmra')
>>> wmra = robots.load("wmra")
>>> wmra.model.nv
16

A robot of your own is a profile file (docs/robots.md): ``robots.load("my_robot.toml")``, or
``robots.register("my_robot.toml")`` and then ``robots.load("my_robot")``.
"""

from __future__ import annotations

from robots.errors import ProfileError, RobotError, UnknownRobotError
from robots.loading import DATA_DIR, LoadedRobot, available, load, urdf_path
from robots.profiles import ArmProfile, RobotProfile, parse_profile, profile, read_profile
from robots.registry import example_profile, examples, register, resolve, unregister
from robots.ridgeback_iiwa import ridgeback_iiwa_urdf
from robots.shopping_cart import shopping_cart_urdf
from robots.wmra import WmraBuild, wmra_urdf

__all__ = [
    "DATA_DIR",
    "ArmProfile",
    "LoadedRobot",
    "ProfileError",
    "RobotError",
    "RobotProfile",
    "UnknownRobotError",
    "WmraBuild",
    "available",
    "example_profile",
    "examples",
    "load",
    "parse_profile",
    "profile",
    "read_profile",
    "register",
    "resolve",
    "ridgeback_iiwa_urdf",
    "shopping_cart_urdf",
    "unregister",
    "urdf_path",
    "wmra_urdf",
]

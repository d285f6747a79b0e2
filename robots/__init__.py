"""Robot and cart models (URDF) and `load(name)` -> Pinocchio model.

>>> import robots
>>> robots.available()
('ridgeback_iiwa', 'shopping_cart', 'wmra')
>>> wmra = robots.load("wmra")
>>> wmra.model.nv
14
"""

from __future__ import annotations

from robots.loading import DATA_DIR, LoadedRobot, available, load, urdf_path
from robots.ridgeback_iiwa import ridgeback_iiwa_urdf
from robots.shopping_cart import shopping_cart_urdf
from robots.wmra import WmraBuild, wmra_urdf

__all__ = [
    "DATA_DIR",
    "LoadedRobot",
    "WmraBuild",
    "available",
    "load",
    "ridgeback_iiwa_urdf",
    "shopping_cart_urdf",
    "urdf_path",
    "wmra_urdf",
]

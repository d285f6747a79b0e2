"""A medium shopping cart (about 15 kg empty): fixed rear wheels, swivel casters in front.

Frame `b` (docs/log_format.md): origin at the midpoint of the fixed rear axle, x
forward, z up; the handle is behind it (negative x). Dimensions are estimates
within the ranges of robots/README.md (no public drawing exists).
"""

from __future__ import annotations

import math

from robots.urdf_text import Shape, box_inertial, combine, cylinder_inertial, joint, link, robot

CART_WHEEL_RADIUS = 0.0635  # 5-inch wheels
CART_REAR_HALF_TRACK = 0.25
CART_FRONT_HALF_TRACK = 0.20
CART_WHEELBASE = 0.75
CART_CASTER_TRAIL = 0.03
#: Handle: a horizontal bar 0.50 m wide, 1.0 m above the floor, 0.15 m behind the rear axle.
CART_HANDLE_X = -0.15
CART_HANDLE_HEIGHT = 1.0
CART_HANDLE_WIDTH = 0.50
CART_HANDLE_Z_B = CART_HANDLE_HEIGHT - CART_WHEEL_RADIUS
#: Part masses (kg) and their centres in frame b; the sum is the empty cart, 15.0 kg.
CART_PARTS = {
    "chassis": (3.6, (0.90, 0.45, 0.03), (0.35, 0.0, 0.06)),
    "basket": (8.0, (0.85, 0.52, 0.40), (0.40, 0.0, 0.62)),
    "uprights": (0.8, (0.04, 0.50, 0.45), (-0.10, 0.0, 0.62)),
}
CART_HANDLE_MASS = 0.8
CART_REAR_WHEEL_MASS = 0.35
CART_CASTER_FORK_MASS = 0.2
CART_CASTER_WHEEL_MASS = 0.35
CART_WHEEL_WIDTH = 0.03


#: Wheel joint orientation: local z = +y, so a positive rate rolls forward.
_WHEEL_RPY = (-math.pi / 2, 0.0, 0.0)
#: Height of a caster's swivel axis above the rear axle (frame b), metres.
_FORK_Z = 0.06


def _wheel_shape() -> tuple[Shape, ...]:
    """Return the visual/collision shape shared by every cart wheel."""
    return (Shape("cylinder", (CART_WHEEL_RADIUS, CART_WHEEL_WIDTH), material="dark"),)


def _body() -> list[str]:
    """Return the floor link `cart_footprint` and the cart body `b` (chassis, basket, uprights) at axle height."""
    shapes, inertials = [], []
    for name, (mass, size, centre) in CART_PARTS.items():
        inertials.append(box_inertial(mass, size, com=centre))
        shapes.append(Shape("box", size, centre, material="silver" if name != "chassis" else "dark"))
    return [
        link("cart_footprint"),
        link("b", combine(inertials), tuple(shapes)),
        joint("b_joint", "fixed", "cart_footprint", "b", xyz=(0, 0, CART_WHEEL_RADIUS)),
    ]


def _handle() -> list[str]:
    """Return the `handle` bar (origin at its midpoint, local y along the bar) fixed to `b`."""
    return [
        link(
            "handle",
            cylinder_inertial(CART_HANDLE_MASS, 0.015, CART_HANDLE_WIDTH, axis="y"),
            (Shape("cylinder", (0.015, CART_HANDLE_WIDTH), rpy=(-math.pi / 2, 0, 0), material="red"),),
        ),
        joint("handle_joint", "fixed", "b", "handle", xyz=(CART_HANDLE_X, 0, CART_HANDLE_Z_B)),
    ]


def _rear_wheel(side: str, sy: float) -> list[str]:
    """Return the fixed-axle rear wheel on `side` (sy = +1 left, -1 right)."""
    return [
        link(
            f"rear_{side}_wheel",
            cylinder_inertial(CART_REAR_WHEEL_MASS, CART_WHEEL_RADIUS, CART_WHEEL_WIDTH),
            _wheel_shape(),
        ),
        joint(
            f"rear_{side}_wheel_joint",
            "continuous",
            "b",
            f"rear_{side}_wheel",
            xyz=(0, sy * CART_REAR_HALF_TRACK, 0),
            rpy=_WHEEL_RPY,
            limit=(0, 0, 0.0, 50.0),
        ),
    ]


def _caster(side: str, sy: float) -> list[str]:
    """Return the front swivel caster on `side` (sy = +1 left, -1 right): fork on a swivel joint, then its wheel."""
    return [
        link(
            f"caster_{side}_fork",
            box_inertial(CART_CASTER_FORK_MASS, (0.04, 0.04, 0.08), com=(-CART_CASTER_TRAIL / 2, 0, -0.02)),
            (Shape("box", (0.04, 0.04, 0.08), (-CART_CASTER_TRAIL / 2, 0, -0.02), material="grey"),),
        ),
        joint(
            f"caster_{side}_swivel",
            "continuous",
            "b",
            f"caster_{side}_fork",
            xyz=(CART_WHEELBASE + CART_CASTER_TRAIL, sy * CART_FRONT_HALF_TRACK, _FORK_Z),
            limit=(0, 0, 0.0, 50.0),
        ),
        link(
            f"caster_{side}_wheel",
            cylinder_inertial(CART_CASTER_WHEEL_MASS, CART_WHEEL_RADIUS, CART_WHEEL_WIDTH),
            _wheel_shape(),
        ),
        joint(
            f"caster_{side}_wheel_joint",
            "continuous",
            f"caster_{side}_fork",
            f"caster_{side}_wheel",
            xyz=(-CART_CASTER_TRAIL, 0, -_FORK_Z),
            rpy=_WHEEL_RPY,
            limit=(0, 0, 0.0, 50.0),
        ),
    ]


def shopping_cart_urdf() -> str:
    """Return the URDF text of the shopping cart (root `cart_footprint` on the floor, frame `b`, link `handle`).

    The `handle` link's origin is the handle's midpoint; its local y axis is the
    segment of candidate contact points, y in [-W/2, W/2].
    """
    parts = _body() + _handle()
    for side, sy in (("left", 1.0), ("right", -1.0)):
        parts += _rear_wheel(side, sy) + _caster(side, sy)
    return robot("shopping_cart", "".join(parts))

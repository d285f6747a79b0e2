"""A medium shopping cart (about 15 kg empty): fixed rear wheels, swivel casters in front.

Frame `b` (LOG_FORMAT.md): origin at the midpoint of the fixed rear axle, x
forward, z up; the handle is behind it (negative x). Dimensions are estimates
within the ranges of robots/README.md (no public drawing exists).
"""

from __future__ import annotations

import math

from robots.urdf_text import Shape, box_inertial, cylinder_inertial, joint, link, robot

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


def shopping_cart_urdf() -> str:
    """Return the URDF text of the shopping cart (root `cart_footprint` on the floor, frame `b`, link `handle`).

    The `handle` link's origin is the handle's midpoint; its local y axis is the
    segment of candidate contact points, y in [-W/2, W/2].
    """
    parts = [link("cart_footprint")]
    shapes, inertials = [], []
    for name, (mass, size, centre) in CART_PARTS.items():
        inertials.append(box_inertial(mass, size, com=centre))
        shapes.append(Shape("box", size, centre, material="silver" if name != "chassis" else "dark"))
    from robots.urdf_text import combine

    parts.append(link("b", combine(inertials), tuple(shapes)))
    parts.append(joint("b_joint", "fixed", "cart_footprint", "b", xyz=(0, 0, CART_WHEEL_RADIUS)))
    parts.append(
        link(
            "handle",
            cylinder_inertial(CART_HANDLE_MASS, 0.015, CART_HANDLE_WIDTH, axis="y"),
            (Shape("cylinder", (0.015, CART_HANDLE_WIDTH), rpy=(-math.pi / 2, 0, 0), material="red"),),
        )
    )
    parts.append(joint("handle_joint", "fixed", "b", "handle", xyz=(CART_HANDLE_X, 0, CART_HANDLE_Z_B)))
    wheel_rpy = (-math.pi / 2, 0.0, 0.0)
    wheel_shape = (Shape("cylinder", (CART_WHEEL_RADIUS, CART_WHEEL_WIDTH), material="dark"),)
    for side, sy in (("left", 1.0), ("right", -1.0)):
        parts.append(
            link(
                f"rear_{side}_wheel",
                cylinder_inertial(CART_REAR_WHEEL_MASS, CART_WHEEL_RADIUS, CART_WHEEL_WIDTH),
                wheel_shape,
            )
        )
        parts.append(
            joint(
                f"rear_{side}_wheel_joint",
                "continuous",
                "b",
                f"rear_{side}_wheel",
                xyz=(0, sy * CART_REAR_HALF_TRACK, 0),
                rpy=wheel_rpy,
                limit=(0, 0, 0.0, 50.0),
            )
        )
        fork_z = 0.06
        parts.append(
            link(
                f"caster_{side}_fork",
                box_inertial(CART_CASTER_FORK_MASS, (0.04, 0.04, 0.08), com=(-CART_CASTER_TRAIL / 2, 0, -0.02)),
                (Shape("box", (0.04, 0.04, 0.08), (-CART_CASTER_TRAIL / 2, 0, -0.02), material="grey"),),
            )
        )
        parts.append(
            joint(
                f"caster_{side}_swivel",
                "continuous",
                "b",
                f"caster_{side}_fork",
                xyz=(CART_WHEELBASE + CART_CASTER_TRAIL, sy * CART_FRONT_HALF_TRACK, fork_z),
                limit=(0, 0, 0.0, 50.0),
            )
        )
        parts.append(
            link(
                f"caster_{side}_wheel",
                cylinder_inertial(CART_CASTER_WHEEL_MASS, CART_WHEEL_RADIUS, CART_WHEEL_WIDTH),
                wheel_shape,
            )
        )
        parts.append(
            joint(
                f"caster_{side}_wheel_joint",
                "continuous",
                f"caster_{side}_fork",
                f"caster_{side}_wheel",
                xyz=(-CART_CASTER_TRAIL, 0, -fork_z),
                rpy=wheel_rpy,
                limit=(0, 0, 0.0, 50.0),
            )
        )
    return robot("shopping_cart", "".join(parts))

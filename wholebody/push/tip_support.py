"""The push controller's side of the tip-over bound (`wholebody.contacts.support`): the cart's support, its load.

`shopping_cart_support` is the default cart's floor contacts (`robots.shopping_cart`: fixed rear wheels, casters
that swivel about axes ``CART_CASTER_TRAIL`` ahead of their wheels); `cart_file_support` reads a cart file's wheels
(docs/mujoco.md's contract: hinge-jointed spheres or cylinders on the floor; a wheel below a vertical hinge is a
caster whose contact moves on a circle about that axis). `cart_load` is what the estimate says the cart puts on its
support this period: mass, CoM and the CoM's acceleration under the desired wrench (cart paper eq. 4).
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

import numpy as np

from cart import model as cart_model
from cart.params import CartParams
from wholebody.contacts.support import CartLoad, SupportPolygon
from wholebody.errors import WholeBodyError
from wholebody.push.geometry import CartGeometry

if TYPE_CHECKING:
    import mujoco


def shopping_cart_support(geometry: CartGeometry) -> SupportPolygon:
    """Return the default shopping cart's support: rear wheels, casters (their trail as radius), CoM below the handle."""
    from robots import shopping_cart as sc

    swivel_x = sc.CART_WHEELBASE + sc.CART_CASTER_TRAIL
    points = (
        (0.0, sc.CART_REAR_HALF_TRACK),
        (0.0, -sc.CART_REAR_HALF_TRACK),
        (swivel_x, sc.CART_FRONT_HALF_TRACK),
        (swivel_x, -sc.CART_FRONT_HALF_TRACK),
    )
    radius = (0.0, 0.0, sc.CART_CASTER_TRAIL, sc.CART_CASTER_TRAIL)
    return SupportPolygon(points, -geometry.frame_height, com_bound(geometry), radius)


def com_bound(geometry: CartGeometry) -> float:
    """Return the bound of the CoM's height above the floor: the handle's height (a pushed cart's mass sits below it)."""
    zs = [geometry.handle.start_b[2], geometry.handle.end_b[2], *(p[2] for p in geometry.grip_points or ())]
    return float(max(zs) + geometry.frame_height)


def cart_load(
    q: np.ndarray, qd: np.ndarray, gamma: np.ndarray, params: CartParams, std: dict | None, std_factor: float
) -> CartLoad:
    """Return the cart's load on its support: the estimate's mass and CoM, the CoM's acceleration in {b}.

    The acceleration is the model's under `gamma` (eq. 4): the {b} origin's plus ``alpha x c - omega^2 c``, in
    {b}; `std`: the estimator's 1-sigma (``params_std()``: "mass", "com" (dx, dy)); None: no margin.
    """
    qdd = cart_model.forward_dynamics(q, qd, gamma, params)
    c, s = math.cos(q[2]), math.sin(q[2])
    R = np.array([[c, -s], [s, c]])
    rc = R @ np.array([params.dx, params.dy])
    a = qdd[:2] + qdd[2] * np.array([-rc[1], rc[0]]) - qd[2] ** 2 * rc
    a_b = R.T @ a
    sd = np.zeros(3) if std is None else finite_or_zero(np.array([std["mass"], *std["com"]], dtype=float))
    return CartLoad(
        float(params.m),
        (float(params.dx), float(params.dy)),
        (float(a_b[0]), float(a_b[1])),
        float(sd[0]),
        (float(sd[1]), float(sd[2])),
        std_factor,
    )


def finite_or_zero(values: np.ndarray) -> np.ndarray:
    """Return ``np.nan_to_num(values, nan=0.0)``: `values` itself when all are finite (the usual case, cheaper)."""
    return values if np.isfinite(values).all() else np.nan_to_num(values, nan=0.0)


def cart_file_support(path: str | os.PathLike, geometry: CartGeometry) -> SupportPolygon | None:
    """Return a cart file's support from its wheels standing on the floor, or None when it has fewer than three."""
    import mujoco

    from wholebody.push import mujoco_cart
    from wholebody.push.cart_file import load_cart_file

    source = load_cart_file(path)
    spec = source.spec()
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cart = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, mujoco_cart.CART_BODY)
    floor = float(data.xpos[cart][2]) - source.z  # the file stands {b} at source.z above its floor
    pts, radii = _wheel_contacts(model, data, cart, floor)
    if len(pts) < 3:
        return None
    try:
        return SupportPolygon(tuple(pts), -source.z, com_bound(geometry), tuple(radii))
    except WholeBodyError:  # collinear wheels: no polygon to bound
        return None


def _wheel_contacts(
    model: mujoco.MjModel, data: mujoco.MjData, cart: int, floor: float
) -> tuple[list[tuple[float, float]], list[float]]:
    """Return the (x, y) in {b} of each wheel's lowest point and its swivel radius (0 for a fixed wheel)."""
    import mujoco

    from wholebody.push import mujoco_cart

    R, p = data.xmat[cart].reshape(3, 3), data.xpos[cart]
    pts: list[tuple[float, float]] = []
    radii: list[float] = []
    wheels = mujoco_cart.rolling_wheels(model, data, cart, floor_z=floor)
    for name in wheels:
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        contact = R.T @ (np.array([data.xpos[b][0], data.xpos[b][1], floor]) - p)
        pts.append((float(contact[0]), float(contact[1])))
        radii.append(_swivel_radius(model, data, b, cart, contact, R, p))
    return pts, radii


def _swivel_radius(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    body: int,
    cart: int,
    contact_b: np.ndarray,
    R: np.ndarray,
    p: np.ndarray,
) -> float:
    """Return the horizontal distance from a wheel's contact to the vertical hinge it swivels on (0: none)."""
    import mujoco

    b = int(model.body_parentid[body])
    while b not in (cart, 0):
        for j in range(int(model.body_jntadr[b]), int(model.body_jntadr[b] + model.body_jntnum[b])):
            if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE) and abs(float(data.xaxis[j][2])) > 0.99:
                axis_b = R.T @ (data.xanchor[j] - p)
                return float(np.hypot(*(axis_b[:2] - contact_b[:2])))
        b = int(model.body_parentid[b])
    return 0.0

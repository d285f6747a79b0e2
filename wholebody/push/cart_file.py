"""Cart files: any MJCF cart that follows the contract below can be pushed by the MuJoCo plant.

The contract (also in docs/mujoco.md):

1. one body named ``cart`` with a free joint; its frame is {b} (x forward, z up) and the cart's
   planar pose is this frame's x, y and yaw; the body's ``pos`` z is the height of {b} when the cart
   stands on the floor;
2. sites on ``cart`` named ``handle`` or ``handle_*`` mark where hands may hold: a point site
   (type sphere, the default) is a grip point; a capsule site (declared with ``fromto``) is a bar that
   may be held anywhere along its axis; at least one such site;
3. the file may contain a floor (the lowest plane in the worldbody whose normal points up,
   `mujoco_cart.floor_plane`); if none, the plant adds one at z = 0 (a cart on a box floor: its top at z = 0);
4. everything else is the file's own (wheels, joints, friction, options); the controller never reads
   the cart's inertial parameters from it (the run reports them as the truth);
5. every mass, inertia and density is a finite number >= 0 (MuJoCo itself drops a negative ``<inertial mass>``
   silently), and the cart weighs what a push handles (`config.CART_MASS_RANGE_KG`, each of its bodies too).

A file that breaks the contract raises :class:`CartFileError` with one line naming what is missing.
:func:`cart_source` also wraps the project's own carts (`CartParams` -> the shopping cart,
`MujocoCart`) behind the same :class:`CartSource` interface.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from cart.params import CartParams
from wholebody.errors import WholeBodyError
from wholebody.push import mujoco_cart

#: prefix of the handle sites' names
HANDLE_PREFIX = "handle"


class CartFileError(WholeBodyError):
    """A cart file that MuJoCo cannot read or that breaks the cart-file contract (docs/mujoco.md)."""


@dataclass(frozen=True)
class HandleSite:
    """A place on the cart where a hand may hold, in {b}: a point (start == end) or a bar from start to end."""

    name: str
    start_b: np.ndarray
    end_b: np.ndarray

    @property
    def is_bar(self) -> bool:
        """Return True for a bar (a capsule site), False for a grip point."""
        return bool(np.linalg.norm(self.end_b - self.start_b) > 1e-9)

    def closest(self, p_b: np.ndarray) -> np.ndarray:
        """Return the point of the handle closest to `p_b` (in {b})."""
        a, b = self.start_b, self.end_b
        ab = b - a
        L2 = float(ab @ ab)
        s = 0.0 if L2 < 1e-18 else float(np.clip((np.asarray(p_b) - a) @ ab / L2, 0.0, 1.0))
        return a + s * ab


@dataclass(frozen=True)
class CartSource:
    """A cart the plant can put in its scene: a fresh spec on demand, {b}'s standing height, handles, wheels."""

    label: str
    make_spec: Callable[[], mujoco.MjSpec]
    #: height of {b} above the floor when the cart stands
    z: float
    handles: tuple[HandleSite, ...]
    #: {wheel body: (spin inertia, rolling radius)} of a compiled scene at rest (None: found by shape)
    named_wheels: tuple[str, ...] | None = None
    #: the cart's plan extent in {b} (`plan_extent`): (x min, x max, y min, y max) m; None: not known
    extent: tuple[float, float, float, float] | None = None
    #: the cart's mass (kg, every body of its subtree); None: not known
    mass: float | None = None

    def spec(self) -> mujoco.MjSpec:
        """Return a new spec of the cart (the scene is composed onto it)."""
        return self.make_spec()

    def distance_to_handle(self, p_b: np.ndarray) -> tuple[float, str]:
        """Return (distance from `p_b` to the closest handle site, that site's name)."""
        best = min(self.handles, key=lambda h: float(np.linalg.norm(h.closest(p_b) - p_b)))
        return float(np.linalg.norm(best.closest(p_b) - p_b)), best.name

    def wheels(self, model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, tuple[float, float]]:
        """Return the cart's wheels {body: (spin inertia, rolling radius)} in a compiled scene (after settling)."""
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, mujoco_cart.CART_BODY)
        if self.named_wheels is not None:
            return mujoco_cart.wheel_spin_inertias(model)
        return mujoco_cart.rolling_wheels(model, data, bid, floor_z=_floor_z(model))


def _floor_z(model: mujoco.MjModel) -> float:
    """Return the height of the floor (`mujoco_cart.floor_plane`; 0 without one: the plane the scene adds)."""
    floor = mujoco_cart.floor_plane(model)
    return float(model.geom_pos[floor][2]) if floor is not None else 0.0


def _floor_bits(model: mujoco.MjModel) -> tuple[int, int]:
    """Return (contype, conaffinity) of the floor (`mujoco_cart.floor_plane`), or (1, 1), the plane the scene adds
    when the file has none (`mujoco_scene`)."""
    floor = mujoco_cart.floor_plane(model)
    if floor is None:
        return 1, 1
    return int(model.geom_contype[floor]), int(model.geom_conaffinity[floor])


def _collides_with_floor(model: mujoco.MjModel, g: int, floor: tuple[int, int]) -> bool:
    """Return whether geom `g` and a floor of (contype, conaffinity) `floor` make contacts (MuJoCo's bit test)."""
    return bool(int(model.geom_contype[g]) & floor[1]) or bool(floor[0] & int(model.geom_conaffinity[g]))


def _project_cart(cart: mujoco_cart.MujocoCart, label: str) -> CartSource:
    """Return the source of one of the project's MuJoCo carts (its handle bar or point from the cart's fields)."""
    hx, hy, hz, w = -cart.handle_distance, cart.handle_y, cart.handle_height, cart.handle_width / 2
    handle = HandleSite(cart.handle_site, np.array([hx, hy - w, hz]), np.array([hx, hy + w, hz]))
    xml = mujoco_cart.mjcf(cart)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, mujoco_cart.CART_BODY)
    return CartSource(
        label=label,
        make_spec=lambda: mujoco.MjSpec.from_string(xml),
        z=cart.wheel_radius,
        handles=(handle,),
        named_wheels=mujoco_cart.WHEEL_BODIES,
        extent=plan_extent(model, data, bid),
        mass=float(model.body_subtreemass[bid]),
    )


def plan_extent(model: mujoco.MjModel, data: mujoco.MjData, cart: int) -> tuple[float, float, float, float]:
    """Return (x min, x max, y min, y max) m in {b} of the bounding boxes of every geom of the cart's subtree (after
    `mj_kinematics`): where on the cart a load can be put."""
    R, p = data.xmat[cart].reshape(3, 3), data.xpos[cart]
    pts = [
        mujoco_cart.geom_corners(model, data, int(g))
        for b in mujoco_cart.subtree_bodies(model, cart)
        for g in range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b]))
    ]
    if not pts:
        return (0.0, 0.0, 0.0, 0.0)
    xy = ((np.concatenate(pts) - p) @ R)[:, :2]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


@contextmanager
def mujoco_warnings() -> Iterator[list[str]]:
    """Collect MuJoCo's warnings into the yielded list while the block runs, instead of its default handler's line
    on stderr and in MUJOCO_LOG.TXT of the working directory (an unstable step warns at every step). An enclosing
    block's collector gets them too; the previous handler is put back after."""
    previous = mujoco.get_mju_user_warning()
    got: list[str] = []

    def collect(message: str) -> None:
        got.append(str(message).strip())
        if callable(previous):
            previous(message)

    mujoco.set_mju_user_warning(collect)
    try:
        yield got
    finally:
        mujoco.set_mju_user_warning(previous)


def warnings_summary(warnings: list[str]) -> str:
    """Return one line saying how often MuJoCo warned and its distinct warnings (the step's time left out)."""
    kinds = list(dict.fromkeys(w.split(" Time = ")[0] for w in warnings))
    more = f" (and {len(kinds) - 3} more kinds)" if len(kinds) > 3 else ""
    return f"MuJoCo warned {len(warnings)} time(s): {'; '.join(kinds[:3])}{more}"


def _first_line(exc: BaseException) -> str:
    """Return MuJoCo's message: its first line, and the line naming the element or the XML error's place."""
    text = [line.strip() for line in str(exc).strip().splitlines() if line.strip()]
    if not text:
        return type(exc).__name__
    where = [line for line in text[1:] if line.startswith(("Element", "XML_ERROR", "Error=XML"))]
    return "; ".join(text[:1] + where[:1])


def _read(path: Path) -> tuple[mujoco.MjSpec, mujoco.MjModel, list[str]]:
    """Return (spec, compiled model, MuJoCo's warnings while reading) of a file, or raise CartFileError with MuJoCo's
    message."""
    if path.is_dir():
        raise CartFileError(f"cart file {path}: is a directory; give the MJCF file")
    if not path.is_file():
        raise CartFileError(f"cart file {path}: no such file")
    try:
        with mujoco_warnings() as warned:
            spec = mujoco.MjSpec.from_file(str(path))
            model = spec.compile()
    except (ValueError, RuntimeError) as exc:
        if "could not find decoder" in str(exc):  # MuJoCo reads a model by its file's extension
            raise CartFileError(
                f"cart file {path}: MuJoCo reads {path.suffix or 'a file without extension'!r} as no model format; a "
                "cart file is MJCF XML ending in .xml"
            ) from None
        raise CartFileError(f"cart file {path}: not a valid MuJoCo model: {_first_line(exc)}") from None
    return spec, model, warned


def _bad_number(values: object, negative_ok: bool = False) -> bool:
    """Return whether any of `values` is not finite or (unless `negative_ok`) negative."""
    a = np.atleast_1d(np.asarray(values, dtype=float))
    return bool(not np.all(np.isfinite(a)) or (not negative_ok and np.any(a < 0.0)))


def _check_inertials(path: Path, spec: mujoco.MjSpec, model: mujoco.MjModel) -> None:
    """Raise naming the body when a mass, inertia, density or centre of mass of the file is negative or not finite:
    MuJoCo drops a negative ``<inertial mass>`` silently (the body then weighs nothing) and reads NaN or inf as a
    number (the simulation then blows up)."""
    for body in spec.bodies:
        name = body.name or "an unnamed body"
        if body.explicitinertial and (_bad_number(body.mass) or _bad_number(body.inertia)):
            raise CartFileError(
                f"cart file {path}: body {name!r} has an <inertial> of mass {body.mass:g} kg and diagonal inertia "
                f"({', '.join(f'{v:g}' for v in body.inertia)}) kg m^2; masses and inertias must be finite numbers >= 0"
            )
        for geom in body.geoms:
            mass_bad = not math.isnan(geom.mass) and _bad_number(geom.mass)  # NaN: not given (from the density)
            if mass_bad or _bad_number(geom.density):
                what = f"mass {geom.mass:g}" if mass_bad else f"density {geom.density:g}"
                raise CartFileError(
                    f"cart file {path}: a geom of body {name!r} has {what}; masses and densities must be finite "
                    "numbers >= 0 (kg, kg/m^3)"
                )
    for b in range(1, model.nbody):
        fields = (model.body_mass[b], model.body_inertia[b], model.body_ipos[b], model.body_pos[b])
        if any(_bad_number(v, negative_ok=True) for v in fields):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f"#{b}"
            raise CartFileError(
                f"cart file {path}: body {name!r} has a mass, inertia or position that is not a finite number "
                f"(mass {float(model.body_mass[b]):g} kg): give numbers, not nan or inf"
            )


def _check_cart_mass(path: Path, model: mujoco.MjModel, cart: int) -> float:
    """Return the cart's mass (kg, its subtree); raise unless it and each of its bodies are within the masses a push
    handles (`config.CART_MASS_RANGE_KG`: a cart of tons sinks into its soft contacts and tips)."""
    from wholebody.push.config import CART_MASS_RANGE_KG

    lo, hi = CART_MASS_RANGE_KG
    bodies = mujoco_cart.subtree_bodies(model, cart)
    heaviest = max(bodies, key=lambda b: float(model.body_mass[b]))
    total = float(model.body_subtreemass[cart])
    if float(model.body_mass[heaviest]) > hi or not lo <= total <= hi:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(heaviest)) or f"#{heaviest}"
        raise CartFileError(
            f"cart file {path}: the cart weighs {total:g} kg (its heaviest body {name!r}: "
            f"{float(model.body_mass[heaviest]):g} kg); a push handles carts of {lo:g} to {hi:g} kg"
        )
    return total


def _check_cart_body(path: Path, model: mujoco.MjModel) -> int:
    """Return the id of body ``cart``; it must exist and carry exactly one free joint."""
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, mujoco_cart.CART_BODY)
    if bid < 0:
        urdf = "<robot" in path.read_text(encoding="utf-8", errors="replace")[:4096]
        hint = " (it is a URDF; a cart file is MJCF: <mujoco> with a body 'cart' on a free joint)" if urdf else ""
        raise CartFileError(f"cart file {path}: no body named 'cart'{hint}")
    joints = range(int(model.body_jntadr[bid]), int(model.body_jntadr[bid] + model.body_jntnum[bid]))
    if not any(int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_FREE) for j in joints):
        raise CartFileError(f"cart file {path}: body 'cart' has no free joint")
    return bid


def _moving_link(model: mujoco.MjModel, body: int, cart: int) -> str | None:
    """Return why a handle site's body does not move with ``cart`` (None when it is ``cart`` or fixed to it)."""
    b = body
    while b != cart:
        if b == 0:
            return "not on 'cart'"
        if int(model.body_jntnum[b]) > 0:
            joint = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, int(model.body_jntadr[b])) or "unnamed"
            return f"which moves relative to 'cart' (joint {joint!r})"
        b = int(model.body_parentid[b])
    return None


def _handle_sites(path: Path, model: mujoco.MjModel, data: mujoco.MjData, cart: int) -> tuple[HandleSite, ...]:
    """Return the handle sites of body ``cart`` (or of a body fixed to it) in {b}; raise on others or other shapes.
    ``data``: after `mj_kinematics` at qpos0 (a site's pose in {b} through any fixed child bodies)."""
    R_cart, p_cart = data.xmat[cart].reshape(3, 3), data.xpos[cart]
    handles = []
    for s in range(model.nsite):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) or ""
        if not (name == HANDLE_PREFIX or name.startswith(HANDLE_PREFIX + "_")):
            continue
        why = _moving_link(model, int(model.site_bodyid[s]), cart)
        if why is not None:
            owner = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.site_bodyid[s]))
            raise CartFileError(f"cart file {path}: handle site {name!r} is on body {owner!r}, {why}")
        pos = R_cart.T @ (data.site_xpos[s] - p_cart)
        kind = int(model.site_type[s])
        if kind == int(mujoco.mjtGeom.mjGEOM_SPHERE):
            handles.append(HandleSite(name, pos.copy(), pos.copy()))
        elif kind in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
            axis = R_cart.T @ data.site_xmat[s].reshape(3, 3)[:, 2] * float(model.site_size[s][1])
            handles.append(HandleSite(name, pos - axis, pos + axis))
        else:
            raise CartFileError(
                f"cart file {path}: handle site {name!r} is neither a point (sphere) nor a bar (capsule)"
            )
    if not handles:
        raise CartFileError(f"cart file {path}: body 'cart' has no site named 'handle' or 'handle_*'")
    return tuple(handles)


#: a wheel's cylinder axis within this angle (rad) of its hinge's rolls on it; one whose radius down from its centre
#: comes this close (m) to the floor is a wheel (`_check_wheels`)
WHEEL_AXIS_TOL = 0.1
FLOOR_TOUCH_M = 5e-3


def _angle_hint(degree: bool) -> str:
    """Return the likely unit mistake behind a turned wheel: radians read as degrees (MuJoCo's default unit) or,
    in a file with ``<compiler angle="radian"/>``, degrees read as radians."""
    if degree:
        return 'an euler meant in radians? MuJoCo reads degrees unless <compiler angle="radian"/>'
    return 'an euler meant in degrees? this file\'s <compiler angle="radian"/> makes MuJoCo read radians'


def _check_wheels(path: Path, model: mujoco.MjModel, data: mujoco.MjData, cart: int, degree: bool = True) -> None:
    """Raise when a cylinder on a horizontal hinge of the cart's subtree reaches the floor by its radius (a wheel,
    as `mujoco_cart.rolling_wheels` reads it) but its axis is not along the hinge: the cart stands on its rim or
    face and slides instead of rolling (a wheel turned by an ``euler`` in the wrong unit: `degree` tells the file's,
    ``MjSpec.compiler.degree``)."""
    floor = _floor_z(model)
    for b in mujoco_cart.subtree_bodies(model, cart):
        hinges = [
            j
            for j in range(int(model.body_jntadr[b]), int(model.body_jntadr[b] + model.body_jntnum[b]))
            if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE)
            and abs(float(data.xaxis[j][2])) <= math.sin(WHEEL_AXIS_TOL)
        ]
        for j in hinges:
            for g in range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b])):
                if int(model.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_CYLINDER):
                    continue
                a = data.geom_xmat[g].reshape(3, 3)[:, 2]
                radius_low = float(data.geom_xpos[g][2] - model.geom_size[g][0])  # as a wheel: its radius down
                angle = math.degrees(math.acos(min(1.0, abs(float(a @ data.xaxis[j])))))
                if radius_low - floor <= FLOOR_TOUCH_M and angle > math.degrees(WHEEL_AXIS_TOL):
                    body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(b))
                    joint = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
                    raise CartFileError(
                        f"cart file {path}: wheel {body!r} stands on a cylinder turned {angle:.0f} degrees from the axis "
                        f"of its hinge {joint!r}, so it slides instead of rolling ({_angle_hint(degree)}; or give the "
                        "cylinder's zaxis)"
                    )


#: handle sites within this distance (m) along x of the rearmost one are the rear group (`rear_handles`)
REAR_DEPTH = 0.10
#: a bar whose ends are at least this far apart along y runs across the cart (held anywhere along it)
ACROSS_MIN_M = 0.05


def rear_handles(handles: tuple[HandleSite, ...]) -> tuple[HandleSite, ...]:
    """Return the handle sites a robot pushing from behind holds: the rear group, its widest cross bar if any.

    The rear group is the sites whose rearmost point is within `REAR_DEPTH` of the rearmost site's (a bed's
    foot-end bar or a basket's front grip is left out). A bar in it running across the cart (along y) is held
    anywhere along it; otherwise the group's sites are grip points.
    """
    xs = [min(float(h.start_b[0]), float(h.end_b[0])) for h in handles]
    rear = tuple(h for h, x in zip(handles, xs) if x <= min(xs) + REAR_DEPTH)
    across = [h for h in rear if h.is_bar and abs(float(h.end_b[1] - h.start_b[1])) >= ACROSS_MIN_M]
    return (max(across, key=lambda h: abs(float(h.end_b[1] - h.start_b[1]))),) if across else rear


#: the largest angle (deg) between {b}'s axes and the world's at the start (x forward, z up, the trajectories' heading)
START_TILT_DEG = 1.0
#: the largest gap (m) between the cart's lowest collision geom and the floor at the start
FLOOR_GAP_M = 0.01
#: the largest distance (m) along x between {b} and the axle of the cart's fixed wheels
AXLE_OFFSET_M = 0.03


def _check_start_pose(path: Path, model: mujoco.MjModel, data: mujoco.MjData, cart: int) -> None:
    """Raise unless {b} starts level and heading along the world's x (the trajectories start heading +x) with the
    cart's lowest collision geom on the floor (a cart sunk into it is thrown up, one above it falls)."""
    R = data.xmat[cart].reshape(3, 3)
    yaw = math.degrees(math.atan2(float(R[1, 0]), float(R[0, 0])))
    tilt = math.degrees(math.acos(min(1.0, float(R[2, 2]))))
    if abs(yaw) > START_TILT_DEG or tilt > START_TILT_DEG:
        raise CartFileError(
            f"cart file {path}: body 'cart' starts turned {yaw:.0f} deg about z and tilted {tilt:.0f} deg; its frame "
            "{b} must start with x forward (the push's direction) and z up: turn its child bodies instead"
        )
    floor, bits = _floor_z(model), _floor_bits(model)
    low, loose = math.inf, []  # the lowest geom that stands on the floor; the geoms on it that pass through
    for b in mujoco_cart.subtree_bodies(model, cart):
        for g in range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b])):
            z = mujoco_cart.geom_lowest_z(model, data, g)
            if _collides_with_floor(model, g, bits):
                low = min(low, z)
            elif z - floor <= FLOOR_GAP_M:
                loose.append(g)
    plane = mujoco_cart.floor_plane(model)
    if bits == (0, 0) and plane is not None:
        raise CartFileError(
            f"cart file {path}: the floor plane {_geom_label(model, plane)} collides with nothing "
            '(contype and conaffinity 0: from a <default>?), so the cart falls through: give it contype="1" '
            'conaffinity="1"'
        )
    if (loose and not low - floor <= FLOOR_GAP_M) or not math.isfinite(low):
        names = ", ".join(_geom_label(model, g) for g in loose[:4]) or "none"
        raise CartFileError(
            f"cart file {path}: no geom of the cart on the floor collides with it (on it: {names}; MuJoCo makes a "
            "contact when one geom's contype shares a bit with the other's conaffinity, and the floor's are "
            f"{bits[0]}/{bits[1]}), so the cart falls through: give the wheels contype and conaffinity 1"
        )
    if plane is None:
        _check_floor_is_a_plane(path, model, data, cart, low)
    gap = low - floor
    if abs(gap) > FLOOR_GAP_M:
        where = "below" if gap < 0 else "above"
        raise CartFileError(
            f"cart file {path}: the cart's lowest collision geom is {abs(gap):.3f} m {where} the floor; set body "
            f"'cart' pos z to {float(data.xpos[cart][2]) - gap:.4g} so its wheels stand on it"
        )


def _check_floor_is_a_plane(path: Path, model: mujoco.MjModel, data: mujoco.MjData, cart: int, low: float) -> None:
    """Raise when a file without an up-facing floor plane stands the cart (its lowest collision geom at `low`) on
    the top of another world geom (a box floor), or sinks it into one under {b}, whose top is not at z = 0: the
    plane the scene adds at z = 0, which the robots stand on, would not be that floor."""
    xy = data.xpos[cart][:2]
    for g in range(model.ngeom):
        if int(model.geom_bodyid[g]) != 0 or int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_PLANE):
            continue
        corners = mujoco_cart.geom_corners(model, data, g)
        bottom, top = float(corners[:, 2].min()), float(corners[:, 2].max())
        under = bool(np.all(corners[:, :2].min(axis=0) <= xy) and np.all(xy <= corners[:, :2].max(axis=0)))
        on_top, sunk = abs(low - top) <= FLOOR_GAP_M, under and bottom - FLOOR_GAP_M <= low < top - FLOOR_GAP_M
        if (on_top or sunk) and abs(top) > FLOOR_GAP_M:
            raise CartFileError(
                f"cart file {path}: the cart stands {'on' if on_top else 'sunk in'} {_geom_label(model, g)}, whose top "
                f'is at z = {top:.4g} m, but the robots stand on a plane: give a <geom type="plane"> at z = {top:.4g} '
                "(or put that top at z = 0)"
            )


def _check_floor_height(path: Path, model: mujoco.MjModel) -> None:
    """Raise when the file's floor plane (`mujoco_cart.floor_plane`) is not at z = 0: the robots stand at z = 0."""
    z = _floor_z(model)
    if abs(z) > FLOOR_GAP_M:
        plane = mujoco_cart.floor_plane(model)
        label = _geom_label(model, plane) if plane is not None else "of the file"
        raise CartFileError(
            f"cart file {path}: the floor plane {label} is at z = {z:.4g} m, but the robots "
            f"stand on z = 0: put the floor at z = 0 and lower the cart's bodies by {z:.4g} m"
        )


def _check_not_tied_to_world(path: Path, model: mujoco.MjModel, cart: int) -> None:
    """Raise when an active equality constraint ties a body of the cart to the world or to a body fixed in it (a
    parking brake's weld): the cart could not be pushed."""

    def subtree(b: int) -> bool:
        while b > 0 and b != cart:
            b = int(model.body_parentid[b])
        return b == cart

    body_types = (int(mujoco.mjtEq.mjEQ_WELD), int(mujoco.mjtEq.mjEQ_CONNECT))
    for e in range(model.neq):
        if int(model.eq_type[e]) not in body_types or not bool(model.eq_active0[e]):
            continue
        if int(model.eq_objtype[e]) not in (int(mujoco.mjtObj.mjOBJ_BODY), int(mujoco.mjtObj.mjOBJ_SITE)):
            continue
        ends = [int(model.eq_obj1id[e]), int(model.eq_obj2id[e])]
        if int(model.eq_objtype[e]) == int(mujoco.mjtObj.mjOBJ_SITE):
            ends = [int(model.site_bodyid[i]) for i in ends]
        fixed = [int(model.body_weldid[b]) == 0 for b in ends]
        if any(subtree(b) for b in ends) and any(fixed):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_EQUALITY, e) or f"number {e}"
            raise CartFileError(
                f"cart file {path}: the equality {name!r} ties the cart to the world (a brake or a mount), so it cannot "
                'be pushed; remove it or make it inactive (active="false")'
            )


def _geom_label(model: mujoco.MjModel, g: int) -> str:
    """Return a geom's name, or 'a <type> of body <name>' for an unnamed one."""
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
    if name:
        return repr(name)
    kind = mujoco.mjtGeom(int(model.geom_type[g])).name.removeprefix("mjGEOM_").lower()
    return f"a {kind} of body {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g]))!r}"


def _check_axle(path: Path, model: mujoco.MjModel, data: mujoco.MjData, cart: int) -> None:
    """Raise when the cart has fixed wheels (on hinges across the cart, no swivel between them and ``cart``, a geom
    on the floor) whose
    axle is not under {b}: the cart model's no-slip point is {b} (eq. 1), and an axle elsewhere makes the pushes
    read as sideways slip."""
    R, p = data.xmat[cart].reshape(3, 3), data.xpos[cart]
    floor = _floor_z(model)
    xs = []
    for b in mujoco_cart.subtree_bodies(model, cart):
        if b == cart or _moving_link(model, int(model.body_parentid[b]), cart) is not None:
            continue  # on a swivel (or deeper): a caster
        for j in range(int(model.body_jntadr[b]), int(model.body_jntadr[b] + model.body_jntnum[b])):
            axis_b = R.T @ data.xaxis[j]
            geoms = range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b]))
            on_floor = any(mujoco_cart.geom_lowest_z(model, data, g) - floor <= FLOOR_TOUCH_M for g in geoms)
            if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE) and abs(float(axis_b[1])) > math.cos(0.1):
                if on_floor:  # a wheel; a backrest's or an anti-tip roller's hinge is not an axle
                    xs.append(float((R.T @ (data.xanchor[j] - p))[0]))
    if xs and abs(float(np.mean(xs))) > AXLE_OFFSET_M:
        x = float(np.mean(xs))
        raise CartFileError(
            f"cart file {path}: the fixed wheels' axle is {x:+.3f} m along x from body 'cart''s origin; {{b}} must "
            "be on that axle (the cart model's no-slip point): move the body's origin there and its children by "
            f"{-x:+.3f} m"
        )


def _check_handles_behind(path: Path, handles: tuple[HandleSite, ...]) -> None:
    """Raise when every handle site is ahead of {b}: the robot pushes from behind, along {b}'s +x."""
    xs = [min(float(h.start_b[0]), float(h.end_b[0])) for h in handles]
    if min(xs) > 0.0:
        raise CartFileError(
            f"cart file {path}: every handle is ahead of {{b}} (x >= {min(xs):.3f} m); the robot pushes from "
            "behind along {b}'s +x: turn the cart's children so x points away from the handle"
        )


def load_cart_file(path: str | os.PathLike) -> CartSource:
    """Return the `CartSource` of an MJCF cart file, or raise `CartFileError` naming what breaks the contract."""
    p = Path(path)
    spec, model, warned = _read(p)
    _check_inertials(p, spec, model)
    if any("NaN" in w for w in warned):
        raise CartFileError(f"cart file {p}: MuJoCo found a NaN in it (an attribute written nan); give numbers")
    cart = _check_cart_body(p, model)
    mass = _check_cart_mass(p, model, cart)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # the file's own pose of every body (qpos0), read by the checks below
    handles = _handle_sites(p, model, data, cart)
    _check_handles_behind(p, handles)
    _check_floor_height(p, model)
    _check_not_tied_to_world(p, model, cart)
    _check_start_pose(p, model, data, cart)
    _check_wheels(p, model, data, cart, bool(spec.compiler.degree))
    _check_axle(p, model, data, cart)
    z = float(model.body_pos[cart][2])  # compiled: a <frame> around the body counts
    if not math.isfinite(z):
        raise CartFileError(f"cart file {p}: body 'cart' has no finite pos")
    return CartSource(
        label=str(p),
        make_spec=lambda: mujoco.MjSpec.from_file(str(p)),
        z=z,
        handles=handles,
        extent=plan_extent(model, data, cart),
        mass=mass,
    )


def cart_source(cart: CartParams | mujoco_cart.MujocoCart | str | os.PathLike) -> CartSource:
    """Return the `CartSource` of `CartParams` (the shopping cart with them), a `MujocoCart` or a cart file path."""
    if isinstance(cart, CartParams):
        return _project_cart(mujoco_cart.shopping_cart(cart), f"shopping cart {cart}")
    if isinstance(cart, mujoco_cart.MujocoCart):
        return _project_cart(cart, "MujocoCart")
    if isinstance(cart, (str, os.PathLike)):
        return load_cart_file(cart)
    raise CartFileError(f"cart must be CartParams, MujocoCart or a file path, got {type(cart).__name__}")

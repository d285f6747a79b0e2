"""The MuJoCo cart: a wheeled cart as an MJCF model and its rigid-body truth.

Nothing here is written to match the project's cart equations. A chassis box (plus an optional payload
box placed off-centre) rides on a free joint over a plane floor, on two fixed rear wheels and two
swivelling front casters with trail. Every wheel is a cylinder with its own mass and spin inertia; the
wheel-floor contacts have ``condim=6`` (sliding, torsional and rolling friction) and MuJoCo's soft
constraints; ``axle_damping`` adds a viscous torque on every wheel axle.

The cart body is named ``cart`` and its frame is {b}: origin at the midpoint of the rear (fixed-wheel)
axle, at axle height, x towards the casters, z up (``docs/mujoco.md`` states the cart-file contract
this model follows). Sites named ``handle`` (a point) or ``handle_bar`` (a capsule along the bar) mark
where hands hold it.

Two makers: :class:`MujocoCart` fields directly (the test bed ``studies.testbeds.mujoco_cart`` draws
random ones), or :func:`shopping_cart` from a :class:`cart.params.CartParams` and the shopping cart's
geometry of ``robots.shopping_cart`` (the push plant's default cart): the chassis then carries an
explicit inertial (``chassis_inertial``) chosen so that the whole cart, wheels included, has exactly the
mass, centre of mass and yaw inertia of the parameters, and the axle damping makes the forward viscous
coefficient ``sigma``.

The truth (:func:`truth_from_state`) is read from MuJoCo: mass, centre of mass in {b}, yaw inertia about
the centre of mass of the cart's subtree, and the effective forward mass including the spin inertia of
every wheel (``m + sum J_spin / r^2``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np

from cart.params import CartParams
from wholebody.errors import WholeBodyError

GRAVITY = 9.81
SETTLE_TIME = 1.0
#: The cart body's name (the cart-file contract) and the bodies of its four wheels.
CART_BODY = "cart"
WHEEL_BODIES = ("wheel_left", "wheel_right", "caster_left_wheel", "caster_right_wheel")
REAR_WHEELS = WHEEL_BODIES[:2]
CASTER_FORKS = ("caster_left", "caster_right")


class CartModelError(WholeBodyError):
    """Parameters that make no physical MuJoCo cart (a negative mass, a chassis with negative inertia)."""


@dataclass(frozen=True)
class MujocoCart:
    """Physical parameters of the MuJoCo cart (SI units; positions in {b}).

    {b}: origin at the midpoint of the rear (fixed-wheel) axle, x towards the casters, z up; the cart
    body frame coincides with {b} (at axle height).

    - ``chassis_mass``: the chassis box, centred at ``(wheelbase / 2, 0)``, ``deck_height`` above the
      axle, length ``wheelbase + 2 chassis_overhang``, width ``chassis_width``, thickness
      ``chassis_thickness``. ``chassis_inertial`` = (mass, (x, y, z) centre, (Ixx, Iyy, Izz) about it),
      when given, replaces the chassis box's mass (the box is then visual only).
    - ``payload_mass`` (0 for none), ``payload_offset`` = (x, y) of its centre in {b}, ``payload_size``
      = full (length, width, height); it rests on the deck.
    - rear wheels at ``y = +-half_track`` (``wheel_radius``, ``wheel_width``, ``wheel_mass``; solid
      cylinders, spin inertia ``m r^2 / 2``).
    - casters: swivel axes at ``x = wheelbase``, ``y = +-caster_half_track``, a fork of
      ``caster_fork_mass`` and height ``caster_fork_height`` (swivel joint to wheel axle), the caster
      wheel ``caster_trail`` behind the swivel axis; ``swivel_damping`` (N m s/rad) and
      ``swivel_frictionloss`` (N m) on the swivel, ``axle_damping`` (N m s/rad) on every wheel axle.
    - contact: ``sliding_friction`` (-), ``torsional_friction`` (m), ``rolling_friction`` (m; MuJoCo's
      rolling coefficient: the resisting force of a rolling wheel is about ``rolling_friction * N / r``),
      ``solref``, ``solimp``.
    - the handle: ``handle_distance`` behind the rear axle (at ``x = -handle_distance``), centred at
      ``handle_y``, ``handle_height`` above the axle; ``handle_width`` > 0 makes it a bar (a capsule
      site ``handle_bar`` along y), 0 a grip point (a site ``handle``).
    """

    chassis_mass: float = 12.0
    payload_mass: float = 10.0
    payload_offset: tuple[float, float] = (0.40, 0.03)
    payload_size: tuple[float, float, float] = (0.30, 0.25, 0.20)
    wheelbase: float = 0.65
    half_track: float = 0.22
    wheel_radius: float = 0.075
    wheel_width: float = 0.03
    wheel_mass: float = 0.5
    caster_half_track: float = 0.20
    caster_trail: float = 0.035
    caster_fork_height: float = 0.06
    caster_fork_mass: float = 0.15
    caster_wheel_radius: float = 0.05
    caster_wheel_width: float = 0.025
    caster_wheel_mass: float = 0.2
    chassis_overhang: float = 0.10
    chassis_width: float = 0.40
    chassis_thickness: float = 0.04
    deck_height: float = 0.10
    rolling_friction: float = 8e-4
    torsional_friction: float = 2e-3
    sliding_friction: float = 0.9
    swivel_damping: float = 0.02
    swivel_frictionloss: float = 0.02
    axle_damping: float = 0.0
    solref: tuple[float, float] = (0.02, 1.0)
    solimp: tuple[float, float, float] = (0.9, 0.95, 0.001)
    handle_distance: float = 0.30
    handle_y: float = 0.0
    handle_height: float = 0.85
    handle_width: float = 0.0
    timestep: float = 0.001
    chassis_inertial: tuple[float, tuple[float, float, float], tuple[float, float, float]] | None = None

    def __post_init__(self) -> None:
        positive = (
            "chassis_mass",
            "wheelbase",
            "half_track",
            "wheel_radius",
            "wheel_width",
            "wheel_mass",
            "caster_half_track",
            "caster_fork_height",
            "caster_fork_mass",
            "caster_wheel_radius",
            "caster_wheel_width",
            "caster_wheel_mass",
            "chassis_width",
            "chassis_thickness",
            "timestep",
        )
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise ValueError(f"MujocoCart.{name} must be > 0, got {getattr(self, name)!r}")
        nonneg = (
            "payload_mass",
            "caster_trail",
            "chassis_overhang",
            "rolling_friction",
            "torsional_friction",
            "sliding_friction",
            "swivel_damping",
            "swivel_frictionloss",
            "axle_damping",
            "handle_width",
        )
        for name in nonneg:
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"MujocoCart.{name} must be >= 0, got {getattr(self, name)!r}")
        if self.handle_distance <= 0.0:
            raise ValueError("MujocoCart.handle_distance must be > 0 (the handle is behind the axle, at -x)")
        if self.chassis_inertial is not None:
            mass, _, diag = self.chassis_inertial
            if not (mass > 0.0 and min(diag) > 0.0):
                raise CartModelError(
                    f"the chassis inertial needs a positive mass and inertia, got {self.chassis_inertial}"
                )

    @property
    def caster_mount_z(self) -> float:
        """Height in {b} of the caster swivel joint (so that the chassis is level at rest)."""
        return self.caster_wheel_radius - self.wheel_radius + self.caster_fork_height

    @property
    def payload_z(self) -> float:
        """Height in {b} of the payload centre (resting on the deck)."""
        return self.deck_height + 0.5 * self.chassis_thickness + 0.5 * self.payload_size[2]

    @property
    def wheel_masses(self) -> float:
        """Mass of the four wheels and two caster forks (kg)."""
        return 2 * self.wheel_mass + 2 * (self.caster_fork_mass + self.caster_wheel_mass)

    @property
    def total_mass(self) -> float:
        """Sum of all body masses (kg)."""
        chassis = self.chassis_mass if self.chassis_inertial is None else self.chassis_inertial[0]
        return chassis + self.payload_mass + self.wheel_masses

    @property
    def handle_site(self) -> str:
        """Return the name of the handle's site: ``handle_bar`` (a bar) or ``handle`` (a grip point)."""
        return "handle_bar" if self.handle_width > 0.0 else "handle"


# --------------------------------------------------------------------------- the shopping cart


def _wheel_parts(c: MujocoCart) -> list[tuple[float, float, float, float]]:
    """Return (mass, x, y, own yaw inertia) of the wheels and forks with the casters trailing, in {b}."""
    parts = []
    for sgn in (1.0, -1.0):
        r, w = c.wheel_radius, c.wheel_width
        parts.append((c.wheel_mass, 0.0, sgn * c.half_track, c.wheel_mass * (3 * r**2 + w**2) / 12))
        fl, fw = c.caster_trail + 0.02, 0.04  # the fork box: full length along x, full width
        x_fork = c.wheelbase - c.caster_trail / 2
        parts.append((c.caster_fork_mass, x_fork, sgn * c.caster_half_track, c.caster_fork_mass * (fl**2 + fw**2) / 12))
        rc, wc = c.caster_wheel_radius, c.caster_wheel_width
        parts.append(
            (
                c.caster_wheel_mass,
                c.wheelbase - c.caster_trail,
                sgn * c.caster_half_track,
                c.caster_wheel_mass * (3 * rc**2 + wc**2) / 12,
            )
        )
    return parts


def shopping_cart(params: CartParams, rolling_friction: float = 1e-4, **overrides: Any) -> MujocoCart:
    """Return the shopping cart of ``robots.shopping_cart`` whose whole body has the mass, CoM and inertia of `params`.

    Wheels, casters (trail, fork) and the handle bar are the shopping cart's; the chassis carries the
    rest of the mass as an explicit inertial: mass ``m - wheels``, centre and yaw inertia solved so that
    the cart (casters trailing) has centre of mass ``(dx, dy)`` in {b} and yaw inertia ``I`` about it.
    The axle damping makes the forward viscous force ``sigma v`` (``sum_i d / r_i^2 = sigma``); the yaw
    coefficient ``sigma_yaw`` has no wheel counterpart and is not modelled (the wheels' torsional friction
    resists turning instead). ``overrides`` replace :class:`MujocoCart` fields (not the inertial).

    Raises `CartModelError` when the parameters leave the chassis a non-positive mass or yaw inertia.
    """
    from robots import shopping_cart as sc
    from wholebody.contacts.handle import HANDLE_WIDTH, HANDLE_X_B, HANDLE_Z_B

    r = sc.CART_WHEEL_RADIUS
    geometry = MujocoCart(
        chassis_mass=1.0,
        payload_mass=0.0,
        wheelbase=sc.CART_WHEELBASE + sc.CART_CASTER_TRAIL,
        half_track=sc.CART_REAR_HALF_TRACK,
        wheel_radius=r,
        wheel_width=sc.CART_WHEEL_WIDTH,
        wheel_mass=sc.CART_REAR_WHEEL_MASS,
        caster_half_track=sc.CART_FRONT_HALF_TRACK,
        caster_trail=sc.CART_CASTER_TRAIL,
        caster_fork_height=0.06,
        caster_fork_mass=sc.CART_CASTER_FORK_MASS,
        caster_wheel_radius=r,
        caster_wheel_width=sc.CART_WHEEL_WIDTH,
        caster_wheel_mass=sc.CART_CASTER_WHEEL_MASS,
        chassis_overhang=0.05,
        chassis_width=0.52,
        chassis_thickness=0.03,
        deck_height=0.06,
        rolling_friction=rolling_friction,
        axle_damping=params.sigma / (2.0 / r**2 + 2.0 / r**2),
        handle_distance=-HANDLE_X_B,
        handle_height=HANDLE_Z_B,
        handle_width=HANDLE_WIDTH,
        timestep=0.002,
    )
    # overrides: MujocoCart fields of several types (floats, tuples, None); `replace` rejects unknown names
    geometry = replace(geometry, **overrides) if overrides else geometry
    parts = np.array(_wheel_parts(geometry))
    m_c = params.m - parts[:, 0].sum()
    if m_c <= 0.0:
        raise CartModelError(f"a {params.m:g} kg cart is lighter than its wheels ({parts[:, 0].sum():g} kg)")
    xc = (params.m * params.dx - (parts[:, 0] * parts[:, 1]).sum()) / m_c
    yc = (params.m * params.dy - (parts[:, 0] * parts[:, 2]).sum()) / m_c
    wheels_izz = (parts[:, 3] + parts[:, 0] * ((parts[:, 1] - params.dx) ** 2 + (parts[:, 2] - params.dy) ** 2)).sum()
    izz = params.I - wheels_izz - m_c * ((xc - params.dx) ** 2 + (yc - params.dy) ** 2)
    if izz <= 0.0:
        raise CartModelError(
            f"no chassis gives the cart a yaw inertia of {params.I:g} kg m^2 about its CoM "
            f"(wheels and the chassis offset alone give {params.I - izz:g})"
        )
    return replace(geometry, chassis_mass=m_c, chassis_inertial=(m_c, (xc, yc, 0.45), _box_inertia(m_c, izz)))


def _box_inertia(mass: float, izz: float) -> tuple[float, float, float]:
    """Return (ixx, iyy, izz): roll and pitch of a box as long and wide as the basket (no planar effect), yaw izz."""
    ixx = mass * (0.52**2 + 0.5**2) / 12.0
    iyy = mass * (0.85**2 + 0.5**2) / 12.0
    iyy = max(iyy, izz - ixx + 1e-6) if izz > ixx + iyy else iyy  # triangle inequality of a rigid body
    ixx = max(ixx, izz - iyy + 1e-6)
    return ixx, iyy, izz


# --------------------------------------------------------------------------- model


def _f(*values: float) -> str:
    return " ".join(f"{float(v):.17g}" for v in values)


def _payload_xml(c: MujocoCart) -> str:
    """Return the MJCF body of the payload box ("" without a payload)."""
    payload = ""
    if c.payload_mass > 0.0:
        px, py = c.payload_offset
        sx, sy, sz = c.payload_size
        payload = f"""
      <body name="payload" pos="{_f(px, py, c.payload_z)}">
        <geom name="payload" type="box" size="{_f(sx / 2, sy / 2, sz / 2)}" mass="{c.payload_mass:.17g}"
              class="body" rgba="0.8 0.5 0.2 1"/>
      </body>"""
    return payload


def _rear_wheels_xml(c: MujocoCart) -> str:
    """Return the MJCF bodies of the two fixed rear wheels (hinge axles on the {b} y axis)."""
    r = c.wheel_radius
    rear = ""
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        rear += f"""
      <body name="wheel_{side}" pos="{_f(0.0, sgn * c.half_track, 0.0)}">
        <joint name="axle_{side}" type="hinge" axis="0 1 0" damping="{c.axle_damping:.17g}"/>
        <geom name="wheel_{side}" type="cylinder" class="body" size="{_f(r)}" mass="{c.wheel_mass:.17g}"
              fromto="{_f(0, -c.wheel_width / 2, 0, 0, c.wheel_width / 2, 0)}" rgba="0.1 0.1 0.1 1"/>
        <geom name="tyre_{side}" type="sphere" class="wheel" size="{_f(r)}" mass="0"/>
      </body>"""
    return rear


def _casters_xml(c: MujocoCart) -> str:
    """Return the MJCF bodies of the two swivelling casters (fork with trail, wheel on its own axle)."""
    rc = c.caster_wheel_radius
    casters = ""
    h, trail = c.caster_fork_height, c.caster_trail
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        casters += f"""
      <body name="caster_{side}" pos="{_f(c.wheelbase, sgn * c.caster_half_track, c.caster_mount_z)}">
        <joint name="swivel_{side}" type="hinge" axis="0 0 1" damping="{c.swivel_damping:.17g}"
               frictionloss="{c.swivel_frictionloss:.17g}"/>
        <geom name="fork_{side}" type="box" class="body" mass="{c.caster_fork_mass:.17g}"
              pos="{_f(-trail / 2, 0, -h / 2)}" size="{_f(trail / 2 + 0.01, 0.02, h / 2)}" rgba="0.3 0.3 0.3 1"/>
        <body name="caster_{side}_wheel" pos="{_f(-trail, 0, -h)}">
          <joint name="caster_axle_{side}" type="hinge" axis="0 1 0" damping="{c.axle_damping:.17g}"/>
          <geom name="caster_wheel_{side}" type="cylinder" class="body" size="{_f(rc)}"
                mass="{c.caster_wheel_mass:.17g}" rgba="0.1 0.1 0.1 1"
                fromto="{_f(0, -c.caster_wheel_width / 2, 0, 0, c.caster_wheel_width / 2, 0)}"/>
          <geom name="caster_tyre_{side}" type="sphere" class="wheel" size="{_f(rc)}" mass="0"/>
        </body>
      </body>"""
    return casters


def _chassis_xml(c: MujocoCart) -> str:
    """Return the chassis: its box geom (massive, or visual beside an explicit inertial) and the handle site."""
    length = c.wheelbase + 2.0 * c.chassis_overhang
    box_pos = _f(c.wheelbase / 2, 0, c.deck_height)
    box_size = _f(length / 2, c.chassis_width / 2, c.chassis_thickness / 2)
    if c.chassis_inertial is None:
        chassis = f"""
      <geom name="chassis" type="box" class="body" mass="{c.chassis_mass:.17g}"
            pos="{box_pos}" size="{box_size}" rgba="0.6 0.6 0.7 1"/>"""
    else:
        mass, com, diag = c.chassis_inertial
        chassis = f"""
      <inertial pos="{_f(*com)}" mass="{mass:.17g}" diaginertia="{_f(*diag)}"/>
      <geom name="chassis" type="box" class="body" mass="0" pos="{box_pos}" size="{box_size}" rgba="0.6 0.6 0.7 1"/>"""
    hx, hz = -c.handle_distance, c.handle_height
    if c.handle_width > 0.0:
        w = c.handle_width / 2
        chassis += f"""
      <site name="handle_bar" type="capsule" size="0.015" rgba="0.8 0.1 0.1 1"
            fromto="{_f(hx, c.handle_y - w, hz, hx, c.handle_y + w, hz)}"/>"""
    else:
        chassis += f"""
      <site name="handle" pos="{_f(hx, c.handle_y, hz)}" size="0.02" rgba="0.8 0.1 0.1 1"/>"""
    return chassis


def mjcf(cart: MujocoCart) -> str:
    """Return the MJCF (XML string) of ``cart`` on a floor; the ``cart`` body frame is {b}."""
    c = cart
    friction = _f(c.sliding_friction, c.torsional_friction, c.rolling_friction)
    payload, rear, casters = _payload_xml(c), _rear_wheels_xml(c), _casters_xml(c)
    return f"""<mujoco model="mujoco_cart">
  <compiler angle="radian" inertiafromgeom="true" autolimits="true"/>
  <option timestep="{c.timestep:.17g}" gravity="0 0 {-GRAVITY}" integrator="implicitfast" cone="elliptic"/>
  <default>
    <geom solref="{_f(*c.solref)}" solimp="{_f(*c.solimp)}"/>
    <default class="body"><geom contype="0" conaffinity="0"/></default>
    <default class="wheel"><geom contype="2" conaffinity="1" condim="6" friction="{friction}"
                                 group="3" rgba="0.1 0.1 0.1 0.3"/></default>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" contype="1" conaffinity="2" condim="6" friction="{friction}"/>
    <body name="{CART_BODY}" pos="0 0 {c.wheel_radius:.17g}">
      <freejoint name="root"/>{_chassis_xml(c)}{payload}{rear}{casters}
    </body>
  </worldbody>
</mujoco>
"""


def build(cart: MujocoCart) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Return (MjModel, MjData) of ``cart`` (data reset, cart standing at the origin)."""
    model = mujoco.MjModel.from_xml_string(mjcf(cart))
    return model, mujoco.MjData(model)


def yaw_of(quat: np.ndarray) -> float:
    """Return the yaw (rad) of a unit quaternion (w, x, y, z)."""
    w, x, y, z = (float(v) for v in quat)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def place(model: mujoco.MjModel, data: mujoco.MjData, cart: MujocoCart, pose: tuple[float, float, float]) -> None:
    """Reset ``data`` and put {b} at the planar ``pose`` (wheels just touching the floor, casters trailing)."""
    mujoco.mj_resetData(model, data)
    x, y, th = pose
    data.qpos[0:3] = (x, y, cart.wheel_radius + 1e-4)
    data.qpos[3:7] = (math.cos(th / 2), 0.0, 0.0, math.sin(th / 2))
    mujoco.mj_forward(model, data)


def settle(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    cart: MujocoCart,
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
    duration: float = SETTLE_TIME,
) -> None:
    """Place {b} at ``pose`` with the casters trailing (swivel 0) and let it settle for ``duration`` s."""
    place(model, data, cart, pose)
    data.xfrc_applied[:] = 0.0
    for _ in range(int(round(duration / model.opt.timestep))):
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)


# --------------------------------------------------------------------------- truth


def geom_corners(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> np.ndarray:
    """Return the world positions (8, 3) of the corners of geom `g`'s bounding box."""
    centre, half = model.geom_aabb[g][:3], model.geom_aabb[g][3:]
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
    return data.geom_xpos[g] + (centre + signs * half) @ data.geom_xmat[g].reshape(3, 3).T


def geom_lowest_z(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> float:
    """Return the world height of the lowest corner of geom `g`'s bounding box."""
    return float(geom_corners(model, data, g)[:, 2].min())


#: a world plane whose normal is within this angle (deg) of +z faces up (a wall's normal is horizontal)
FLOOR_NORMAL_TOL_DEG = 1.0


def floor_plane(model: mujoco.MjModel) -> int | None:
    """Return the floor of a compiled model: the lowest plane geom of the world body whose normal points up (+z
    within `FLOOR_NORMAL_TOL_DEG`), None without one. The one rule of the cart-file checks (`cart_file`) and of the
    scene (`mujoco_scene`); a world geom's ``geom_pos``/``geom_quat`` are in the world frame."""
    cos_tol = math.cos(math.radians(FLOOR_NORMAL_TOL_DEG))
    planes = []
    for g in range(model.ngeom):
        if int(model.geom_bodyid[g]) != 0 or int(model.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_PLANE):
            continue
        _, x, y, _ = (float(v) for v in model.geom_quat[g])
        normal_z = 1.0 - 2.0 * (x * x + y * y)  # the z entry of the plane's z axis (unit quaternion)
        if normal_z >= cos_tol:
            planes.append(g)
    return min(planes, key=lambda g: float(model.geom_pos[g][2])) if planes else None


def subtree_bodies(model: mujoco.MjModel, root: int) -> np.ndarray:
    """Return the ids of the bodies in the subtree of body ``root`` (itself included)."""
    ids = [root]
    for b in range(root + 1, model.nbody):
        parent = int(model.body_parentid[b])
        if parent in ids:
            ids.append(b)
    return np.array(ids, dtype=int)


def composite_inertia(
    model: mujoco.MjModel, data: mujoco.MjData, root: int | None = None, extra: Sequence[int] = ()
) -> tuple[float, np.ndarray, float]:
    """Return (mass, CoM in {s}, yaw inertia about the vertical axis through the CoM) of a subtree.

    ``root``: the subtree's body id (None: every body but the world). The yaw inertia sums every body's
    own inertia rotated to {s} (``ximat diag(body_inertia) ximat^T``, its zz entry) and the parallel-axis
    term ``m_i ((x_i - x_c)^2 + (y_i - y_c)^2)``. ``extra``: more bodies counted with the subtree (a load welded
    on, not its child). Needs ``data`` after ``mj_forward`` (or a step).
    """
    ids = np.arange(1, model.nbody) if root is None else subtree_bodies(model, root)
    ids = np.r_[ids, np.asarray(extra, dtype=int)]
    masses = np.asarray(model.body_mass[ids], dtype=float)
    pos = np.asarray(data.xipos[ids], dtype=float)
    mass = float(masses.sum())
    com = (masses[:, None] * pos).sum(axis=0) / mass
    rot = np.asarray(data.ximat[ids], dtype=float).reshape(-1, 3, 3)
    izz_own = np.einsum("nj,nj->n", rot[:, 2, :] ** 2, np.asarray(model.body_inertia[ids], dtype=float))
    d = pos[:, :2] - com[:2]
    inertia = float(izz_own.sum() + (masses * (d**2).sum(axis=1)).sum())
    return mass, com, inertia


def add_point_mass(model: mujoco.MjModel, body: int, mass: float, point: Sequence[float]) -> None:
    """Put a point mass (kg; negative: take it out) at ``point`` in the body's frame into the body's inertial.

    The body's inertia about its frame's origin, ``R diag(I) R^T + m (|c|^2 1 - c c^T)``, gains the point's
    ``m_l (|p|^2 1 - p p^T)``; the sum is taken back about the new centre of mass and diagonalised into
    ``body_mass``, ``body_ipos``, ``body_iquat``, ``body_inertia`` (the engine reads them at every step; the
    compiler's same-frame and simple-body shortcuts are turned off for the body; call ``mj_setConst`` for the
    derived constants such as ``body_subtreemass``). Raises `CartModelError` when the body
    left has no mass or breaks a rigid body's inertia (more taken out than is there, or from where it is not).
    """
    p = np.asarray(point, dtype=float)
    m0, c0 = float(model.body_mass[body]), np.asarray(model.body_ipos[body], dtype=float)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, np.asarray(model.body_iquat[body], dtype=float))
    R = rot.reshape(3, 3)
    inertia_o = R @ np.diag(model.body_inertia[body]) @ R.T + _shifted(m0, c0) + _shifted(mass, p)
    m1 = m0 + mass
    if m1 <= 1e-9:
        raise CartModelError(f"taking {-mass:g} kg out of body {body}: it holds {m0:g} kg")
    c1 = (m0 * c0 + mass * p) / m1
    vals, vecs = np.linalg.eigh(inertia_o - _shifted(m1, c1))
    if vals.min() <= 1e-12 or vals.max() > vals.sum() - vals.max() + 1e-9:
        raise CartModelError(f"taking {-mass:g} kg out at {np.round(p, 3)} leaves body {body} no rigid inertia")
    if np.linalg.det(vecs) < 0.0:
        vecs[:, 0] = -vecs[:, 0]
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, vecs.reshape(-1))
    model.body_mass[body], model.body_ipos[body] = m1, c1
    model.body_iquat[body], model.body_inertia[body] = quat, vals
    # the compiler's shortcuts for an inertial frame on the body's frame, or a diagonal mass matrix, no longer hold
    model.body_sameframe[body] = mujoco.mjtSameFrame.mjSAMEFRAME_NONE
    if model.body_simple[body]:
        model.body_simple[body] = 0
        model.dof_simplenum[model.body_dofadr[body] : model.body_dofadr[body] + model.body_dofnum[body]] = 0


def _shifted(mass: float, c: np.ndarray) -> np.ndarray:
    """Return the inertia a point mass at ``c`` adds about the origin: m (|c|^2 1 - c c^T)."""
    return mass * (float(c @ c) * np.eye(3) - np.outer(c, c))


def _spin_inertia(model: mujoco.MjModel, body: int, joint: int) -> float:
    """Return the inertia (kg m^2) of ``body`` about the axis of its hinge ``joint``, through its CoM."""
    axis = np.asarray(model.jnt_axis[joint], dtype=float)  # in the body frame
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, np.asarray(model.body_iquat[body], dtype=float))
    a = rot.reshape(3, 3).T @ axis  # inertial frame -> body frame, transposed
    return float(a @ (np.asarray(model.body_inertia[body], dtype=float) * a))


def wheel_spin_inertias(model: mujoco.MjModel) -> dict[str, tuple[float, float]]:
    """Return {wheel body: (spin inertia about its axle (kg m^2), rolling radius (m))} of the four named wheels."""
    out: dict[str, tuple[float, float]] = {}
    for name in WHEEL_BODIES:
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        jid = int(model.body_jntadr[bid])
        gid = int(model.body_geomadr[bid])
        out[name] = (_spin_inertia(model, bid, jid), float(model.geom_size[gid][0]))
    return out


def rolling_wheels(
    model: mujoco.MjModel, data: mujoco.MjData, root: int, floor_z: float = 0.0
) -> dict[str, tuple[float, float]]:
    """Return {body: (spin inertia, rolling radius)} of the wheels of the subtree of ``root``, found by shape.

    A wheel is a body of the subtree on a hinge joint whose axis is horizontal (within 0.1 rad) and
    whose lowest geom touches the floor (within 5 mm); its rolling radius is the height of the axle
    above the floor. Needs ``data`` after ``mj_forward`` with the cart standing on its wheels.
    """
    out: dict[str, tuple[float, float]] = {}
    for b in subtree_bodies(model, root):
        for j in range(int(model.body_jntadr[b]), int(model.body_jntadr[b] + model.body_jntnum[b])):
            if int(model.jnt_type[j]) != int(mujoco.mjtJoint.mjJNT_HINGE):
                continue
            axis_w = data.xaxis[j]
            if abs(float(axis_w[2])) > math.sin(0.1):
                continue
            lowest = math.inf
            for g in range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b])):
                if int(model.geom_type[g]) in (int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
                    lowest = min(lowest, float(data.geom_xpos[g][2] - model.geom_size[g][0]))
            if lowest - floor_z > 5e-3 or lowest == math.inf:
                continue
            radius = float(data.xanchor[j][2]) - floor_z
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(b)) or f"body{b}"
            out[name] = (_spin_inertia(model, int(b), j), radius)
            break
    return out


def planar_pose(data: mujoco.MjData, body: int) -> tuple[float, float, float]:
    """Return (x, y, yaw) of a body's frame in {s}."""
    return float(data.xpos[body][0]), float(data.xpos[body][1]), yaw_of(data.xquat[body])


def welded_loads(model: mujoco.MjModel, data: mujoco.MjData, root: int, exclude: Sequence[int] = ()) -> list[int]:
    """Return the bodies an active weld equality attaches to the subtree of ``root``: the whole tree (from its body
    under the world) of each body welded to it, unless that tree is ``root``'s or its top body is in ``exclude``
    (the robots, whose hands are welded to the handle). A load strapped on by a weld rides with the cart."""
    sub = set(subtree_bodies(model, root))
    out: list[int] = []
    for e in range(model.neq):
        if int(model.eq_type[e]) != int(mujoco.mjtEq.mjEQ_WELD) or not data.eq_active[e]:
            continue
        if int(model.eq_objtype[e]) != int(mujoco.mjtObj.mjOBJ_BODY):
            continue
        a, b = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
        other = b if a in sub else a if b in sub else 0
        if other == 0:
            continue
        top = int(model.body_rootid[other])
        if top in sub or top in exclude or top == 0:
            continue
        out += [int(x) for x in subtree_bodies(model, top) if int(x) not in out]
    return out


def truth_from_state(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    body: str = CART_BODY,
    wheels: dict[str, tuple[float, float]] | None = None,
    extra: Sequence[int] = (),
) -> dict[str, float]:
    """Return the cart's rigid-body truth at the current state (``data`` after ``mj_forward``).

    Keys: ``m`` (kg, ``body_subtreemass`` of the cart body), ``dx``, ``dy`` (m, ``subtree_com`` in {b}),
    ``I_about_com`` (kg m^2, yaw inertia of the composite body about the vertical axis through the CoM)
    and ``m_effective_forward_incl_wheel_spin`` (kg, ``m + sum J_spin / r^2`` over ``wheels``; default:
    the four wheels of :func:`mjcf`). ``extra``: bodies counted with the cart (:func:`welded_loads`).
    """
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    mass, com, inertia = composite_inertia(model, data, bid, extra)
    sub_mass = float(model.body_subtreemass[bid])
    sub_com = np.asarray(data.subtree_com[bid], dtype=float)
    if not len(extra) and (abs(sub_mass - mass) > 1e-9 * mass or np.max(np.abs(sub_com - com)) > 1e-9):
        raise RuntimeError("composite mass/CoM disagree with MuJoCo's subtree mass/CoM")
    sub_mass, sub_com = mass, com
    th = yaw_of(data.xquat[bid])
    rel = sub_com[:2] - data.xpos[bid][:2]
    c, s = math.cos(th), math.sin(th)
    dx, dy = c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1]
    spins = wheel_spin_inertias(model) if wheels is None else wheels
    m_eff = sub_mass + sum(j / rad**2 for j, rad in spins.values())
    return {
        "m": sub_mass,
        "dx": float(dx),
        "dy": float(dy),
        "I_about_com": inertia,
        "m_effective_forward_incl_wheel_spin": float(m_eff),
    }


def truth(cart: MujocoCart) -> dict[str, float]:
    """Return :func:`truth_from_state` of ``cart`` after 1 s of settling with the casters trailing."""
    model, data = build(cart)
    settle(model, data, cart)
    return truth_from_state(model, data)


# --------------------------------------------------------------------------- the cart's joints over a run


#: the joint types a cart's own moving parts may have (a free joint makes a body of its own), as named here
JOINT_KINDS = {
    int(mujoco.mjtJoint.mjJNT_HINGE): "hinge",
    int(mujoco.mjtJoint.mjJNT_SLIDE): "slide",
    int(mujoco.mjtJoint.mjJNT_BALL): "ball",
}
#: qpos entries per joint kind (a ball joint: its quaternion w, x, y, z)
JOINT_NQ = {"hinge": 1, "slide": 1, "ball": 4}


def joint_label(model: mujoco.MjModel, joint: int) -> str:
    """Return a joint's name, or ``<body>_joint<k>`` (its k-th joint) for an unnamed one."""
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    if name:
        return name
    body = int(model.jnt_bodyid[joint])
    body_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body{body}"
    return f"{body_name}_joint{joint - int(model.body_jntadr[body])}"


def subtree_joints(model: mujoco.MjModel, root: int) -> list[tuple[str, str, int]]:
    """Return (label, kind, qpos address) of every hinge, slide and ball joint below body ``root``, in body order.

    These are a cart's own moving parts: caster swivels, wheel axles, a wobbling stem. The order (bodies by id,
    each body's joints in turn) is the same in the cart file compiled alone and in a scene the robots were
    attached to, so a page can replay them on a model built from the file (`wholebody.viz.mjcf`).
    """
    out = []
    for b in subtree_bodies(model, root):
        for j in range(int(model.body_jntadr[b]), int(model.body_jntadr[b] + model.body_jntnum[b])):
            kind = JOINT_KINDS.get(int(model.jnt_type[j]))
            if kind is not None:
                out.append((joint_label(model, j), kind, int(model.jnt_qposadr[j])))
    return out


@dataclass
class CartJointRecord:
    """The cart's own joints (caster swivels, wheel spins, ...) sampled once per control period, for the page.

    ``names``/``kinds`` from `subtree_joints`; ``t`` (s) and ``q`` (the joints' qpos entries, in order) grow by
    `record`. A report's reader sees only `to_dict` (the joints and the sample count); a page reads `series`.
    """

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    addresses: tuple[int, ...]
    t: list[float] = field(default_factory=list)
    q: list[np.ndarray] = field(default_factory=list)

    @staticmethod
    def of(model: mujoco.MjModel, body: str | int = CART_BODY) -> CartJointRecord:
        """Return an empty record of the joints below body ``body`` (a name or an id) of ``model``: the cart's, or a
        robot's from its root body (its names carry the scene's robot prefix, ``r0/``)."""
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body) if isinstance(body, str) else int(body)
        joints = subtree_joints(model, bid)
        return CartJointRecord(
            tuple(n for n, _, _ in joints), tuple(k for _, k, _ in joints), tuple(a for _, _, a in joints)
        )

    def record(self, t: float, data: mujoco.MjData) -> None:
        """Append the joints' positions at time ``t`` (s) from ``data.qpos``."""
        self.t.append(float(t))
        parts = [data.qpos[a : a + JOINT_NQ[k]] for a, k in zip(self.addresses, self.kinds)]
        self.q.append(np.concatenate(parts) if parts else np.zeros(0))  # a cart without joints of its own: none

    def series(self) -> tuple[np.ndarray, np.ndarray]:
        """Return (t (N,), q (N, n_q)) of the samples so far."""
        width = sum(JOINT_NQ[k] for k in self.kinds)
        q = np.array(self.q, dtype=float).reshape(len(self.q), width)
        return np.array(self.t, dtype=float), q

    def to_dict(self) -> dict:
        """Return what a JSON report shows of the record: the joints and the number of samples."""
        return {"joints": list(self.names), "samples": len(self.t)}


#: the default cart's joints (`mjcf`) under their names in the shopping cart's URDF (`robots.shopping_cart`), which
#: a page draws for it: same places, axes and zero angles (casters trailing)
URDF_JOINTS = {
    "axle_left": "rear_left_wheel_joint",
    "axle_right": "rear_right_wheel_joint",
    "swivel_left": "caster_left_swivel",
    "swivel_right": "caster_right_swivel",
    "caster_axle_left": "caster_left_wheel_joint",
    "caster_axle_right": "caster_right_wheel_joint",
}

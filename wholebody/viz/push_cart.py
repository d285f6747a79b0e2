"""The cart a push run's page draws, and its joints over the run: what the plant did, or a model of it.

- A cart file (``PushConfig.cart_model``): the file's own bodies and geoms (`wholebody.viz.mjcf.cart_file_robot`),
  a hospital bed as a bed; its joints (casters, wheels) as the MuJoCo plant recorded them
  (`wholebody.push.mujoco_cart.CartJointRecord`, in the plant report's ``cart_joints``), else at rest.
- The default cart: the shopping cart's URDF. On the MuJoCo plant its casters swivel and its wheels spin as the
  plant's joints did (recorded, mapped by `wholebody.push.mujoco_cart.URDF_JOINTS`); on the kinematic plant (no
  casters simulated) the casters swivel as rolling without side slip turns them
  (`wholebody.push.report.swivel_casters`) and the wheels stay still.
- The robot (`robot_joints`): on the MuJoCo plant its casters, wheels and arm as the plant's joints were (the plant
  report's ``robot_joints``); without a record its casters by the trail model over its base's true motion.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

import robots

#: the page's legend line on the cart's casters, by where their angles come from
CASTER_SOURCES = {
    "recorded": "casters and wheels: swivel and spin as the MuJoCo plant turned them (its joints, each control period)",
    "trail": "casters: swivel as rolling without side slip turns them (from the true motion of cart and base)",
    "rest": "casters and wheels: drawn at rest (the run recorded no joint angles)",
}


@dataclass(frozen=True)
class RunCart:
    """What a page draws as the run's cart: ``robot`` (a `robots.load` name or a loaded model) named ``name``,
    its joint configurations ``joints`` (one row per page sample, nq - 4 entries) and where they come from
    (``source``: a key of `CASTER_SOURCES`; ``legend``: its legend line)."""

    robot: str | robots.LoadedRobot
    name: str
    joints: np.ndarray
    source: str

    @property
    def legend(self) -> str:
        """Return the page's legend line on the casters."""
        return CASTER_SOURCES[self.source]


def recorded_rows(t_record: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Return, for each time t, the index of the latest recorded sample at or before it (the first one before any)."""
    k = np.searchsorted(np.asarray(t_record, dtype=float), np.asarray(t, dtype=float) + 1e-9, side="right") - 1
    return np.clip(k, 0, len(t_record) - 1)


def urdf_joints_from_record(
    model: pin.Model,
    names: tuple[str, ...],
    kinds: tuple[str, ...],
    q: np.ndarray,
    name_map: dict[str, str],
    base: np.ndarray | None = None,
) -> np.ndarray:
    """Return configurations (N, nq - 4) of a planar-rooted URDF model whose joints `name_map` names for recorded
    hinge joints (a continuous joint gets cos, sin of the angle; a revolute one the angle); the others as in
    `base` (N, nq - 4), neutral without it."""
    from wholebody.push.mujoco_cart import JOINT_NQ

    q = np.atleast_2d(np.asarray(q, dtype=float))
    out = np.tile(pin.neutral(model)[4:], (len(q), 1)) if base is None else np.array(base, dtype=float)
    col = 0
    for name, kind in zip(names, kinds):
        target = name_map.get(name)
        if kind == "hinge" and target is not None and model.existJointName(target):
            j = model.joints[model.getJointId(target)]
            if j.nq == 2:
                out[:, j.idx_q - 4], out[:, j.idx_q - 3] = np.cos(q[:, col]), np.sin(q[:, col])
            elif j.nq == 1:
                out[:, j.idx_q - 4] = q[:, col]
        col += JOINT_NQ[kind]
    return out


def _trail_joints(result: Any, idx: np.ndarray) -> np.ndarray:
    """Return the shopping cart's joints with the casters swivelled by the no-side-slip trail model, wheels still."""
    from wholebody.push.report import swivel_casters

    model = robots.load("shopping_cart").model
    rest = np.tile(pin.neutral(model)[4:], (len(result.t), 1))
    return swivel_casters(model, rest, result.q_true, result.qd_true, result.config.dt)[idx]


def run_cart(result: Any, idx: np.ndarray, name: str = "cart") -> RunCart:
    """Return the cart a page of the push run `result` (`wholebody.push.config.PushResult`) draws at samples `idx`.

    A cart file's cart is named `name`; the default cart is ``shopping_cart``. See the module doc for the joints.
    """
    from wholebody.push.mujoco_cart import URDF_JOINTS
    from wholebody.viz.mjcf import cart_file_robot

    record = (result.plant_report or {}).get("cart_joints")
    cart_model = getattr(result.config, "cart_model", None)
    if record is None or len(record.t) == 0:
        if cart_model is None:
            return RunCart("shopping_cart", "shopping_cart", _trail_joints(result, idx), "trail")
        robot = cart_file_robot(cart_model, name=name).robot
        return RunCart(robot, name, np.tile(pin.neutral(robot.model)[4:], (len(idx), 1)), "rest")
    t_record, q_record = record.series()
    rows = q_record[recorded_rows(t_record, result.t[idx])]
    if cart_model is not None:
        cart = cart_file_robot(cart_model, name=name)
        return RunCart(cart.robot, name, cart.joints_from_record(record.names, record.kinds, rows), "recorded")
    model = robots.load("shopping_cart").model
    joints = urdf_joints_from_record(model, record.names, record.kinds, rows, URDF_JOINTS)
    return RunCart("shopping_cart", "shopping_cart", joints, "recorded")


def robot_joints(result: Any, model: pin.Model, rest: np.ndarray, idx: np.ndarray, robot: int = 0) -> np.ndarray:
    """Return robot `robot`'s joint configurations (len(idx), nq - 4) for the page from `rest` (N, nq - 4: its state
    over the run): the joints the MuJoCo plant recorded (`recorded_robot_joints`), else its casters swivelled by the
    trail model over its base's true motion (`wholebody.push.report.swivel_casters`: the kinematic plant has no
    casters)."""
    from wholebody.push.report import swivel_casters

    recorded = recorded_robot_joints(result, model, np.asarray(rest, dtype=float)[idx], idx, robot)
    if recorded is not None:
        return recorded
    base = np.asarray(result.robot_x, dtype=float)[:, robot, :3]
    dt = float(result.config.dt)
    unwrapped = np.column_stack([base[:, :2], np.unwrap(base[:, 2])])
    velocities = np.gradient(unwrapped, dt, axis=0) if len(base) > 1 else np.zeros_like(base)
    return swivel_casters(model, rest, base, velocities, dt)[idx]


def recorded_robot_joints(
    result: Any, model: pin.Model, rest: np.ndarray, idx: np.ndarray, robot: int = 0
) -> np.ndarray | None:
    """Return robot `robot`'s joint configurations at samples `idx` with every joint the MuJoCo plant recorded of it
    (the plant report's ``robot_joints``: casters, wheels, arm; matched by name without the scene's ``r0/``
    prefix) over `rest` (its configurations at `idx` from its state); None when the run recorded none (the page
    then swivels its casters by the trail model, `wholebody.push.report.swivel_casters`)."""
    records = (result.plant_report or {}).get("robot_joints") or []
    if len(records) <= robot or len(records[robot].t) == 0:
        return None
    record = records[robot]
    t_record, q_record = record.series()
    rows = q_record[recorded_rows(t_record, result.t[idx])]
    name_map = {name: name.split("/", 1)[-1] for name in record.names}
    return urdf_joints_from_record(model, record.names, record.kinds, rows, name_map, base=rest)

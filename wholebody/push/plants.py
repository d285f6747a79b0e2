"""Which plant answers the push controller: the kinematic plant or the MuJoCo plant (`PushConfig.plant`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from cart.params import CartParams
from wholebody.push.config import PushConfig
from wholebody.push.kinematic_plant import KinematicPlant
from wholebody.push.plant import Plant, SimulatedPlant

if TYPE_CHECKING:
    from wholebody.push.loop import PushSetup


def kinematic_plant(config: PushConfig, setup: PushSetup) -> KinematicPlant:
    """Return the kinematic plant of `config` starting where `setup` holds the handle."""
    robots_ = [
        (mm.wb, x, mm.ft_id if mm.n_hands == 1 else list(zip(mm.hand_ids, mm.ft_ids)))
        for mm, x in zip(setup.controller.robots, setup.robot_x0)
    ]
    return KinematicPlant(
        robots_,
        setup.q0,
        setup.qd0,
        config.true_params,
        config.noise,
        config.dt,
        config.substeps,
        config.seed,
        config.load_changes,
    )


def make_plant(config: PushConfig, setup: PushSetup) -> SimulatedPlant:
    """Return the plant `config.plant` names, holding the cart where `setup`'s robots grasp it."""
    if config.plant == "kinematic":
        return kinematic_plant(config, setup)
    from wholebody.push.mujoco_plant import MujocoPlant

    cart: Any = config.cart_model if config.cart_model is not None else config.true_params
    return MujocoPlant(
        setup.controller.robots,
        setup.q0,
        cart,
        noise=config.noise,
        seed=config.seed,
        load_changes=config.load_changes,
    )


def plant_truth(config: PushConfig, plant: Plant) -> CartParams:
    """Return the cart parameters the run's estimate is judged against.

    The kinematic plant simulates `config.true_params`. A MuJoCo cart is a rigid body with spinning wheels:
    its mass is the mass the forward motion feels (wheel spin included), its CoM and yaw inertia the rigid
    body's, read from the engine (the controller never sees them).
    """
    inertial = getattr(plant, "cart_inertial", None)
    if inertial is None:
        return config.true_params
    return _inertial_params(inertial(), config.true_params.sigma)


def _inertial_params(c: Any, sigma: float) -> CartParams:
    """Return the `CartParams` of a MuJoCo cart's `CartInertial`: effective mass, CoM, yaw inertia."""
    dx, dy = (float(v) for v in np.asarray(c.com_b, dtype=float)[:2])
    return CartParams(float(c.mass_effective), dx, dy, float(c.inertia), sigma)


def plant_truth_schedule(config: PushConfig, plant: Plant) -> list[tuple[float, CartParams]]:
    """Return [(t, the truth from t on)], the first at t = 0: `plant_truth`, stepping at each load change the plant
    made (the kinematic plant's parameters; the MuJoCo cart's inertial read from the engine after each)."""
    schedule = getattr(plant, "truth_schedule", None)
    if schedule is not None:
        return list(schedule())
    log = getattr(plant, "inertial_log", None)
    if log is not None:
        return [(t, _inertial_params(c, config.true_params.sigma)) for t, c in log]
    return [(0.0, plant_truth(config, plant))]


def plant_report(plant: Plant) -> dict:
    """Return the plant's own diagnostics (`MujocoPlant.report`), with ``plant`` naming it; empty keys otherwise."""
    report = getattr(plant, "report", None)
    out = {"plant": "mujoco" if report is not None else "kinematic"}
    if report is not None:
        out.update(report())
    return out

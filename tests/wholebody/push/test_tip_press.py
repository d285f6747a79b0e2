"""A downward press on the handle (the tip-over bound's way to hold the cart on an edge) loads the MuJoCo cart's
forward motion only through rolling resistance, which scales with the wheels' normal load (issue #28: the press
does not read as mass)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from cart.params import CartParams
from wholebody.push import mujoco_cart

TRUTH = CartParams(20.0, 0.3, 0.15, 1.5, 4.0)
HANDLE = np.array([-0.15, 0.0, 0.9365])  # the handle's middle in {b}
PUSH, PRESS, SECONDS = 10.0, 30.0, 1.5  # N forward, N down, s


def _speed_after_push(press: float, rolling_friction: float) -> float:
    """Return the cart's forward speed (m/s) after `SECONDS` of `PUSH` N forward and `press` N down at the handle."""
    cart = mujoco_cart.shopping_cart(TRUTH, rolling_friction=rolling_friction)
    model, data = mujoco_cart.build(cart)
    mujoco_cart.settle(model, data, cart)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, mujoco_cart.CART_BODY)
    for _ in range(int(SECONDS / model.opt.timestep)):
        R = data.xmat[body].reshape(3, 3)
        f = R @ np.array([PUSH, 0.0, 0.0]) + np.array([0.0, 0.0, -press])
        arm = data.xpos[body] + R @ HANDLE - data.xipos[body]  # the force acts at the handle, xfrc at the CoM
        data.xfrc_applied[body, :3] = f
        data.xfrc_applied[body, 3:] = np.cross(arm, f)
        mujoco.mj_step(model, data)
    R = data.xmat[body].reshape(3, 3)
    return float(R[:, 0] @ _linear_velocity(model, data, body))


def _linear_velocity(model: mujoco.MjModel, data: mujoco.MjData, body: int) -> np.ndarray:
    """Return the world velocity (m/s) of the body frame's origin."""
    vel = np.zeros(6)
    mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, vel, 0)
    return vel[3:]


@pytest.mark.parametrize("rolling_friction", [1e-4, 2e-3])
def test_a_press_costs_the_forward_motion_only_its_share_of_rolling_resistance(rolling_friction: float) -> None:
    """Rolling resistance scales with the wheels' normal load: a 30 N press on the 196 N cart takes about 30/196 of
    what the weight's rolling resistance takes from a 10 N push's speed. The default cart (1e-4 m, the push
    plant's): under 0.1 % of the speed, where a 5 % mass error would take 5 %; a cart with 20 x the rolling
    friction loses its share (the test sees a press where there is one)."""
    frictionless = _speed_after_push(0.0, 0.0)
    free = _speed_after_push(0.0, rolling_friction)
    pressed = _speed_after_push(PRESS, rolling_friction)
    share = PRESS / (TRUTH.m * 9.81)
    assert free - pressed == pytest.approx(share * (frictionless - free), rel=0.35, abs=2e-4)
    if rolling_friction <= 1e-4:
        assert free - pressed < 1e-3 * free

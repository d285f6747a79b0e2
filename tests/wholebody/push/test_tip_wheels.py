"""The tip-over bound against the MuJoCo cart's wheels (static roll moments), and its margin for the estimate's error (issue #28)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from cart.params import CartParams
from wholebody.contacts.support import CartLoad, tip_rows
from wholebody.push import PushConfig, mujoco_cart

TRUTH = CartParams(20.0, 0.3, 0.15, 1.5, 5.0)
HANDLE = np.array([-0.15, 0.0, 0.9365])  # the handle's middle in {b}


def _support():  # noqa: ANN202
    s = PushConfig(plant="mujoco", robot="wmra", contact="fixed").support_polygon()
    assert s is not None
    return s


def _roll_limit(load: CartLoad, sign: float) -> float:
    """Return the largest pure roll moment (N m, about -x for sign +1: toward the +y edge) the bound allows."""
    C, h, _ = tip_rows(_support(), load, HANDLE)
    c = C @ np.array([0.0, 0.0, 0.0, -sign, 0.0, 0.0])
    return float(min(h[k] / c[k] for k in range(len(c)) if c[k] > 1e-9))


def _wheel_loads_under(moment_x: float) -> tuple[dict[str, float], float]:
    """Return each tyre's floor normal force (N) and the roll (deg) after 0.5 s of a roll moment on the cart."""
    cart = mujoco_cart.shopping_cart(TRUTH)
    model, data = mujoco_cart.build(cart)
    mujoco_cart.settle(model, data, cart)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, mujoco_cart.CART_BODY)
    data.xfrc_applied[body, 3] = moment_x
    for _ in range(int(0.5 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    loads: dict[str, float] = {}
    f6 = np.zeros(6)
    for i in range(data.ncon):
        c = data.contact[i]
        mujoco.mj_contactForce(model, data, i, f6)
        for g in (c.geom1, c.geom2):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
            if "tyre" in name:
                loads[name] = loads.get(name, 0.0) + float(f6[0])
    R = data.xmat[body].reshape(3, 3)
    return loads, float(np.degrees(np.arctan2(R[2, 1], R[2, 2])))


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_bound_is_where_the_mujoco_carts_wheels_unload(sign: float) -> None:
    """The support polygon is the MuJoCo cart's: 0.9 of the bound's roll limit (true load) keeps all four tyres
    on the floor; 1.3 of it lifts one (the side's rear wheel first: four wheels on a rigid frame)."""
    limit = _roll_limit(CartLoad(TRUTH.m, (TRUTH.dx, TRUTH.dy)), sign)
    below, _ = _wheel_loads_under(-sign * 0.9 * limit)
    above, _ = _wheel_loads_under(-sign * 1.3 * limit)
    assert len(below) == 4 and min(below.values()) > 0.5
    assert len(above) < 4 or min(above.values()) < 0.5


def test_a_margin_of_three_sigma_covers_the_estimate_that_tipped_the_wmras_cart() -> None:
    """WMRA MuJoCo Traj. 2, seed 0, at 16.6 s in the second turn (no margin): the estimate (19.8 kg, CoM (0.265,
    0.075) m, 1-sigma 2.0 kg, (0.159, 0.015) m) against the truth (20 kg, (0.30, 0.15) m, CoM 0.47 m above the
    floor), the CoM accelerating (0.14, -0.54) m/s^2. With 3 sigma off the holding moment the bound allows no more
    roll moment toward the +y edge than the true cart holds under that acceleration; with the estimate as it is it
    allowed 12 N m, and the cart tipped. (The default, `PushConfig.tip_std_factor` 1.5, allows 6.1 N m against the
    4.9 the truth holds here; its runs keep the cart up, the bound's CoM height being twice the cart's.)"""
    a = (0.14, -0.54)
    assert 0.0 < PushConfig().tip_std_factor <= 3.0
    est = CartLoad(19.8, (0.265, 0.075), a, 2.0, (0.159, 0.015), 3.0)
    true_hold = TRUTH.m * 9.81 * float(_support().com_margin((TRUTH.dx, TRUTH.dy)).min())
    true_tip = TRUTH.m * 0.47 * -a[1]
    assert _roll_limit(est, 1.0) <= true_hold - true_tip
    assert _roll_limit(CartLoad(19.8, (0.265, 0.075), a), 1.0) > true_hold - true_tip  # no margin: past it

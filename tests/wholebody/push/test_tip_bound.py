"""The push loop keeps every wheel of the cart loaded (`PushConfig.tip_std_factor`, `wholebody.contacts.support`)."""

from __future__ import annotations

import numpy as np
import pytest

from cart.params import CartParams
from wholebody.contacts.support import CartLoad, tip_rows
from wholebody.push import PushConfig, run_push
from wholebody.push.geometry import DEFAULT_GEOMETRY
from wholebody.push.robot import handle_point
from wholebody.push.tip_support import cart_load, shopping_cart_support


def test_default_support_is_the_shopping_carts_wheels() -> None:
    s = PushConfig().support_polygon()
    assert s is not None
    pts = np.asarray(s.points)
    assert np.allclose(sorted(pts[:, 1]), [-0.25, -0.2, 0.2, 0.25])
    assert s.floor_z == pytest.approx(-DEFAULT_GEOMETRY.frame_height)
    assert s.com_height == pytest.approx(1.0)  # the handle's height above the floor


def test_cart_file_support_reads_the_wheels_and_the_casters_trail() -> None:
    s = PushConfig(plant="mujoco", contact="fixed", cart_model="examples/carts/wheelchair.xml").support_polygon()
    assert s is not None and len(s.points) == 4
    r = np.broadcast_to(np.asarray(s.radius), (4,))
    assert np.count_nonzero(r > 0.0) == 2  # two casters swivel, the two big wheels do not


def test_cart_load_of_a_turn_in_place_is_centripetal() -> None:
    """Turning in place about {b} at constant rate w: the CoM c accelerates by -w^2 c (with the wrench that holds w)."""
    p = CartParams(20.0, 0.3, 0.15, 2.3, 0.0)
    w = 0.8
    q, qd = np.array([1.0, 2.0, 0.7]), np.array([0.0, 0.0, w])
    from cart import model as cm

    # the generalized force that keeps qdd = 0: M qdd + C qd = gamma - constraint, solved by least squares
    gammas = [np.array([fx, fy, 0.0]) for fx in np.linspace(-10, 10, 41) for fy in np.linspace(-10, 10, 41)]
    gamma = min(gammas, key=lambda g: float(np.linalg.norm(cm.forward_dynamics(q, qd, g, p))))
    load = cart_load(q, qd, gamma, p, None, 0.0)
    qdd = cm.forward_dynamics(q, qd, gamma, p)
    assert np.linalg.norm(qdd) < 0.05
    assert np.allclose(load.acceleration, -(w**2) * np.array([0.3, 0.15]), atol=0.03)


def test_the_loop_does_not_tip_the_cart_in_traj2s_second_turn() -> None:
    """Kinematic Traj. 2: the second turn (right) wants a lateral hand force toward the cart's near edge (CoM 0.05 m
    inside it, the casters' swivel radius counted). With the bound the hands' moment about that edge stays within
    what the cart's weight holds."""
    truth = PushConfig().true_params
    support = shopping_cart_support(DEFAULT_GEOMETRY)

    def worst(tip: bool) -> float:
        res = run_push(PushConfig(trajectory=2, contact="fixed", tip_bound=tip))
        point = handle_point(float(res.contact_y[0, 0]), DEFAULT_GEOMETRY)
        C, h, _ = tip_rows(support, CartLoad(truth.m, (truth.dx, truth.dy)), point[None])
        return float(np.max(res.wrenches[:, 0] @ C.T - h))

    assert worst(False) > 9.95  # past the holding moment by more than all the weight holds (9.95 N m): it tips
    assert worst(True) < 1.0


def test_tip_bound_auto_is_on_with_the_mujoco_plant_and_the_cli_sets_it() -> None:
    import argparse

    from cartpush.cli import push

    assert not PushConfig().tip_on()  # the kinematic plant's rigid planar cart cannot tip
    assert PushConfig(plant="mujoco", contact="fixed").tip_on()
    assert (
        PushConfig(tip_bound=True).tip_on()
        and not PushConfig(plant="mujoco", contact="fixed", tip_bound=False).tip_on()
    )
    parser = argparse.ArgumentParser()
    push.register(parser.add_subparsers())
    assert push.config_from_args(parser.parse_args(["push", "--tip-bound", "off"])).tip_bound is False
    assert push.config_from_args(parser.parse_args(["push", "--tip-bound"])).tip_bound is True
    assert push.config_from_args(parser.parse_args(["push"])).tip_bound == "auto"

"""The controller is told only where the handle is: from a cart file's handle sites, never its inertia."""

from __future__ import annotations

import numpy as np
import pytest

from wholebody.errors import WholeBodyError
from wholebody.push import PushConfig, build_controller
from wholebody.push.geometry import DEFAULT_GEOMETRY, CartGeometry, geometry_from_cart_file
from wholebody.push.mujoco_cart import MujocoCart, mjcf
from wholebody.push.robot import cart_se3


def _cart_file(tmp_path, **kw) -> str:
    path = tmp_path / "cart.xml"
    path.write_text(mjcf(MujocoCart(**kw)))
    return str(path)


def test_a_bar_handle_is_read_from_the_file(tmp_path):
    geo = geometry_from_cart_file(_cart_file(tmp_path, handle_distance=0.45, handle_height=0.8, handle_width=0.6))
    assert geo.grips is None
    np.testing.assert_allclose(geo.point(0.1), [-0.45, 0.1, 0.8], atol=1e-9)
    assert geo.y_range == pytest.approx((-0.3, 0.3))
    assert geo.frame_height == pytest.approx(MujocoCart().wheel_radius)
    assert geo.grid()[0] == pytest.approx(-0.3) and geo.grid()[-1] == pytest.approx(0.3)


def test_a_point_grip_is_the_only_place_to_hold(tmp_path):
    geo = geometry_from_cart_file(_cart_file(tmp_path, handle_distance=0.4, handle_y=0.05, handle_width=0.0))
    assert geo.grips == pytest.approx((0.05,))
    assert geo.nearest(-0.2) == pytest.approx(0.05)
    np.testing.assert_allclose(geo.grid(), [0.05])


def test_the_robot_holds_the_cart_files_handle(tmp_path):
    path = _cart_file(tmp_path, handle_distance=0.45, handle_height=0.8, handle_width=0.6)
    config = PushConfig(trajectory=1, plant="mujoco", contact="fixed", cart_model=path)
    setup = build_controller(config)
    mm = setup.controller.robots[0]
    geo = config.cart_geometry()
    hand_b = cart_se3(setup.q0, geo).actInv(mm.wb.ee_placement(mm.x)).translation
    np.testing.assert_allclose(hand_b, geo.point(float(config.contact_y0()[0])), atol=1e-4)
    assert not np.allclose(geo.point(0.0), DEFAULT_GEOMETRY.point(0.0))


def test_bad_geometry_is_refused():
    with pytest.raises(WholeBodyError):
        CartGeometry(frame_height=float("nan"))
    with pytest.raises(WholeBodyError):
        PushConfig(cart_model="cart.xml")  # a cart file needs the MuJoCo plant

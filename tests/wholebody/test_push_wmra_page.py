"""Browser test: the Meshcat page of a short WMRA push shows the wheelchair-mounted arm and the cart.

`cartpush push --robot wmra --html` writes `wholebody.push.report.save_scene(result, path)`; here a 4 s
run (the CLI's floor is 8 s, the page is the same) is rendered by headless Chromium at its first frame and
half-way, against the same page with the WMRA and the cart hidden (as tests/wholebody/test_browser.py does,
whose helpers it imports: without Chromium this module is skipped with that module's message saying what to
install). The WMRA's blue seat must be on screen where the page's following camera puts it: before
`build_scene` took the robot from the run's config, the page drew the Ridgeback + iiwa instead.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from test_browser import HEIGHT, WIDTH, _root_pose, render, window  # skips this module without Chromium

import robots
from robots.shopping_cart import CART_WHEEL_RADIUS

DURATION = 4.0
SEAT_B = np.array([0.15, 0.0, 0.35])  # seat cushion centre in the WMRA's base_link (robots/wmra.urdf)


def is_blue(p):
    """The seat's saturated blue (~(22, 66, 175)), not the sky gradient behind it (r >= 60 where b > 150)."""
    return (p[:, 2] > 150) & (p[:, 0] < 45) & (p[:, 1] < 100)


@pytest.fixture(scope="module")
def wmra_shots(tmp_path_factory):
    from wholebody.push import PushConfig, build_scene, run_push, save_scene

    tmp = tmp_path_factory.mktemp("wmra")
    result = run_push(PushConfig(robot="wmra", trajectory=2, duration=DURATION))
    page = save_scene(result, tmp / "wmra.html")  # what `push --html` writes
    with build_scene(result) as scene:
        duration = scene.animation_duration()
        times = {"start": 0.0, "middle": duration / 2}
        cameras = {k: scene.camera_at(t) for k, t in times.items()}
        keys = scene.animation_keys()
        frame_times = np.linspace(0.0, duration, len(keys["/meshcat/wmra"]["position"]))
        for name in ("wmra", "shopping_cart"):
            scene.viewer[name].set_property("visible", False)
        scene.save_html(tmp / "hidden.html")
    wmra = robots.load("wmra")
    pin.framesForwardKinematics(wmra.model, wmra.data, pin.neutral(wmra.model))
    base_z = wmra.data.oMf[wmra.model.getFrameId("base_link")].translation[2]
    shots = {}
    for k, t in times.items():
        img = render(page, tmp / f"wmra_{k}.png", tmp / "profile", f"#t={t:.3f}")
        ref = render(tmp / "hidden.html", tmp / f"hidden_{k}.png", tmp / "profile", f"#t={t:.3f}")
        base, yaw = _root_pose(keys, "/meshcat/wmra", frame_times, t)
        cart, cart_yaw = _root_pose(keys, "/meshcat/shopping_cart", frame_times, t)
        c, s = np.cos(yaw), np.sin(yaw)
        seat = base + np.array([c * SEAT_B[0], s * SEAT_B[0], base_z + SEAT_B[2]])
        basket = cart + np.array([0.4 * np.cos(cart_yaw), 0.4 * np.sin(cart_yaw), CART_WHEEL_RADIUS + 0.6])
        uv = {name: cameras[k].project(p, WIDTH, HEIGHT)[0] for name, p in (("seat", seat), ("basket", basket))}
        shots[k] = (img, ref, uv)
    return shots


@pytest.mark.parametrize("when", ("start", "middle"))
def test_wmra_page_shows_wheelchair_arm_and_cart(wmra_shots, when):
    img, ref, uv = wmra_shots[when]
    assert img.shape == (HEIGHT, WIDTH, 3)
    for name, p in uv.items():
        diff = np.abs(window(img, p, 6) - window(ref, p, 6)).mean()
        assert diff > 40, f"{when}: {name}: mean |page - page without robot and cart| = {diff:.1f} at {p.round()}"
    changed = (np.abs(img - ref).sum(axis=2) > 60).mean()
    assert 0.05 < changed < 0.6, f"{when}: WMRA and cart cover {changed:.0%} of the page (empty floor?)"
    seat = is_blue(window(img, uv["seat"], 6)).mean()
    assert seat > 0.3, f"{when}: only {seat:.0%} of the pixels at the WMRA's seat are its blue"
    assert is_blue(window(ref, uv["seat"], 6)).mean() < 0.05, f"{when}: the hidden page is already blue there"
    # No Ridgeback yellow anywhere: the page draws the robot that ran, not the default one.
    yellow = ((img[..., 0] > 150) & (img[..., 1] > 120) & (img[..., 2] < 90)).mean()
    assert yellow < 0.002, f"{when}: {yellow:.1%} of the page is Ridgeback yellow"

"""Tests of wholebody.viz: recorded Meshcat scene vs Pinocchio kinematics, arrows, CoM, animation, page, server, CLI."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import umsgpack

import robots
from cart.logs import CartLog, write_log
from robots.errors import UnknownRobotError
from robots.shopping_cart import CART_HANDLE_X, CART_HANDLE_Z_B, CART_WHEEL_RADIUS
from cartpush.cli import main
from wholebody.viz.scene import ARROW_HEAD
from wholebody.push.scenes import pushing_configuration, pushing_scene
from wholebody.viz import COM_MARKER_Z, Camera, Scene, SceneError, log_scene


@pytest.fixture(scope="module")
def scene():
    with Scene(["ridgeback_iiwa", "shopping_cart"]) as sc:
        yield sc


def test_geometry_world_placement_matches_pinocchio(scene):
    """Every recorded visual (parent planar pose x Pinocchio local placement) equals Pinocchio's oMg for the full q."""
    rng = np.random.default_rng(0)
    for name in ("ridgeback_iiwa", "shopping_cart"):
        robot = robots.load(name)
        pose = (rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-math.pi, math.pi))
        joints = {f"iiwa_joint_{i}": rng.uniform(-1, 1) for i in range(1, 8)} if name == "ridgeback_iiwa" else None
        q = scene.set_robot_pose(name, pose, joints)
        pin.forwardKinematics(robot.model, robot.data, q)
        pin.updateGeometryPlacements(robot.model, robot.data, robot.visual_model, robot.visual_data)
        for gid, geom in enumerate(robot.visual_model.geometryObjects):
            T = scene.world_transform(f"/meshcat/{name}/visuals/{geom.name}")
            np.testing.assert_allclose(T, robot.visual_data.oMg[gid].homogeneous, atol=1e-9)


def test_cart_handle_position_closed_form(scene):
    """The handle frame is at b + R(theta) (CART_HANDLE_X, 0) at height wheel radius + CART_HANDLE_Z_B."""
    x, y, th = 1.3, -0.4, 0.7
    scene.set_robot_pose("shopping_cart", (x, y, th))
    expected = [x + math.cos(th) * CART_HANDLE_X, y + math.sin(th) * CART_HANDLE_X, CART_WHEEL_RADIUS + CART_HANDLE_Z_B]
    np.testing.assert_allclose(scene.frame_position("shopping_cart", "handle"), expected, atol=1e-12)
    np.testing.assert_allclose(scene.cart_to_world([(CART_HANDLE_X, 0.0)])[0], expected, atol=1e-12)


def _tip(scene: Scene, kind: str, name: str, head_length: float = ARROW_HEAD) -> tuple[np.ndarray, np.ndarray]:
    """Return (tail, tip) of an arrow from the recorded transforms (shaft along x, head of nominal `head_length`)."""
    base = f"/meshcat/wrenches/{kind}/{name}"
    head = scene.world_transform(base + "/head")
    tail = scene.world_transform(base)[:3, 3]
    tip = head[:3, 3] + head[:3, :3] @ np.array([head_length / 2, 0.0, 0.0])  # head centre + half its (scaled) length
    return tail, tip


@pytest.mark.parametrize("force", [(30.0, 5.0), (-12.0, 40.0, 3.0), (0.5, -0.2)])
def test_wrench_arrow_spans_scaled_force(scene, force):
    """Arrow tail at the origin, tip at origin + scale * force (also when shorter than the nominal head)."""
    origin = np.array([0.4, -0.2, 1.0])
    length = scene.show_wrench("t", origin, force, kind="desired", scale=0.02)
    f = np.append(force, 0.0)[:3]
    assert length == pytest.approx(0.02 * np.linalg.norm(f))
    tail, tip = _tip(scene, "desired", "t")
    np.testing.assert_allclose(tail, origin, atol=1e-12)
    np.testing.assert_allclose(tip, origin + 0.02 * f, atol=1e-9)


def test_wrench_torque_arrow_is_vertical(scene):
    scene.show_wrench("tq", (0.0, 0.0, 1.0), (10.0, 0.0), torque=-5.0, scale=0.01)
    tail, tip = _tip(scene, "applied", "tq_torque", head_length=0.04)
    np.testing.assert_allclose(tip - tail, [0.0, 0.0, -0.05], atol=1e-9)


def test_com_markers_follow_cart_pose(scene):
    x, y, th = 2.0, 1.0, -1.1
    scene.set_robot_pose("shopping_cart", (x, y, th))
    world = scene.show_com((0.3, 0.15), (0.25, -0.05))
    for key, (dx, dy), p in zip(("com_true", "com_est"), ((0.3, 0.15), (0.25, -0.05)), world):
        expected = [x + math.cos(th) * dx - math.sin(th) * dy, y + math.sin(th) * dx + math.cos(th) * dy, COM_MARKER_Z]
        np.testing.assert_allclose(p, expected, atol=1e-12)
        np.testing.assert_allclose(scene.world_transform(f"/meshcat/com/{key}")[:3, 3], expected, atol=1e-12)


def test_contact_in_cart_frame(scene):
    scene.set_robot_pose("shopping_cart", (0.9, 0.0, math.pi / 2))
    world = scene.show_contact("arm0", [(CART_HANDLE_X, 0.1)], frame="b")
    np.testing.assert_allclose(world[0], [0.9 - 0.1, CART_HANDLE_X, CART_HANDLE_Z_B + CART_WHEEL_RADIUS], atol=1e-12)
    np.testing.assert_allclose(scene.world_transform("/meshcat/contacts/arm0/0")[:3, 3], world[0], atol=1e-12)


def test_animation_keys_resample_log_times():
    """Frames at k / fps take the latest sample at or before that time; quaternions encode the yaw."""
    t = np.array([0.0, 0.3, 0.35, 1.0])
    poses = np.array([[0, 0, 0], [1, 0, 0.5], [2, 1, 1.0], [3, 2, -2.0]], dtype=float)
    with Scene(["shopping_cart"]) as sc:
        n = sc.animate(t, {"shopping_cart": poses}, fps=10)
        keys = sc.animation_keys()["/meshcat/shopping_cart"]
    assert n == 11
    sample = [0, 0, 0, 1, 2, 2, 2, 2, 2, 2, 3]  # frame times 0.0 .. 1.0
    np.testing.assert_allclose(keys["position"][:, :2], poses[sample, :2], atol=1e-12)
    yaw = 2 * np.arctan2(keys["quaternion"][:, 2], keys["quaternion"][:, 3])
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - poses[sample, 2]))), 0.0, atol=1e-12)


def test_animation_of_moving_joints_matches_pinocchio():
    robot = robots.load("ridgeback_iiwa")
    t = np.array([0.0, 1.0])
    joints = np.tile(pin.neutral(robot.model)[4:], (2, 1))
    i4 = robot.model.joints[robot.model.getJointId("iiwa_joint_4")].idx_q - 4
    joints[1, i4] = -1.2
    with Scene(["ridgeback_iiwa"]) as sc:
        sc.animate(t, {"ridgeback_iiwa": np.zeros((2, 3))}, q_joints={"ridgeback_iiwa": joints}, fps=1)
        keys = sc.animation_keys()
    q = pin.neutral(robot.model)
    q[4:] = joints[1]
    pin.forwardKinematics(robot.model, robot.data, q)
    pin.updateGeometryPlacements(robot.model, robot.data, robot.visual_model, robot.visual_data)
    gid = robot.visual_model.getGeometryId("iiwa_link_7_0")
    np.testing.assert_allclose(
        keys["/meshcat/ridgeback_iiwa/visuals/iiwa_link_7_0"]["position"][1],
        robot.visual_data.oMg[gid].translation,
        atol=1e-12,
    )


def test_static_page_is_self_contained_and_replays_scene(tmp_path):
    with pushing_scene() as sc:
        sc.show_trace("path", [(0, 0), (1, 0.2), (2, 0.0)])
        sc.animate([0.0, 1.0], {"shopping_cart": [(0.9, 0, 0), (1.4, 0, 0)]})
        path = sc.save_html(tmp_path / "scene.html")
        n_commands = len(sc.window.commands())
    html = path.read_text()
    assert not re.search(r"<script[^>]+src=", html) and "http://" not in html.split("<script>")[0]
    calls = re.findall(r'handle_command_bytearray\(b64\("([A-Za-z0-9+/=]+)"\)\)', html)
    assert len(calls) == n_commands
    import base64
    import umsgpack

    kinds = [umsgpack.unpackb(base64.b64decode(c))["type"] for c in calls]
    assert kinds[-1] == "set_animation" and kinds.count("set_animation") == 1
    assert kinds.count("set_object") > 30


def test_camera_projection_closed_form():
    cam = Camera(target=(0.0, 0.0, 0.0), eye=(0.0, -4.0, 0.0), fov_deg=60.0)
    uv = cam.project(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), 800, 600)
    f = 300 / math.tan(math.radians(30))  # focal length in pixels (vertical fov, square pixels)
    np.testing.assert_allclose(uv, [[400, 300], [400 + f / 4, 300], [400, 300 - f / 4]], atol=1e-9)


@pytest.mark.parametrize(
    "name, cart, contact_y",
    [
        ("ridgeback_iiwa", (0.9, 0.3, 0.4), 0.0),
        ("ridgeback_iiwa", (0.2, -0.5, -1.1), 0.15),
        ("wmra", (0.0, 0.0, 0.3), 0.1),
    ],
)
def test_pushing_configuration_holds_handle_with_push_grasp(name, cart, contact_y):
    """The hand sits on the handle point, tool axis forward and `grasp_pitch` down, base where the profile says."""
    from robots.profiles import profile

    prof = profile(name)
    base, q = pushing_configuration(cart, contact_y, robot=name)
    robot = robots.load(name)
    pin.framesForwardKinematics(robot.model, robot.data, q)
    M = robot.data.oMf[robot.frame_id("ee")]
    c, s = math.cos(cart[2]), math.sin(cart[2])
    handle = [
        cart[0] + c * CART_HANDLE_X - s * contact_y,
        cart[1] + s * CART_HANDLE_X + c * contact_y,
        CART_WHEEL_RADIUS + CART_HANDLE_Z_B,
    ]
    np.testing.assert_allclose(M.translation, handle, atol=1e-5)
    cp, sp = math.cos(prof.grasp_pitch), math.sin(prof.grasp_pitch)
    np.testing.assert_allclose(M.rotation[:, 2], [cp * c, cp * s, -sp], atol=1e-5)  # tool axis
    np.testing.assert_allclose(M.rotation[:, 0], [sp * c, sp * s, cp], atol=1e-5)  # fingers
    bx = CART_HANDLE_X + prof.push_base_x
    by = contact_y if prof.push_base_y is None else prof.push_base_y
    np.testing.assert_allclose(base, [cart[0] + c * bx - s * by, cart[1] + s * bx + c * by, cart[2]], atol=1e-12)
    np.testing.assert_allclose(q[:4], [base[0], base[1], math.cos(base[2]), math.sin(base[2])], atol=1e-12)
    lo, hi = robot.model.lowerPositionLimit[4:], robot.model.upperPositionLimit[4:]
    assert np.all(q[4:] >= lo - 1e-12) and np.all(q[4:] <= hi + 1e-12)


def test_pushing_configuration_refuses_a_robot_that_does_not_push():
    with pytest.raises(SceneError, match="does not push"):
        pushing_configuration(robot="shopping_cart")
    with pytest.raises(SceneError, match="3 finite numbers"):
        pushing_configuration((0.0, math.nan, 0.0))


def test_bad_input_raises_project_errors():
    with pytest.raises(UnknownRobotError):
        Scene(["nope"])
    with Scene(["shopping_cart"]) as sc:
        with pytest.raises(SceneError):
            sc.set_robot_pose("shopping_cart", (0.0, np.nan, 0.0))
        with pytest.raises(SceneError):
            sc.set_robot_pose("ridgeback_iiwa", (0.0, 0.0, 0.0))
        with pytest.raises(SceneError):
            sc.show_wrench("a", (0, 0, 0), (1, 0), kind="sensed")
        with pytest.raises(SceneError):
            sc.show_trace("a", [(0, 0)])
        with pytest.raises(SceneError):
            sc.animate([0.0, 0.0], {"shopping_cart": np.zeros((2, 3))})


def test_server_starts_and_close_stops_it():
    sc = Scene(["shopping_cart"], serve=True)
    try:
        proc = sc._server
        assert proc.poll() is None
        assert re.match(r"http://127\.0\.0\.1:\d+/static/", sc.url)
        sc.set_robot_pose("shopping_cart", (1.0, 0.0, 0.0))  # forwarded to the live server (would block if not)
    finally:
        sc.close()
    assert proc.poll() is not None
    sc.close()  # idempotent


def _write_log(path, n=40):
    t = np.linspace(0.0, 2.0, n)
    q = np.column_stack((0.5 * t, 0.1 * t**2, 0.2 * t))
    gamma = np.column_stack((np.full(n, 10.0), np.full(n, 1.0), np.zeros(n)))
    contact = np.column_stack((np.full(n, -0.15), np.linspace(-0.2, 0.2, n)))
    write_log(path, CartLog(t=t, q=q, gamma=gamma, contact_b=contact))
    return t, q, contact


def test_log_scene_animates_cart_and_contact(tmp_path):
    t, q, contact = _write_log(tmp_path / "run.csv")
    with log_scene(tmp_path / "run.csv", fps=10) as sc:
        keys = sc.animation_keys()
    idx = np.searchsorted(t, np.arange(21) / 10, side="right") - 1
    np.testing.assert_allclose(keys["/meshcat/shopping_cart"]["position"][:, :2], q[idx, :2], atol=1e-9)
    c, s = np.cos(q[idx, 2]), np.sin(q[idx, 2])
    cx = q[idx, 0] + c * contact[idx, 0] - s * contact[idx, 1]
    np.testing.assert_allclose(keys["/meshcat/contacts/shopping_cart/0"]["position"][:, 0], cx, atol=1e-9)


def test_cli_view_html_and_errors(tmp_path, capsys):
    out = tmp_path / "robot.html"
    assert main(["view", "--robot", "wmra", "--html", str(out)]) == 0
    assert out.stat().st_size > 500_000 and "wrote" in capsys.readouterr().out
    _write_log(tmp_path / "run.csv")
    assert main(["view", str(tmp_path / "run.csv"), "--html", str(tmp_path / "log.html")]) == 0
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x,y\n0,0,0\n")
    for argv in (
        ["view", "--robot", "nope"],
        ["view", str(tmp_path / "missing.csv")],
        ["view", str(bad)],
        ["view", "--scenario", "12", "--html", str(out)],
        ["view", "--robot", "wmra", "--html", str(tmp_path / "no" / "x.html")],
    ):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("cartpush view: error:") and err.count("\n") == 1


def test_cli_view_scenario_writes_page(tmp_path):
    out = tmp_path / "s3.html"
    assert main(["view", "--scenario", "3", "--duration", "2", "--html", str(out)]) == 0
    assert out.stat().st_size > 500_000


def test_library_code_never_selects_a_matplotlib_backend():
    """Only command-line entry points may call matplotlib.use (it turns off a notebook's inline figures)."""
    root = Path(__file__).resolve().parents[2]
    offenders = [
        str(p.relative_to(root))
        for pkg in ("cart", "wholebody", "studies", "robots")
        for p in (root / pkg).rglob("*.py")
        if "matplotlib.use(" in p.read_text(encoding="utf-8") and "cartpush/cli/" not in p.as_posix()
    ]
    assert not offenders, f"library modules select a Matplotlib backend: {offenders}"


def test_animated_page_plays_on_open_from_first_frame_and_follows():
    """The static state is the first frame, the page plays when opened, and the camera follows the named robots."""
    with Scene(["shopping_cart"]) as sc:
        sc.animate(
            [0.0, 1.0, 2.0],
            {"shopping_cart": [(0.0, 0, 0), (1.0, 0, 0), (3.0, 1.0, 0)]},
            fps=10,
            follow=("shopping_cart",),
        )
        np.testing.assert_allclose(sc.world_transform("/meshcat/shopping_cart")[:3, 3], 0.0, atol=1e-12)
        html = sc.static_html()
        cam0, cam = sc.camera_at(0.0), sc.camera_at(2.0)
        assert sc.animation_duration() == pytest.approx(2.0)
        with pytest.raises(SceneError):
            sc.animate([0.0, 1.0], {"shopping_cart": np.zeros((2, 3))}, follow=("ridgeback_iiwa",))
    anim = umsgpack.unpackb(sc.window.animation)
    assert anim["options"]["play"] is True
    assert '[["meshcat", "shopping_cart"]]' in html and "anim.seek = seek" in html
    assert 'id="cartpush-play"' in html and "!m && !pause && true" in html  # pause button; plays without a fragment
    np.testing.assert_allclose(np.subtract(cam.eye, cam0.eye), [3.0, 1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(np.subtract(cam.target, cam0.target), [3.0, 1.0, 0.0], atol=1e-9)


def test_page_opened_paused_when_asked():
    """``animate(play=False)``: the page opens paused (``#play`` starts it)."""
    with Scene(["shopping_cart"]) as sc:
        sc.animate([0.0, 1.0], {"shopping_cart": [(0.0, 0, 0), (1.0, 0, 0)]}, fps=10, play=False)
        html = sc.static_html()
    assert "!m && !pause && false" in html


def test_default_scene_puts_cart_ahead_and_frames_everything():
    """Scene(robot, cart) with defaults: the cart stands ahead of the robot and the camera sees the arm's tip."""
    with Scene(["ridgeback_iiwa", "shopping_cart"]) as sc:
        np.testing.assert_allclose(sc.robot_q("shopping_cart")[:2], (0.9, 0.0))
        cam = sc.camera
        pts = np.array([sc.frame_position("ridgeback_iiwa", "ee"), sc.frame_position("shopping_cart", "handle")])
    uv = cam.project(pts, 1024, 768)
    assert np.all((uv > 20) & (uv < (1004, 748))), f"projected off screen: {uv.round()}"


def test_legend_names_what_the_scene_draws():
    """The page's legend lists the arrows (with their scale), the CoM spheres, the contact and the traces drawn."""
    with Scene(["shopping_cart"]) as sc:
        assert sc.legend() == []
        sc.show_wrench("arm0", [(CART_HANDLE_X, 0.0)], (10.0, 0.0), torque=1.0, frame="b", scale=0.03)
        sc.show_com((0.3, 0.1), (0.25, 0.0))
        sc.show_contact("arm0", [(CART_HANDLE_X, 0.0)], frame="b")
        sc.show_trace("plan", [(0.0, 0.0), (1.0, 0.0)], label="cyan line: the plan")
        texts = [e.text for e in sc.legend()]
        html = sc.static_html()
    assert any("force the hand applies, 3 cm per N (10 N = 30 cm)" in t for t in texts)
    assert any("yaw torque" in t for t in texts)
    assert any("true CoM" in t for t in texts) and any("estimated CoM" in t for t in texts)
    assert "cyan line: the plan" in texts and any("contact point" in t for t in texts)
    assert all(t.split(",")[0] in html for t in texts)


def test_animation_scale_draws_a_median_push_force_visibly_and_clips_peaks():
    """3.5 N median hand force -> 5 cm per N; a 60 N peak is clipped to ARROW_MAX."""
    from wholebody.viz.scene import ARROW_MAX

    t = np.linspace(0.0, 1.0, 11)
    forces = np.column_stack((np.full(11, 3.5), np.zeros(11)))
    forces[5, 0] = 60.0
    origins = np.zeros((11, 3))
    with Scene(["shopping_cart"]) as sc:
        sc.animate(t, {"shopping_cart": np.zeros((11, 3))}, wrenches={"hand": (origins, forces)}, fps=10)
        keys = sc.animation_keys()
        assert sc.arrow_scale == pytest.approx(0.05)
    shaft = keys["/meshcat/wrenches/applied/hand/shaft"]["scale"][:, 0]
    head = keys["/meshcat/wrenches/applied/hand/head"]["scale"][:, 0] * ARROW_HEAD
    np.testing.assert_allclose((shaft + head)[0], 0.05 * 3.5, atol=1e-9)
    assert (shaft + head)[5] == pytest.approx(ARROW_MAX)


def test_axes_at_the_origin_are_hidden():
    """Meshcat's axes (a blue vertical line at the origin, read as a torque arrow) are hidden."""
    with Scene(["shopping_cart"]) as sc:
        props = [umsgpack.unpackb(b) for b in sc.window.commands()]
    assert any(c.get("path") == "/Axes" and c.get("property") == "visible" and c["value"] is False for c in props)


def test_iframe_is_compressed_and_wrapped():
    """The notebook iframe holds the gzipped page (a third of its size) inside a <div> (no IPython warning)."""
    import base64
    import gzip
    import html as html_mod
    import re

    with Scene(["shopping_cart"]) as sc:
        page, frame = sc.static_html(), sc.iframe()
    assert frame.startswith("<div") and "<iframe" in frame
    blob = re.search(r'atob\("([A-Za-z0-9+/=]+)"\)', html_mod.unescape(frame)).group(1)
    assert gzip.decompress(base64.b64decode(blob)).decode("utf-8") == page
    assert len(frame) < 0.5 * len(page)


def _robot_pixel_height(scene: Scene, name: str, height: int = 768) -> float:
    """Return the projected height (px, 1024x768 page) of robot `name`'s frames as displayed, with the page's camera."""
    robot = scene.robots[name]
    pin.framesForwardKinematics(robot.model, robot.data, scene.robot_q(name))
    uv = scene.camera.project(np.array([f.translation for f in robot.data.oMf]), 1024, height)
    assert np.all((uv > 0) & (uv < (1024, height))), f"{name} is partly off screen: {uv.min(axis=0)}, {uv.max(axis=0)}"
    return float(np.ptp(uv[:, 1]))


def test_scenario_page_frames_the_robot_not_the_whole_path():
    """`view --scenario 6`: the robot fills a quarter of the page's height at the first frame, and the camera follows."""
    from wholebody.push.scenes import scenario_scene

    with scenario_scene(6, duration=4.0) as sc:
        assert _robot_pixel_height(sc, "ridgeback_iiwa") > 0.25 * 768
        assert sc.follow == ("ridgeback_iiwa", "shopping_cart")
        texts = " ".join(e.text for e in sc.legend())
        html = sc.static_html()
    assert "true CoM" in texts and "estimated CoM" in texts and "desired path" in texts
    assert "CoM error" in html and '"unit":"cm"' in html  # the live read-out, in cm


def test_log_page_frames_and_follows_the_cart():
    """`view LOG`: the cart is large on screen at its first sample and the camera follows it."""
    t = np.linspace(0.0, 10.0, 101)
    log = CartLog(t=t, q=np.column_stack((0.8 * t, np.zeros_like(t), np.zeros_like(t))), gamma=np.ones((101, 3)))
    with log_scene(log) as sc:
        assert _robot_pixel_height(sc, "shopping_cart") > 0.2 * 768
        assert sc.follow == ("shopping_cart",)
        np.testing.assert_allclose(np.subtract(sc.camera_at(10.0).eye, sc.camera.eye), [8.0, 0.0, 0.0], atol=1e-9)

"""A cart file drawn as itself (wholebody.viz.mjcf) and a push page's cart and its joints (wholebody.viz.push_cart).

The Pinocchio model built from a cart file must put every drawn geom where MuJoCo puts it, for any angles of the
file's joints; a page replays the angles a MuJoCo run recorded (`wholebody.push.mujoco_cart.CartJointRecord`), and
falls back to the no-side-slip trail model only for the kinematic plant.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from cart.params import CartParams
from wholebody.push import mujoco_cart
from wholebody.push.cart_file import load_cart_file
from wholebody.viz import Scene, SceneError
from wholebody.viz.mjcf import VISIBLE_GROUPS, cart_file_robot, cart_robot
from wholebody.viz.push_cart import CASTER_SOURCES, recorded_rows, run_cart

CARTS = Path(__file__).resolve().parents[2] / "examples" / "carts"
FILES = sorted(CARTS.glob("*.xml"))


def _mujoco_geoms(mj: mujoco.MjModel, qpos: np.ndarray) -> dict[str, np.ndarray]:
    """Return the world pose (4x4) of every visible geom of the cart subtree at qpos (MuJoCo's kinematics)."""
    from wholebody.push.mujoco_cart import subtree_bodies

    d = mujoco.MjData(mj)
    d.qpos[:] = qpos
    mujoco.mj_kinematics(mj, d)
    bodies = set(int(b) for b in subtree_bodies(mj, mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, "cart")))
    out = {}
    for g in range(mj.ngeom):
        if int(mj.geom_bodyid[g]) in bodies and int(mj.geom_group[g]) in VISIBLE_GROUPS:
            if int(mj.geom_type[g]) in (int(mujoco.mjtGeom.mjGEOM_MESH), int(mujoco.mjtGeom.mjGEOM_ELLIPSOID)):
                continue  # drawn as the box around them (offset by the box's centre)
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = d.geom_xmat[g].reshape(3, 3), d.geom_xpos[g]
            out[g] = T
    return out


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_every_geom_is_where_mujoco_puts_it_for_any_joint_angles(path):
    """The cart at a planar pose with random joint angles: each drawn geom's pose is MuJoCo's (the file's {b} at
    its standing height, the planar root on the floor)."""
    mj = load_cart_file(path).spec().compile()
    cart = cart_robot(mj)
    cid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, "cart")
    record = mujoco_cart.CartJointRecord.of(mj)
    assert set(record.names) == set(cart.joints) and record.names  # every caster and wheel joint is replayed
    rng = np.random.default_rng(3)
    x, y, th = 0.7, -0.4, 0.9
    qpos = mj.qpos0.copy()
    for _, kind, adr in mujoco_cart.subtree_joints(mj, cid):
        qpos[adr] += rng.uniform(-1.5, 1.5) if kind == "hinge" else rng.uniform(-0.003, 0.003)
    root = int(mj.jnt_qposadr[int(mj.body_jntadr[cid])])
    qpos[root : root + 7] = [x, y, mj.body_pos[cid][2], math.cos(th / 2), 0.0, 0.0, math.sin(th / 2)]
    d = mujoco.MjData(mj)
    d.qpos[:] = qpos
    record.record(0.0, d)
    q = np.r_[
        x, y, math.cos(th), math.sin(th), cart.joints_from_record(record.names, record.kinds, record.series()[1])[0]
    ]
    model, geoms = cart.robot.model, cart.robot.visual_model
    data, gdata = model.createData(), pin.GeometryData(geoms)
    pin.forwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, geoms, gdata)
    expected = _mujoco_geoms(mj, qpos)
    drawn = {g.name: gdata.oMg[i].homogeneous for i, g in enumerate(geoms.geometryObjects)}
    matched = 0
    for g, T in expected.items():
        body = int(mj.geom_bodyid[g])
        own = f"{mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, body)}_geom{g - int(mj.body_geomadr[body])}"
        name = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_GEOM, g) or own
        if name not in drawn:
            continue  # a transparent geom (alpha 0) is not drawn
        R = T[:3, :3]
        np.testing.assert_allclose(drawn[name][:3, 3], T[:3, 3], atol=1e-9, err_msg=name)
        # the shape's own axis (z: a capsule's or cylinder's) agrees; boxes need their full rotation
        np.testing.assert_allclose(drawn[name][:3, :3], R, atol=1e-9, err_msg=name)
        matched += 1
    assert matched >= 0.8 * len(expected)


def test_a_hospital_bed_is_drawn_bed_sized_with_its_push_bar():
    """The bed's deck is a 2.1 m x 0.95 m box 0.57 m above the floor; {b} at 0.55 m, the bar 0.40 m above it."""
    cart = cart_file_robot(CARTS / "hospital_bed.xml")
    deck = next(g for g in cart.robot.visual_model.geometryObjects if g.name == "deck")
    np.testing.assert_allclose(2 * deck.geometry.halfSide, [2.1, 0.95, 0.06], atol=1e-9)
    with Scene(["ridgeback_iiwa", cart.robot]) as scene:
        assert scene.cart == "cart"
        z_b, z_handle = scene.cart_heights()
        assert z_b == pytest.approx(0.55) and z_handle == pytest.approx(0.40)
        scene.set_robot_pose("cart", (1.0, 0.5, math.pi / 2))
        np.testing.assert_allclose(scene.cart_to_world([(-0.16, 0.0)])[0], [1.0, 0.5 - 0.16, 0.95], atol=1e-9)
        T = scene.world_transform("/meshcat/cart/visuals/deck")
        np.testing.assert_allclose(T[:3, 3], [1.0, 0.5 + 0.87, 0.57], atol=1e-9)
        bar = scene.world_transform("/meshcat/cart/visuals/handle_headboard")
        assert bar[2, 3] == pytest.approx(0.95)


def test_a_scene_without_a_cart_says_so():
    with Scene(["ridgeback_iiwa"]) as scene:
        assert scene.cart is None
        with pytest.raises(SceneError, match="no cart"):
            scene.cart_to_world([(0.0, 0.0)])


def test_the_shopping_cart_keeps_its_heights():
    from robots.shopping_cart import CART_HANDLE_Z_B, CART_WHEEL_RADIUS

    with Scene(["shopping_cart"]) as scene:
        assert scene.cart == "shopping_cart"
        assert scene.cart_heights() == pytest.approx((CART_WHEEL_RADIUS, CART_HANDLE_Z_B))


def test_recorded_rows_take_the_latest_sample_at_or_before_each_time():
    t_rec = np.array([0.0, 0.01, 0.02, 0.03])
    np.testing.assert_array_equal(recorded_rows(t_rec, np.array([0.0, 0.01, 0.025, 0.5, -1.0])), [0, 1, 2, 3, 0])


def _result(n: int = 200, dt: float = 0.01) -> SimpleNamespace:
    """A push result as a page reads it: a cart turning left at 0.3 m/s, 0.4 rad/s (no controller run)."""
    t = dt * np.arange(n)
    th = 0.4 * t
    q = np.column_stack([np.cumsum(0.3 * np.cos(th)) * dt, np.cumsum(0.3 * np.sin(th)) * dt, th])
    qd = np.column_stack([0.3 * np.cos(th), 0.3 * np.sin(th), np.full(n, 0.4)])
    cfg = SimpleNamespace(dt=dt, cart_model=None)
    return SimpleNamespace(t=t, q_true=q, qd_true=qd, config=cfg, plant_report={"plant": "kinematic"})


def _record(mj: mujoco.MjModel, t: np.ndarray, angle: dict[str, np.ndarray]) -> mujoco_cart.CartJointRecord:
    """A record of the cart's joints with the given hinge angles over time (others at their reference)."""
    record = mujoco_cart.CartJointRecord.of(mj)
    d = mujoco.MjData(mj)
    for k, tk in enumerate(t):
        for name, _, adr in zip(record.names, record.kinds, record.addresses):
            d.qpos[adr] = angle[name][k] if name in angle else mj.qpos0[adr]
        record.record(float(tk), d)
    return record


def test_the_kinematic_plants_cart_swivels_by_the_trail_model():
    result = _result()
    cart = run_cart(result, np.arange(0, 200, 10))
    assert cart.source == "trail" and cart.legend == CASTER_SOURCES["trail"] and cart.robot == "shopping_cart"
    with Scene(["shopping_cart"]) as scene:
        j = scene.robots["shopping_cart"].model.joints[
            scene.robots["shopping_cart"].model.getJointId("caster_left_swivel")
        ]
        psi = np.arctan2(cart.joints[:, j.idx_q - 3], cart.joints[:, j.idx_q - 4])
        assert np.ptp(psi) > 0.05  # the cart turns: the trail model swivels the caster


def test_a_mujoco_run_of_the_default_cart_replays_the_recorded_angles_not_the_trail_model():
    """The shopping cart's casters and wheels at the recorded angles (URDF names), even where rolling without side
    slip would turn them otherwise (a sticky caster)."""
    result = _result()
    result.plant_report = {"plant": "mujoco"}
    mj, _ = mujoco_cart.build(mujoco_cart.shopping_cart(CartParams(20.0, 0.3, 0.15, 3.0, 5.0)))
    t_rec = np.r_[result.t, result.t[-1] + 0.01]
    stuck = np.full(len(t_rec), 0.25)  # the left caster stays at 0.25 rad whatever the motion
    spin = 4.0 * t_rec
    result.plant_report["cart_joints"] = _record(mj, t_rec, {"swivel_left": stuck, "axle_right": spin})
    idx = np.arange(0, 200, 10)
    cart = run_cart(result, idx)
    assert cart.source == "recorded" and cart.robot == "shopping_cart"
    with Scene(["shopping_cart"]) as scene:
        model = scene.robots["shopping_cart"].model
        swivel = model.joints[model.getJointId("caster_left_swivel")].idx_q - 4
        wheel = model.joints[model.getJointId("rear_right_wheel_joint")].idx_q - 4
    np.testing.assert_allclose(np.arctan2(cart.joints[:, swivel + 1], cart.joints[:, swivel]), 0.25, atol=1e-12)
    np.testing.assert_allclose(
        np.arctan2(cart.joints[:, wheel + 1], cart.joints[:, wheel]), np.angle(np.exp(1j * spin[idx])), atol=1e-12
    )


def test_a_cart_file_run_draws_the_file_with_its_recorded_joints():
    path = CARTS / "hospital_bed.xml"
    result = _result()
    result.config.cart_model = str(path)
    idx = np.arange(0, 200, 10)
    at_rest = run_cart(result, idx)
    assert at_rest.source == "rest" and not isinstance(at_rest.robot, str) and at_rest.name == "cart"
    assert np.all(at_rest.joints == 0.0)
    mj = load_cart_file(path).spec().compile()
    t_rec = np.r_[result.t, result.t[-1] + 0.01]
    swing = np.linspace(0.0, math.pi, len(t_rec))
    result.plant_report = {"plant": "mujoco", "cart_joints": _record(mj, t_rec, {"swivel_foot_left": swing})}
    cart = run_cart(result, idx)
    assert cart.source == "recorded"
    k = cart_file_robot(path).joints["swivel_foot_left"][0]
    np.testing.assert_allclose(cart.joints[:, k], swing[idx], atol=1e-12)
    others = np.delete(cart.joints, k, axis=1)
    assert np.all(others == 0.0)


def test_the_record_reports_only_its_joints_and_length_in_json():
    from cart.jsonout import dumps_strict

    mj, d = mujoco_cart.build(mujoco_cart.MujocoCart())
    record = mujoco_cart.CartJointRecord.of(mj)
    for k in range(3):
        record.record(0.01 * k, d)
    assert dumps_strict({"cart_joints": record}) == (
        '{"cart_joints": {"joints": ["axle_left", "axle_right", "swivel_left", "caster_axle_left", "swivel_right", '
        '"caster_axle_right"], "samples": 3}}'
    )
    assert record.series()[1].shape == (3, 6)


def test_cli_view_draws_a_cart_file_and_refuses_a_broken_one(tmp_path, capsys):
    from cartpush.cli import main

    out = tmp_path / "bed.html"
    assert main(["view", "--cart-model", str(CARTS / "hospital_bed.xml"), "--html", str(out)]) == 0
    page = out.read_text()
    assert "handle sites" in page and out.stat().st_size > 500_000
    broken = tmp_path / "broken.xml"
    broken.write_text(
        '<mujoco><worldbody><body name="crate"><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'
    )
    capsys.readouterr()
    assert main(["view", "--cart-model", str(broken), "--html", str(out)]) == 2
    err = capsys.readouterr().err
    assert "no body named 'cart'" in err and err.count("\n") == 1


def test_a_mujoco_run_draws_the_robots_recorded_casters_and_wheels_over_its_state():
    """The WMRA's joints the plant recorded (scene names `r0/...`) replace the page's: a caster stuck at 0.3 rad,
    a wheel turning; joints the record lacks keep the state's values; no record: None (the trail model)."""
    import robots
    from wholebody.viz.push_cart import recorded_robot_joints

    model = robots.load("wmra").model
    result = _result()
    idx = np.arange(0, 200, 10)
    rest = np.tile(pin.neutral(model)[4:], (len(idx), 1))
    arm = model.joints[model.getJointId("arm_joint3")].idx_q - 4
    rest[:, arm] = 0.7  # from the robot's state
    assert recorded_robot_joints(result, model, rest, idx) is None
    t_rec = np.r_[result.t, result.t[-1] + 0.01]
    record = mujoco_cart.CartJointRecord(("r0/caster_left_swivel", "r0/wheel_right_joint"), ("hinge", "hinge"), (0, 1))
    for k, tk in enumerate(t_rec):
        record.t.append(float(tk))
        record.q.append(np.array([0.3, 2.0 * tk]))
    result.plant_report = {"plant": "mujoco", "robot_joints": [record]}
    q = recorded_robot_joints(result, model, rest, idx)
    caster = model.joints[model.getJointId("caster_left_swivel")].idx_q - 4
    wheel = model.joints[model.getJointId("wheel_right_joint")].idx_q - 4
    np.testing.assert_allclose(np.arctan2(q[:, caster + 1], q[:, caster]), 0.3, atol=1e-12)
    np.testing.assert_allclose(
        np.arctan2(q[:, wheel + 1], q[:, wheel]), np.angle(np.exp(2j * result.t[idx])), atol=1e-9
    )
    assert np.all(q[:, arm] == 0.7)
    others = np.ones(q.shape[1], bool)
    others[[caster, caster + 1, wheel, wheel + 1]] = False
    np.testing.assert_array_equal(q[:, others], rest[:, others])


def test_handle_sites_are_drawn_orange_and_big_enough_to_see(tmp_path):
    """A wheelchair's two 5 mm grip points hid inside its 12 mm posts in the site's default grey: each handle site
    is drawn in `HANDLE_RGBA` at least `HANDLE_MIN_RADIUS` across, where the file puts it."""
    from wholebody.viz.mjcf import HANDLE_MIN_RADIUS, HANDLE_RGBA

    path = tmp_path / "grips.xml"
    path.write_text(
        '<mujoco><worldbody><geom type="plane" size="0 0 1"/><body name="cart" pos="0 0 0.02"><freejoint/>'
        '<geom type="box" size="0.3 0.2 0.02" mass="5"/>'
        '<site name="handle_l" pos="-0.2 0.22 0.8" size="0.005"/><site name="handle_r" pos="-0.2 -0.22 0.8" size="0.005"/>'
        "</body></worldbody></mujoco>"
    )
    cart = cart_file_robot(path)
    grips = {g.name: g for g in cart.robot.visual_model.geometryObjects if g.name.startswith("handle")}
    assert sorted(grips) == ["handle_l", "handle_r"]
    for name, y in (("handle_l", 0.22), ("handle_r", -0.22)):
        g = grips[name]
        assert np.allclose(g.meshColor, HANDLE_RGBA) and g.geometry.radius >= HANDLE_MIN_RADIUS
        assert g.placement.translation[:2] == pytest.approx([-0.2, y], abs=1e-9)

"""Cart files (docs/mujoco.md): each break of the contract gets its one-line message; a conforming file is pushed."""

from __future__ import annotations

from pathlib import Path

import pytest

from wholebody.push import PushConfig, build_controller, mujoco_cart
from wholebody.push.cart_file import CartFileError, load_cart_file
from wholebody.push.config import TRUE_CART
from wholebody.errors import WholeBodyError
from wholebody.push.mujoco_plant import MujocoPlant, MujocoPlantError

GOOD_BODY = """
    <body name="cart" pos="0 0 0.05">
      <freejoint/>
      <geom type="box" size="0.4 0.25 0.05" mass="12"/>
      {sites}
    </body>"""
EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "carts"
BAR = '<site name="handle" type="capsule" size="0.015" fromto="-0.15 -0.25 0.9 -0.15 0.25 0.9"/>'
#: a wheel on a hinge along y, its cylinder turned by `turn`: 90 degrees about x rolls on the hinge, 1.5708 (radians
#: meant, degrees read: MuJoCo's default unit) leaves it a puck under the axle
PUCK = (
    '<body name="wl" pos="0 0.3 0.05"><joint name="axle_l" type="hinge" axis="0 1 0"/>'
    '<geom type="cylinder" size="0.1 0.02" {turn}/></body>'
)


def _write(tmp_path, body: str, floor: bool = True) -> str:
    plane = '<geom name="ground" type="plane" size="0 0 1"/>' if floor else ""
    path = tmp_path / "cart.xml"
    path.write_text(f"<mujoco><worldbody>{plane}{body}</worldbody></mujoco>")
    return str(path)


@pytest.mark.parametrize(
    "body, message",
    [
        (GOOD_BODY.replace('name="cart"', 'name="trolley"').format(sites=BAR), "no body named 'cart'"),
        (GOOD_BODY.replace("<freejoint/>", '<joint type="slide" axis="1 0 0"/>').format(sites=BAR), "no free joint"),
        (GOOD_BODY.format(sites='<site name="grip" pos="-0.15 0 0.9"/>'), "no site named 'handle' or 'handle_\\*'"),
        (
            GOOD_BODY.format(sites='<site name="handle_left" type="box" size="0.02 0.02 0.02" pos="-0.15 0 0.9"/>'),
            "handle site 'handle_left' is neither a point",
        ),
        (
            GOOD_BODY.format(
                sites='<body name="bar" pos="-0.15 0 0.9"><joint name="hinge" axis="0 1 0"/><geom size="0.02"/>'
                '<site name="handle"/></body>'
            ),
            "handle site 'handle' is on body 'bar', which moves relative to 'cart' \\(joint 'hinge'\\)",
        ),
        (
            GOOD_BODY.format(sites=BAR.replace('name="handle"', 'name="bar"'))
            + '<body name="post" pos="1 1 0"><geom size="0.05"/><site name="handle"/></body>',
            "handle site 'handle' is on body 'post', not on 'cart'",
        ),
        ("<body name='cart'><freejoint/><geom type='nonsense'/></body>", "not a valid MuJoCo model"),
        (
            GOOD_BODY.format(sites=BAR + PUCK.format(turn='euler="1.5708 0 0"')),
            "wheel 'wl' stands on a cylinder turned 88 degrees from the axis of its hinge 'axle_l', so it slides",
        ),
        (
            GOOD_BODY.replace('pos="0 0 0.05"', 'pos="0 0 0.05" euler="0 0 90"').format(sites=BAR),
            "body 'cart' starts turned 90 deg about z",
        ),
        (GOOD_BODY.replace('pos="0 0 0.05"', 'pos="0 0 0"').format(sites=BAR), "0.050 m below the floor"),
        (GOOD_BODY.replace('pos="0 0 0.05"', 'pos="0 0 0.6"').format(sites=BAR), "0.550 m above the floor"),
        (GOOD_BODY.format(sites=BAR.replace("-0.15", "1.05")), "every handle is ahead of \\{b\\}"),
        (  # a fixed axle 0.4 m behind the body's origin: {b} is not the no-slip point
            GOOD_BODY.format(
                sites=BAR + PUCK.format(turn='euler="90 0 0"').replace('pos="0 0.3 0.05"', 'pos="-0.4 0.3 0.05"')
            ),
            "the fixed wheels' axle is -0.400 m along x",
        ),
    ],
    ids=[
        "no_cart_body",
        "no_free_joint",
        "no_handle_site",
        "handle_not_point_or_bar",
        "handle_on_moving_child",
        "handle_elsewhere",
        "bad_mjcf",
        "wheel_turned_in_degrees",
        "cart_turned",
        "cart_sunk",
        "cart_floating",
        "handle_ahead",
        "axle_off_b",
    ],
)
def test_each_break_of_the_contract_gets_its_message(tmp_path, body, message):
    with pytest.raises(CartFileError, match=message) as info:
        load_cart_file(_write(tmp_path, body))
    assert "\n" not in str(info.value)


def test_a_floor_plane_off_z_0_is_refused_the_robots_stand_at_0(tmp_path):
    raised = GOOD_BODY.replace('pos="0 0 0.05"', 'pos="0 0 0.35"').format(sites=BAR)
    path = tmp_path / "cart.xml"
    path.write_text(
        f'<mujoco><worldbody><geom name="ground" type="plane" size="0 0 1" pos="0 0 0.3"/>{raised}</worldbody></mujoco>'
    )
    with pytest.raises(CartFileError, match="the floor plane 'ground' is at z = 0.3 m, but the robots stand on z = 0"):
        load_cart_file(str(path))


@pytest.mark.parametrize("active, refused", [("true", True), ("false", False)])
def test_a_cart_welded_to_the_world_is_refused(tmp_path, active, refused):
    body = GOOD_BODY.format(sites=BAR)
    path = tmp_path / "cart.xml"
    path.write_text(
        f'<mujoco><worldbody><geom name="ground" type="plane" size="0 0 1"/>{body}</worldbody>'
        f'<equality><weld name="parking_brake" body1="cart" active="{active}"/></equality></mujoco>'
    )
    if refused:
        with pytest.raises(CartFileError, match="the equality 'parking_brake' ties the cart to the world"):
            load_cart_file(str(path))
    else:
        assert load_cart_file(str(path)).mass is not None


@pytest.mark.parametrize(
    "body, floor, message",
    [
        (  # the box on the floor collides with nothing: a <default> that makes every geom visual
            GOOD_BODY.replace('mass="12"', 'mass="12" contype="0" conaffinity="0"').format(sites=BAR),
            '<geom name="ground" type="plane" size="0 0 1"/>',
            "no geom of the cart on the floor collides with it \\(on it: a box of body 'cart'",
        ),
        (  # bits that never meet: the box's contype 2 against the floor's conaffinity 1, and the other way
            GOOD_BODY.replace('mass="12"', 'mass="12" contype="2" conaffinity="2"').format(sites=BAR),
            '<geom name="ground" type="plane" size="0 0 1"/>',
            "the floor's are 1/1\\), so the cart falls through",
        ),
        (
            GOOD_BODY.format(sites=BAR),
            '<geom name="ground" type="plane" size="0 0 1" contype="0" conaffinity="0"/>',
            "the floor plane 'ground' collides with nothing",
        ),
    ],
    ids=["cart_geoms_visual", "bits_never_meet", "floor_visual"],
)
def test_a_cart_that_would_fall_through_the_floor_is_refused(tmp_path, body, floor, message):
    path = tmp_path / "cart.xml"
    path.write_text(f"<mujoco><worldbody>{floor}{body}</worldbody></mujoco>")
    with pytest.raises(CartFileError, match=message) as info:
        load_cart_file(path)
    assert "\n" not in str(info.value)


def test_a_cart_whose_floor_contacts_are_excluded_is_refused_after_the_settle(tmp_path):
    """Geometry passes (the box collides by its bits) but an <exclude> drops its contacts: it falls in the settle."""
    xml = mujoco_cart.mjcf(mujoco_cart.shopping_cart(TRUE_CART))
    bodies = [b for b in mujoco_cart.WHEEL_BODIES] + ["cart"]
    exclude = "".join(f'<exclude body1="world" body2="{b}"/>' for b in bodies)
    xml = xml.replace("</mujoco>", f"<contact>{exclude}</contact></mujoco>")
    path = tmp_path / "cart.xml"
    path.write_text(xml)
    assert load_cart_file(path).handles
    setup = build_controller(PushConfig(contact="fixed", duration=1.0))
    with pytest.raises(MujocoPlantError, match="it does not stand on the floor after the .* settle"):
        MujocoPlant(setup.controller.robots, setup.q0, path)


def test_a_wheel_turned_onto_its_hinge_is_a_wheel(tmp_path):
    """The same wheel turned 90 degrees (its axis along the hinge's) rolls: the file loads."""
    assert load_cart_file(_write(tmp_path, GOOD_BODY.format(sites=BAR + PUCK.format(turn='euler="90 0 0"')))).handles


def test_missing_file_a_directory_and_a_urdf(tmp_path):
    with pytest.raises(CartFileError, match="no such file"):
        load_cart_file(tmp_path / "none.xml")
    with pytest.raises(CartFileError, match="is a directory; give the MJCF file"):
        load_cart_file(tmp_path)
    urdf = Path(__file__).resolve().parents[3] / "robots" / "shopping_cart.urdf"
    with pytest.raises(CartFileError, match="it is a URDF; a cart file is MJCF"):
        load_cart_file(urdf)


def test_handles_in_b(tmp_path):
    sites = BAR + '<site name="handle_side" pos="0.2 0.3 0.5"/>'
    src = load_cart_file(_write(tmp_path, GOOD_BODY.format(sites=sites)))
    bar, point = src.handles
    assert bar.is_bar and not point.is_bar
    assert bar.start_b.tolist() == pytest.approx([-0.15, -0.25, 0.9]) or bar.end_b.tolist() == pytest.approx(
        [-0.15, -0.25, 0.9]
    )
    assert src.distance_to_handle([-0.15, 0.1, 0.9])[0] == pytest.approx(0.0, abs=1e-9)  # anywhere on the bar
    assert src.distance_to_handle([0.2, 0.3, 0.6]) == pytest.approx((0.1, "handle_side"))
    assert src.z == pytest.approx(0.05)


def test_a_conforming_file_without_floor_is_pushed_and_reports_its_truth(tmp_path):
    """The shopping cart written as a file (floor removed): the plant adds a floor, finds the wheels by shape."""
    xml = mujoco_cart.mjcf(mujoco_cart.shopping_cart(TRUE_CART))
    start = xml.index('<geom name="floor"')
    xml = xml[:start] + xml[xml.index("/>", start) + 2 :]
    path = tmp_path / "shopping_cart.xml"
    path.write_text(xml)
    setup = build_controller(PushConfig(contact="fixed", duration=1.0))
    plant = MujocoPlant(setup.controller.robots, setup.q0, path)
    ci = plant.cart_inertial()
    assert ci.mass == pytest.approx(TRUE_CART.m, rel=1e-9)
    # rolling radius from the axle's height over the (added) floor: soft contacts sink by about a millimetre
    assert ci.mass_effective == pytest.approx(TRUE_CART.m + 4 * 0.35 / 2, rel=0.01)
    assert plant.scene.model.ngeom > 0 and plant.cart_state()[0][2] == pytest.approx(0.0, abs=1e-3)  # stands still


def test_the_robot_holds_the_rear_handles(tmp_path):
    """A bar at each end (a bed's head and foot), a grip at the front, grips along x: the rear ones are held."""
    from wholebody.push.geometry import geometry_from_cart_file

    front = '<site name="handle_foot" type="capsule" size="0.015" fromto="1.9 -0.4 0.5 1.9 0.4 0.5"/>'
    seat = '<site name="handle_seat" pos="-0.1 0 0.7"/>'  # a grip point near the bar: the bar wins
    geo = geometry_from_cart_file(_write(tmp_path, GOOD_BODY.format(sites=BAR + front + seat)))
    assert geo.grips is None and geo.y_range == pytest.approx((-0.25, 0.25))
    assert geo.point(0.0) == pytest.approx([-0.15, 0.0, 0.9])
    tubes = "".join(  # a wheelchair's push handles as short tubes pointing back (capsules along x)
        f'<site name="handle_{s}" type="capsule" size="0.015" fromto="-0.05 {y} 0.6 -0.15 {y} 0.6"/>'
        for s, y in (("left", 0.21), ("right", -0.21))
    )
    geo = geometry_from_cart_file(_write(tmp_path, GOOD_BODY.format(sites=tubes + front)))
    assert geo.grips == pytest.approx((0.21, -0.21)) and geo.point(0.21) == pytest.approx([-0.1, 0.21, 0.6])


def test_a_bed_with_a_bar_at_each_end_is_held_at_the_head(tmp_path):
    """The hand starts at the head bar (not refused as 1 m from it, the two bars' mean)."""
    xml = (EXAMPLES / "hospital_bed.xml").read_text()
    foot = '<site name="handle_foot" type="capsule" size="0.016" fromto="1.92 -0.40 0.40 1.92 0.40 0.40"/>'
    path = tmp_path / "bed.xml"
    path.write_text(xml.replace('<geom name="footboard"', foot + '<geom name="footboard"'))
    config = PushConfig(plant="mujoco", contact="fixed", cart_model=str(path), duration=1.0)
    setup = build_controller(config)
    plant = MujocoPlant(setup.controller.robots, setup.q0, path)
    assert plant.cart_inertial().mass > 240.0


def test_a_load_welded_to_the_cart_counts_in_its_truth_and_a_welded_hand_does_not():
    """A 60 kg crate on its own free joint strapped on by a weld rides with the cart: the truth is the composite;
    a robot's hand welded to the handle (its tree excluded) is not part of it."""
    import mujoco

    crate = '<body name="crate" pos="0.2 -0.1 0.25"><freejoint/><geom type="box" size="0.2 0.2 0.15" mass="60"/></body>'
    hand = '<body name="hand" pos="-0.15 0 0.9"><freejoint/><geom size="0.03" mass="2"/></body>'
    xml = (
        f"<mujoco><worldbody>{GOOD_BODY.format(sites=BAR)}{crate}{hand}</worldbody><equality>"
        '<weld body1="crate" body2="cart"/><weld body1="hand" body2="cart"/></equality></mujoco>'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cart, hand_id = (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in ("cart", "hand"))
    loads = mujoco_cart.welded_loads(model, data, cart, exclude=[hand_id])
    assert [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in loads] == ["crate"]
    truth = mujoco_cart.truth_from_state(model, data, wheels={}, extra=loads)
    assert truth["m"] == pytest.approx(72.0)
    assert (truth["dx"], truth["dy"]) == pytest.approx((60 * 0.2 / 72, 60 * -0.1 / 72))
    alone = mujoco_cart.truth_from_state(model, data, wheels={})
    assert alone["m"] == pytest.approx(12.0) and alone["dx"] == pytest.approx(0.0, abs=1e-12)
    data.eq_active[0] = 0  # the strap released: the crate no longer rides with the cart
    assert mujoco_cart.welded_loads(model, data, cart, exclude=[hand_id]) == []


def test_a_hinge_across_the_cart_off_the_floor_is_not_an_axle(tmp_path):
    """A bed's backrest hinged about y 0.65 m ahead of {b}, 0.4 m up: not a wheel, so not the no-slip axle."""
    backrest = (
        '<body name="backrest" pos="0.65 0 0.45"><joint name="tilt" type="hinge" axis="0 1 0"/>'
        '<geom type="box" size="0.3 0.25 0.02" mass="5"/></body>'
    )
    assert load_cart_file(_write(tmp_path, GOOD_BODY.format(sites=BAR + backrest))).handles


def test_grips_at_different_heights_are_each_held_at_their_own_point(tmp_path):
    """Two push grips 0.1 m apart in height and 0.08 m in depth: each hand takes its own grip, the plant's grasp
    check (hand within `handle_tolerance` of a site) holds for both, and one grip with two arms is refused."""
    from wholebody.push.geometry import geometry_from_cart_file

    grips = '<site name="handle_l" pos="-0.2 0.25 0.85"/><site name="handle_r" pos="-0.28 -0.25 0.95"/>'
    path = _write(tmp_path, GOOD_BODY.format(sites=grips))
    geo = geometry_from_cart_file(path)
    assert geo.point(0.25) == pytest.approx([-0.2, 0.25, 0.85])
    assert geo.point(-0.25) == pytest.approx([-0.28, -0.25, 0.95])
    for arms in (1, 2):
        config = PushConfig(contact="fixed", duration=1.0, plant="mujoco", cart_model=path, n_arms=arms)
        setup = build_controller(config)
        plant = MujocoPlant(setup.controller.robots, setup.q0, path)  # raises when a hand is off its grip
        assert plant.cart_inertial().mass == pytest.approx(12.0)
    one = _write(tmp_path, GOOD_BODY.format(sites='<site name="handle" pos="-0.2 0 0.85"/>'))
    with pytest.raises(WholeBodyError, match="is one grip point .*: two arms need two grips or a bar across the cart"):
        PushConfig(contact="fixed", duration=1.0, plant="mujoco", cart_model=one, n_arms=2).contact_y0()


def test_an_edited_cart_file_is_read_again(tmp_path):
    """A notebook edits the file between two runs: the second run's geometry is the edited file's."""
    path = _write(tmp_path, GOOD_BODY.format(sites=BAR))
    config = PushConfig(contact="fixed", duration=1.0, plant="mujoco", cart_model=path)
    assert config.cart_geometry().handle.start_b[2] == pytest.approx(0.9)
    _write(tmp_path, GOOD_BODY.format(sites=BAR.replace(" 0.9", " 0.95")))
    assert config.cart_geometry().handle.start_b[2] == pytest.approx(0.95)

"""Cart files and the scene composed on them: the floor (one rule for the checks and the scene), the names the scene
adds, the memory it sizes, and the hints of the refusals (docs/mujoco.md, "Cart files")."""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

from wholebody.push import PushConfig, build_controller, mujoco_cart, mujoco_scene
from wholebody.push.cart_file import CartFileError, load_cart_file
from wholebody.push.config import TRUE_CART
from wholebody.push.mujoco_plant import MujocoPlant

#: a box cart on two wheels (across y, under {b}), its bar behind {b}; {extra} goes in the cart's body
CART = """
    <body name="cart" pos="0 0 {z}">
      <freejoint/>
      <geom type="box" pos="0.3 0 0.15" size="0.4 0.25 0.02" mass="12" contype="0" conaffinity="0"/>
      <site name="handle" type="capsule" size="0.015" fromto="-0.15 -0.25 0.9 -0.15 0.25 0.9"/>
      <body name="wl" pos="0 0.3 0"><joint name="axle_l" axis="0 1 0"/>
        <geom type="cylinder" size="0.1 0.02" zaxis="0 1 0" mass="1"/></body>
      <body name="wr" pos="0 -0.3 0"><joint name="axle_r" axis="0 1 0"/>
        <geom type="cylinder" size="0.1 0.02" zaxis="0 1 0" mass="1"/></body>
      <body name="front" pos="0.7 0 -0.05"><geom type="sphere" size="0.05" mass="0.5"/></body>
      {extra}
    </body>"""
#: two decorative walls (horizontal normals, colliding with nothing), the first one lower than the floor
WALLS = (
    '<geom name="wall_n" type="plane" pos="0 6 -0.5" zaxis="0 -1 0" size="10 1 0.1" contype="0" conaffinity="0"/>'
    '<geom name="wall_s" type="plane" pos="0 -6 1" zaxis="0 1 0" size="10 1 0.1" contype="0" conaffinity="0"/>'
)


def _file(tmp_path, world: str, z: float = 0.1, extra: str = "", head: str = "") -> str:
    """Write a cart file: `head` (compiler, size), `world` (floor and walls) and the cart at height `z`."""
    path = tmp_path / "cart.xml"
    path.write_text(f"<mujoco>{head}<worldbody>{world}{CART.format(z=z, extra=extra)}</worldbody></mujoco>")
    return str(path)


def _plant(path: str, robot: str = PushConfig.robot) -> MujocoPlant:
    """Return the MuJoCo plant of `robot` (the default one) holding the cart of `path` (composed and settled)."""
    config = PushConfig(robot=robot, contact="fixed", duration=1.0, plant="mujoco", cart_model=path)
    setup = build_controller(config)
    return MujocoPlant(setup.controller.robots, setup.q0, path)


def _alone(path: str) -> mujoco.MjModel:
    """Return the scene composed on the cart of `path` with no robot (its floor, names and memory)."""
    source = load_cart_file(path)
    return mujoco_scene.compose(source.spec(), (0.0, 0.0, 0.0), source.z, [], 0.002).model


def _world_planes(model: mujoco.MjModel) -> list[str]:
    """Return the names of the world body's plane geoms."""
    return [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == 0 and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE
    ]


# --------------------------------------------------------------------------- the floor: one rule


def test_the_floor_is_the_lowest_world_plane_facing_up():
    """Walls (one below the floor), a tilted plane and a plane on a body are not the floor; the lowest up-facing
    world plane is, wherever it stands in the file."""
    xml = (
        f"<mujoco><worldbody>{WALLS}"
        '<geom name="ramp" type="plane" pos="0 0 -0.3" euler="0 5 0" size="1 1 1"/>'
        '<geom name="high" type="plane" pos="0 0 0.4" size="1 1 1"/>'
        '<geom name="floor" type="plane" pos="0 0 -0.2" size="1 1 1"/>'
        '<body name="base"><geom name="on_body" type="plane" pos="0 0 -1" size="1 1 1"/></body>'
        "</worldbody></mujoco>"
    )
    model = mujoco.MjModel.from_xml_string(xml)
    assert mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, mujoco_cart.floor_plane(model)) == "floor"
    walls_only = mujoco.MjModel.from_xml_string(f"<mujoco><worldbody>{WALLS}</worldbody></mujoco>")
    assert mujoco_cart.floor_plane(walls_only) is None


def test_walls_before_the_floor_are_not_the_floor_of_the_checks(tmp_path):
    """A wall at the floor's height listed first: the file loads (not 'the floor plane 'wall_n' collides with
    nothing')."""
    walls = WALLS.replace('pos="0 6 -0.5"', 'pos="0 6 0"')
    assert load_cart_file(_file(tmp_path, walls + '<geom name="floor" type="plane" size="10 10 0.1"/>')).handles


def test_walls_before_the_floor_are_not_the_floor_of_the_scene(tmp_path):
    """The robots' floor contacts go with the floor (contype 2, conaffinity 4, priority 1), not the first wall
    (0, 0): with the wall's bits a differential base falls through the floor. The supports' bit (no geom uses it)
    joins the floor's conaffinity; the walls keep theirs."""
    floor = '<geom name="floor" type="plane" size="10 10 0.1" contype="2" conaffinity="4" priority="1"/>'
    spec = mujoco.MjSpec.from_string(f"<mujoco><worldbody>{WALLS}{floor}</worldbody></mujoco>")
    contype, conaffinity, priority = mujoco_scene._floor_bits(spec, spec.compile(), set())
    assert (contype, priority) == (0, 1) and conaffinity & (2 | 4) == 0 and bin(conaffinity).count("1") == 1
    assert spec.geom("floor").conaffinity == 4 | conaffinity and spec.geom("floor").contype == 2
    assert [g.conaffinity for g in spec.worldbody.geoms][:2] == [0, 0]
    assert len(spec.worldbody.geoms) == 3  # nothing added


def test_a_wheeled_robot_stands_on_the_floor_behind_walls(tmp_path):
    """The WMRA (a differential base on tyres) and a cart file whose walls come first: its tyres collide with the
    floor (they took the first wall's bits, 0 and 0, and the robot fell through the floor)."""
    walls = WALLS.replace('pos="0 6 -0.5"', 'pos="0 6 1"')  # above the floor: the checks saw the floor
    plant = _plant(_file(tmp_path, walls + '<geom name="floor" type="plane" size="10 10 0.1"/>'), robot="wmra")
    model = plant.scene.model
    tyres = [
        g
        for g in range(model.ngeom)
        if (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "").endswith(mujoco_scene.CONTACT_SUFFIX)
    ]
    floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    assert tyres and all(model.geom_contype[g] & model.geom_conaffinity[floor] for g in tyres)
    assert all(model.geom_conaffinity[g] == 0 for g in tyres)  # the robots' supports never touch each other
    assert abs(plant.scene.data.qpos[plant.scene.robots[0].base_qpos[2]]) < 0.05  # on the floor after the settle


# --------------------------------------------------------------------------- the names the scene adds


@pytest.mark.parametrize(
    "world, extra",
    [
        ('<geom name="floor" type="box" pos="0 0 -0.05" size="20 20 0.05"/>', ""),  # a box floor, top at z = 0
        ('<body name="ground"><geom name="floor" type="plane" size="10 10 0.1"/></body>', ""),  # a plane on a body
        (
            "",
            '<geom name="floor" type="box" pos="0.3 0 0.3" size="0.3 0.2 0.005" mass="1" contype="0" conaffinity="0"/>',
        ),  # a basket's floor
        (WALLS.replace('name="wall_n"', 'name="floor"'), ""),  # a wall named floor
    ],
    ids=["box_floor", "plane_on_a_body", "basket_floor", "wall_named_floor"],
)
def test_the_added_floor_takes_a_name_the_file_does_not_use(tmp_path, world, extra):
    """No up-facing world plane but a geom named 'floor': the scene's plane at z = 0 is named otherwise."""
    path = _file(tmp_path, world, extra=extra)
    model = _alone(path)
    g = mujoco_cart.floor_plane(model)
    assert g is not None and model.geom_pos[g][2] == 0.0
    assert mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) == "floor_1"
    assert len(_world_planes(model)) == len(_world_planes(mujoco.MjModel.from_xml_path(path))) + 1


def test_the_scene_names_clear_the_files_names(tmp_path):
    """A site named 'grasp0' and a body under the robot's prefix 'r0/' in the cart: the robot is attached and
    welded under other names, to a new site at its hand; the file's site stays where it was."""
    extra = '<site name="grasp0" pos="0 0 0.3"/><body name="r0/tray" pos="0.3 0 0.2"><geom size="0.02"/></body>'
    plant = _plant(_file(tmp_path, '<geom name="floor" type="plane" size="10 10 0.1"/>', extra=extra))
    model, robot = plant.scene.model, plant.scene.robots[0]
    assert robot.prefix not in ("r0/",) and robot.prefix.endswith("/")
    site = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, robot.handle_site)
    assert site != "grasp0" and model.site_bodyid[robot.handle_site] == plant.scene.cart_body
    assert mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_EQUALITY, robot.weld) == site
    own = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "grasp0")
    assert own >= 0 and model.site_pos[own].tolist() == [0.0, 0.0, 0.3]


# --------------------------------------------------------------------------- memory


def test_the_scene_sizes_its_own_memory(tmp_path):
    """<size memory="20K"/> sized the cart alone: the scene with the robot gets MuJoCo's own size and settles (it
    ran out of memory); a file asking for more than that keeps its own."""
    floor = '<geom name="floor" type="plane" size="10 10 0.1"/>'
    plant = _plant(_file(tmp_path, floor, head='<size memory="20K"/>'))
    assert plant.scene.model.narena > 20 * 1024
    big = 64 * 1024 * 1024
    assert _alone(_file(tmp_path, floor, head=f'<size memory="{big}"/>')).narena == big


# --------------------------------------------------------------------------- refusals and their hints


def test_a_cart_on_a_raised_box_floor_is_told_to_give_a_plane(tmp_path):
    """The cart on a box whose top is at z = 0.1 (no plane), or sunk into it at z = 0 (where the last message sent
    it): the robots stand on a plane, so the file is refused with the plane to give; the box with its top at z = 0
    loads."""
    raised = '<geom name="floor" type="box" pos="0 0 0.05" size="20 20 0.05"/>'
    for z, how in ((0.2, "on"), (0.1, "sunk in")):
        with pytest.raises(CartFileError, match=f"stands {how} 'floor'.* give a <geom type=\"plane\"> at z = 0.1 "):
            load_cart_file(_file(tmp_path, raised, z=z))
    assert load_cart_file(_file(tmp_path, raised.replace("0 0 0.05", "0 0 -0.05"), z=0.1)).handles


@pytest.mark.parametrize(
    "head, hint",
    [
        ("", 'an euler meant in radians\\? MuJoCo reads degrees unless <compiler angle="radian"/>'),
        ('<compiler angle="radian"/>', 'an euler meant in degrees\\? this file\'s <compiler angle="radian"/> makes'),
    ],
    ids=["degrees", "radians"],
)
def test_a_turned_wheel_is_told_the_unit_mistake_of_its_file(tmp_path, head, hint):
    """A wheel's cylinder turned off its hinge by an euler in the wrong unit: the hint names the file's unit."""
    floor = '<geom name="floor" type="plane" size="10 10 0.1"/>'
    turn = 'euler="1.5708 0 0"' if not head else 'euler="90 0 0"'
    path = Path(_file(tmp_path, floor, head=head))
    path.write_text(path.read_text().replace('zaxis="0 1 0"', turn))
    with pytest.raises(CartFileError, match=f"so it slides instead of rolling \\({hint}") as info:
        load_cart_file(path)
    assert "\n" not in str(info.value)


def test_two_robots_side_by_side_never_touch_each_other_or_the_cart(tmp_path):
    """Two WMRAs holding a cart file whose wheels and floor collide by contype and conaffinity 1 (a file's usual): their
    tyres and casters took the floor's 1/1 and touched each other's once the bases moved, pushing them apart (hands
    off the handle from the start; lost at 4.4 s on Traj. 1). Now each support's contype is a bit only the floor's
    conaffinity has."""
    from wholebody.push import run_push

    xml = mujoco_cart.mjcf(mujoco_cart.shopping_cart(TRUE_CART))
    for old in ('contype="2" conaffinity="1"', 'contype="1" conaffinity="2"'):  # the wheels', the floor's
        xml = xml.replace(old, 'contype="1" conaffinity="1"')
    path = tmp_path / "cart.xml"
    path.write_text(xml)
    config = PushConfig(
        robot="wmra", n_arms=2, contact="fixed", trajectory=1, duration=8.0, plant="mujoco", cart_model=str(path),
        fixed_contact_y=(-0.2, 0.2),
    )  # fmt: skip
    assert run_push(config).metrics.grasp_error_max_m < 0.02

"""`cartpush push --plant mujoco --cart-model FILE`: each break of the cart-file contract (docs/mujoco.md) stops the
command with one line naming what is missing, exit 2, before any physics runs."""

from __future__ import annotations

import re

import pytest

from cartpush.cli import main

BODY = """
    <body name="cart" pos="0 0 0.05">
      <freejoint/>
      <geom type="box" size="0.4 0.25 0.05" mass="12"/>
      {sites}
    </body>"""
BAR = '<site name="handle" type="capsule" size="0.015" fromto="-0.15 -0.25 0.9 -0.15 0.25 0.9"/>'
BREAKS = {
    "no_cart_body": (BODY.replace('name="cart"', 'name="trolley"').format(sites=BAR), "no body named 'cart'"),
    "no_free_joint": (
        BODY.replace("<freejoint/>", '<joint type="slide" axis="1 0 0"/>').format(sites=BAR),
        "body 'cart' has no free joint",
    ),
    "no_handle_site": (
        BODY.format(sites='<site name="grip" pos="-0.15 0 0.9"/>'),
        "no site named 'handle' or 'handle_*'",
    ),
    "handle_a_box": (
        BODY.format(sites='<site name="handle_left" type="box" size="0.02 0.02 0.02" pos="-0.15 0 0.9"/>'),
        "handle site 'handle_left' is neither a point",
    ),
    "handle_on_a_hinge": (
        BODY.format(
            sites='<body name="bar" pos="-0.15 0 0.9"><joint name="hinge" axis="0 1 0"/><geom size="0.02"/>'
            '<site name="handle"/></body>'
        ),
        "which moves relative to 'cart' (joint 'hinge')",
    ),
    "not_mjcf": ("<body name='cart'><freejoint/><geom type='nonsense'/></body>", "not a valid MuJoCo model"),
}


@pytest.mark.parametrize("name", sorted(BREAKS))
def test_each_break_of_the_contract_stops_the_push_with_one_line(tmp_path, capsys, name):
    body, message = BREAKS[name]
    path = tmp_path / f"{name}.xml"
    path.write_text(f'<mujoco><worldbody><geom name="ground" type="plane" size="0 0 1"/>{body}</worldbody></mujoco>')
    code = main(["push", "--plant", "mujoco", "--cart-model", str(path), "--duration", "8", "--json"])
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 2 and captured.out == ""
    assert len(lines) == 1 and message in lines[0] and str(path) in lines[0], lines


def test_a_handle_out_of_the_arms_reach_says_where_it_is(tmp_path, capsys):
    """A bar 2 m high: the default robot's arm cannot hold it; the one line says where the handle point is and how
    far the closest grasp leaves the hand."""
    path = tmp_path / "high.xml"
    high = BAR.replace(" 0.9 ", " 2.0 ").replace(' 0.9"', ' 2.0"')
    path.write_text(
        f'<mujoco><worldbody><geom name="ground" type="plane" size="0 0 1"/>{BODY.format(sites=high)}</worldbody></mujoco>'
    )
    code = main(["push", "--plant", "mujoco", "--cart-model", str(path), "--duration", "8", "--json"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert (
        re.search(r"the handle point is at \(-0.15, -?0.\d+, 2.0\d\) m", lines[0])
        and "out of the arm's reach" in lines[0]
    )


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda tmp: tmp, "is a directory; give the MJCF file"),
        (lambda tmp: tmp / "none.xml", "no such file"),
        (
            lambda tmp: tmp / "cart.txt",
            "MuJoCo reads '.txt' as no model format; a cart file is MJCF XML ending in .xml",
        ),
    ],
    ids=["directory", "missing", "txt"],
)
def test_a_path_that_is_not_a_cart_file_is_one_line(tmp_path, capsys, make, message):
    (tmp_path / "cart.txt").write_text(
        f'<mujoco><worldbody><geom name="ground" type="plane" size="0 0 1"/>{BODY.format(sites=BAR)}</worldbody></mujoco>'
    )
    code = main(["push", "--plant", "mujoco", "--cart-model", str(make(tmp_path)), "--duration", "8", "--json"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and message in lines[0], lines


def test_a_handle_out_of_the_wmra_reach_says_how_high_it_is(tmp_path, capsys):
    """The WMRA's reach map finds no place along a 2 m high bar: the line says where the bar is."""
    path = tmp_path / "high.xml"
    high = BAR.replace(" 0.9 ", " 2.0 ").replace(' 0.9"', ' 2.0"')
    path.write_text(
        f'<mujoco><worldbody><geom name="ground" type="plane" size="0 0 1"/>{BODY.format(sites=high)}</worldbody></mujoco>'
    )
    code = main(["push", "--robot", "wmra", "--plant", "mujoco", "--cart-model", str(path), "--duration", "8"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert "reaches the handle nowhere along it" in lines[0] and "2.05 m above the floor" in lines[0], lines


def test_a_cart_on_a_raised_box_floor_stops_the_push_with_one_line(tmp_path, capsys):
    """A box floor with its top at z = 0.1 and no plane: the robots stand on a plane, so the command says to give one
    at that height (it said to raise the cart to 0.1 m, which then failed after the settle)."""
    path = tmp_path / "box_floor.xml"
    box = '<geom name="floor" type="box" pos="0 0 0.05" size="20 20 0.05"/>'
    path.write_text(
        f"<mujoco><worldbody>{box}{BODY.replace('0 0 0.05', '0 0 0.15').format(sites=BAR)}</worldbody></mujoco>"
    )
    code = main(["push", "--plant", "mujoco", "--cart-model", str(path), "--duration", "8", "--json"])
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 2 and captured.out == "" and len(lines) == 1, lines
    assert str(path) in lines[0] and 'give a <geom type="plane"> at z = 0.1 ' in lines[0], lines

"""The example cart files (examples/carts/): each follows the contract, stands in the plant, and one is pushed.

Also the structures other people's files use that the reader must handle (a <frame> around the cart, a handle
on a body fixed to the cart, a bar given by its axis, degrees) and the run's plain statement of what happened.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from wholebody.push import PushConfig, build_controller
from wholebody.push.cart_file import load_cart_file
from wholebody.push.loop import run_loop
from wholebody.push.mujoco_plant import MujocoPlant
from wholebody.push.plants import plant_report
from wholebody.push.report import what_happened

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "carts"
FILES = sorted(EXAMPLES.glob("*.xml"))


def test_the_four_kinds_ship():
    assert {f.stem for f in FILES} >= {"wheelchair", "worn_shopping_cart", "hospital_bed", "four_caster_trolley"}


@pytest.mark.parametrize("path", FILES, ids=[f.stem for f in FILES])
def test_example_cart_stands_in_the_plant_with_its_own_mass(path):
    source = load_cart_file(path)  # the contract check
    assert source.handles
    config = PushConfig(plant="mujoco", contact="fixed", cart_model=str(path), duration=1.0)
    setup = build_controller(config)
    plant = MujocoPlant(setup.controller.robots, setup.q0, path)
    alone = mujoco.MjModel.from_xml_path(str(path))  # the file by itself: an independent mass
    cart = mujoco.mj_name2id(alone, mujoco.mjtObj.mjOBJ_BODY, "cart")
    assert plant.cart_inertial().mass == pytest.approx(float(alone.body_subtreemass[cart]), rel=1e-9)
    pose, vel = plant.cart_state()
    assert np.hypot(*pose[:2]) < 5e-3 and abs(pose[2]) < 5e-3  # settled where it was put, held by the hands
    assert np.abs(vel).max() < 0.02
    d = plant.scene.data
    z = float(d.xpos[plant.scene.cart_body][2])
    assert z == pytest.approx(source.z, abs=5e-3)  # on its wheels, not sunk or tipped


def test_the_wheelchair_is_pushed_and_the_run_says_what_happened():
    path = EXAMPLES / "wheelchair.xml"
    config = PushConfig(trajectory=1, plant="mujoco", contact="fixed", cart_model=str(path), duration=1.5)
    setup = build_controller(config)
    plant = MujocoPlant(setup.controller.robots, setup.q0, path, noise=config.noise, seed=config.seed)
    result = replace(run_loop(config, setup.controller, plant), plant_report=plant_report(plant))
    # the 1.5 s trajectory's ramp is steep (the paper's profile squeezed): the bar for ordinary carts
    assert result.metrics.tracking_rms_mm < 20.0 and result.metrics.tracking_max_mm < 50.0
    assert 85.0 < result.plant_report["cart_mass_kg"] < 90.0  # frame, wheels and the 70 kg occupant
    lines = what_happened(result)
    assert lines[0].startswith("tracked:")
    assert any(line.startswith("no lateral slip") for line in lines)  # a fixed rear axle
    assert any(line.startswith("grip slip at most") for line in lines)


BODY = """
    <body name="cart" pos="0 0 {z}">
      <freejoint/>
      <geom type="box" size="0.4 0.25 0.05" mass="12"/>
      {inside}
    </body>"""


def _write(tmp_path, xml: str) -> Path:
    path = tmp_path / "cart.xml"
    path.write_text(xml)
    return path


def test_a_frame_around_the_cart_counts_in_its_height(tmp_path):
    body = BODY.format(z=-0.05, inside='<site name="handle" pos="-0.2 0 0.9"/>')
    src = load_cart_file(
        _write(tmp_path, f'<mujoco><worldbody><frame pos="0 0 0.1">{body}</frame></worldbody></mujoco>')
    )
    assert src.z == pytest.approx(0.05)


def test_handles_on_a_body_fixed_to_the_cart_and_bars_by_axis_in_degrees(tmp_path):
    inside = (
        '<body name="handlebar" pos="-0.2 0 0.8" euler="0 0 90">'
        '<site name="handle_bar" type="capsule" size="0.015 0.25" euler="90 0 0"/>'
        '<site name="handle_grip" pos="0.1 0 0.05"/></body>'
        '<site name="handle_tube" type="cylinder" size="0.015 0.2" pos="-0.3 0 0.9" zaxis="0 1 0"/>'
    )
    xml = f'<mujoco><compiler angle="degree"/><worldbody>{BODY.format(z=0.05, inside=inside)}</worldbody></mujoco>'
    handles = {h.name: h for h in load_cart_file(_write(tmp_path, xml)).handles}
    bar, grip, tube = handles["handle_bar"], handles["handle_grip"], handles["handle_tube"]
    # the capsule's axis: body yaw 90 deg, site roll 90 deg: the site's z axis is the cart's x axis
    ends = sorted([bar.start_b.tolist(), bar.end_b.tolist()])
    assert ends[0] == pytest.approx([-0.45, 0.0, 0.8]) and ends[1] == pytest.approx([0.05, 0.0, 0.8])
    assert grip.start_b.tolist() == pytest.approx([-0.2, 0.1, 0.85])  # (0.1, 0) in the yawed body: +y of the cart
    assert tube.is_bar and abs(tube.end_b[1] - tube.start_b[1]) == pytest.approx(0.4)


def test_push_json_says_what_happened(capsys):
    """The kinematic plant's cart cannot slip sideways (its model's constraint): the run says so, and it tracked."""
    from cartpush.cli import main

    assert main(["push", "--trajectory", "1", "--duration", "8", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["cart_lateral_slip_max_m_s"] < 1e-6
    lines = out["what_happened"]
    assert lines[0].startswith("tracked:") and f"{out['tracking_rms_mm']:.1f} mm RMS" in lines[0]
    assert any(line.startswith("no lateral slip") for line in lines)


def test_push_json_reports_the_bases_measured_side_speed(capsys):
    """The WMRA's wheels cannot slide sideways on the kinematic plant: its base's side speed from its true poses is
    (numerically) zero; a run that kept the cart carries no ``before_loss``."""
    from cartpush.cli import main

    assert main(["push", "--robot", "wmra", "--trajectory", "2", "--duration", "9", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert 0.0 <= out["base_lateral_speed_measured_max_m_s"] < 2e-3
    assert out["tracking_lost_at_s"] is None and "before_loss" not in out

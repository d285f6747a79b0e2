"""End to end (needs the mujoco_plant.py and report.py patches of helper 7): a MuJoCo run's page draws the
casters as the plant turned them, and a cart file's run draws the file's cart (a hospital bed as a bed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from wholebody.push import PushConfig, run_push
from wholebody.push.report import build_scene
from wholebody.viz.push_cart import CASTER_SOURCES
from wholebody.viz.scene import _frame_schedule

BED = Path(__file__).resolve().parents[2] / "examples" / "carts" / "hospital_bed.xml"


def _yaw(quat: np.ndarray) -> np.ndarray:
    """Return the rotation about z of (x, y, z, w) keys that turn about z only."""
    return 2.0 * np.arctan2(quat[:, 2], quat[:, 3])


def test_the_page_of_a_mujoco_run_swivels_the_casters_as_the_plant_did():
    result = run_push(PushConfig(trajectory=2, duration=6.0, plant="mujoco", contact="fixed"))
    record = result.plant_report["cart_joints"]
    t_rec, q_rec = record.series()
    np.testing.assert_allclose(t_rec[: len(result.t)], result.t, atol=1e-9)  # at t = 0 and after every period
    swivel = q_rec[:, record.names.index("swivel_left")]
    assert np.ptp(swivel) > 0.05  # the caster turns on Traj. 2
    scene = build_scene(result, fps=10)
    fork = scene.animation_keys()["/meshcat/shopping_cart/visuals/caster_left_fork_0"]["quaternion"]
    page_t = result.t[::10]  # build_scene's samples at 10 frames per second
    shown = _frame_schedule(page_t, 10)[1]  # the sample each frame shows
    expected = swivel[np.searchsorted(t_rec, page_t + 1e-9, side="right") - 1][shown]
    np.testing.assert_allclose(np.angle(np.exp(1j * (_yaw(fork) - expected))), 0.0, atol=1e-9)
    assert scene.legend_entry("casters").text == CASTER_SOURCES["recorded"]


def test_the_page_of_a_cart_file_run_draws_the_file_and_holds_its_bar():
    result = run_push(PushConfig(trajectory=1, duration=3.0, plant="mujoco", contact="fixed", cart_model=str(BED)))
    scene = build_scene(result, fps=10)
    assert scene.cart == "cart" and "shopping_cart" not in scene.robots
    deck = scene.world_transform("/meshcat/cart/visuals/deck")
    assert deck[2, 3] == pytest.approx(0.57, abs=0.01)  # the bed's deck, 0.57 m above the floor
    arrow = scene.world_transform("/meshcat/wrenches/measured/hand")[:3, 3]
    bar = scene.world_transform("/meshcat/cart/visuals/handle_headboard")[:3, 3]
    assert abs(arrow[2] - 0.06 - bar[2]) < 0.03  # the hand force starts at the push bar (measured: 6 cm higher)


def test_the_page_of_a_wmra_run_turns_its_casters_as_the_plant_did():
    result = run_push(PushConfig(trajectory=2, duration=5.0, plant="mujoco", contact="fixed", robot="wmra"))
    (record,) = result.plant_report["robot_joints"]
    t_rec, q_rec = record.series()
    swivel = q_rec[:, record.names.index("r0/caster_left_swivel")]
    assert np.ptp(swivel) > 0.05
    scene = build_scene(result, fps=10)
    keys = scene.animation_keys()
    fork = keys["/meshcat/wmra/visuals/caster_left_fork_0"]
    page_t = result.t[::10]
    shown = _frame_schedule(page_t, 10)[1]
    expected = swivel[np.searchsorted(t_rec, page_t + 1e-9, side="right") - 1][shown]
    np.testing.assert_allclose(np.angle(np.exp(1j * (_yaw(fork["quaternion"]) - expected))), 0.0, atol=1e-9)

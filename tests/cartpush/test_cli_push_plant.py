"""`cartpush push --plant mujoco`: the same controller against the physics engine, and its report."""

from __future__ import annotations

import json
import re

import numpy as np

import pytest

from cartpush.cli import main


def test_push_on_the_mujoco_plant_reports_the_physics(capsys):
    code = main(["push", "--plant", "mujoco", "--trajectory", "1", "--duration", "8", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert out["plant"] == "mujoco"
    # the cart's mass the forward motion feels includes its wheels' spin inertia
    assert out["cart_mass_effective_kg"] > out["cart_mass_kg"]
    assert out["grasp_slip_max_m"] < 0.005
    assert out["tracking_rms_mm"] < 20.0
    for key in ("wrench_error_rms_n", "real_time_factor", "base_wheel_slip_max_m_s"):
        assert key in out


def test_kinematic_is_the_default_plant(capsys):
    assert main(["push", "--trajectory", "1", "--duration", "8", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["plant"] == "kinematic"


def test_a_cart_model_on_the_kinematic_plant_or_not_a_model_is_refused(capsys, tmp_path):
    assert main(["push", "--plant", "kinematic", "--cart-model", str(tmp_path / "c.xml")]) == 2
    assert "--cart-model needs the MuJoCo plant" in capsys.readouterr().err
    bad = tmp_path / "c.xml"
    bad.write_text("<mujoco><worldbody/></mujoco>")
    assert main(["push", "--plant", "mujoco", "--cart-model", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cart" in err[0]


def test_a_cart_model_alone_means_the_mujoco_plant():
    import argparse

    from cartpush.cli import push

    parser = argparse.ArgumentParser()
    push.register(parser.add_subparsers())
    args = ["push", "--cart-model", "examples/carts/wheelchair.xml"]
    cfg = push.config_from_args(parser.parse_args(args))
    assert (cfg.plant, cfg.contact, cfg.cart_model) == ("mujoco", "fixed", "examples/carts/wheelchair.xml")
    assert push.config_from_args(parser.parse_args(["push"])).plant == "kinematic"


def test_look_ahead_reaches_the_reference_clock_and_bad_horizons_are_refused(capsys):
    from cartpush.cli.push import _time_scaling

    settings = _time_scaling(4.0, "mujoco")
    assert settings != "auto" and settings.horizon == 4.0
    assert _time_scaling(0.0, "mujoco") == "auto"
    for argv in (["--plant", "mujoco", "--look-ahead", "-1"], ["--look-ahead", "4"]):
        assert main(["push", *argv, "--duration", "8"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--look-ahead" in err[0]


def test_initial_com_reaches_the_estimate_and_bad_values_are_refused(capsys):
    """With estimation off the CoM error is the guess's: 0.15 m by default (0.3, 0 for 0.3, 0.15), 0 when the
    guess is the truth."""
    args = ["push", "--trajectory", "1", "--duration", "8", "--no-estimation", "--json"]
    assert main(args) == 0
    assert json.loads(capsys.readouterr().out)["com_error_final_m"] == pytest.approx(0.15, abs=1e-9)
    assert main([*args, "--initial-com", "0.3,0.15"]) == 0
    assert json.loads(capsys.readouterr().out)["com_error_final_m"] == pytest.approx(0.0, abs=1e-9)
    for bad in ("0.3", "0.3,x", "0.3,0,1", "nan,0", "9,0"):
        assert main(["push", "--initial-com", bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--initial-com takes DX,DY" in err[0], err


def test_contact_y_is_checked_against_the_cart_files_handle(tmp_path, capsys):
    """A bar from y = 0.05 to 0.45: 0.3 is on it (the shopping cart's [-0.25, 0.25] is not the rule), 0.5 is not."""
    import argparse

    from cartpush.cli import push

    bar = '<site name="handle" type="capsule" size="0.015" fromto="-0.15 0.05 0.9 -0.15 0.45 0.9"/>'
    path = tmp_path / "offset.xml"
    path.write_text(
        '<mujoco><worldbody><geom name="ground" type="plane" size="0 0 1"/><body name="cart" pos="0 0 0.05">'
        f'<freejoint/><geom type="box" size="0.4 0.25 0.05" mass="12"/>{bar}</body></worldbody></mujoco>'
    )
    parser = argparse.ArgumentParser()
    push.register(parser.add_subparsers())
    args = ["push", "--plant", "mujoco", "--cart-model", str(path), "--contact-y"]
    assert push.config_from_args(parser.parse_args([*args, "0.3"])).fixed_contact_y == (0.3,)
    assert main([*args, "0.5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "within the handle's [0.05, 0.45] m, got [0.5]" in err[0], err


def test_a_default_contact_out_of_reach_moves_and_a_given_one_names_the_span(tmp_path, capsys):
    """The WMRA's default contact (y = 0.1 m) on a 0.3 m bar 0.6 m high is out of reach: the run holds the nearest
    point the arm holds, stands behind it as for a point the user gives, and says so; the default point given by the
    user is refused with the reachable span."""
    bar = '<site name="handle" type="capsule" size="0.015" fromto="-0.1 -0.15 0.6 -0.1 0.15 0.6"/>'
    path = tmp_path / "child.xml"
    path.write_text(
        '<mujoco><worldbody><geom name="ground" type="plane" size="0 0 1"/><body name="cart" pos="0 0 0.05">'
        f'<freejoint/><geom type="box" size="0.3 0.18 0.05" mass="6"/>{bar}</body></worldbody></mujoco>'
    )
    args = ["push", "--robot", "wmra", "--plant", "mujoco", "--cart-model", str(path), "--duration", "8"]
    assert main([*args, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    note = [s for s in out["what_happened"] if s.startswith("contact:")]
    held = re.search(
        r"default contact y = 0\.100 m is out of its arm's reach on this handle; held at y = (-?0\.\d+)", note[0]
    )
    assert held and float(held.group(1)) < 0.1, note
    # set up as if the user had given that point: the robot stands behind it (the same start, to the bit; this
    # box slides on the floor and is lost in both runs, which MuJoCo does not repeat to the bit)
    from dataclasses import replace

    from wholebody.push.config import PushConfig
    from wholebody.push.loop import run_push

    cfg = PushConfig(robot="wmra", plant="mujoco", contact="fixed", cart_model=str(path), duration=8.0)
    moved = run_push(cfg)
    assert moved.config.fixed_contact_y == pytest.approx((float(held.group(1)),), abs=5e-4)
    assert moved.setup_notes == tuple(note)
    given = run_push(replace(cfg, fixed_contact_y=moved.config.fixed_contact_y))
    assert given.setup_notes == () and np.array_equal(given.robot_x[0], moved.robot_x[0])
    assert np.array_equal(given.q_true[:100], moved.q_true[:100])
    code = main([*args, "--contact-y", "0.1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert re.search(r"it reaches \[-?0\.\d+, -?0\.\d+\] m: give a contact point there \(--contact-y", err[0]), err

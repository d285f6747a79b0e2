"""`cartpush push --plant mujoco`: the same controller against the physics engine, and its report."""

from __future__ import annotations

import json

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


def test_a_cart_model_without_the_mujoco_plant_or_not_a_model_is_refused(capsys, tmp_path):
    assert main(["push", "--cart-model", str(tmp_path / "c.xml")]) == 2
    assert "--plant mujoco" in capsys.readouterr().err
    bad = tmp_path / "c.xml"
    bad.write_text("<mujoco><worldbody/></mujoco>")
    assert main(["push", "--plant", "mujoco", "--cart-model", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cart" in err[0]


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

"""The CLI dispatcher and `cartpush demo`."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from cartpush.cli import main


def test_demo_json_lists_every_robot(capsys):
    assert main(["demo", "--robots-only", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    names = {r["name"]: r for r in out["robots"]}
    assert set(names) == {"wmra", "ridgeback_iiwa", "shopping_cart"}
    assert names["shopping_cart"]["mass_kg"] == pytest.approx(15.0)
    assert names["wmra"]["frame"] == "ee" and names["shopping_cart"]["frame"] == "handle"


def test_console_script_help_has_example():
    out = subprocess.run([sys.executable, "-m", "cartpush.cli", "--help"], capture_output=True, text=True)
    assert out.returncode == 0 and "Example" in out.stdout


def test_unknown_subcommand_exits_2():
    with pytest.raises(SystemExit) as exc:
        main(["no-such-command"])
    assert exc.value.code == 2


def test_demo_rejects_short_duration(capsys):
    assert main(["demo", "--duration", "2"]) == 2
    assert "at least 8 s" in capsys.readouterr().err


def test_demo_json_reports_mm_and_unobservable_stretches(tmp_path, capsys):
    assert main(["demo", "--duration", "8", "--json", "--out", str(tmp_path)]) == 0
    out = json.loads(capsys.readouterr().out)
    est, frozen = out["runs"]["with estimation"], out["runs"]["without estimation"]
    assert frozen["tracking_rms_mm"] > est["tracking_rms_mm"] > 0.1  # mm, not m
    assert not any(k.startswith("tracking") and k.endswith("_m") for k in est)
    assert all(b - a >= 1.0 - 1e-9 for a, b in est["mass_unobservable_s"] + est["com_unobservable_s"])
    assert frozen["mass_unobservable_s"] == [] and frozen["com_unobservable_s"] == []
    table = (tmp_path / "comparison.md").read_text()
    assert "track RMS [mm]" in table and "with estimation: unobservable" in table
    assert {p.name for p in tmp_path.iterdir()} >= {
        "path.png",
        "tracking_estimation.png",
        "estimate.png",
        "hand_wrenches.png",
        "arm_torques.png",
        "scene.html",
        "scene_mujoco.html",
        "push_log.csv",
        "comparison.md",
    }


def test_demo_table_gives_the_com_in_cm_and_says_what_unobservable_means(tmp_path, capsys):
    assert main(["demo", "--duration", "8", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "CoM err [cm]" in out and "CoM err [m]" not in out
    assert "the estimate is held from earlier data, not updated" in out
    assert "arm torque peak" in out and "(within the limits)" in out
    assert "plays when opened" in out
    physics = next(line for line in out.splitlines() if "MuJoCo plant, Traj. 1: " in line and "real time" in line)
    assert "measured minus allocated" in physics and "grip slip max" in physics
    assert "scene_mujoco.html: the MuJoCo run" in out
    table = (tmp_path / "comparison.md").read_text()
    assert "CoM err [cm]" in table and "with estimation: arm torque peak" in table


# -- verdicts with their reasons -----------------------------------------------------------------------------------
def test_track_explains_saturated_steps_by_the_limit_reached():
    from cartpush.cli.track import flag_reasons

    m = {
        "steps": 6000,
        "saturated_steps": 1116,
        "singular_steps": 0,
        "solver_failures": 0,
        "max_band_distance_m": 0.7000008,
        "max_joint_speed_ratio": 0.086,
        "max_wheel_speed_ratio": 0.258,
        "min_joint_limit_margin_rad": 0.317,
        "max_position_error_m": 0.000185,
    }
    lines = flag_reasons(m, band=0.7)
    assert "1116 of 6000 steps (19 %)" in lines[0] and "0.7 m band's edge" in lines[0]
    assert lines[1].startswith("the hand still tracked the path") and "0.1850 mm" in lines[1]
    m["max_band_distance_m"], m["max_wheel_speed_ratio"] = 0.5, 1.0
    assert "a wheel reached its rate limit" in flag_reasons(m, band=0.7)[0]
    assert flag_reasons({**m, "saturated_steps": 0}, band=0.7) == []


def _fake_run(peak_nm: float):
    from types import SimpleNamespace

    t = np.arange(0.0, 2.0, 0.01)
    tau = np.zeros((len(t), 1, 7))
    tau[100:110, 0, 2] = peak_nm  # 0.1 s on joint 3
    limit = np.array([60.0, 60.0, 30.0, 30.0, 15.0, 10.0, 10.0])
    return SimpleNamespace(t=t, arm_torque=tau, effort_limit=limit, config=SimpleNamespace(dt=0.01))


def test_push_torque_verdict_warns_over_the_limit_and_names_the_joint():
    from wholebody.push.report import torque_verdict

    line, over = torque_verdict(_fake_run(37.0))
    assert over and "1.23 x effortLimit" in line and "joint 3 at 37.0 of 30 N m" in line
    assert "OVER THE LIMIT for 0.10 s (joints 3)" in line and "t = 1.0 s" in line
    line, over = torque_verdict(_fake_run(15.0))
    assert not over and "within the limits" in line


def test_plan_contacts_infeasible_names_the_limit_and_rounds_the_closest_wrench(capsys):
    assert main(["plan-contacts", "--wrench", "-1e3", "0", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "e-" not in err
    assert "grip pull limit" in err and "--grip-force" in err and "fx -100.00 N, fy 0.00 N, tau 0.00 N m" in err


def test_demo_says_what_each_file_of_its_report_shows(tmp_path):
    """After the run the demo lists the report's files with what each shows, the pages by their full path."""
    from cartpush.cli.demo import REPORT_FILES, report_listing

    for name in ("scene.html", "estimate.png", "unrelated.txt"):
        (tmp_path / name).write_text("x")
    lines = report_listing(tmp_path)
    assert lines == [
        f"  {(tmp_path / 'scene.html').resolve()}: {REPORT_FILES['scene.html']}",
        f"  estimate.png: {REPORT_FILES['estimate.png']}",
    ]

"""The CLI dispatcher and `cartpush demo`."""

from __future__ import annotations

import json
import subprocess
import sys

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
        "arm_torques.png",
        "scene.html",
        "push_log.csv",
        "comparison.md",
    }

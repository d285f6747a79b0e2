"""Tests of `cartpush track`: JSON fields, CSV output, bad input."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from cartpush.cli import main
from wholebody.motion.experiments import run_tracking


def test_track_json_matches_library(capsys):
    assert main(["track", "sine", "--duration", "5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in (
        "max_position_error_m",
        "rms_position_error_m",
        "max_orientation_error_rad",
        "min_joint_limit_margin_rad",
        "steps",
    ):
        assert key in out
    assert out["steps"] == 500
    ref = run_tracking("wmra", "sine", duration=5.0)
    assert out["max_position_error_m"] == pytest.approx(ref.max_position_error_m)
    assert out["max_band_distance_m"] is None


def test_track_csv_and_band(tmp_path, capsys):
    log = tmp_path / "run.csv"
    assert (
        main(
            [
                "track",
                "line",
                "--robot",
                "ridgeback_iiwa",
                "--band",
                "0.3",
                "--duration",
                "2",
                "--out",
                str(log),
                "--json",
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert out["band_radius"] == 0.3 and out["max_band_distance_m"] <= 0.3 + 1e-6
    rows = list(csv.DictReader(open(log)))
    assert len(rows) == 201
    last = rows[-1]
    assert float(last["time_s"]) == pytest.approx(2.0)
    d = np.array([float(last[f"ee_desired_{c}_m"]) - float(rows[0][f"ee_desired_{c}_m"]) for c in "xyz"])
    np.testing.assert_allclose(d, [0.18, 0.0, 0.0], atol=1e-9)
    err = max(
        np.linalg.norm([float(r[f"ee_desired_{c}_m"]) - float(r[f"ee_actual_{c}_m"]) for c in "xyz"]) for r in rows
    )
    assert err == pytest.approx(out["max_position_error_m"], abs=1e-9)


def test_track_table_output(capsys):
    assert main(["track", "line", "--duration", "1"]) == 0
    assert "RMS position error" in capsys.readouterr().out


@pytest.mark.parametrize("argv", [["track", "line", "--band", "-1"], ["track", "line", "--duration", "0"]])
def test_bad_input_exits_2(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("cartpush track: error:") and err.count("\n") == 1

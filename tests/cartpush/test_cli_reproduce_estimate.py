"""CLI: `cartpush reproduce` (subset) and `cartpush estimate` on a simulated log and on bad logs."""

import json

import numpy as np
import pytest

from cart import table1
from cart.logs import CartLog, write_log
from cartpush.cli import main


def test_reproduce_json_fields_and_outputs(tmp_path, capsys):
    assert main(["reproduce", "--json", "--tests", "4", "--duration", "12", "--out", str(tmp_path)]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [set(r) for r in rows] == [
        {
            "test",
            "mass_error_final_kg",
            "mass_converged_s",
            "com_error_final_m",
            "tracking_rms_mm",
            "tracking_rms_no_estimation_mm",
            "tracking_max_after_5s_mm",
            "tracking_max_after_5s_no_estimation_mm",
            "mass_error_rms_kg",
            "mass_error_max_after_5s_kg",
            "com_error_rms_m",
            "com_error_max_after_5s_m",
            "time_mass_within_1kg_s",
            "time_com_within_1cm_s",
            "online",
        }
    ]
    r = rows[0]
    # the online estimator's row beside the paper's EKF: its errors and the load changes it found
    assert {"mass_error_final_kg", "time_mass_within_1kg_s", "load_changes"} <= set(r["online"])
    assert r["online"]["mass_error_final_kg"] < 1.0 and r["online"]["load_changes"] == []
    assert r["test"] == 4 and r["mass_error_final_kg"] < 0.5
    assert r["tracking_rms_no_estimation_mm"] > r["tracking_rms_mm"]
    # millimetres: the study's own run, recomputed independently from its poses
    run = table1.run_test(table1.TESTS[3], True, duration=12.0)
    late = run.t >= 5.0
    err = np.hypot(*(run.q_desired[late, :2] - run.q[late, :2]).T)
    assert r["tracking_rms_mm"] == pytest.approx(1e3 * np.sqrt(np.mean(err**2)), rel=1e-12)
    assert r["tracking_max_after_5s_mm"] == pytest.approx(1e3 * err.max(), rel=1e-12)
    # time-resolved: the max after 5 s bounds the final error, the time within 1 kg fits in the run
    assert r["mass_error_final_kg"] <= r["mass_error_max_after_5s_kg"] < 1.0
    assert r["com_error_final_m"] <= r["com_error_max_after_5s_m"]
    assert 0.0 < r["time_mass_within_1kg_s"] <= 12.0 + 1e-9
    for name in ("fig4_tracking_error.png", "table.csv", "table.md"):
        assert (tmp_path / name).stat().st_size > 0
    md = (tmp_path / "table.md").read_text()
    assert "m err max >5 s [kg]" in md and "mass_error_final_kg" not in md
    assert "track RMS [mm]" in md and "[m]" not in md.split("CoM err final [cm]")[1].splitlines()[0]
    assert "test 4: Traj. 2, m guess 16 kg" in md


def test_reproduce_table_headers_match_table_md_and_flag_unobservable_stretches(tmp_path, capsys):
    from cartpush.cli.reproduce import table_header

    assert main(["reproduce", "--tests", "11", "--duration", "15", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    header = table_header()
    assert all("[" in h for h in header[1:])  # units on every metric
    assert out.splitlines()[0].split() == "  ".join(header).split()
    assert (tmp_path / "table.md").read_text().splitlines()[0] == "| " + " | ".join(header) + " |"
    # test 11: the payload change at 10 s leaves the mass estimate > 1 kg off for a stretch
    assert "test 11: Traj. 2" in out and "note: test 11: mass estimate off by > 1 kg" in out
    # no progress output off a terminal (pytest's stderr is not one)
    assert capsys.readouterr().err == ""


def test_a_failed_run_is_reported_beside_the_tests_that_completed(tmp_path, capsys, monkeypatch):
    from cart.errors import NumericalError

    real = table1.run_test

    def failing(test, estimate=True, *args, estimator="ekf", **kwargs):
        if (test.test, estimate, estimator) in {(2, True, "online"), (3, True, "ekf")}:
            raise NumericalError("z must be finite, got [nan]")
        return real(test, estimate, *args, estimator=estimator, **kwargs)

    monkeypatch.setattr(table1, "run_test", failing)
    argv = ["reproduce", "--tests", "1,2,3", "--duration", "6", "--workers", "1", "--out", str(tmp_path)]
    assert main([*argv, "--json"]) == 3
    cap = capsys.readouterr()
    rows = json.loads(cap.out)
    assert [r["test"] for r in rows] == [1, 2, 3]
    assert "failed" not in rows[0] and "failed" not in rows[0]["online"]
    assert rows[1]["online"] == {"failed": "online estimator run failed: NumericalError: z must be finite, got [nan]"}
    assert rows[1]["mass_error_final_kg"] < 5.0  # the paper's EKF row of test 2 is kept
    assert rows[2] == {"test": 3, "failed": "the paper's EKF run failed: NumericalError: z must be finite, got [nan]"}
    assert len(cap.err.strip().splitlines()) == 1 and "2 of 3 tests had a failed run" in cap.err
    md = (tmp_path / "table.md").read_text()
    assert "- FAILED: test 3: the paper's EKF run failed" in md and "- FAILED: test 2: online estimator" in md
    assert (tmp_path / "fig4_tracking_error.png").stat().st_size > 0
    assert main(argv) == 3
    out = capsys.readouterr().out.splitlines()
    row3 = next(line.split() for line in out if line.split()[:1] == ["3"])
    assert set(row3[1:]) == {"failed"}


def test_reproduce_rejects_zero_workers(capsys):
    assert main(["reproduce", "--workers", "0", "--tests", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--workers" in err[0]


def test_estimate_json_on_simulated_log(tmp_path, capsys):
    run = table1.run_test(table1.TESTS[5], True, duration=30.0)
    path = tmp_path / "push.csv"
    write_log(path, CartLog(t=run.t, q=run.q, gamma=run.gamma))
    for method in ("ls", "ekf"):
        assert main(["estimate", str(path), "--method", method, "--mass-guess", "15", "--json"]) == 0
        out = json.loads(capsys.readouterr().out)
        # the contract's fields (docs/architecture.md), whatever the method
        assert {"mass", "com", "inertia", "sigma", "sigma_yaw", "std", "nis_mean", "model_fits", "warnings"} <= set(out)
        assert set(out["std"]) == {"mass", "com", "inertia", "sigma", "sigma_yaw"}
        assert out["method"] == method
        assert abs(out["mass"] - 20.0) < 1.0


def test_estimate_bad_log_exits_2_with_one_line(tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text("t,x,y,theta,fx,fy,tau\n0,0,0,0,0,0,0\n")
    assert main(["estimate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bad.csv" in err

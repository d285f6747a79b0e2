"""CLI: `cartpush reproduce` (subset) and `cartpush estimate` on a simulated log and on bad logs."""
import json

import numpy as np

from studies import table1
from cart.logs import CartLog, write_log
from wholebody.cli import main


def test_reproduce_json_fields_and_outputs(tmp_path, capsys):
    assert main(["reproduce", "--json", "--tests", "4", "--duration", "12", "--out", str(tmp_path)]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [set(r) for r in rows] == [{"test", "mass_error_final_kg", "mass_converged_s", "com_error_final_m",
                                       "tracking_rms_m", "tracking_rms_no_estimation_m"}]
    assert rows[0]["test"] == 4 and rows[0]["mass_error_final_kg"] < 0.5
    assert rows[0]["tracking_rms_no_estimation_m"] > rows[0]["tracking_rms_m"]
    for name in ("fig4_tracking_error.png", "table.csv", "table.md"):
        assert (tmp_path / name).stat().st_size > 0


def test_estimate_json_on_simulated_log(tmp_path, capsys):
    run = table1.run_test(table1.TESTS[5], True, duration=30.0)
    path = tmp_path / "push.csv"
    write_log(path, CartLog(t=run.t, q=run.q, gamma=run.gamma))
    for method in ("ls", "ekf"):
        assert main(["estimate", str(path), "--method", method, "--mass-guess", "15", "--json"]) == 0
        out = json.loads(capsys.readouterr().out)
        # the contract's fields (DESIGN.md), whatever the method
        assert {"mass", "com", "inertia", "sigma", "sigma_yaw", "std", "nis_mean", "model_fits",
                "warnings"} <= set(out)
        assert set(out["std"]) == {"mass", "com", "inertia", "sigma", "sigma_yaw"}
        assert out["method"] == method
        assert abs(out["mass"] - 20.0) < 1.0


def test_estimate_bad_log_exits_2_with_one_line(tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text("t,x,y,theta,fx,fy,tau\n0,0,0,0,0,0,0\n")
    assert main(["estimate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bad.csv" in err

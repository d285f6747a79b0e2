"""`cartpush diagnose`: JSON fields, plots, bad input."""

from __future__ import annotations

import json
import os

import numpy as np

from studies.testbeds.hidden_effects import random_case
from cart.logs import write_log
from cartpush.cli import main


def test_diagnose_json_and_plots(tmp_path, capsys):
    h = random_case("time_delay", np.random.default_rng(21))
    path = str(tmp_path / "run.csv.gz")
    write_log(path, h.measured, wrap_theta=True)
    out_dir = str(tmp_path / "plots")
    assert main(["diagnose", path, "--json", "--out", out_dir]) == 0
    d = json.loads(capsys.readouterr().out)
    assert [e["name"] for e in d["effects"]][:1] == ["time_delay"]
    assert abs(d["effects"][0]["parameters"]["delay"] - h.effects[0].params["delay"]) < 0.03
    assert d["gap_after"] <= 0.5 * d["gap_before"]
    assert "RMS excess position error" in d["gap_metric"] and d["rms_before"] >= d["gap_before"]
    assert "Delta BIC" in d["effects"][0]["reason"] and "ms" in d["effects"][0]["reason"]  # the delay's sign read out
    assert all(v["reason"] for v in d["not_named"]) and isinstance(d["warnings"], list)
    for name in ("replay.png", "residuals.png"):
        assert os.path.getsize(os.path.join(out_dir, name)) > 10_000


def test_diagnose_table_without_velocity_columns(tmp_path, capsys):
    h = random_case(None, np.random.default_rng(22))
    from dataclasses import replace

    path = str(tmp_path / "run.csv")
    write_log(path, replace(h.measured, qd=None))
    assert main(["diagnose", path]) == 0
    assert "named effects: none" in capsys.readouterr().out


def test_bad_log_exits_2_with_one_line(tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text("t,x,y,theta,fx,fy\n0,0,0,0,0,0\n")
    assert main(["diagnose", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tau" in err[0]


def test_wrench_in_the_cart_frame_exits_2_with_one_line(tmp_path, capsys):
    from studies.testbeds.hidden_effects import defective_log

    h = random_case(None, np.random.default_rng(9103), duration=30.0, rate=100.0, jitter=0.1)
    path = str(tmp_path / "cart_frame.csv")
    write_log(path, defective_log(h.measured, "wrench_in_cart_frame", np.random.default_rng(4)))
    assert main(["diagnose", path]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cart frame" in err[0]

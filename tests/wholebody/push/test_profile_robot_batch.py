"""`cartpush batch push`: a campaign over robots (names or profile files) x masses x trajectories, resumable."""

from __future__ import annotations

import json

import pytest

from cartpush.batch.push_campaign import PushRun, campaign, done_runs, run_campaign
from cartpush.batch import BatchError
from cartpush.cli.app import main
from tests.robots.profile_files import write_profile


def test_campaign_lines_resume_and_a_broken_profile_is_an_error_line(tmp_path, capsys):
    bad = write_profile(
        tmp_path,
        'name = "ghost"\nurdf = "ghost.urdf"\nbase = "differential"\n'
        'wheel_joints = ["l", "r"]\n[[arms]]\njoints = ["a"]\ngripper_frame = "g"\n',
        "ghost.toml",
    )
    out = tmp_path / "push.jsonl"
    argv = ["batch", "push", "--robots", "wmra", str(bad), "--masses", "20", "--trajectories", "1"]
    argv += ["--duration", "8", "--out", str(out), "--json"]
    assert main(argv) == 3  # one run failed: FAILED_EXIT
    summary = json.loads(capsys.readouterr().out)
    assert summary["runs"] == 2 and summary["ok"] == 1 and summary["failed"] == 1
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    ok = next(r for r in lines if r["ok"])
    assert ok["run"] == {
        "robot": "wmra",
        "mass": 20.0,
        "trajectory": 1,
        "arms": 1,
        "plant": "kinematic",
        "duration": 8.0,
        "seed": 0,
    }
    assert 0 < ok["result"]["tracking_rms_mm"] < 20 and ok["result"]["arm_torque_limit_ratio"] <= 1.0
    failed = next(r for r in lines if not r["ok"])
    assert failed["run"]["robot"] == str(bad) and "urdf: file" in failed["error"] and "\n" not in failed["error"]
    # a rerun skips the done run and retries the failed one
    assert main(argv) == 3  # the retried run fails again
    again = json.loads(capsys.readouterr().out)
    assert again["skipped"] == 1 and again["ran"] == 1 and again["failed"] == 1
    assert done_runs(out) == {PushRun("wmra", 20.0, 1, duration=8.0).key()}
    row = next(r for r in again["table"] if r["ok"])
    assert row["tracking_rms_mm"] == pytest.approx(ok["result"]["tracking_rms_mm"])


def test_campaign_is_checked_before_any_run(tmp_path):
    runs = campaign(["wmra", "ridgeback_iiwa"], [15, 30], [1, 2])
    assert len(runs) == 8 and runs[0] == PushRun("wmra", 15.0, 1) and runs[-1] == PushRun("ridgeback_iiwa", 30.0, 2)
    for bad in (dict(robots=["nope"]), dict(masses=[-1]), dict(trajectories=[3]), dict(robots=["shopping_cart"])):
        kw = dict(robots=["wmra"], masses=[20], trajectories=[1]) | bad
        with pytest.raises(BatchError):
            campaign(**kw)
    with pytest.raises(BatchError, match="--plant"):
        campaign(["wmra"], [20], [1], plant="gazebo")
    with pytest.raises(BatchError, match="directory"):
        run_campaign(runs[:1], tmp_path)


CAMPAIGN = ["--robots", "wmra", "ridgeback_iiwa", "--masses", "15", "25", "--trajectories", "1", "--duration", "8"]


def test_two_robots_by_two_masses_on_two_workers_write_four_lines_and_a_rerun_runs_nothing(tmp_path, capsys):
    out = tmp_path / "campaign.jsonl"
    argv = ["batch", "push", *CAMPAIGN, "--workers", "2", "--out", str(out), "--json"]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert len(lines) == 4 and all(r["ok"] for r in lines) and summary["workers"] == 2
    assert {(r["run"]["robot"], r["run"]["mass"]) for r in lines} == {
        (rb, m) for rb in ("wmra", "ridgeback_iiwa") for m in (15.0, 25.0)
    }
    assert main(argv) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["ran"] == 0 and again["skipped"] == 4
    assert len(out.read_text().splitlines()) == 4


def test_the_campaign_on_a_local_ray_cluster(tmp_path):
    """The same campaign as Ray tasks (a local cluster: what `ray start --head` gives) writes the same lines."""
    from tests.optional import require_module

    ray = require_module("ray", "pip install 'cartpush[cluster]'")
    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
    try:
        runs = campaign(["wmra", "ridgeback_iiwa"], [15.0, 25.0], [1], duration=8.0)
        out = tmp_path / "ray.jsonl"
        summary = run_campaign(runs, out, workers=None, ray_address="auto", progress=False)
        assert summary["backend"] == "ray"
        lines = [json.loads(x) for x in out.read_text().splitlines()]
        assert len(lines) == 4 and all(r["ok"] for r in lines)
        assert run_campaign(runs, out, workers=None, ray_address="auto", progress=False)["ran"] == 0
    finally:
        ray.shutdown()

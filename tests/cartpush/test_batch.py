"""`cartpush batch`: the same results as one-by-one runs (1 and 2 local workers, a local Ray), resume, bad logs."""

from __future__ import annotations

import json
import os

import pytest

from cart.logs import write_log
from studies.testbeds import rigid_sim
from cartpush.batch import BatchError, CommandJob, done_paths, expand_inputs, run_batch
from tests.optional import require_module
from cartpush.cli.app import main

N_GOOD = 3


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Three 15 s logs from the independent test bed and one malformed log, in one directory."""
    d = tmp_path_factory.mktemp("batch_logs")
    good = []
    for seed in range(N_GOOD):
        log, _ = rigid_sim.simulate(rigid_sim.random_case(seed, duration=15.0, rate_hz=100.0))
        path = d / f"run{seed}.csv.gz"
        write_log(path, log)
        good.append(str(path))
    bad = d / "broken.csv"
    bad.write_text("t,x,y,theta,fx,fy,tau\n0.0,0,0,0,1,2\nnot,a,number,at,all,,\n")
    return {"dir": str(d), "good": good, "bad": str(bad)}


@pytest.fixture(scope="module")
def reference(logs):
    """`cartpush estimate LOG --json` run one by one (in process), per log."""
    out = {}
    for path in logs["good"]:
        import contextlib
        import io

        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(["estimate", path, "--json"]) == 0
        out[path] = json.loads(buf.getvalue())
    return out


def _lines(path):
    with open(path, encoding="utf-8") as fh:
        return [json.loads(line) for line in fh if line.strip()]


def _same(a, b) -> bool:
    """Whether two JSON results are the same up to floating-point rounding (1e-12 relative).

    `batch` runs each log in a worker process with OpenBLAS on one thread (as `cartpush estimate` runs); the reference
    runs in this process, whose numpy loaded with the default threads: a multi-threaded product sums in another
    order, and a std may differ in its last digits.
    """
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return a == pytest.approx(b, rel=1e-12, abs=1e-300, nan_ok=True)
    return a == b


def _check_same(lines, logs, reference):
    by_path = {rec["path"]: rec for rec in lines}
    assert len(lines) == N_GOOD + 1 and set(by_path) == set(logs["good"]) | {logs["bad"]}
    for path in logs["good"]:
        assert by_path[path]["ok"] is True, by_path[path]
        assert _same(by_path[path]["result"], reference[path]), (by_path[path]["result"], reference[path])
    bad = by_path[logs["bad"]]
    assert bad["ok"] is False and "\n" not in bad["error"] and bad["error"]


def test_expand_inputs(logs, tmp_path):
    """A directory gives its logs sorted; a glob its matches; duplicates once; a typo is an error."""
    d = logs["dir"]
    from_dir = expand_inputs([d])
    assert from_dir == sorted(logs["good"] + [logs["bad"]])
    assert expand_inputs([os.path.join(d, "run*.csv.gz"), logs["good"][0]]) == logs["good"]
    with pytest.raises(BatchError, match="no such file"):
        expand_inputs([os.path.join(d, "nothing*.csv")])
    with pytest.raises(BatchError, match="holds no"):
        expand_inputs([str(tmp_path)])


@pytest.mark.parametrize("workers", [1, 2])
def test_local_workers_match_one_by_one(logs, reference, tmp_path, workers, capsys):
    """The CLI on 1 and 2 joblib workers writes the command's --json result per log; the bad log is an error line
    and makes the exit code FAILED_EXIT (3) with a summary line on stderr."""
    out = tmp_path / "results.jsonl"
    assert main(["batch", "estimate", logs["dir"], "--out", str(out), "--workers", str(workers), "--json"]) == 3
    captured = capsys.readouterr()
    assert "1 of 4 failed" in captured.err and "exit code 3" in captured.err
    summary = json.loads(captured.out)
    assert summary["ran"] == N_GOOD + 1 and summary["ok"] == N_GOOD and summary["failed"] == 1
    assert summary["backend"] == "joblib" and summary["logs_per_min"] > 0
    _check_same(_lines(out), logs, reference)


def test_ray_matches_one_by_one(logs, reference, tmp_path):
    """The same engine on a local Ray instance gives the same lines."""
    ray = require_module("ray", "pip install 'cartpush[cluster]'")
    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
    try:
        out = tmp_path / "ray.jsonl"
        summary = run_batch(
            CommandJob("estimate"), expand_inputs([logs["dir"]]), out, workers=None, ray_address="auto", progress=False
        )
        assert summary["backend"] == "ray" and summary["workers"] == 2
        assert summary["ok"] == N_GOOD and summary["failed"] == 1
        _check_same(_lines(out), logs, reference)
    finally:
        ray.shutdown()


class CountingJob:
    """A job that records the paths it ran (in process: workers=1)."""

    def __init__(self, job):
        self.job = job
        self.calls = []

    def __call__(self, path):
        self.calls.append(path)
        return self.job(path)


def test_resume_runs_only_the_missing(logs, reference, tmp_path):
    """After an interrupted run (two lines done, one cut mid-line, a failed line), a rerun runs only what is missing."""
    out = tmp_path / "partial.jsonl"
    g0, g1, g2 = logs["good"]
    done = [
        {"path": g0, "ok": True, "result": reference[g0]},
        {"path": g1, "ok": True, "result": reference[g1]},
        {"path": logs["bad"], "ok": False, "error": "an earlier failure"},
    ]
    text = "".join(json.dumps(rec) + "\n" for rec in done) + '{"path": "' + g2 + '", "ok": tr'
    out.write_text(text)
    assert done_paths(out) == {g0, g1}
    job = CountingJob(CommandJob("estimate"))
    summary = run_batch(job, expand_inputs([logs["dir"]]), out, workers=1, progress=False)
    assert sorted(job.calls) == sorted([g2, logs["bad"]])
    assert summary["skipped"] == 2 and summary["ran"] == 2
    lines = []
    for line in out.read_text().splitlines():
        try:
            lines.append(json.loads(line))
        except ValueError:
            assert line.endswith('"ok": tr')  # the cut line stays, on its own line
    assert [rec["path"] for rec in lines[:3]] == [g0, g1, logs["bad"]]
    new = {rec["path"]: rec for rec in lines[3:]}
    assert set(new) == {g2, logs["bad"]} and _same(new[g2]["result"], reference[g2]) and not new[logs["bad"]]["ok"]
    job2 = CountingJob(CommandJob("estimate"))  # everything good is done now: only the bad log is retried
    run_batch(job2, expand_inputs([logs["dir"]]), out, workers=1, progress=False)
    assert job2.calls == [logs["bad"]]


def test_diagnose_job_and_bad_options(logs, tmp_path, capsys):
    """The diagnose job gives an error line for the malformed log; unusable options are one line and exit 2."""
    out = tmp_path / "diag.jsonl"
    summary = run_batch(CommandJob("diagnose"), [logs["bad"]], out, progress=False)
    assert summary["failed"] == 1 and _lines(out)[0]["ok"] is False
    assert main(["batch", "diagnose", logs["bad"], "--out", str(out), "--job-args=--threshold -1"]) == 2
    assert "--threshold" in capsys.readouterr().err
    assert main(["batch", "estimate", logs["bad"], "--out", str(tmp_path), "--json"]) == 2
    assert main(["batch", "estimate", logs["bad"], "--out", str(out), "--workers", "0"]) == 2


def test_exit_code_only_when_a_log_failed(logs, tmp_path, capsys):
    """Good logs only: exit 0 and no failure line; all logs failing: exit 3 with "all" in the summary line."""
    out = tmp_path / "good.jsonl"
    assert main(["batch", "estimate", *logs["good"], "--out", str(out)]) == 0
    assert "failed (" not in capsys.readouterr().err
    assert main(["batch", "estimate", logs["bad"], "--out", str(tmp_path / "bad.jsonl")]) == 3
    assert "1 of 1 failed (all)" in capsys.readouterr().err

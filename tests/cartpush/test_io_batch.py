"""`cartpush batch --out` that is no results file (a cart log) is refused, a results file is resumed;
a bad --job-args is one line naming the argument."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cartpush.batch import BatchError
from cartpush.cli import main
from cartpush.cli.batch import check_results_file
from tests.cartpush.cli_helpers import one_error_line, tiny_log


@pytest.fixture
def log(tmp_path) -> str:
    return tiny_log(tmp_path / "run.csv")


def test_an_existing_cart_log_as_out_is_refused_and_untouched(log, tmp_path, capsys):
    other = tmp_path / "other_cart_log.csv"
    other.write_bytes(Path(log).read_bytes())
    before = other.read_bytes()
    assert main(["batch", "estimate", log, "--out", str(other)]) == 2
    line = one_error_line(capsys, "batch")
    assert "is not a JSON Lines results file (its first line is not a JSON object" in line
    assert other.read_bytes() == before


def test_a_results_file_is_resumed_and_an_empty_file_taken(log, tmp_path, capsys):
    out = tmp_path / "results.jsonl"
    out.write_text("")
    assert main(["batch", "estimate", log, "--out", str(out)]) == 0
    assert main(["batch", "estimate", log, "--out", str(out)]) == 0  # appending to its own results: resumed
    assert "1 already done" in capsys.readouterr().out
    assert [json.loads(s)["ok"] for s in out.read_text().splitlines()] == [True]


@pytest.mark.parametrize(
    "first, ok",
    [
        ('{"path": "/a.csv", "ok": true}\n', True),
        ('\n{"path": "/a.csv", "ok": tr', True),  # a first line cut by an interrupted run
        ("t,x,y,theta,fx,fy,tau\n", False),
        ("# log: sim1\n", False),
        ("[1, 2]\n", False),
    ],
)
def test_check_results_file_looks_at_the_first_line(tmp_path, first, ok):
    out = tmp_path / "results.jsonl"
    out.write_text(first)
    if ok:
        check_results_file(str(out), [])
    else:
        with pytest.raises(BatchError, match="not a JSON Lines results file"):
            check_results_file(str(out), [])


@pytest.mark.parametrize(
    "job_args, fragment",
    [
        ("--method foo", "--job-args '--method foo': argument --method: invalid choice: 'foo'"),
        ("--bogus 3", "--job-args '--bogus 3': unrecognized arguments: --bogus 3"),
    ],
)
def test_a_bad_job_argument_is_one_line_naming_it(log, tmp_path, capsys, job_args, fragment):
    out = tmp_path / "results.jsonl"
    assert main(["batch", "estimate", log, "--out", str(out), f"--job-args={job_args}"]) == 2
    assert fragment in one_error_line(capsys, "batch")
    assert not out.exists()


@pytest.mark.parametrize(
    ("extra", "named"),
    [(["--masses", "20"], "--masses: an option"), (["--plant", "mujoco", "--duration", "10"], "--plant, --duration")],
)
def test_a_push_option_given_to_batch_estimate_is_refused_not_ignored(log, tmp_path, capsys, extra, named):
    out = tmp_path / "r.jsonl"
    assert main(["batch", "estimate", log, "--out", str(out), *extra]) == 2
    line = one_error_line(capsys, "batch")
    assert named in line and "of batch push only" in line and not out.exists()

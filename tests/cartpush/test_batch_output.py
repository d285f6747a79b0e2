"""`cartpush batch --out`: refused before anything runs when it is an input log, a device, a directory or unwritable."""

from __future__ import annotations

import os

import pytest

from cartpush.batch import BatchError, OutputPathError, check_output, run_batch
from cartpush.cli.app import main


def _never_called(path: str) -> dict:
    raise AssertionError(f"the job ran on {path} although --out was refused")


@pytest.fixture
def log_file(tmp_path):
    """A file standing in for an input log (the refusal must come before it is read)."""
    p = tmp_path / "run.csv"
    p.write_text("t,x,y,theta,fx,fy,tau\n")
    return p


def test_out_that_is_an_input_log_is_refused_and_the_log_untouched(log_file, tmp_path):
    before = log_file.read_bytes()
    with pytest.raises(OutputPathError, match="one of the input logs"):
        run_batch(_never_called, [str(log_file)], log_file)
    link = tmp_path / "link.jsonl"
    os.symlink(log_file, link)  # the same file under another name
    with pytest.raises(OutputPathError, match="one of the input logs"):
        run_batch(_never_called, [str(log_file)], link)
    assert log_file.read_bytes() == before


@pytest.mark.parametrize("device", ["/dev/full", "/dev/null"])
def test_out_that_is_a_device_is_refused(log_file, device):
    if not os.path.exists(device):
        pytest.skip(f"{device} does not exist here")
    with pytest.raises(OutputPathError, match="a device"):
        run_batch(_never_called, [str(log_file)], device)


@pytest.mark.parametrize("device", ["/dev/stdout", "/dev/stderr", "/proc/self/fd/1"])
def test_out_that_names_a_stream_is_refused_whatever_it_is_redirected_to(log_file, device):
    # run under pytest's capture, /dev/stdout may lead to a regular (temporary) file: still refused
    with pytest.raises(OutputPathError, match="a device"):
        run_batch(_never_called, [str(log_file)], device)


def test_a_link_to_a_device_is_refused(log_file, tmp_path):
    link = tmp_path / "results.jsonl"
    os.symlink("/dev/null", link)
    with pytest.raises(OutputPathError, match="a device"):
        check_output(link, [str(log_file)])


def test_out_that_is_a_directory_or_in_a_missing_directory_is_refused(log_file, tmp_path):
    with pytest.raises(OutputPathError, match="is a directory"):
        check_output(tmp_path, [str(log_file)])
    with pytest.raises(OutputPathError, match="does not exist"):
        check_output(tmp_path / "missing" / "out.jsonl", [str(log_file)])


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root writes anywhere")
def test_out_in_a_read_only_directory_is_refused(log_file, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        with pytest.raises(OutputPathError, match="not writable"):
            check_output(ro / "out.jsonl", [str(log_file)])
    finally:
        ro.chmod(0o700)


def test_a_new_results_file_next_to_the_logs_is_accepted(log_file, tmp_path):
    check_output(tmp_path / "results.jsonl", [str(log_file)])  # no exception
    assert issubclass(OutputPathError, BatchError)


def test_cli_refuses_with_one_line_and_exit_2(log_file, capsys):
    before = log_file.read_bytes()
    code = main(["batch", "estimate", str(log_file), "--out", str(log_file)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "one of the input logs" in err[0]
    assert log_file.read_bytes() == before


def test_out_under_a_regular_file_names_the_file(log_file, tmp_path):
    """An outside tester's --out a_file/x.jsonl was told the directory does not exist."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    with pytest.raises(OutputPathError, match="a_file is a file, not a directory"):
        check_output(blocker / "sub" / "x.jsonl", [str(log_file)])

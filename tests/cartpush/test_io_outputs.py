"""Outputs the CLI cannot write: a device refused before the run; an OSError while writing (a full disk, a
read-only file system) one line and exit code 2, naming the file or the output options and what to do."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cartpush.cli import main, options
from cartpush.errors import OptionError
from tests.cartpush.cli_helpers import one_error_line, tiny_log

BAG = Path(__file__).resolve().parents[2] / "cartpush" / "ros" / "data" / "sample_push.bag"
BAG_TOPICS = ["--pose-topic", "/mocap/cart", "--wrench-topic", "/ft_sensor/wrench"]


@pytest.mark.parametrize(
    "argv, option",
    [
        (["view", "--robot", "wmra", "--html", "/dev/full"], "--html"),
        (["track", "line", "--json", "--duration", "5", "--out", "/dev/full"], "--out"),
        (["track", "line", "--duration", "5", "--out", "/dev/null"], "--out"),
        (["push", "--duration", "8", "--json", "--html", "/dev/full"], "--html"),
        (["import", str(BAG), "-o", "/dev/full", *BAG_TOPICS], "-o"),
    ],
)
def test_a_device_as_output_file_is_refused_before_the_run(argv, option, capsys):
    device = argv[argv.index(option) + 1]
    if not os.path.exists(device):
        pytest.skip(f"{device} does not exist here")
    assert main(argv) == 2
    line = one_error_line(capsys, argv[0])
    assert f"{option} {device}: is a character device" in line
    assert "give the name of a file" in line


def test_output_file_refuses_a_fifo_and_a_stream_and_takes_a_file(tmp_path):
    fifo = tmp_path / "page.html"
    os.mkfifo(fifo)
    with pytest.raises(OptionError, match="FIFO"):
        options.writable_file(fifo, "--html")
    with pytest.raises(OptionError, match="under /dev or /proc"):
        options.output_file("/dev/stdout", "--out")  # whatever the shell redirected it to
    assert options.writable_file(tmp_path / "run.csv") == tmp_path / "run.csv"


@pytest.mark.parametrize(
    "exc, fragments",
    [
        (OSError(errno.ENOSPC, "No space left on device"), ["no space left on the device", "--out", "free space"]),
        (OSError(errno.EDQUOT, "Disk quota exceeded"), ["disk quota exceeded", "--out", "write elsewhere"]),
        (OSError(errno.EROFS, "Read-only file system", "/mnt/ro/run.csv"), ["read-only file system", "/mnt/ro"]),
        (OSError(errno.EIO, "Input/output error", "run.csv"), ["input/output error", "run.csv", "check the disk"]),
        (OSError("no errno at all"), ["no errno at all"]),
    ],
)
def test_an_oserror_while_running_is_one_line_exit_2(monkeypatch, capsys, tmp_path, exc, fragments):
    import cartpush.cli.track as mod

    def fail(args):
        raise exc

    monkeypatch.setattr(mod, "run", fail)
    assert main(["track", "line", "--out", str(tmp_path / "run.csv")]) == 2
    line = one_error_line(capsys, "track")
    for fragment in fragments:
        assert fragment in line, line
    monkeypatch.setattr(mod, "run", fail)
    assert main(["--debug", "track", "line"]) == 2  # bad environment, not a bug: no traceback either
    one_error_line(capsys, "track")


def test_broken_pipe_and_memory_error_keep_their_codes(monkeypatch, capsys):
    import cartpush.cli.track as mod

    def pipe(args):
        raise BrokenPipeError(errno.EPIPE, "Broken pipe")

    def memory(args):
        raise MemoryError

    monkeypatch.setattr(mod, "run", memory)
    assert main(["track", "line"]) == 2
    assert "out of memory (reduce the duration or the log size)" in one_error_line(capsys, "track")
    monkeypatch.setattr(mod, "run", pipe)
    monkeypatch.setattr("cartpush.cli.app._closed_stdout", lambda: 141)  # keep pytest's stdout
    assert main(["track", "line"]) == 141


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_stdout_on_a_full_disk_is_one_line_exit_2(tmp_path):
    log = tiny_log(tmp_path / "run.csv")
    with open("/dev/full", "w") as full:
        proc = subprocess.run(
            [sys.executable, "-m", "cartpush.cli", "estimate", log, "--json"],
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
        )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0] == "cartpush estimate: error: no space left on the device: free space or write elsewhere"

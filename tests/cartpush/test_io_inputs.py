"""Inputs the CLI must not hang on or destroy: a FIFO or a device as the log (refused up front, one line),
a gzip file named .csv (read as gzip), `import -o` naming the bag itself (refused, the bag untouched)."""

from __future__ import annotations

import gzip
import os
import shutil
import signal
from pathlib import Path

import numpy as np
import pytest

from cart.errors import LogFormatError
from cart.logs import read_log
from cartpush.cli import main
from tests.cartpush.cli_helpers import one_error_line, tiny_log

BAG = Path(__file__).resolve().parents[2] / "cartpush" / "ros" / "data" / "sample_push.bag"
BAG_TOPICS = ["--pose-topic", "/mocap/cart", "--wrench-topic", "/ft_sensor/wrench"]


class Hung(BaseException):
    """Raised by the alarm when a read blocks (not an Exception: the CLI must not turn it into exit 1 or 2)."""


@pytest.fixture
def alarm():
    """Fail a test that blocks for 10 s (reading a FIFO without a writer blocks in open) instead of hanging."""

    def ring(signum, frame):
        raise Hung

    previous = signal.signal(signal.SIGALRM, ring)
    signal.alarm(10)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def test_a_fifo_as_the_log_is_refused_at_once(tmp_path, capsys, alarm):
    fifo = tmp_path / "run.csv"
    os.mkfifo(fifo)
    with pytest.raises(LogFormatError, match="FIFO"):
        read_log(fifo)
    assert main(["estimate", str(fifo)]) == 2
    line = one_error_line(capsys, "estimate")
    assert f"{fifo}: is a FIFO (named pipe), not a log file; save the log to a regular file" in line


@pytest.mark.parametrize("device", ["/dev/null"])  # /dev/zero too, but the old reader ran out of memory on it
def test_a_device_as_the_log_is_refused(device, capsys):
    if not os.path.exists(device):
        pytest.skip(f"{device} does not exist here")
    assert main(["estimate", device]) == 2
    assert f"{device}: is a character device, not a log file" in one_error_line(capsys, "estimate")


def test_a_fifo_as_the_bag_is_refused_at_once(tmp_path, capsys, alarm):
    fifo = tmp_path / "run.bag"
    os.mkfifo(fifo)
    assert main(["import", str(fifo), "--list"]) == 2
    assert f"BAG {fifo}: is a FIFO (named pipe)" in one_error_line(capsys, "import")


def test_a_fifo_named_bag_given_to_estimate_is_refused_at_once(tmp_path, capsys, alarm):
    fifo = tmp_path / "run.bag"
    os.mkfifo(fifo)
    assert main(["estimate", str(fifo)]) == 2
    assert f"{fifo}: is a FIFO (named pipe), not a bag file" in one_error_line(capsys, "estimate")


def test_a_gzip_log_named_csv_is_read_as_gzip(tmp_path, capsys):
    plain = tiny_log(tmp_path / "run.csv")
    named = tmp_path / "gz_named.csv"
    named.write_bytes(gzip.compress(Path(plain).read_bytes()))
    a, b = read_log(plain), read_log(named)
    assert np.array_equal(a.t, b.t) and np.array_equal(a.q, b.q) and np.array_equal(a.gamma, b.gamma)
    assert main(["estimate", str(named), "--json"]) == 0
    capsys.readouterr()


def test_a_plain_log_named_gz_is_read_as_text_and_binary_named_gz_says_so(tmp_path):
    plain = tiny_log(tmp_path / "run.csv")
    named = tmp_path / "plain_named.csv.gz"
    named.write_bytes(Path(plain).read_bytes())
    a, b = read_log(plain), read_log(named)
    assert np.array_equal(a.t, b.t) and np.array_equal(a.gamma, b.gamma)
    garbage = tmp_path / "garbage.csv.gz"
    garbage.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(LogFormatError, match=r"named \.gz, but not gzip-compressed either"):
        read_log(garbage)


def test_import_onto_the_bag_itself_is_refused_and_the_bag_untouched(tmp_path, capsys):
    bag = tmp_path / "run.bag"
    shutil.copyfile(BAG, bag)
    before = bag.read_bytes()
    link = tmp_path / "run.csv"
    os.symlink(bag, link)  # the same file under another name
    for out in (bag, link, tmp_path / ".." / tmp_path.name / "run.bag"):
        assert main(["import", str(bag), "-o", str(out), *BAG_TOPICS]) == 2
        assert "is the bag being imported" in one_error_line(capsys, "import")
    assert bag.read_bytes() == before


def test_import_into_a_ros2_bag_folder_is_refused(tmp_path, capsys):
    folder = tmp_path / "rosbag2_run"
    folder.mkdir()
    (folder / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    assert main(["import", str(folder), "-o", str(folder / "metadata.yaml"), *BAG_TOPICS]) == 2
    assert "inside the bag folder" in one_error_line(capsys, "import")

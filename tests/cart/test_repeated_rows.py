"""Issue 30: a row written twice (every column, time included, equal to the previous row) is dropped with a
note; it was refused ("time ... is equal to the previous time", exit 2). Rows at one time with different
values are still refused."""

from __future__ import annotations

import re

import numpy as np
import pytest

from cart.errors import LogFormatError
from cart.logs import CartLog, read_log, write_log


def _lines(tmp_path):
    t = np.arange(200) * 0.01
    q = np.column_stack([0.3 * t, 0.1 * t * t, 0.2 * t])
    g = np.column_stack([np.sin(t), np.cos(t), 0.1 * t])
    path = tmp_path / "base.csv"
    write_log(path, CartLog(t=t, q=q, gamma=g))
    lines = path.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("t,"))
    return lines, head, read_log(path)


def test_a_row_written_twice_is_dropped_with_a_note(tmp_path):
    lines, head, base = _lines(tmp_path)
    body = lines[head + 1 :]
    body.insert(51, body[50])
    body.insert(121, body[120])
    path = tmp_path / "twice.csv"
    path.write_text("\n".join(lines[: head + 1] + body) + "\n")
    log = read_log(path)
    assert len(log.t) == len(base.t) and np.array_equal(log.t, base.t) and np.array_equal(log.gamma, base.gamma)
    assert any("2 row(s) repeat the previous row exactly" in w for w in log.warnings)


def test_rows_at_one_time_with_different_values_are_refused(tmp_path):
    lines, head, _ = _lines(tmp_path)
    body = lines[head + 1 :]
    fields = body[50].split(",")
    fields[4] = "7.5"
    body.insert(51, ",".join(fields))
    path = tmp_path / "clash.csv"
    path.write_text("\n".join(lines[: head + 1] + body) + "\n")
    with pytest.raises(LogFormatError, match="equal to the previous time"):
        read_log(path)


def test_notes_after_a_dropped_row_name_the_file_lines(tmp_path):
    lines, head, _ = _lines(tmp_path)
    body = lines[head + 1 :]
    body.insert(21, body[20])  # written twice: dropped
    fields = body[151].split(",")
    fields[1] = "9.0"  # a 9 m jump on this row
    body[151] = ",".join(fields)
    fields = body[171].split(",")
    fields[0] = "0.005"  # back in time on this row
    body[171] = ",".join(fields)
    path = tmp_path / "twice_glitch.csv"
    path.write_text("\n".join(lines[: head + 1] + body) + "\n")
    with pytest.raises(LogFormatError, match=f"line {head + 2 + 171}: time 0.005"):
        read_log(path)
    body[171] = lines[head + 1 + 170]
    path.write_text("\n".join(lines[: head + 1] + body) + "\n")
    notes = " ".join(read_log(path).warnings)
    named = [int(k) for k in re.findall(r"around line (\d+)", notes)]
    jump = head + 2 + 151  # the glitch's file line; a 0.05 s window (5 rows) ends on it or starts there
    assert named and named[0] in (jump, jump + 5), notes

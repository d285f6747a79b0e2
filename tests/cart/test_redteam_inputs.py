"""Issue 30, bad input as recording set-ups write it: every refusal names the problem and the fix.

Logs written the ways real tools write them: rows out of time order or repeated, fields separated by
semicolons or tabs, two streams merged with empty cells, time in micro- or nanoseconds (also since
the Unix epoch). Each is refused by the reader or the unit check with the conversion that repairs it.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from cart.errors import LogFormatError
from cart.logs import CartLog, read_log, write_log
from cart.streams import split_streams
from cart.units import UnitsError, check_units

HEADER = "t,x,y,theta,fx,fy,tau"


def _push(duration: float = 10.0, dt: float = 0.01) -> CartLog:
    t = np.arange(0.0, duration, dt)
    q = np.column_stack([0.5 * t, 0.1 * np.sin(0.3 * t), 0.2 * np.sin(0.5 * t)])
    g = np.column_stack([10.0 + 2 * np.sin(t), 0 * t, 0.5 * np.sin(2 * t)])
    return CartLog(t=t, q=q, gamma=g)


def _write_rows(path, rows: list[str], header: str = HEADER) -> None:
    path.write_text("\n".join([header, *rows]) + "\n")


def _rows(n: int = 6) -> list[str]:
    return [f"{0.01 * k:.2f},{0.005 * k},0,0,1,0,0" for k in range(n)]


@pytest.mark.parametrize(
    "swap, words",
    [
        ("back", r"line 5: time 0\.02 is before the previous time 0\.03 \(1 step\(s\) back in time\)"),
        ("repeat", r"line 4: time 0\.01 is equal to the previous time 0\.01 \(1 repeated time\(s\)\)"),
    ],
)
def test_time_out_of_order_names_the_fix_in_plain_numbers(tmp_path, swap, words):
    rows = _rows()
    if swap == "back":
        rows[2], rows[3] = rows[3], rows[2]
    else:
        rows[2] = rows[1].replace(",1,0,0", ",2,0,0")  # the same time, another wrench (a row written twice is dropped)
    path = tmp_path / "order.csv"
    _write_rows(path, rows)
    with pytest.raises(LogFormatError, match=words) as err:
        read_log(path)
    assert "sort the rows by t" in str(err.value) and "np.float64" not in str(err.value)


@pytest.mark.parametrize("sep, name", [(";", "semicolons"), ("\t", "tabs")])
def test_other_field_separators_are_named(tmp_path, sep, name):
    path = tmp_path / "sep.csv"
    _write_rows(path, [r.replace(",", sep) for r in _rows()], header=HEADER.replace(",", sep))
    with pytest.raises(LogFormatError, match=f"line 1: the columns are separated by {name}; .*comma-separated"):
        read_log(path)


@pytest.mark.parametrize("cell, words", [("", "empty value"), ("nan", "non-finite value 'nan'")])
def test_merged_streams_with_empty_cells_name_the_fill(tmp_path, cell, words):
    rows = _rows()
    rows[2] = rows[2].split(",", 1)[0] + f",{cell},{cell},{cell},1,0,0"  # an F/T-only row: no pose
    path = tmp_path / "cells.csv"
    _write_rows(path, rows)
    with pytest.raises(LogFormatError, match=f"line 4: column x: {words} .*repeat each stream's last sample"):
        read_log(path)


@pytest.mark.parametrize("factor, unit", [(1e3, "milliseconds"), (1e6, "microseconds"), (1e9, "nanoseconds")])
def test_time_unit_named_from_the_pose_period(factor, unit):
    log = _push()
    scaled = CartLog(t=log.t * factor, q=log.q, gamma=log.gamma)
    with pytest.raises(UnitsError, match=re.escape(f"time looks like {unit}; divide t by {factor:g}")):
        check_units(split_streams(scaled))


@pytest.mark.parametrize("factor, unit", [(1e3, "milliseconds"), (1e6, "microseconds"), (1e9, "nanoseconds")])
def test_unix_time_in_sub_second_units_is_named(tmp_path, factor, unit):
    path = tmp_path / "epoch.csv"
    _write_rows(path, [f"{(1.7e9 + 0.01 * k) * factor:.0f},{0.005 * k},0,0,1,0,0" for k in range(6)])
    with pytest.raises(
        LogFormatError, match="column t: .*" + re.escape(f"Unix time in {unit}: divide t by {factor:g}")
    ):
        read_log(path)


def test_unix_time_in_seconds_is_read(tmp_path):
    log = _push()
    path = tmp_path / "epoch_s.csv"
    write_log(path, CartLog(t=log.t + 1.7e9, q=log.q, gamma=log.gamma))
    back = read_log(path)
    assert len(back) == len(log) and np.allclose(np.diff(back.t), 0.01, atol=1e-6)


def test_a_unix_time_written_with_too_few_digits_is_named(tmp_path):
    path = tmp_path / "epoch7.csv"
    _write_rows(path, [f"{1.7e9 + 0.01 * k:.7g},{0.005 * k},0,0,1,0,0" for k in range(40)])
    with pytest.raises(LogFormatError, match="too few digits to tell the samples apart .*subtract the start time"):
        read_log(path)


def test_csv_quoting_is_read(tmp_path):
    log = _push()
    plain = tmp_path / "plain.csv"
    write_log(plain, log)
    lines = plain.read_text().splitlines()
    quoted = tmp_path / "quoted.csv"
    quoted.write_text("\n".join(",".join(f'"{v}"' for v in line.split(",")) for line in lines) + "\n")
    back = read_log(quoted)
    np.testing.assert_array_equal(back.q, read_log(plain).q)


def test_a_cart_that_circles_many_times_is_not_told_its_heading_is_in_degrees(tmp_path):
    t = np.arange(0.0, 120.0, 0.01)
    heading = 0.4 * t  # 7.6 turns, unwrapped, in radians
    x = np.cumsum(0.5 * np.cos(heading)) * 0.01
    y = np.cumsum(0.5 * np.sin(heading)) * 0.01
    g = np.column_stack([5.0 + np.sin(t), np.cos(t), 0.3 * np.sin(2 * t)])
    path = tmp_path / "circles.csv"
    write_log(path, CartLog(t=t, q=np.column_stack([x, y, heading]), gamma=g))
    assert not any("degrees" in w for w in read_log(path).warnings)
    write_log(path, CartLog(t=t, q=np.column_stack([x, y, np.degrees(heading)]), gamma=g))
    assert any("degrees" in w for w in read_log(path).warnings)

"""Issue 14, property test: random malformed and random valid-but-odd logs, through `read_log` and the CLI.

Contract: `read_log` returns a finite CartLog or raises LogFormatError (nothing else);
`cartpush estimate|diagnose LOG --json` exits 2 with one line on stderr, or exits 0
with strictly valid JSON (no NaN / Infinity anywhere).
"""

from __future__ import annotations

import contextlib
import gzip
import io
import json
import math
import os
import tempfile

import numpy as np
from hypothesis import HealthCheck, given, settings, strategies as st

from cart.errors import LogFormatError
from cart.logs import CartLog, read_log, write_log
from cartpush.cli import main

HEADER = "t,x,y,theta,fx,fy,tau"
SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _valid_rows(n: int, seed: int) -> list[str]:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.02, n))
    return [
        f"{t[k]:.6f},{0.3 * t[k] ** 2:.6f},{0.01 * math.sin(t[k]):.6f},{0.1 * t[k]:.6f},"
        f"{10 + 3 * math.sin(5 * t[k]):.4f},{0.5:.4f},{math.sin(3 * t[k]):.4f}"
        for k in range(n)
    ]


MUTATIONS = (
    "drop_column",
    "non_numeric",
    "nan_cell",
    "inf_cell",
    "huge_cell",
    "repeat_time",
    "too_few_rows",
    "empty",
    "bom",
    "crlf",
    "extra_field",
    "missing_field",
    "lone_contact",
    "blank_lines",
    "comments",
    "garbage_bytes",
    "reorder_columns",
    "decreasing_time",
    "spaces",
    "header_only",
    "gzip_garbage",
    "negative_zero",
    "exponent",
)


@st.composite
def malformed_log(draw):
    """(bytes of a log file, suffix) built from a valid small log with one mutation."""
    n = draw(st.integers(3, 40))
    rows = _valid_rows(n, draw(st.integers(0, 10_000)))
    header = HEADER
    kind = draw(st.sampled_from(MUTATIONS))
    r = draw(st.integers(0, n - 1))
    c = draw(st.integers(0, 6))
    fields = rows[r].split(",")
    suffix = ".csv"
    prefix = b""
    if kind == "drop_column":
        cols = HEADER.split(",")
        del cols[c]
        header = ",".join(cols)
        rows = [",".join(x for i, x in enumerate(row.split(",")) if i != c) for row in rows]
    elif kind in ("non_numeric", "nan_cell", "inf_cell", "huge_cell", "negative_zero", "exponent", "spaces"):
        fields[c] = {
            "non_numeric": draw(st.sampled_from(["abc", "", "1,0", "0x10", "--1", "1e", "None"])),
            "nan_cell": draw(st.sampled_from(["nan", "NaN", "-nan"])),
            "inf_cell": draw(st.sampled_from(["inf", "-inf", "Infinity", "1e999"])),
            "huge_cell": draw(st.sampled_from(["1e300", "-1e300", "1e13", "1.7976931348623157e308"])),
            "negative_zero": "-0.0",
            "exponent": "1e-300",
            "spaces": f"  {fields[c]}  ",
        }[kind]
        rows[r] = ",".join(fields)
    elif kind == "repeat_time" and n > 1:
        rows[r] = rows[r - 1] if r > 0 else rows[r]
        if r == 0:
            rows[1] = rows[0]
    elif kind == "decreasing_time":
        rows = rows[::-1]
    elif kind == "too_few_rows":
        rows = rows[: draw(st.integers(0, 2))]
    elif kind == "empty":
        header, rows = "", []
    elif kind == "header_only":
        rows = []
    elif kind == "bom":
        prefix = b"\xef\xbb\xbf"
    elif kind == "extra_field":
        rows[r] += ",1"
    elif kind == "missing_field":
        rows[r] = ",".join(fields[:-1])
    elif kind == "lone_contact":
        name = draw(st.sampled_from(["contact_x", "contact_y"]))
        header += "," + name
        rows = [row + ",0.1" for row in rows]
    elif kind == "blank_lines":
        rows.insert(r, "")
    elif kind == "comments":
        header = "# robot: test\n# note: a: b\n#\n" + header
    elif kind == "reorder_columns":
        cols = HEADER.split(",")
        perm = draw(st.permutations(range(7)))
        header = ",".join(cols[i] for i in perm)
        rows = [",".join(row.split(",")[i] for i in perm) for row in rows]
    text = "\n".join([header] + rows) + "\n"
    data = prefix + text.encode()
    if kind == "crlf":
        data = data.replace(b"\n", b"\r\n")
    elif kind == "garbage_bytes":
        data = draw(st.binary(min_size=0, max_size=200))
    elif kind == "gzip_garbage":
        suffix = ".csv.gz"
        data = draw(st.sampled_from([gzip.compress(data)[:-8], b"\x1f\x8b\x08\x00garbage", gzip.compress(data)]))
    return data, suffix


@st.composite
def odd_valid_log(draw):
    """A valid CartLog with unusual content: static, tiny/huge scales, units off, few rows, irregular time."""
    n = draw(st.integers(3, 60))
    rng = np.random.default_rng(draw(st.integers(0, 10_000)))
    dt = draw(st.sampled_from([1e-3, 0.01, 0.1, 1.0, 10.0]))
    t = np.cumsum(rng.uniform(0.2, 1.8, n) * dt) + draw(st.sampled_from([0.0, 1.7e9]))
    kind = draw(st.sampled_from(["static", "moving", "zero_wrench", "degrees", "mm", "map", "glitch", "spin"]))
    s = t - t[0]
    q = np.column_stack([0.2 * s, 0.01 * np.sin(s), 0.05 * s])
    g = np.column_stack([10 + 3 * np.sin(5 * s), 0.0 * s, np.sin(3 * s)])
    if kind == "static":
        q[:] = q[0]
    elif kind == "zero_wrench":
        g[:] = 0.0
    elif kind == "degrees":
        q[:, 2] = np.degrees(q[:, 2])
    elif kind == "mm":
        q[:, :2] *= 1000.0
    elif kind == "map":
        q[:, :2] += (512_345.0, 4_123_456.0)
    elif kind == "glitch":
        q[n // 2, 0] += 5.0
    elif kind == "spin":
        q[:, 2] = 30.0 * s
    q += rng.normal(size=q.shape) * draw(st.sampled_from([0.0, 1e-4, 5e-3]))
    return CartLog(t=t, q=q, gamma=g)


def _write_bytes(directory: str, data: bytes, suffix: str) -> str:
    path = os.path.join(directory, "log" + suffix)
    with open(path, "wb") as fh:
        fh.write(data)
    return path


def _refuse_constant(name):
    raise ValueError(f"non-strict JSON: {name}")


def _check_finite(obj) -> None:
    if isinstance(obj, float):
        assert math.isfinite(obj)
    elif isinstance(obj, dict):
        for v in obj.values():
            _check_finite(v)
    elif isinstance(obj, list):
        for v in obj:
            _check_finite(v)


def _run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def _assert_cli_contract(command: str, path: str) -> None:
    code, out, err = _run_cli([command, path, "--json"])
    assert code in (0, 2), (code, err)
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"cartpush {command}: error:"), err
        assert out == ""
    else:
        result = json.loads(out, parse_constant=_refuse_constant)
        _check_finite(result)


def _assert_reader_contract(path: str) -> None:
    try:
        log = read_log(path)
    except LogFormatError as exc:
        assert str(exc) and "\n" not in str(exc)
        return
    assert len(log) >= 3 and np.all(np.isfinite(log.q)) and np.all(np.isfinite(log.gamma))
    assert np.all(np.diff(log.t) > 0)
    assert all(isinstance(w, str) for w in log.warnings)


@settings(max_examples=150, **SETTINGS)
@given(malformed_log())
def test_read_log_on_malformed_logs(case):
    data, suffix = case
    with tempfile.TemporaryDirectory() as d:
        _assert_reader_contract(_write_bytes(d, data, suffix))


@settings(max_examples=60, **SETTINGS)
@given(odd_valid_log())
def test_read_log_on_odd_valid_logs(log):
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "odd.csv")
        write_log(path, log)
        _assert_reader_contract(path)


def _check_command(command, case):
    with tempfile.TemporaryDirectory() as d:
        if isinstance(case, CartLog):
            path = os.path.join(d, "odd.csv")
            write_log(path, case)
        else:
            path = _write_bytes(d, *case)
        _assert_cli_contract(command, path)


@settings(max_examples=25, **SETTINGS)
@given(st.one_of(malformed_log(), odd_valid_log()))
def test_estimate_cli_contract(case):
    _check_command("estimate", case)


@settings(max_examples=8, **SETTINGS)
@given(st.one_of(malformed_log(), odd_valid_log()))
def test_diagnose_cli_contract(case):
    _check_command("diagnose", case)

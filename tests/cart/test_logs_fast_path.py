"""The log reader's fast path (pyarrow's CSV reader) reads what Python's ``float`` reads, bit for bit, and leaves
everything else to the checked parser: same values, or the same error, as with the checked parser alone."""

from __future__ import annotations

import gzip

import numpy as np
import pytest

from cart import logs
from cart.errors import LogFormatError

HEADER = "t,x,y,theta,fx,fy,tau"
COLUMNS = HEADER.split(",")


def _bits(a: np.ndarray) -> np.ndarray:
    return np.asarray(a, dtype=np.float64).view(np.int64)


def _cells(rng: np.random.Generator, n: int) -> list[list[str]]:
    """Return n rows of 6 value cells in many spellings: repr, %.6g, %.17g, exponents, -0.0, integers, '+'."""
    forms = [
        repr,
        lambda v: f"{v:.6g}",
        lambda v: f"{v:.17g}",
        lambda v: f"{v:.3e}",
        lambda v: f"{v:E}",
        lambda v: f"+{abs(v)!r}",
        lambda v: str(int(v * 1000)),
        lambda v: f"{v:.12f}",
        lambda v: f"{v * 1e-30!r}",
    ]
    rows = []
    for _ in range(n):
        values = rng.standard_normal(6) * 10.0 ** rng.integers(-8, 6, 6)
        row = [forms[int(k)](float(v)) for k, v in zip(rng.integers(0, len(forms), 6), values)]
        if rng.random() < 0.1:
            row[int(rng.integers(6))] = rng.choice(["-0.0", "-0", "+0", "0e0", "-0e-0", "0.", ".5", "5."])
        rows.append(row)
    return rows


@pytest.mark.parametrize("seed", [3, 17])
def test_fast_path_values_equal_float_bit_for_bit(seed):
    """Random floats in every spelling: the fast path answers, with exactly Python's float of each field."""
    rng = np.random.default_rng(seed)
    cells = _cells(rng, 3000)
    body = [",".join([f"{0.005 * k!r}", *row]) for k, row in enumerate(cells)]
    fast = logs._parse_rows_fast("\n".join(body).encode(), body, COLUMNS, COLUMNS)
    assert fast is not None
    expected = np.array([[float(c) for c in line.split(",")] for line in body])
    assert np.array_equal(_bits(fast), _bits(expected))  # -0.0 and the last bit included


def test_read_log_uses_the_file_bytes(tmp_path):
    """Metadata with non-ASCII text, CRLF / CR endings and a byte-order mark: the body is found and read exactly."""
    rng = np.random.default_rng(5)
    rows = [[f"{0.01 * k!r}", *row] for k, row in enumerate(_cells(rng, 200))]
    for sep in ("\n", "\r\n", "\r"):
        text = sep.join(["# note: µ-cart ✓ ünïcode", "# robot: ρ", "", HEADER, *[",".join(r) for r in rows]]) + sep
        path = tmp_path / f"log{len(sep)}{sep == chr(13)}.csv.gz"
        path.write_bytes(gzip.compress(b"\xef\xbb\xbf" + text.encode()))
        log = logs.read_log(path)
        values = np.array([[float(c) for c in r] for r in rows])
        assert np.array_equal(_bits(log.t), _bits(values[:, 0]))
        assert np.array_equal(_bits(log.q[:, :2]), _bits(values[:, 1:3]))
        assert np.array_equal(_bits(log.gamma), _bits(values[:, 4:7]))
        assert log.metadata["note"] == "µ-cart ✓ ünïcode"


def _outcome(path) -> tuple[str, object]:
    try:
        log = logs.read_log(path)
    except LogFormatError as exc:
        return "error", str(exc)
    return "log", (log.t, log.q, log.gamma, log.qd, log.warnings)


def _checked_outcome(path, monkeypatch) -> tuple[str, object]:
    with monkeypatch.context() as m:
        m.setattr(logs, "_parse_rows_fast", lambda *args: None)
        return _outcome(path)


def _same(a: tuple[str, object], b: tuple[str, object]) -> bool:
    if a[0] != b[0] or a[0] == "error":
        return a == b
    for x, y in zip(a[1], b[1]):  # type: ignore[call-overload]
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if x is None or y is None or not np.array_equal(_bits(x), _bits(y)):
                return False
        elif x != y:
            return False
    return True


ODD_CELLS = [
    "nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1_000", " 1.0", "1.0 ", "\t1.0", "0x10", "", "NA", "null",
    "N/A", "true", "1e", "1d5", "1e999", "1e13", "+-1", "1..0", "\uff11", "\u0663", "\ufeff1.0", "1.0\x00",
    "\xa01.0", "1.0\u2003", '"1.0"', "1,5",
]  # fmt: skip


@pytest.mark.parametrize("cell", ODD_CELLS)
def test_odd_cells_read_as_the_checked_parser_reads_them(cell, tmp_path, monkeypatch):
    """Text pyarrow and Python's float may disagree on: the reader's answer (values or error) is the checked one."""
    lines = [HEADER] + [f"{0.01 * k},1.0,2.0,0.1,0.0,0.0,0.0" for k in range(6)]
    lines[3] = f"0.02,{cell},2.0,0.1,0.0,0.0,0.0"
    path = tmp_path / "odd.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    got = _outcome(path)
    assert _same(got, _checked_outcome(path, monkeypatch)), got


LAYOUTS = {
    "trailing comma": lambda rows: [r + "," for r in rows],
    "trailing comma on one line": lambda rows: rows[:2] + [rows[2] + ","] + rows[3:],
    "missing field": lambda rows: rows[:2] + [rows[2].rsplit(",", 1)[0]] + rows[3:],
    "crlf": lambda rows: [r + "\r" for r in rows],
    "blank line": lambda rows: rows[:2] + [""] + rows[2:],
    "blank line of spaces": lambda rows: rows[:2] + ["   "] + rows[2:],
    "comment line": lambda rows: rows[:2] + ["# marker"] + rows[2:],
    "form feed ends a line": lambda rows: rows[:2] + [rows[2].replace(",0.1,", ",0.1\x0c,")] + rows[3:],
    "vertical tab": lambda rows: rows[:2] + [rows[2] + "\x0b"] + rows[3:],
    "next line": lambda rows: rows[:2] + [rows[2].replace(",2.0,", ",2.0\x85,")] + rows[3:],
    "line separator": lambda rows: rows[:2] + [rows[2].replace(",2.0,", ",\u20282.0,")] + rows[3:],
    "byte-order mark mid-file": lambda rows: rows[:2] + ["\ufeff" + rows[2]] + rows[3:],
    "quoted values": lambda rows: ['"' + r.replace(",", '","') + '"' for r in rows],
    "extra text column": lambda rows: rows,
}


@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_odd_layouts_read_as_the_checked_parser_reads_them(name, tmp_path, monkeypatch):
    """Line endings, empty or extra fields, quoting, BOMs: the same values or the same error as the checked parser."""
    rows = [f"{0.01 * k},{1.0 + k},2.0,0.1,0.5,0.0,0.0" for k in range(8)]
    header = HEADER + (",note" if name == "extra text column" else "")
    if name == "extra text column":
        rows = [r + f",row {k}" for k, r in enumerate(rows)]
    header = '"' + header.replace(",", '","') + '"' if name == "quoted values" else header
    path = tmp_path / "layout.csv"
    path.write_bytes(("\n".join(["# log: odd", header, *LAYOUTS[name](rows)]) + "\n").encode())
    got = _outcome(path)
    assert _same(got, _checked_outcome(path, monkeypatch)), got


def test_the_fast_path_declines_what_it_cannot_vouch_for():
    """The fast path itself returns None on each kind of doubt (so the comparisons above can fail)."""
    body = [f"{0.01 * k},1.0,2.0,0.1,0.0,0.0,0.0" for k in range(4)]
    assert logs._parse_rows_fast("\n".join(body).encode(), body, COLUMNS, COLUMNS) is not None
    for bad in (
        body[:2] + ["0.02,nan,2.0,0.1,0.0,0.0,0.0"] + body[3:],
        body[:2] + ["0.02,1e13,2.0,0.1,0.0,0.0,0.0"] + body[3:],
        body[:2] + ["0.02,,2.0,0.1,0.0,0.0,0.0"] + body[3:],
        body[:2] + ["0.02,1.0,2.0,0.1,0.0,0.0"] + body[3:],
        body[:2] + ["0.02,1_0,2.0,0.1,0.0,0.0,0.0"] + body[3:],
    ):
        assert logs._parse_rows_fast("\n".join(bad).encode(), bad, COLUMNS, COLUMNS) is None, bad[2]
    blob = "\n".join(body).encode()
    assert logs._parse_rows_fast(blob, body + body[-1:], COLUMNS, COLUMNS) is None  # a row count unlike the lines'

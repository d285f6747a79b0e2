"""Read and write cart logs (docs/log_format.md) and estimate velocities from the pose.

A log is a CSV (or ``.csv.gz``) with ``# key: value`` metadata comments, one
header line and one row per sample; see ``docs/cart.md`` for the columns.
Bad input raises :class:`~cart.errors.LogFormatError` naming the file, the
line and the problem. Headings are unwrapped on reading. A UTF-8 byte-order
mark is accepted. Values beyond ``MAX_ABS_VALUE`` (e.g. 1e300) are rejected:
no quantity of a pushed cart comes near them and they overflow the models.
Data that is valid but implausible for a cart (heading apparently in
degrees, positions in millimetres, time in milliseconds, motion-capture
glitches) is read, with plain-language notes in ``CartLog.warnings``
(:func:`plausibility_warnings`).
"""

from __future__ import annotations

import codecs
import gzip
import math
import os
import re
import stat
import zlib
from dataclasses import dataclass, field

import numpy as np

from cart._kernels_identify import median
from cart.errors import LogFormatError
from cart.heading import unwrap_heading

REQUIRED_COLUMNS = ("t", "x", "y", "theta", "fx", "fy", "tau")
VELOCITY_COLUMNS = ("vx", "vy", "omega")
CONTACT_COLUMNS = ("contact_x", "contact_y")
#: Largest magnitude a value may have (any unit of the format); beyond it the reader refuses the log.
MAX_ABS_VALUE = 1e12
#: Plausibility limits (warnings, never a rejection): no pushed cart exceeds them.
PLAUSIBLE_SPEED = 20.0  # m/s
PLAUSIBLE_ACCELERATION = 100.0  # m/s^2 (about 10 g), over 0.1 s windows
PLAUSIBLE_YAW_STEP = 0.5  # rad per sample, together with
PLAUSIBLE_YAW_RATE = 15.0  # rad/s
PLAUSIBLE_HEADING = 6 * math.pi  # |theta| of a wrapped or slowly unwrapped heading (3 turns)
PLAUSIBLE_MEDIAN_DT = 0.5  # s
_EMPTY_CELL_FIX = (
    f"(every row needs all of {', '.join(REQUIRED_COLUMNS)}: two sensor streams merged with empty cells? "
    "repeat each stream's last sample on the rows where it has none, or drop those rows)"
)


@dataclass(frozen=True)
class CartLog:
    """A cart log: times, poses, generalized forces and optional velocities / contact points.

    ``t`` (N,), ``q`` (N, 3) = (x, y, theta unwrapped), ``gamma`` (N, 3) =
    (fx, fy in {s}, tau about the {b} origin), ``qd`` (N, 3) or None,
    ``contact_b`` (N, 2) or None, ``metadata`` the ``# key: value`` comments,
    ``warnings`` the reader's plausibility notes (:func:`plausibility_warnings`).
    """

    t: np.ndarray
    q: np.ndarray
    gamma: np.ndarray
    qd: np.ndarray | None = None
    contact_b: np.ndarray | None = None
    metadata: dict[str, str] = field(default_factory=dict)
    source: str = "<memory>"
    warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.t)
        shapes = {"q": (n, 3), "gamma": (n, 3)}
        if self.qd is not None:
            shapes["qd"] = (n, 3)
        if self.contact_b is not None:
            shapes["contact_b"] = (n, 2)
        for name, shape in shapes.items():
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != shape:
                raise LogFormatError(f"{self.source}: {name} has shape {arr.shape}, expected {shape}")
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "t", np.asarray(self.t, dtype=float).reshape(n))
        object.__setattr__(self, "warnings", tuple(self.warnings))

    def __len__(self) -> int:
        return len(self.t)

    @property
    def has_velocities(self) -> bool:
        """Return True when the log carries measured velocities."""
        return self.qd is not None

    def velocities(self, half_window: float = 0.05) -> np.ndarray:
        """Return qd (N, 3): the measured velocities, or estimates from the pose when absent."""
        if self.qd is not None:
            return self.qd
        return estimate_velocities(self.t, self.q, half_window)


def local_fit(
    t: np.ndarray, y: np.ndarray, half_window: float = 0.05, degree: int = 2
) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, int]:
    """Return (coef, scale, pinv, start, width) of local least-squares polynomials at every t_i.

    Each sample gets a polynomial of ``degree`` in ``(t - t_i) / scale`` fitted
    to the ``2k+1`` neighbours around it, ``k = round(half_window / median dt)``
    (at least ``degree // 2 + 1``; windows shift inwards at the ends): ``coef``
    (n, degree+1, k) for ``y`` (n, k), ``pinv`` (n, degree+1, width) the fit's
    linear map from the window's samples (``y[start_i : start_i + width]``).
    """
    t = np.asarray(t, dtype=float)
    y2 = np.asarray(y, dtype=float).reshape(len(t), -1)
    n = len(t)
    med_dt = float(median(np.diff(t)))
    k = max(degree // 2 + 1, int(round(half_window / med_dt)))
    width = min(2 * k + 1, n)
    start = np.clip(np.arange(n) - width // 2, 0, n - width)
    idx = start[:, None] + np.arange(width)[None, :]
    tau = t[idx] - t[:, None]  # (n, width)
    scale = max(float(np.max(np.abs(tau))), 1e-12)
    vander = (tau / scale)[:, :, None] ** np.arange(degree + 1)[None, None, :]  # (n, width, degree+1)
    normal = np.einsum("nwi,nwj->nij", vander, vander)
    pinv = np.linalg.solve(normal, np.transpose(vander, (0, 2, 1)))  # (n, degree+1, width)
    coef = np.einsum("niw,nwk->nik", pinv, y2[idx])
    return coef, scale, pinv, start, width


def local_polyfit(
    t: np.ndarray, q: np.ndarray, half_window: float = 0.05, degree: int = 2
) -> tuple[np.ndarray, np.ndarray, int]:
    """Return (smoothed q, dq/dt, window size) of local least-squares polynomials (irregular Savitzky-Golay).

    See `local_fit` for the windows.
    """
    smooth, slope, width = local_polyfits(t, [q], half_window, degree)
    return smooth[0], slope[0], width


def local_polyfits(
    t: np.ndarray, arrays: list[np.ndarray], half_window: float = 0.05, degree: int = 2
) -> tuple[list[np.ndarray], list[np.ndarray], int]:
    """Return ([smoothed a], [da/dt], window size) of :func:`local_polyfit` for each array of ``arrays`` (N, k)
    sampled at the same ``t``: the windows and the fits' linear map are computed once (`local_fit`)."""
    arrays = [np.asarray(a, dtype=float) for a in arrays]
    if len(t) < degree + 1:
        raise LogFormatError(f"need at least {degree + 1} samples to estimate velocities, got {len(t)}")
    coef, scale, pinv, start, width = local_fit(t, arrays[0], half_window, degree)
    idx = start[:, None] + np.arange(width)[None, :]
    coefs = [coef] + [np.einsum("niw,nwk->nik", pinv, a.reshape(len(t), -1)[idx]) for a in arrays[1:]]
    smooth = [c[:, 0, :].reshape(a.shape) for c, a in zip(coefs, arrays)]
    return smooth, [(c[:, 1, :] / scale).reshape(a.shape) for c, a in zip(coefs, arrays)], width


def estimate_velocities(t: np.ndarray, q: np.ndarray, half_window: float = 0.05, degree: int = 2) -> np.ndarray:
    """Return velocities (N, k) of samples q (N, k) by local polynomial fits (Savitzky-Golay for irregular t)."""
    return local_polyfit(t, q, half_window, degree)[1]


#: The first two bytes of every gzip file (RFC 1952): such a file is decompressed whatever its name.
GZIP_MAGIC = b"\x1f\x8b"


def file_kind(path: os.PathLike | str) -> str | None:
    """Return what the existing ``path`` is when it is no regular file ("a FIFO (named pipe)", "a character
    device", ...), else None (a regular file, a directory, or nothing there yet). Links are followed."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    kinds = (
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    )
    return next((name for test, name in kinds if test(mode)), None)


def _check_regular_file(path: str) -> None:
    """Raise LogFormatError when ``path`` exists but is no regular file or directory: reading a FIFO waits for
    a writer forever, a device (``/dev/zero``) never ends. Missing files and directories fail at ``open``."""
    kind = file_kind(path)
    if kind is not None:
        raise LogFormatError(f"{path}: is {kind}, not a log file; save the log to a regular file and give that")


def _read_lines(path: str) -> tuple[list[str], str, bytes]:
    """Return the file's (lines, text, UTF-8 bytes of the text): a gzip file (known by its magic bytes, whatever
    its name: a plain-text log named .gz is read as it is) decompressed in one call; utf-8-sig: a byte-order mark that Excel and some Windows
    tools write is not part of the header (nor of the bytes). Only a regular file is read."""
    _check_regular_file(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read()
        if data.startswith(GZIP_MAGIC):
            data = gzip.decompress(data)
        text = data.decode("utf-8-sig")
    except (OSError, EOFError, zlib.error) as exc:  # gzip's BadGzipFile is an OSError; corrupt data a zlib.error
        if isinstance(exc, (FileNotFoundError, IsADirectoryError, PermissionError)):
            raise
        raise LogFormatError(f"{path}: cannot read the file: {exc}") from None
    except UnicodeDecodeError as exc:
        gz = " (named .gz, but not gzip-compressed either)" if path.endswith(".gz") else ""
        raise LogFormatError(f"{path}: not UTF-8 text{gz} ({exc.reason} at byte {exc.start})") from None
    return text.splitlines(), text, data[3:] if data.startswith(codecs.BOM_UTF8) else data


def _tail_bytes(text: str, data: bytes, lines: list[str], first: int) -> memoryview:
    """Return the bytes of ``text`` (UTF-8 ``data``) from its line ``first`` (an index of ``lines``, its
    ``splitlines``) on, without a copy: each line ends with ``\\r\\n`` or one character (``str.splitlines``)."""
    pos = 0
    for line in lines[:first]:
        pos += len(line) + (2 if text.startswith("\r\n", pos + len(line)) else 1)
    return memoryview(data)[len(text[: min(pos, len(text))].encode()) :]


def _metadata(lines: list[str]) -> tuple[dict[str, str], int]:
    """Return the ``# key: value`` metadata and the index of the header line (comments and blank lines skipped)."""
    metadata: dict[str, str] = {}
    i = 0
    while i < len(lines) and (lines[i].startswith("#") or not lines[i].strip()):
        text = lines[i][1:].strip() if lines[i].startswith("#") else ""
        if ":" in text:
            key, value = text.split(":", 1)
            metadata[key.strip()] = value.strip()
        i += 1
    return metadata, i


_UNIT_IN_NAME = re.compile(r"^\s*([^\[\(]*?)\s*[\[\(]\s*([^\]\)]*?)\s*[\]\)]\s*$")


def _column_name(cell: str) -> tuple[str, str]:
    """Return (name, unit) of a header cell: case folded, a unit in brackets split off ("X [mm]" -> "x", "mm")."""
    match = _UNIT_IN_NAME.match(cell)
    if match:
        return match.group(1).strip().lower(), match.group(2)
    return cell.strip().lower(), ""


def header_units(line: str) -> str:
    """Return the units a header line states in brackets ("x: mm, theta: deg"), '' when it states none."""
    named = [_column_name(c) for c in line.split(",")]
    return ", ".join(f"{name}: {unit}" for name, unit in named if unit)


def _header_columns(path: str, line: str, header_line: int) -> tuple[list[str], list[str]]:
    """Return (header, the columns the reader uses); raise LogFormatError for missing, duplicate or lone columns.

    Names are matched without regard to case, and a unit in brackets after a name ("t [s]", "x (m)") is
    split off (:func:`header_units`; the units are checked by :func:`cart.units.check_declared_units`).
    """
    header = [_column_name(h)[0] for h in line.split(",")]
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    for sep, name in ((";", "semicolons"), ("\t", "tabs"), (None, "spaces")):
        if missing and all(c in [h.strip() for h in line.split(sep)] for c in REQUIRED_COLUMNS):
            raise LogFormatError(
                f"{path}: line {header_line}: the columns are separated by {name}; the log format is "
                "comma-separated with a decimal point: write it with ',' between fields"
            )
    if missing:
        raise LogFormatError(
            f"{path}: line {header_line}: missing required column(s) {', '.join(missing)} (header is {line.strip()!r})"
        )
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise LogFormatError(f"{path}: line {header_line}: duplicate column(s) {', '.join(dup)}")
    lone = [c for c in CONTACT_COLUMNS if c in header]
    if len(lone) == 1:
        other = [c for c in CONTACT_COLUMNS if c not in header][0]
        raise LogFormatError(
            f"{path}: line {header_line}: column {lone[0]} without {other}; the contact point needs both (or neither)"
        )
    return header, [c for c in REQUIRED_COLUMNS + VELOCITY_COLUMNS + CONTACT_COLUMNS if c in header]


def _parse_value(path: str, lineno: int, name: str, text: str) -> float:
    """Return the float of one field; raise LogFormatError naming the line and column when it is not usable."""
    try:
        value = float(text)
    except ValueError:
        if not text:
            raise LogFormatError(f"{path}: line {lineno}: column {name}: empty value {_EMPTY_CELL_FIX}") from None
        raise LogFormatError(f"{path}: line {lineno}: column {name}: non-numeric value {text!r}") from None
    if not -MAX_ABS_VALUE <= value <= MAX_ABS_VALUE:
        if not math.isfinite(value):
            raise LogFormatError(
                f"{path}: line {lineno}: column {name}: non-finite value {text!r}"
                + (f" {_EMPTY_CELL_FIX}" if math.isnan(value) else "")
            )
        raise LogFormatError(
            f"{path}: line {lineno}: column {name}: value {text} is out of range "
            f"(|value| > {MAX_ABS_VALUE:g} in SI units){_epoch_hint(name, value)}"
        )
    return value


def _epoch_hint(name: str, value: float) -> str:
    """Return the conversion for a time beyond ``MAX_ABS_VALUE``: a Unix time in ms, us or ns ('' otherwise)."""
    if name != "t" or value <= 0:
        return ""
    for unit, factor in (("milliseconds", 1e3), ("microseconds", 1e6), ("nanoseconds", 1e9)):
        if value / factor <= 1e11:  # a Unix time in s is ~1.7e9 until the year 5000
            return f"; t looks like a Unix time in {unit}: divide t by {factor:g} (LOG_FORMAT: seconds)"
    return ""


def _parse_rows_fast(
    blob: bytes | memoryview, body: list[str], header: list[str], wanted: list[str]
) -> np.ndarray | None:
    """Return the values (rows, len(wanted)) of the data lines ``body`` (``blob``: their UTF-8 bytes) in one
    pyarrow CSV conversion, or None when any line needs the checked parser :func:`_parse_rows`.

    Valid when every line has all fields and every used field is a float64 by pyarrow's parser (correctly
    rounded, as ``float``; no nulls, no quoting, no inference: text ``float`` refuses, "nan" or "inf" fail
    here or at the range check) and the used columns are within ``MAX_ABS_VALUE``. pyarrow ends lines at
    ``\\n`` / ``\\r`` only: a line ``str.splitlines`` also ends elsewhere gives fewer rows than ``body``.
    """
    if not body or not all(body):  # pyarrow skips or refuses an empty line: its file line would be lost
        return None
    import pyarrow as pa
    import pyarrow.csv as pa_csv

    names = [f"c{k}" for k in range(len(header))]
    used = [names[header.index(c)] for c in wanted]
    try:
        table = pa_csv.read_csv(
            pa.BufferReader(blob),
            read_options=pa_csv.ReadOptions(column_names=names, use_threads=False),
            parse_options=pa_csv.ParseOptions(quote_char=False, escape_char=False, ignore_empty_lines=False),
            convert_options=pa_csv.ConvertOptions(
                column_types={n: pa.float64() for n in names},
                include_columns=used,
                null_values=[],
                strings_can_be_null=False,
                quoted_strings_can_be_null=False,
            ),
        )
    except (pa.ArrowException, ValueError):
        return None
    if table.num_rows != len(body) or any(table.column(n).null_count for n in used):
        return None
    rows = np.column_stack([table.column(n).to_numpy() for n in used]).astype(float, copy=False)
    return rows if np.all(np.abs(rows) <= MAX_ABS_VALUE) else None


def _parse_rows(path: str, body: list[str], header: list[str], wanted: list[str], line_of: np.ndarray) -> np.ndarray:
    """Return the values (rows, len(wanted)) of the data lines; ``line_of``: the file line of each."""
    fast = _parse_rows_fast("\n".join(body).encode(), body, header, wanted)
    if fast is not None:
        return fast
    col = {c: header.index(c) for c in wanted}
    rows = np.empty((len(body), len(wanted)))
    for r, line in enumerate(body):
        lineno = int(line_of[r])
        fields = line.split(",")
        if len(fields) != len(header):
            raise LogFormatError(f"{path}: line {lineno}: expected {len(header)} fields, found {len(fields)}")
        for k, name in enumerate(wanted):
            rows[r, k] = _parse_value(path, lineno, name, fields[col[name]].strip())
    return rows


def _check_time_order(path: str, t: np.ndarray, line_of: np.ndarray) -> None:
    """Raise LogFormatError at the first time that is not strictly increasing, naming how many and the fix.

    ``line_of``: the file line of each sample (rows dropped before this check keep their neighbours' lines).
    """
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0.0)
    if not bad.size:
        return
    r = int(bad[0]) + 1
    back, same = int(np.sum(steps < 0.0)), int(np.sum(steps == 0.0))
    what = "equal to" if t[r] == t[r - 1] else "before"
    counts = ", ".join(
        text for n, text in ((back, f"{back} step(s) back in time"), (same, f"{same} repeated time(s)")) if n
    )
    fix = "sort the rows by t and keep one row per time"
    if same > 0.05 * len(t) and float(np.max(np.abs(t))) > 1e6:
        fix = (
            f"t reaches {float(np.max(np.abs(t))):.4g} s but is written with too few digits to tell the samples "
            "apart (a Unix time?): write t with more significant digits, or subtract the start time"
        )
    raise LogFormatError(
        f"{path}: line {int(line_of[r])}: time {float(t[r])!r} is {what} the previous time "
        f"{float(t[r - 1])!r} ({counts}); t must be strictly increasing: {fix}"
    )


def _without_repeated_rows(data: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Return the columns without rows that repeat the previous row in every column (time included), and the kept rows.

    A row written twice (a logger flushing the same sample again) carries no new sample: dropping it is
    exact. Rows at the same time with different values stay (:func:`_check_time_order` refuses them).
    """
    cols = np.column_stack(list(data.values()))
    again = np.r_[False, np.all(cols[1:] == cols[:-1], axis=1)]
    if not again.any() or int((~again).sum()) < 3:  # too few distinct rows: refused as they are
        return data, np.arange(len(cols))
    return {name: v[~again] for name, v in data.items()}, np.flatnonzero(~again)


def _log_from_columns(
    path: str, data: dict[str, np.ndarray], metadata: dict[str, str], row_lines: np.ndarray
) -> CartLog:
    """Return the CartLog of the parsed columns (heading unwrapped, missing velocity columns estimated) with notes.

    ``row_lines``: the file line of each row.
    """
    n_rows = len(data["t"])
    data, kept = _without_repeated_rows(data)
    repeated = n_rows - len(kept)
    line_of = row_lines[kept]  # the file line of each kept row
    t = data["t"]
    _check_time_order(path, t, line_of)
    q = np.column_stack([data["x"], data["y"], unwrap_heading(t, data["theta"])])
    gamma = np.column_stack([data["fx"], data["fy"], data["tau"]])
    qd = None
    present = [c for c in VELOCITY_COLUMNS if c in data]
    if present:
        estimated = estimate_velocities(t, q) if len(present) < 3 else None
        qd = np.column_stack(
            [data[c] if c in data or estimated is None else estimated[:, k] for k, c in enumerate(VELOCITY_COLUMNS)]
        )
    contact = None
    if all(c in data for c in CONTACT_COLUMNS):
        contact = np.column_stack([data["contact_x"], data["contact_y"]])
    log = CartLog(t=t, q=q, gamma=gamma, qd=qd, contact_b=contact, metadata=metadata, source=path)
    notes = plausibility_warnings(log, raw_theta=data["theta"], line_of=line_of)
    if repeated:
        notes.insert(0, f"{repeated} row(s) repeat the previous row exactly, time included: dropped (written twice)")
    if notes:
        object.__setattr__(log, "warnings", tuple(notes))
    return log


def _data_lines(lines: list[str], first: int) -> tuple[list[str], np.ndarray, int]:
    """Return (the data lines from index ``first`` on, the file line of each, the number of comment lines).

    Blank lines and comment lines among the rows are not rows (a marker a recorder wrote, a flush).
    """
    line_of = np.array([k + 1 for k in range(first, len(lines)) if lines[k].strip() and lines[k][0] != "#"], int)
    comments = sum(1 for k in range(first, len(lines)) if lines[k].startswith("#"))
    return [lines[k - 1] for k in line_of], line_of, comments


def read_log(path: str | os.PathLike) -> CartLog:
    """Return the CartLog of a docs/log_format.md file (.csv or .csv.gz); raise LogFormatError on bad input."""
    path = os.fspath(path)
    lines, text, data = _read_lines(path)
    metadata, i = _metadata(lines)
    if i >= len(lines):
        raise LogFormatError(f"{path}: the file is empty (no header line)")
    header_line = i + 1
    blob = _tail_bytes(text, data, lines, i + 1)
    if '"' in lines[i]:  # CSV quoting ("t","x",... or "0.1","2.0",...): the quotes are not part of the values
        lines = lines[:i] + [line.replace('"', "") for line in lines[i:]]
        blob = memoryview(bytes(blob).replace(b'"', b""))
    header, wanted = _header_columns(path, lines[i], header_line)
    units = header_units(lines[i])
    if units:
        metadata["units (header)"] = units
    body, line_of, comments = lines[i + 1 :], np.arange(i + 2, len(lines) + 1), 0
    rows = _parse_rows_fast(blob, body, header, wanted)  # a plain table: no blank or comment line parses this way
    if rows is None:
        body, line_of, comments = _data_lines(lines, i + 1)
        rows = _parse_rows(path, body, header, wanted, line_of)
    if len(body) < 3:
        raise LogFormatError(f"{path}: only {len(body)} data row(s); a log needs at least 3")
    log = _log_from_columns(path, {name: rows[:, k] for k, name in enumerate(wanted)}, metadata, line_of)
    if comments:
        note = f"{comments} comment line(s) among the rows ('#' ...): skipped, they are not samples"
        object.__setattr__(log, "warnings", (note, *log.warnings))
    return log


def _rolls_along_heading(log: CartLog, span: float = 0.1) -> bool:
    """Return True when the cart travels along its heading read in radians (forwards or backwards, eq. 3).

    Over windows of ``span`` seconds in which the cart moves beyond ten typical pose steps, the median
    |sin(travel direction - heading)| is below 0.3: the heading is in radians, however many turns it makes.
    """
    t, q = log.t, log.q
    med = float(median(np.diff(t)))
    w = max(1, int(math.ceil(span / med))) if med > 0 else 1
    if len(t) <= w + 10:
        return False
    d = q[w:, :2] - q[:-w, :2]
    moving = np.hypot(d[:, 0], d[:, 1]) > 10.0 * np.median(np.abs(np.diff(q[:, :2], axis=0))) + 1e-12
    if moving.sum() < 10:
        return False
    psi = np.arctan2(d[moving, 1], d[moving, 0])
    heading = 0.5 * (q[w:, 2] + q[:-w, 2])[moving]
    return float(median(np.abs(np.sin(psi - heading)))) < 0.3


def _heading_notes(log: CartLog, dt: np.ndarray, raw_theta: np.ndarray | None, where) -> list[str]:
    """Return the notes on the heading: steps too fast for a cart, or more than three turns (degrees?)."""
    notes = []
    theta = log.q[:, 2]
    step = np.abs(np.diff(theta))
    rate = step / dt
    bad = np.nonzero((step > PLAUSIBLE_YAW_STEP) & (rate > PLAUSIBLE_YAW_RATE))[0]
    if bad.size:
        i = int(bad[np.argmax(step[bad])])
        notes.append(
            f"heading changes by {step[i]:.3g} rad in one sample ({rate[i]:.3g} rad/s) at {where(i + 1)}, "
            f"{bad.size} such step(s); if theta is in degrees, convert it to radians"
        )
    raw = theta if raw_theta is None else np.asarray(raw_theta, dtype=float)
    if float(np.max(np.abs(raw))) > PLAUSIBLE_HEADING and not bad.size and not _rolls_along_heading(log):
        notes.append(
            f"heading reaches {float(np.max(np.abs(raw))):.4g} rad (more than three turns); if theta is in "
            f"degrees, convert it to radians"
        )
    return notes


def _motion_notes(log: CartLog, med: float, where) -> list[str]:
    """Return the notes on speeds and accelerations over windows of ~0.05 s / 0.1 s (glitch, or millimetres?)."""
    notes = []
    t, n = log.t, len(log.t)
    w = max(1, int(math.ceil(0.05 / med))) if med > 0 else 1  # single-sample noise averages out
    if n > w:
        span = t[w:] - t[:-w]
        vel = (log.q[w:, :2] - log.q[:-w, :2]) / span[:, None]
        speed = np.hypot(vel[:, 0], vel[:, 1])
        i = int(np.argmax(speed))
        if speed[i] > PLAUSIBLE_SPEED:
            notes.append(
                f"the pose moves at {speed[i]:.3g} m/s around {where(i + w)} (a cart moves at a few m/s): "
                f"a motion-capture glitch, or positions in millimetres?"
            )
        elif len(speed) > w:
            tv = 0.5 * (t[w:] + t[:-w])
            acc = np.hypot(*((vel[w:] - vel[:-w]) / (tv[w:] - tv[:-w])[:, None]).T)
            j = int(np.argmax(acc))
            if acc[j] > PLAUSIBLE_ACCELERATION:
                notes.append(
                    f"the pose accelerates at {acc[j]:.3g} m/s^2 around {where(j + w)} (no pushed cart "
                    f"exceeds ~10 m/s^2): a motion-capture glitch, or positions in millimetres?"
                )
    if log.qd is not None:
        vspeed = np.hypot(log.qd[:, 0], log.qd[:, 1])
        i = int(np.argmax(vspeed))
        if vspeed[i] > PLAUSIBLE_SPEED:
            notes.append(
                f"the logged velocity reaches {vspeed[i]:.3g} m/s at {where(i)}: a glitch, or vx, vy not in m/s?"
            )
    return notes


def plausibility_warnings(
    log: CartLog, raw_theta: np.ndarray | None = None, first_line: int | None = None, line_of: np.ndarray | None = None
) -> list[str]:
    """Return plain-language notes on what looks implausible for a pushed cart (empty when nothing does).

    Flags what usually means a unit mistake or a glitch: heading steps beyond
    ``PLAUSIBLE_YAW_STEP`` per sample at more than ``PLAUSIBLE_YAW_RATE`` or a
    heading beyond three turns (degrees?), speeds beyond ``PLAUSIBLE_SPEED`` or
    accelerations beyond ``PLAUSIBLE_ACCELERATION`` (millimetres? a
    motion-capture glitch?), a median sample interval beyond
    ``PLAUSIBLE_MEDIAN_DT`` (milliseconds?), a wrench that is zero throughout.
    Never rejects: a 1 kg block at 1 cm/s and a 150 kg bed are valid carts.
    ``raw_theta``: the heading as logged (before unwrapping); ``first_line``:
    the file line of sample 0, to name lines instead of sample indices; ``line_of``: the file line of
    every sample (when rows were dropped on reading), which takes precedence.
    """
    notes: list[str] = []
    if len(log.t) < 2:
        return notes

    def where(i: int) -> str:
        if line_of is not None:
            return f"line {int(line_of[i])}"
        return f"line {first_line + i}" if first_line is not None else f"sample {i}"

    dt = np.diff(log.t)
    med = float(median(dt))
    if med > PLAUSIBLE_MEDIAN_DT:
        notes.append(
            f"median sample interval {med:g} s is long for a cart log (motion capture runs at 10 Hz or "
            f"more); if t is in milliseconds, convert it to seconds"
        )
    same = np.all(log.q[1:] == log.q[:-1], axis=1)
    rows = np.r_[0, np.flatnonzero(~same) + 1]
    if same.any() and len(rows) > 3:  # a held pose (multi-rate table, dropout): the pose's own samples
        poses = CartLog(t=log.t[rows], q=log.q[rows], gamma=log.gamma[rows])
        raw = None if raw_theta is None else np.asarray(raw_theta, dtype=float)[rows]
        notes += _heading_notes(poses, np.diff(poses.t), raw, lambda i: where(int(rows[i])))
        notes += _motion_notes(poses, float(median(np.diff(poses.t))), lambda i: where(int(rows[i])))
    else:
        notes += _heading_notes(log, dt, raw_theta, where)
        notes += _motion_notes(log, med, where)
    if not np.any(log.gamma):
        notes.append(
            "the wrench (fx, fy, tau) is zero throughout: the log carries no information on the cart's inertia"
        )
    return notes


def write_log(path: str | os.PathLike, log: CartLog, wrap_theta: bool = False) -> None:
    """Write ``log`` as docs/log_format.md CSV (gzip-compressed if the name ends in .gz)."""
    path = os.fspath(path)
    columns = list(REQUIRED_COLUMNS)
    theta = np.angle(np.exp(1j * log.q[:, 2])) if wrap_theta else log.q[:, 2]
    blocks = [log.t[:, None], log.q[:, :2], theta[:, None], log.gamma]
    if log.qd is not None:
        columns += list(VELOCITY_COLUMNS)
        blocks.append(log.qd)
    if log.contact_b is not None:
        columns += list(CONTACT_COLUMNS)
        blocks.append(log.contact_b)
    table = np.hstack(blocks)
    out = [f"# {k}: {str(v).replace(chr(10), ' ')}" for k, v in log.metadata.items()]
    out.append(",".join(columns))
    out.extend(",".join(repr(float(v)) for v in row) for row in table)
    text = "\n".join(out) + "\n"
    if path.endswith(".gz"):
        with gzip.open(path, "wt", encoding="utf-8", newline="") as fh:
            fh.write(text)
    else:
        with open(path, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)

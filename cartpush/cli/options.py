"""Validation of command-line options at the boundary, before any work (light: no numpy, no robots).

Every check raises :class:`cart.errors.CartpushError` subclasses with a message
naming the option, so the CLI prints one line and exits with code 2.
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

from cartpush.errors import OptionError

#: Longest simulated time any command accepts (s): the memory budget of the simulations
#: (a few arrays of one row per control step; 3600 s at 100 Hz is 360,000 rows).
MAX_SIM_DURATION = 3600.0
#: Most simulation steps (duration x rate) any command accepts.
MAX_SIM_STEPS = 2_000_000
#: Largest seed accepted (numpy's SeedSequence takes any non-negative integer; keep it sane).
MAX_SEED = 2**63 - 1


def finite(
    name: str,
    value: float,
    *,
    positive: bool = False,
    nonnegative: bool = False,
    minimum: float | None = None,
    maximum: float | None = None,
    why: str = "",
) -> float:
    """Return ``value`` if it is a finite number within the bounds; raise OptionError naming ``name`` otherwise."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise OptionError(f"{name} must be a number, got {value!r}") from None
    suffix = f" ({why})" if why else ""
    if not math.isfinite(v):
        raise OptionError(f"{name} must be a finite number, got {value}{suffix}")
    if positive and not v > 0:
        raise OptionError(f"{name} must be positive, got {value}{suffix}")
    if nonnegative and v < 0:
        raise OptionError(f"{name} must be >= 0, got {value}{suffix}")
    if minimum is not None and v < minimum:
        raise OptionError(f"{name} must be at least {minimum:g}, got {value}{suffix}")
    if maximum is not None and v > maximum:
        raise OptionError(f"{name} must be at most {maximum:g}, got {value}{suffix}")
    return v


def duration(
    value: float, *, minimum: float = 0.0, why: str = "", rate: float | None = None, name: str = "--duration"
) -> float:
    """Return a validated simulated duration: finite, positive, >= minimum, within the memory budget."""
    v = finite(name, value, positive=True)
    if v < minimum:
        raise OptionError(f"{name} must be at least {minimum:g} s{f' ({why})' if why else ''}, got {value}")
    if v > MAX_SIM_DURATION:
        raise OptionError(
            f"{name} must be at most {MAX_SIM_DURATION:g} s (memory budget of the simulation), got {value}"
        )
    if rate is not None and v * rate > MAX_SIM_STEPS:
        raise OptionError(f"{name} x rate = {v * rate:.3g} steps exceeds the budget of {MAX_SIM_STEPS} steps")
    return v


def seed(value: int) -> int:
    """Return a validated random seed (an integer >= 0)."""
    if not isinstance(value, int) or value < 0 or value > MAX_SEED:
        raise OptionError(f"--seed must be an integer between 0 and 2**63-1, got {value}")
    return value


def writable_dir(path: os.PathLike | str, option: str = "--out", create: bool = True) -> Path:
    """Return ``path`` after creating it with its parents (``create``) and checking a file can be written into it."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OptionError(f"{option}: {str(p)!r} exists and is not a directory")
    if not create and not p.is_dir():
        raise OptionError(f"{option}: the directory {str(p)!r} does not exist")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OptionError(f"{option}: cannot create the directory {str(p)!r} ({exc.strerror or exc})") from None
    try:
        fd, probe = tempfile.mkstemp(prefix=".cartpush_write_test_", dir=p)
    except OSError as exc:
        raise OptionError(f"{option}: cannot write into {str(p)!r} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)
    return p


def input_file(path: os.PathLike | str, name: str = "LOG") -> None:
    """Raise OptionError when the input ``path`` is a FIFO, device or socket: reading it would wait for a
    writer forever (a FIFO) or never end (``/dev/zero``). A missing file fails later, where it is opened."""
    from cart.logs import file_kind

    kind = file_kind(path)
    if kind is not None:
        raise OptionError(f"{name} {os.fspath(path)}: is {kind}, not a file; save the data to a file and give that")


def output_file(path: os.PathLike | str, option: str = "--out") -> None:
    """Raise OptionError when the output ``path`` is a device, FIFO or socket, or lies under /dev or /proc
    (``/dev/full``, ``/dev/null``, ``/dev/stdout``): the same rule as ``cartpush batch --out``."""
    from cart.logs import file_kind
    from cartpush.batch.engine import device_path

    kind = file_kind(path)
    if kind is not None or device_path(os.fspath(path)):
        what = kind or "a device (a path under /dev or /proc)"
        raise OptionError(f"{option} {os.fspath(path)}: is {what}, not a file; give the name of a file to write")


def writable_file(path: os.PathLike | str, option: str = "--out", create: bool = True) -> Path:
    """Return ``path`` after checking it names a writable file in a writable directory (`writable_dir`),
    not a device (`output_file`)."""
    p = Path(path)
    if str(path) == "" or p.is_dir():
        raise OptionError(f"{option}: {str(p)!r} is a directory, expected a file name")
    output_file(p, option)
    if p.exists() and not os.access(p, os.W_OK):
        raise OptionError(f"{option}: {str(p)!r} is not writable")
    writable_dir(p.parent if str(p.parent) else Path("."), option, create=create)
    return p

"""Helpers shared by the CLI tests: the one error line of a refused command, a tiny log that `estimate` reads."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cart.logs import CartLog, write_log


def one_error_line(capsys, command: str) -> str:
    """Return the one stderr line of a refused ``cartpush COMMAND`` (assert there is one, ``cartpush CMD: error:``)."""
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"cartpush {command}: error:"), err
    return lines[0]


def tiny_log(path: Path | str) -> str:
    """Write a 3 s log of a cart accelerating and turning slowly at ``path``; return the path."""
    t = np.arange(0.0, 3.0, 0.01)
    q = np.column_stack([0.2 * t**2, 0 * t, 0.05 * t])
    g = np.column_stack([10 + 5 * np.sin(3 * t), 0 * t, np.sin(2 * t)])
    write_log(path, CartLog(t=t, q=q, gamma=g))
    return str(path)

"""Small dense solves through LAPACK's gesv (the routine ``np.linalg.solve`` calls) without numpy's per-call
wrapping: the same numbers at a quarter of the cost on 3 x 3 and 6 x 6 systems (the online estimator's per-step
solves, the cart model's constrained dynamics)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import get_lapack_funcs

_GESV = get_lapack_funcs(("gesv",), (np.zeros((1, 1)),))[0]


def solve_small(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return ``np.linalg.solve(a, b)`` for one small system (LAPACK's gesv, the routine numpy calls, without
    numpy's per-call wrapping); raises ``np.linalg.LinAlgError`` when ``a`` is singular."""
    x, info = _GESV(a, b)[2:]
    if info != 0:
        raise np.linalg.LinAlgError("Singular matrix")
    return x

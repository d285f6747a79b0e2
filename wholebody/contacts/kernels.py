"""Compiled inner loop of the contact-point search (numba, cached on disk, bounds-checked).

`WrenchAllocator.closed_form_effort` is the objective a local search evaluates hundreds of times per contact
choice; one compiled call replaces its ten small numpy calls.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from wholebody.motion.kernels import cholesky_solve


@njit(cache=True, boundscheck=True)
def equality_optimum_effort(
    A_template: np.ndarray,
    fx_cols: np.ndarray,
    fy_cols: np.ndarray,
    points: np.ndarray,
    Pinv: np.ndarray,
    rhs: np.ndarray,
    Gin: np.ndarray,
    h: np.ndarray,
    Q: np.ndarray,
) -> tuple[float, bool]:
    """Return (x^T Q x, True) for the equality-only optimum x = P^-1 A^T (A P^-1 A^T)^-1 rhs at contact points
    (N, 3) if Gin x <= h, else (nan, False).

    A is `A_template` with the torque row's lever arms (-p_y at the fx columns, p_x at the fy columns; paper
    eq. 24) filled in. False also when A P^-1 A^T is not positive definite (the QP decides).
    """
    A = A_template.copy()
    r, nx = A.shape
    for i in range(points.shape[0]):
        A[r - 1, fx_cols[i]] = -points[i, 1]
        A[r - 1, fy_cols[i]] = points[i, 0]
    M = Pinv @ A.T  # (nx, r)
    y, ok = cholesky_solve(A @ M, rhs)
    if not ok:
        return np.nan, False
    x = M @ y
    for k in range(Gin.shape[0]):
        s = 0.0
        for j in range(nx):
            s += Gin[k, j] * x[j]
        if not s <= h[k]:
            return np.nan, False
    return float(x @ (Q @ x)), True

"""Any other backend through `qpsolvers.solve_qp` (the fallback of the whole-body step, benchmarks)."""

from __future__ import annotations

from typing import Any

import numpy as np
import qpsolvers


def solve_qpsolvers(
    H: np.ndarray,
    c: np.ndarray,
    G: np.ndarray | None,
    h: np.ndarray | None,
    lb: np.ndarray,
    ub: np.ndarray,
    solver: str,
    tolerance: float,
) -> np.ndarray | None:
    """Return the QP's solution by `qpsolvers.solve_qp(solver=...)`, or None if it fails or is not finite."""
    # solver-specific keyword arguments, passed through by qpsolvers to the solver
    options: dict[str, Any] = {"eps_abs": tolerance, "eps_rel": 0.0} if solver == "proxqp" else {}
    try:
        u = qpsolvers.solve_qp(H, c, G, h, lb=lb, ub=ub, solver=solver, **options)
    except Exception:  # noqa: BLE001 - any solver failure is reported as None
        return None
    if u is None or not np.all(np.isfinite(u)):
        return None
    return u

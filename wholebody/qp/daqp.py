"""daqp (a dual active-set solver) called directly on the whole-body step's QP."""

from __future__ import annotations

import math

import daqp
import numpy as np

from wholebody.motion.kernels import unconstrained_if_feasible


class DaqpSolver:
    """The step's QP solved exactly: the unconstrained minimiser when it satisfies every constraint, else daqp.

    With H positive definite (the controller's damping makes it so), the minimiser ``u = -H^-1 c`` that
    satisfies ``lb <= u <= ub`` and ``G u <= h`` exactly is the QP's solution: it is returned without calling a
    solver (`kernels.unconstrained_if_feasible`; in free-space tracking most steps end here). Otherwise daqp (a
    dual active-set solver) solves the QP, its data laid out as `qpsolvers` lays them out for daqp (the box as
    daqp's simple bounds, then the rows of G with lower bound -1e30), so that it returns what
    ``qpsolvers.solve_qp(..., solver="daqp")`` returns, without its per-call checks and copies. Each solve starts
    from an empty active set: the step's input does not depend on earlier steps.
    """

    def __init__(self) -> None:
        self._n = self._m = -1

    def _size(self, n: int, m: int) -> None:
        self._n, self._m = n, m
        self._no_rows, self._no_rhs = np.zeros((0, n)), np.zeros(0)
        self._upper, self._lower = np.empty(n + m), np.full(n + m, -1e30)
        self._sense = np.zeros(n + m, dtype=np.intc)  # all inequalities; daqp reads it, never writes it

    def solve(
        self,
        H: np.ndarray,
        c: np.ndarray,
        G: np.ndarray | None,
        h: np.ndarray | None,
        lb: np.ndarray,
        ub: np.ndarray,
        G_changed: bool = True,
    ) -> np.ndarray | None:
        """Return the QP's solution (a new array), or None if daqp does not report it solved (or it is not finite)."""
        n, m = c.shape[0], 0 if G is None else G.shape[0]
        if n != self._n or m != self._m:
            self._size(n, m)
        u, feasible = unconstrained_if_feasible(
            H, c, self._no_rows if G is None else G, self._no_rhs if h is None else h, lb, ub
        )
        if feasible:
            return u  # a NaN in the data fails the positive-definiteness or the feasibility test
        if m == 0:
            u, cost, flag, _ = daqp.solve(H, c, self._no_rows, ub, lb, self._sense)
        else:
            upper, lower = self._upper, self._lower
            upper[:n], upper[n:], lower[:n] = ub, h, lb
            u, cost, flag, _ = daqp.solve(H, c, np.ascontiguousarray(G), upper, lower, self._sense)
        return u if flag > 0 and math.isfinite(cost) else None  # daqp reports NaN data solved: its cost is NaN

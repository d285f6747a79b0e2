"""ProxQP (proxsuite's dense solver) called directly: one problem built once and updated in place.

Both QPs of the project use it: the whole-body step (`solve`: box and inequalities, warm-started or not) and the
wrench allocation (`solve_equality`: equalities and inequalities, cold for a new equality matrix, warm otherwise).
"""

from __future__ import annotations

import numpy as np
from proxsuite import proxqp

_SOLVED = proxqp.QPSolverOutput.PROXQP_SOLVED


class ProxQPSolver:
    """A dense ProxQP problem built once and updated in place each step (box constraints native).

    With `warm_start` True each solve starts from the previous solution and keeps the first
    preconditioner; the solution moves within the solver's tolerance (the QP's strong convexity is only
    its damping, so along nearly free directions u moves by up to ~2e-3 while the cost stays within ~3e-7
    relative and J u within ~6e-7 of the exact optimum on the recorded steps). With `warm_start` False every solve starts from ProxQP's equality-constrained
    initial guess and recomputes the preconditioner, which reproduces a fresh `proxqp.dense.solve` to ~1e-10.
    """

    def __init__(self, tolerance: float, warm_start: bool = True) -> None:
        self.tolerance = tolerance
        self.warm_start = warm_start
        self._qp: proxqp.dense.QP | None = None
        self._n = self._m = -1

    def reset(self) -> None:
        """Forget the problem (the next solve builds it afresh)."""
        self._qp = None

    def _build(self, n: int, m: int) -> proxqp.dense.QP:
        qp = proxqp.dense.QP(n, 0, m, True)
        qp.settings.eps_abs = self.tolerance
        qp.settings.eps_rel = 0.0
        if self.warm_start:
            qp.settings.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        return qp

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
        """Return the QP's solution, or None if ProxQP does not report it solved (or it is not finite).

        `G_changed` False: G is the one of the previous solve (not passed to ProxQP again).
        """
        qp = self._qp
        if qp is None or self._m != (0 if G is None else G.shape[0]) or self._n != c.shape[0]:
            qp = self._init(H, c, G, h, lb, ub)
        elif G is None:
            qp.update(H=H, g=c, l_box=lb, u_box=ub, update_preconditioner=not self.warm_start)
        elif G_changed:
            qp.update(H=H, g=c, C=G, u=h, l_box=lb, u_box=ub, update_preconditioner=not self.warm_start)
        else:
            qp.update(H=H, g=c, u=h, l_box=lb, u_box=ub, update_preconditioner=not self.warm_start)
        qp.solve()
        if self._info.status != _SOLVED:  # NaN data never meets the residual tolerance: SOLVED means finite
            self._qp = None  # do not warm start from a failed solve
            return None
        return self._x.copy()

    def _init(
        self, H: np.ndarray, c: np.ndarray, G: np.ndarray | None, h: np.ndarray | None, lb: np.ndarray, ub: np.ndarray
    ) -> proxqp.dense.QP:
        """Build and initialise the problem for the shapes of (c, G)."""
        self._n, self._m = c.shape[0], 0 if G is None else G.shape[0]
        qp = self._qp = self._build(self._n, self._m)
        qp.init(H, c, None, None, G, None if G is None else np.full(self._m, -np.inf), h, lb, ub)
        self._results = qp.results
        self._info = self._results.info
        self._x = self._results.x  # a view of the solution vector, sized once per problem
        return qp

    # ------------------------------------------------------------------ equality-constrained problems
    def solve_equality(
        self,
        H: np.ndarray,
        c: np.ndarray,
        A: np.ndarray,
        b: np.ndarray,
        G: np.ndarray,
        h: np.ndarray,
        A_changed: bool,
    ) -> np.ndarray | None:
        """Return the solution of ``min 1/2 x^T H x + c^T x  s.t.  A x = b, G x <= h``, or None if ProxQP fails.

        A new equality matrix (``A_changed``, or the first call) initializes the problem cold (scaled on it); a new
        right-hand side only updates it and warm-starts from the previous solution. A warm start that fails is
        retried cold, and a failed solve is never warm-started from. H, c, G and h are those of the first call
        after a `reset` (the allocation's cost and inequalities change only with its contacts or torque limits).
        """
        qp = self._qp
        if qp is None or A_changed:
            qp = self._cold_equality(H, c, A, b, G, h)
        else:
            qp.update(b=b)
            qp.solve()
            if not _solved(qp):
                qp = self._cold_equality(H, c, A, b, G, h)
        if not _solved(qp):
            self._qp = None
            return None
        return qp.results.x.copy()

    def _cold_equality(
        self, H: np.ndarray, c: np.ndarray, A: np.ndarray, b: np.ndarray, G: np.ndarray, h: np.ndarray
    ) -> proxqp.dense.QP:
        """Build, initialise and solve the equality-constrained problem from scratch; return it."""
        nx = H.shape[0]
        qp = self._qp = proxqp.dense.QP(nx, A.shape[0], G.shape[0])
        qp.settings.eps_abs = self.tolerance
        qp.settings.eps_rel = 0.0
        qp.settings.verbose = False
        qp.init(H, c, A, b, G, np.full(len(h), -np.inf), h)
        qp.solve()  # ProxQP crashes when asked to warm-start before its first solve
        if self.warm_start:
            qp.settings.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        return qp


def _solved(qp: proxqp.dense.QP) -> bool:
    """Return True if ProxQP reports the last solve solved."""
    return bool(qp.results.info.status == _SOLVED)

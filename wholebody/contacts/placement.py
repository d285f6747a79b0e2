"""Where the arms hold the handle: the globally minimum-effort contact points.

The effort of a set of contact points is the optimal value ``V(s)`` of the
wrench allocation QP (`wholebody.contacts.allocation`) with the contacts at curvilinear
coordinates ``s`` on the handle segment. A least-squares cost over many
candidate points would spread the force over all of them, so the points are
chosen by search over the segment:

1. enumerate a grid of the segment (``resolution`` metres) — all ordered
   tuples whose neighbours keep ``min_spacing`` for several arms;
2. refine the best grid candidates locally (bounded Brent for one arm,
   Nelder–Mead in the spacing-feasible region for several).

For one arm on a handle perpendicular to x_b (the default handle) with the
default wrench effort, ``V`` is convex in ``s``: the contact enters the
constraints only through ``tau_b = ... - y * fx`` with ``fx`` fixed by the
first row, so ``V(y) = phi(Gamma_tau + y Gamma_x)`` where ``phi`` is the value
of a convex parametric QP in its right-hand side (convex). The grid minimum
then brackets the global minimum and Brent finds it. For several arms the grid
is the globality argument (the tests compare against a much finer grid).
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations
from typing import Sequence

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from wholebody.contacts.allocation import AllocationResult, ArmLimits, EffortWeights, WrenchAllocator
from wholebody.contacts.handle import HandleSegment
from wholebody.errors import InfeasibleWrenchError, WholeBodyError


@dataclass(frozen=True)
class ContactPlan:
    """Chosen contact points (N x 3 in {b}), their coordinates s on the handle, and the allocation."""

    points_b: np.ndarray
    s: np.ndarray
    allocation: AllocationResult
    effort: float
    evaluations: int


class _Objective:
    """V(s): allocation effort with contacts at handle coordinates s (inf if infeasible)."""

    def __init__(self, gamma, handle, allocator: WrenchAllocator) -> None:
        self.gamma = np.asarray(gamma, dtype=float)
        self.handle = handle
        self.alloc = allocator
        self.count = 0
        self.best_infeasible: tuple[float, np.ndarray] | None = None
        self.tol = 1e-7 * max(1.0, float(np.max(np.abs(self.gamma))))

    def result(self, s: np.ndarray) -> AllocationResult:
        self.count += 1
        self.alloc.set_points([self.handle.point(float(v)) for v in s])
        return self.alloc.solve(self.gamma, raise_on_infeasible=False)

    def __call__(self, s: np.ndarray) -> float:
        res = self.result(s)
        if res.residual > self.tol:
            if self.best_infeasible is None or res.residual < self.best_infeasible[0]:
                self.best_infeasible = (res.residual, np.array(s, dtype=float))
            return np.inf
        return res.effort


def _spacing_ok(s: np.ndarray, length: float, spacing: float) -> bool:
    return bool(s[0] >= -1e-12 and s[-1] <= length + 1e-12 and np.all(np.diff(s) >= spacing - 1e-12))


def optimal_contact_points(
    gamma_b: Sequence[float],
    handle: HandleSegment | None = None,
    n_arms: int = 1,
    min_spacing: float = 0.2,
    limits: ArmLimits | Sequence[ArmLimits] = ArmLimits(),
    weights: EffortWeights = EffortWeights(),
    only_motion_directions: bool = False,
    solver: str = "proxqp",
    resolution: float = 0.01,
    refine: int = 3,
) -> ContactPlan:
    """Return the contact points on the handle minimizing the allocation effort for gamma_b.

    Several arms keep ``min_spacing`` (metres) between neighbours along the
    handle (arm i holds a smaller s than arm i+1). Raises `InfeasibleWrenchError`
    (with the binding limit of the least-infeasible grid candidate) when no
    placement can produce gamma_b.
    """
    handle = HandleSegment.default() if handle is None else handle
    if n_arms < 1:
        raise WholeBodyError(f"need at least one arm, got {n_arms}")
    if not (resolution > 0 and np.isfinite(resolution)):
        raise WholeBodyError(f"grid resolution must be positive, got {resolution}")
    L = handle.length
    if n_arms > 1 and (n_arms - 1) * min_spacing > L + 1e-12:
        raise WholeBodyError(f"{n_arms} arms {min_spacing} m apart do not fit on a {L:.3f} m handle")
    spacing = max(0.0, float(min_spacing)) if n_arms > 1 else 0.0
    allocator = WrenchAllocator(
        [handle.point(0.0)] * n_arms, limits, weights, solver, only_motion_directions
    )
    obj = _Objective(gamma_b, handle, allocator)

    n_grid = max(2, int(np.ceil(L / resolution)) + 1)
    grid = np.linspace(0.0, L, n_grid)
    step = grid[1] - grid[0]
    if n_arms == 1:
        candidates = [np.array([g]) for g in grid]
    else:
        k = int(np.ceil(spacing / step - 1e-9))
        candidates = [
            grid[list(idx)] for idx in combinations(range(n_grid), n_arms) if np.all(np.diff(idx) >= k)
        ]
        candidates = [c for c in candidates if _spacing_ok(c, L, spacing)]
    values = np.array([obj(c) for c in candidates])
    if not np.any(np.isfinite(values)):
        s_bad = obj.best_infeasible[1] if obj.best_infeasible is not None else candidates[0]
        allocator.set_points([handle.point(float(v)) for v in s_bad])
        allocator.solve(gamma_b)  # raises InfeasibleWrenchError naming the binding limit
        raise InfeasibleWrenchError("no contact placement produces the requested wrench", binding="unknown")

    order = np.argsort(values)
    best_s, best_v = candidates[order[0]].copy(), float(values[order[0]])
    for idx in order[: max(1, refine)]:
        if not np.isfinite(values[idx]):
            break
        s0 = candidates[idx]
        if n_arms == 1:
            lo, hi = max(0.0, s0[0] - step), min(L, s0[0] + step)
            r = minimize_scalar(lambda v: obj(np.array([v])), bounds=(lo, hi), method="bounded", options={"xatol": 1e-7})
            s_new, v_new = np.array([r.x]), float(r.fun)
        else:
            def penalized(s: np.ndarray) -> float:
                s = np.sort(s)
                return obj(s) if _spacing_ok(s, L, spacing) else np.inf

            simplex = np.vstack([s0] + [s0 + step * np.eye(n_arms)[j] * (1 if s0[j] + step <= L else -1) for j in range(n_arms)])
            r = minimize(penalized, s0, method="Nelder-Mead", options={"initial_simplex": simplex, "xatol": 1e-6, "fatol": 1e-9, "maxfev": 400})
            s_new, v_new = np.sort(r.x), float(r.fun)
        if np.isfinite(v_new) and v_new < best_v:
            best_s, best_v = s_new, v_new
    final = obj.result(best_s)
    points = np.array([handle.point(float(v)) for v in best_s])
    return ContactPlan(points, best_s, final, float(final.effort), obj.count)


def effort_profile(
    gamma_b: Sequence[float],
    s_values: Sequence[float],
    handle: HandleSegment | None = None,
    limits: ArmLimits = ArmLimits(),
    weights: EffortWeights = EffortWeights(),
    only_motion_directions: bool = False,
    solver: str = "proxqp",
) -> np.ndarray:
    """Return the one-arm effort V(s) at each handle coordinate (inf where infeasible)."""
    handle = HandleSegment.default() if handle is None else handle
    obj = _Objective(gamma_b, handle, WrenchAllocator([handle.point(0.0)], limits, weights, solver, only_motion_directions))
    return np.array([obj(np.array([float(s)])) for s in s_values])

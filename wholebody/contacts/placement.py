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
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize, minimize_scalar

from wholebody.contacts.allocation import AllocationResult, ArmLimits, EffortWeights, WrenchAllocator
from wholebody.contacts.handle import HandleSegment
from wholebody.errors import InfeasibleWrenchError, WholeBodyError


@dataclass(frozen=True)
class ContactPlan:
    """Chosen contact points (N x 3 in {b}), their coordinates s on the handle, and the allocation.

    ``evaluations`` counts the contact sets whose allocation was computed (in the vectorized closed form or
    by the QP); grid candidates pruned by the lower bound are not counted.
    """

    points_b: np.ndarray
    s: np.ndarray
    allocation: AllocationResult
    effort: float
    evaluations: int


@dataclass(frozen=True)
class EffortSweep:
    """Allocations of T cart wrenches at M contact sets (N arms each), from `effort_sweep`.

    ``effort`` (M, T): the allocation effort where ``solved``, elsewhere the effort of the equality-only
    optimum, a lower bound on it (no joint-torque weights); ``residual`` (M, T) and ``wrenches_ee``
    (M, T, N, 6) are those of `WrenchAllocator.solve` where ``solved``.
    """

    effort: np.ndarray
    residual: np.ndarray
    wrenches_ee: np.ndarray
    solved: np.ndarray

    def feasible_effort(self, tol: np.ndarray | float) -> np.ndarray:
        """Return the effort where the wrench is produced (residual <= tol, per wrench or scalar), inf elsewhere."""
        return np.where(self.solved & (self.residual <= tol), self.effort, np.inf)


def effort_sweep(
    allocator: WrenchAllocator, points_b: np.ndarray, gammas: np.ndarray, solve: np.ndarray | None = None
) -> EffortSweep:
    """Return the allocation of every wrench ``gammas`` (T, 3) at every contact set ``points_b`` (M, N, 3).

    The one effort sweep of the package: the equality-only optimum of all M x T problems at once
    (`WrenchAllocator.closed_form_batch`; exact wherever it keeps every limit), then `allocator.solve`
    (``raise_on_infeasible=False``) for the others, restricted to the mask ``solve`` (M, T) when given.
    The allocator is left at the last contact set solved.
    """
    pts = np.asarray(points_b, dtype=float)
    gam = np.asarray(gammas, dtype=float).reshape(-1, 3)
    X, exact, effort = allocator.closed_form_batch(pts, gam)
    M, T = exact.shape
    W = np.zeros((M, T, 6 * pts.shape[1]))
    W[..., allocator.free] = X
    G, _ = allocator._equality_batch(pts)
    d = (np.einsum("mrk,mtk->mtr", G, W) - gam)[..., allocator.rows]
    residual = np.sqrt(np.sum(d * d, axis=-1))
    todo = ~exact if solve is None else (~exact & np.asarray(solve, dtype=bool))
    for m in np.flatnonzero(todo.any(axis=1)):
        allocator.set_points(pts[m])
        for t in np.flatnonzero(todo[m]):
            res = allocator.solve(gam[t], raise_on_infeasible=False)
            effort[m, t], residual[m, t], W[m, t] = res.effort, res.residual, res.wrenches_ee.reshape(-1)
    return EffortSweep(effort, residual, W.reshape(M, T, -1, 6), exact | todo)


class _Objective:
    """V(s): allocation effort with contacts at handle coordinates s (inf if infeasible)."""

    def __init__(self, gamma, handle, allocator: WrenchAllocator) -> None:
        self.gamma = np.asarray(gamma, dtype=float)
        self.handle = handle
        self.alloc = allocator
        self.count = 0
        self.tol = 1e-7 * max(1.0, float(np.max(np.abs(self.gamma))))
        self._start, self._dir = np.asarray(handle.start_b), handle.direction

    def result(self, s: np.ndarray) -> AllocationResult:
        self.count += 1
        self.alloc.set_points([self.handle.point(float(v)) for v in s])
        return self.alloc.solve(self.gamma, raise_on_infeasible=False)

    def __call__(self, s: np.ndarray) -> float:
        pts = self._start + np.asarray(s, dtype=float)[:, None] * self._dir  # = handle.point(s_i)
        self.count += 1
        effort = self.alloc.closed_form_effort(pts, self.gamma)
        if effort is not None:  # the closed form keeps every limit: it is the QP optimum
            return effort
        self.alloc.set_points(pts)
        res = self.alloc.optimum(self.gamma)
        return np.inf if res is None or res.residual > self.tol else res.effort

    def least_infeasible(self, candidates: np.ndarray) -> np.ndarray:
        """Return the candidate whose closest achievable wrench misses gamma by the least (all infeasible)."""
        residuals = [self.result(c).residual for c in candidates]
        return candidates[int(np.argmin(residuals))]

    def grid_values(self, candidates: np.ndarray, keep: int) -> np.ndarray:
        """Return V at the candidates (K, N): exact for the ``keep`` smallest (and any tie), inf for the rest.

        All candidates in the vectorized closed form first (`effort_sweep` without QP); then, in increasing
        order of that lower bound, the QP for the others until the bound exceeds the ``keep``-th smallest
        exact value: a pruned candidate costs at least its bound, so the ``keep`` best are those of a brute
        force over the whole grid.
        """
        pts = np.asarray(self.handle.start_b) + candidates[..., None] * self.handle.direction  # (K, N, 3)
        sweep = effort_sweep(self.alloc, pts, self.gamma[None], solve=np.zeros((len(candidates), 1), bool))
        values = sweep.feasible_effort(self.tol)[:, 0]
        self.count += int(sweep.solved.sum())
        best = sorted(values[np.isfinite(values)].tolist())[:keep]  # the `keep` smallest exact values so far
        for k in np.argsort(sweep.effort[:, 0], kind="stable"):
            if sweep.solved[k, 0]:
                continue
            kth = best[keep - 1] if len(best) >= keep else np.inf
            if sweep.effort[k, 0] > kth * (1.0 + 1e-9) + 1e-12:
                break
            values[k] = self(candidates[k])
            if np.isfinite(values[k]):
                best = sorted(best + [float(values[k])])[:keep]
        return values


def _spacing_ok(s: np.ndarray, length: float, spacing: float) -> bool:
    v = s.tolist()
    return v[0] >= -1e-12 and v[-1] <= length + 1e-12 and all(b - a >= spacing - 1e-12 for a, b in zip(v, v[1:]))


def _grid(length: float, n_arms: int, spacing: float, resolution: float) -> tuple[np.ndarray, float]:
    """Return the spacing-feasible ordered grid tuples (K, n_arms) on [0, length] and the grid step."""
    n_grid = max(2, int(np.ceil(length / resolution)) + 1)
    grid = np.linspace(0.0, length, n_grid)
    step = grid[1] - grid[0]
    if n_arms == 1:
        return grid[:, None], step
    k = int(np.ceil(spacing / step - 1e-9))
    idx = np.array(list(combinations(range(n_grid), n_arms)), dtype=int).reshape(-1, n_arms)
    c = grid[idx[np.all(np.diff(idx, axis=1) >= k, axis=1)]]
    ok = (c[:, 0] >= -1e-12) & (c[:, -1] <= length + 1e-12) & np.all(np.diff(c, axis=1) >= spacing - 1e-12, axis=1)
    return c[ok], step


def _refine(obj: _Objective, s0: np.ndarray, step: float, length: float, spacing: float) -> tuple[np.ndarray, float]:
    """Return a local minimum of V near grid point s0: bounded Brent (one arm), Nelder–Mead (several)."""
    n_arms = len(s0)
    if n_arms == 1:
        lo, hi = max(0.0, s0[0] - step), min(length, s0[0] + step)
        r = minimize_scalar(lambda v: obj(np.array([v])), bounds=(lo, hi), method="bounded", options={"xatol": 1e-7})
        return np.array([r.x]), float(r.fun)

    def penalized(s: np.ndarray) -> float:
        s = np.sort(s)
        return obj(s) if _spacing_ok(s, length, spacing) else np.inf

    simplex = np.vstack(
        [s0] + [s0 + step * np.eye(n_arms)[j] * (1 if s0[j] + step <= length else -1) for j in range(n_arms)]
    )
    r = minimize(
        penalized,
        s0,
        method="Nelder-Mead",
        options={"initial_simplex": simplex, "xatol": 1e-6, "fatol": 1e-9, "maxfev": 400},
    )
    return np.sort(r.x), float(r.fun)


def _raise_infeasible(obj: _Objective, candidates: np.ndarray) -> None:
    """Raise `InfeasibleWrenchError` naming the binding limit at the least-infeasible grid candidate."""
    s_bad = obj.least_infeasible(candidates)
    obj.alloc.set_points([obj.handle.point(float(v)) for v in s_bad])
    obj.alloc.solve(obj.gamma)  # raises InfeasibleWrenchError naming the binding limit
    raise InfeasibleWrenchError("no contact placement produces the requested wrench", binding="unknown")


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
    placement can produce gamma_b. The ``refine`` best grid candidates (the
    same as a brute force over the grid's QPs, `_Objective.grid_values`) are refined locally.
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
    allocator = WrenchAllocator([handle.point(0.0)] * n_arms, limits, weights, solver, only_motion_directions)
    obj = _Objective(gamma_b, handle, allocator)
    candidates, step = _grid(L, n_arms, spacing, resolution)
    values = obj.grid_values(candidates, max(1, refine))
    if not np.any(np.isfinite(values)):
        _raise_infeasible(obj, candidates)
    order = np.argsort(values, kind="stable")
    best_s, best_v = candidates[order[0]].copy(), float(values[order[0]])
    for idx in order[: max(1, refine)]:
        if not np.isfinite(values[idx]):
            break
        s_new, v_new = _refine(obj, candidates[idx], step, L, spacing)
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
    """Return the one-arm effort V(s) at each handle coordinate (inf where infeasible), by `effort_sweep`."""
    handle = HandleSegment.default() if handle is None else handle
    gamma = np.asarray(gamma_b, dtype=float)
    s = np.asarray(s_values, dtype=float).reshape(-1)
    if np.any(s < -1e-12) or np.any(s > handle.length + 1e-12):
        raise WholeBodyError(f"handle coordinates must lie in [0, {handle.length}]")
    alloc = WrenchAllocator([handle.point(0.0)], limits, weights, solver, only_motion_directions)
    pts = (np.asarray(handle.start_b) + s[:, None] * handle.direction)[:, None, :]
    sweep = effort_sweep(alloc, pts, gamma[None])
    return sweep.feasible_effort(1e-7 * max(1.0, float(np.max(np.abs(gamma)))))[:, 0]


# ---------------------------------------------------------------------------------------------- reachability
#: "Reachable with margin": the posture holding a contact keeps this joint-limit margin (rad) and the arm's
#: 6 x 7 Jacobian keeps this smallest singular value (away from full extension and singularities).
REACH_JOINT_MARGIN = 0.15
REACH_MIN_SIGMA = 0.1


def _arm_ik(
    wb,
    base_pose: np.ndarray,
    target,
    seed: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    tol: float = 1e-5,
    max_nfev: int = 400,
) -> np.ndarray | None:
    """Return arm joints within [lo, hi] placing the end effector at `target` (pin.SE3), or None."""
    import pinocchio as pin
    from scipy.optimize import least_squares

    x = np.r_[base_pose, np.zeros(wb.n_arm)]
    model, data, fid = wb.model, wb.data, wb.ee_frame_id

    def residual(qa: np.ndarray) -> np.ndarray:
        x[3:] = qa
        return pin.log6(wb.ee_placement(x).actInv(target)).vector

    def jacobian(qa: np.ndarray) -> np.ndarray:  # d log6(oMee^-1 T) / dq = -Jlog6(T^-1 oMee) J_local
        x[3:] = qa
        q = wb.to_pinocchio_q(x)
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)[:, wb.arm_idx_v]
        iMd = pin.updateFramePlacement(model, data, fid).actInv(target)
        return -pin.Jlog6(iMd.inverse()) @ J

    sol = least_squares(
        residual,
        np.clip(seed, lo + 1e-9, hi - 1e-9),
        jac=jacobian,
        bounds=(lo, hi),
        xtol=1e-12,
        ftol=1e-12,
        max_nfev=max_nfev,
    )
    return sol.x if np.linalg.norm(sol.fun) <= tol else None


@dataclass(frozen=True)
class ReachMap:
    """Which handle points one arm holds with margin from its base's pushing pose, and at what static torque.

    Attributes:
        y: handle coordinates (m, along y_b) of the grid.
        postures: (n, n_arm) arm posture holding each point (NaN where not reachable with margin).
        joint_margin: (n,) distance (rad) of that posture to the nearest joint limit (-inf: not reachable).
        gravity: (n, n_arm) gravity torques at the posture (N m).
        jacobian: (n, 6, n_arm) hand Jacobian, {b}-aligned at the grasp point: tau_push = J^T w.
        effort_limit: (n_arm,) joint torque limits (N m).
        reason: (n,) why a point is not reachable ("" when it is).
    """

    y: np.ndarray
    postures: np.ndarray
    joint_margin: np.ndarray
    gravity: np.ndarray
    jacobian: np.ndarray
    effort_limit: np.ndarray
    reason: tuple

    @property
    def reachable(self) -> np.ndarray:
        """Return the mask of grid points the arm holds with margin."""
        return np.isfinite(self.joint_margin)

    def index(self, y: float) -> int:
        """Return the grid index nearest to y."""
        return int(np.argmin(np.abs(self.y - y)))

    def is_reachable(self, y: float) -> bool:
        """Return True when y lies within the reachable grid (between reachable neighbours)."""
        ok = self.reachable
        if not ok.any():
            return False
        lo, hi = self.y[ok].min(), self.y[ok].max()
        return bool(lo - 1e-9 <= y <= hi + 1e-9)

    def nearest_reachable(self, y: float) -> float:
        """Return the reachable grid point nearest to y; raise `InfeasibleWrenchError` (reach) if none."""
        ok = self.reachable
        if not ok.any():
            raise InfeasibleWrenchError(f"the arm holds no handle point with margin: {self.reason[0]}", binding="reach")
        ys = self.y[ok]
        return float(ys[np.argmin(np.abs(ys - y))])

    def torque(self, y: float, wrench_b: Sequence[float]) -> np.ndarray:
        """Return the static joint torques g(q) + J^T w holding handle point y with hand wrench w ({b}-aligned)."""
        i = self.index(y)
        return self.gravity[i] + self.jacobian[i].T @ np.asarray(wrench_b, dtype=float)

    def torque_ratio(self, y: float, wrench_b: Sequence[float]) -> float:
        """Return max_j |tau_j| / effortLimit_j of `torque`."""
        return float(np.max(np.abs(self.torque(y, wrench_b)) / self.effort_limit))


def reach_map(
    wb,
    base_pose_of,
    target_of,
    y_values: npt.ArrayLike,
    seed: npt.ArrayLike,
    y_start: float,
    joint_margin: float = REACH_JOINT_MARGIN,
    min_sigma: float = REACH_MIN_SIGMA,
) -> ReachMap:
    """Return the `ReachMap` of an arm along the handle (reachability with joint limits, not just geometry).

    Args:
        wb: the robot's `WholeBody`.
        base_pose_of: y -> planar base pose (cart at the origin) from which the arm holds handle point y.
        target_of: y -> grasp pose (pin.SE3) of handle point y (cart at the origin).
        y_values: handle grid (m), increasing.
        seed: arm posture near the grasp of `y_start`.
        y_start: where the continuation starts; it proceeds to both ends along one posture branch
            (the one the arm moves through when its contact slides) and stops at the first point that fails.

    A point is reachable with margin when the grasp IK converges with every joint `joint_margin` rad inside
    its limits and the arm's Jacobian there keeps its smallest singular value above `min_sigma` (the hand can
    still move every way: not at full extension).
    """
    ys = np.asarray(y_values, dtype=float)
    lo_m, hi_m = wb.arm_lower + joint_margin, wb.arm_upper - joint_margin

    def hold(y: float, prev: np.ndarray) -> tuple[np.ndarray | None, str]:
        return _hold_point(wb, base_pose_of(y), target_of(y), prev, lo_m, hi_m, joint_margin, min_sigma)

    i0 = int(np.argmin(np.abs(ys - y_start)))
    postures, margin, reason = _reach_branches(wb, ys, i0, seed, hold)
    gravity, jac = _static_terms(wb, base_pose_of, ys, postures, margin)
    effort = wb.model.effortLimit[wb.arm_idx_v].copy()
    return ReachMap(ys, postures, margin, gravity, jac, effort, tuple(reason))


def _hold_point(
    wb,
    base: np.ndarray,
    target,
    prev: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    joint_margin: float,
    min_sigma: float,
) -> tuple[np.ndarray | None, str]:
    """Return (posture, "") holding `target` from `base` with margin near `prev`, or (None, why not)."""
    qa = _arm_ik(wb, base, target, prev, lo, hi)
    if qa is None:
        return None, f"grasp IK fails within {joint_margin} rad of the joint limits"
    x = np.r_[base, qa]
    sigma = float(np.linalg.svd(wb.combined_jacobian(x)[:, : wb.n_arm], compute_uv=False)[-1])
    if sigma < min_sigma:
        return None, (
            f"the arm is near full extension or a singularity (smallest singular "
            f"value of its Jacobian {sigma:.3f} < {min_sigma})"
        )
    return qa, ""


def _reach_branches(wb, ys: np.ndarray, i0: int, seed: npt.ArrayLike, hold) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Return (postures, joint margins, reasons) continuing `hold` from grid index i0 to both ends.

    Each direction starts from `seed`, seeds every point with the previous posture and stops at the first
    point `hold` fails (the rest of that direction is "beyond an unreachable point").
    """
    n, na = ys.size, wb.n_arm
    postures = np.full((n, na), np.nan)
    margin = np.full(n, -np.inf)
    reason = [""] * n
    for order in (range(i0, n), range(i0 - 1, -1, -1)):
        prev = np.asarray(seed, dtype=float)
        failed = False
        for i in order:
            if failed:
                reason[i] = "beyond an unreachable point"
                continue
            qa, why = hold(ys[i], prev)
            if qa is None:
                failed, reason[i] = True, why
                continue
            postures[i], prev = qa, qa
            margin[i] = float(min(np.min(qa - wb.arm_lower), np.min(wb.arm_upper - qa)))
    return postures, margin, reason


def _static_terms(
    wb, base_pose_of, ys: np.ndarray, postures: np.ndarray, margin: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Return (gravity torques (n, n_arm), hand Jacobians (n, 6, n_arm)) at the reachable postures (zeros elsewhere)."""
    import pinocchio as pin

    n, na = ys.size, wb.n_arm
    gravity = np.zeros((n, na))
    jac = np.zeros((n, 6, na))
    for i in np.flatnonzero(np.isfinite(margin)):
        x = np.r_[base_pose_of(ys[i]), postures[i]]
        q = wb.to_pinocchio_q(x)
        gravity[i] = pin.computeGeneralizedGravity(wb.model, wb.data, q)[wb.arm_idx_v]
        jac[i] = wb.combined_jacobian(x)[:, :na]
    return gravity, jac


def robot_contact_point(
    gamma_b: Sequence[float],
    reach: ReachMap,
    limits: ArmLimits = ArmLimits(),
    weights: EffortWeights = EffortWeights(),
    torque_fraction: float = 1.0,
    solver: str = "proxqp",
) -> tuple[float, AllocationResult]:
    """Return (contact y, allocation) of one arm: minimum effort over the points it holds with margin.

    Raises `InfeasibleWrenchError` naming what binds: ``reach`` (no handle point reachable with margin),
    ``joint torque <joint>`` (every reachable point that produces the wrench needs more than
    ``torque_fraction`` of a joint's effortLimit), or the allocation's own limit (grip, force/torque bound).
    """
    from wholebody.contacts.handle import HandleSegment

    handle = HandleSegment.default()
    ok = reach.reachable
    if not ok.any():
        raise InfeasibleWrenchError(f"no handle point is reachable with margin ({reach.reason[0]})", binding="reach")
    alloc = WrenchAllocator([handle.start_b], limits, weights, solver)
    gamma = np.asarray(gamma_b, dtype=float)
    tol = 1e-7 * max(1.0, float(np.max(np.abs(gamma))))
    best, worst_torque, alloc_fail = None, None, None
    for y in reach.y[ok]:
        alloc.set_points([np.array([handle.start_b[0], y, handle.start_b[2]])])
        res = alloc.solve(gamma, raise_on_infeasible=False)
        if res.residual > tol:
            alloc_fail = y
            continue
        tau = reach.torque(y, res.wrenches_ee[0])
        ratio = np.abs(tau) / reach.effort_limit
        if ratio.max() > torque_fraction:
            if worst_torque is None or ratio.max() < worst_torque[0]:
                worst_torque = (float(ratio.max()), int(np.argmax(ratio)), float(y))
            continue
        if best is None or res.effort < best[2].effort:
            best = (float(y), None, res)
    if best is not None:
        return best[0], best[2]
    if worst_torque is not None:
        r, j, y = worst_torque
        raise InfeasibleWrenchError(
            f"joint torque binds: arm joint {j + 1} needs {r:.2f} x its effortLimit at "
            f"the best reachable point y = {y:.3f} m",
            binding=f"joint torque (arm joint {j + 1})",
        )
    alloc.set_points([np.array([handle.start_b[0], alloc_fail, handle.start_b[2]])])
    alloc.solve(gamma)  # raises naming the allocation limit that binds (grip, force or torque bound)
    raise InfeasibleWrenchError("no reachable contact produces the wrench", binding="unknown")

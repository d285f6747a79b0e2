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


# ---------------------------------------------------------------------------------------------- reachability
#: "Reachable with margin": the posture holding a contact keeps this joint-limit margin (rad) and the arm's
#: 6 x 7 Jacobian keeps this smallest singular value (away from full extension and singularities).
REACH_JOINT_MARGIN = 0.15
REACH_MIN_SIGMA = 0.1


def _arm_ik(wb, base_pose: np.ndarray, target, seed: np.ndarray, lo: np.ndarray, hi: np.ndarray,
            tol: float = 1e-5, max_nfev: int = 400) -> np.ndarray | None:
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

    sol = least_squares(residual, np.clip(seed, lo + 1e-9, hi - 1e-9), jac=jacobian, bounds=(lo, hi),
                        xtol=1e-12, ftol=1e-12, max_nfev=max_nfev)
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


def reach_map(wb, base_pose_of, target_of, y_values: Sequence[float], seed: Sequence[float], y_start: float,
              joint_margin: float = REACH_JOINT_MARGIN, min_sigma: float = REACH_MIN_SIGMA) -> ReachMap:
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
    import pinocchio as pin

    ys = np.asarray(y_values, dtype=float)
    n, na = ys.size, wb.n_arm
    postures = np.full((n, na), np.nan)
    margin = np.full(n, -np.inf)
    reason = [""] * n
    lo_m, hi_m = wb.arm_lower + joint_margin, wb.arm_upper - joint_margin
    i0 = int(np.argmin(np.abs(ys - y_start)))
    for order in (range(i0, n), range(i0 - 1, -1, -1)):
        prev = np.asarray(seed, dtype=float)
        failed = False
        for i in order:
            if failed:
                reason[i] = "beyond an unreachable point"
                continue
            base, target = base_pose_of(ys[i]), target_of(ys[i])
            qa = _arm_ik(wb, base, target, prev, lo_m, hi_m)
            if qa is None:
                failed, reason[i] = True, f"grasp IK fails within {joint_margin} rad of the joint limits"
                continue
            x = np.r_[base, qa]
            sigma = float(np.linalg.svd(wb.combined_jacobian(x)[:, :na], compute_uv=False)[-1])
            if sigma < min_sigma:
                failed, reason[i] = True, (f"the arm is near full extension or a singularity (smallest singular "
                                           f"value of its Jacobian {sigma:.3f} < {min_sigma})")
            if failed:
                continue
            postures[i], prev = qa, qa
            margin[i] = float(min(np.min(qa - wb.arm_lower), np.min(wb.arm_upper - qa)))
    gravity = np.zeros((n, na))
    jac = np.zeros((n, 6, na))
    for i in np.flatnonzero(np.isfinite(margin)):
        x = np.r_[base_pose_of(ys[i]), postures[i]]
        q = wb.to_pinocchio_q(x)
        gravity[i] = pin.computeGeneralizedGravity(wb.model, wb.data, q)[wb.arm_idx_v]
        jac[i] = wb.combined_jacobian(x)[:, :na]
    effort = wb.model.effortLimit[wb.arm_idx_v].copy()
    return ReachMap(ys, postures, margin, gravity, jac, effort, tuple(reason))


def robot_contact_point(gamma_b: Sequence[float], reach: ReachMap, limits: ArmLimits = ArmLimits(),
                        weights: EffortWeights = EffortWeights(), torque_fraction: float = 1.0,
                        solver: str = "proxqp") -> tuple[float, AllocationResult]:
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
        raise InfeasibleWrenchError(f"joint torque binds: arm joint {j + 1} needs {r:.2f} x its effortLimit at "
                                    f"the best reachable point y = {y:.3f} m", binding=f"joint torque (arm joint {j + 1})")
    alloc.set_points([np.array([handle.start_b[0], alloc_fail, handle.start_b[2]])])
    alloc.solve(gamma)  # raises naming the allocation limit that binds (grip, force or torque bound)
    raise InfeasibleWrenchError("no reachable contact produces the wrench", binding="unknown")

"""Multi-arm wrench allocation as a QP (paper eq. 25) through `qpsolvers`.

Given the cart wrench ``Gamma_MM = (fx, fy, tau)`` in {b} and N contacts on the
handle, find each end effector's wrench ``[f; tau]`` (in its contact frame
{a}) that minimizes a weighted effort subject to

* ``sum_i G_i w_i = Gamma_MM`` (all three rows, or only the rows the cart can
  move along, ``fx_b`` and ``tau``, when ``only_motion_directions``: the wheel
  constraint absorbs the lateral force);
* per-arm force and torque bounds (boxes);
* a grasp model: the gripper pulls only up to its friction capacity, and the
  tangential force and the torques stay inside linearized friction cones whose
  normal load is the grip squeeze plus the push;
* joint torque limits ``|J_i^T w_i| <= tau_max`` when Jacobians are given.

`WrenchAllocator` builds the matrices once for a set of contacts and limits and
then solves for a new ``Gamma_MM`` per call (the hot path of a control loop).
An unconstrained-optimum shortcut (closed-form KKT) is taken when it already
satisfies every inequality, which is then the exact QP optimum.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import qpsolvers
import scipy.sparse as sp

from wholebody.contacts.handle import ContactSpec, grasp_map
from wholebody.errors import InfeasibleWrenchError, WholeBodyError

#: Robotiq 2F-85 grip force range (N).
GRIP_FORCE_RANGE = (20.0, 235.0)
#: Components of [f; tau]: index -> short name.
COMPONENTS = ("fx", "fy", "fz", "tau_x", "tau_y", "tau_z")
#: Components used by a planar contact (the others are fixed to zero).
PLANAR_COMPONENTS = (0, 1, 5)


@dataclass(frozen=True)
class GraspModel:
    """Parallel gripper holding the handle (Robotiq 2F-85 by default).

    The contact normal is x of {a} (the hand pushes along +x). The normal load is
    ``N = 2 * grip_force + fx``: both fingers squeeze, a push adds to it. Then
    pulling is limited by friction, ``-fx <= 2 * friction * grip_force``; the
    tangential force ``(fy, fz)`` stays in a friction cone ``|f_t| <= friction * N``
    (a ``facets``-sided inscribed pyramid; exact ``|fy| <= friction * N`` when
    planar), and each torque component obeys ``|tau_k| <= torque_arm * N``.
    """

    grip_force: float = 100.0
    friction: float = 0.5
    torque_arm: float = 0.02
    facets: int = 8

    def __post_init__(self) -> None:
        lo, hi = GRIP_FORCE_RANGE
        if not (lo <= self.grip_force <= hi):
            raise WholeBodyError(f"grip force {self.grip_force} N is outside the gripper's range [{lo}, {hi}] N")
        if not (self.friction > 0.0 and self.torque_arm >= 0.0 and self.facets >= 3):
            raise WholeBodyError("grasp model needs friction > 0, torque_arm >= 0 and facets >= 3")

    @property
    def pull_capacity(self) -> float:
        """Return the largest pulling force (N) the friction grip holds."""
        return 2.0 * self.friction * self.grip_force


@dataclass(frozen=True)
class ArmLimits:
    """Per-arm limits: box bounds on each force/torque component, and a grasp model.

    ``planar=True`` fixes fz, tau_x and tau_y to zero (they only load the floor).
    """

    max_force: float = 150.0
    max_torque: float = 20.0
    grasp: GraspModel | None = GraspModel()
    planar: bool = True

    def __post_init__(self) -> None:
        if not (self.max_force > 0.0 and self.max_torque >= 0.0):
            raise WholeBodyError("arm limits need max_force > 0 and max_torque >= 0")


@dataclass(frozen=True)
class EffortWeights:
    """Weights of the effort: force and torque components, or joint torques."""

    force: float = 1.0
    torque: float = 1.0
    joint: float = 1.0

    def __post_init__(self) -> None:
        if not (self.force > 0.0 and self.torque > 0.0 and self.joint > 0.0):
            raise WholeBodyError("effort weights must be positive")


@dataclass(frozen=True)
class AllocationResult:
    """End-effector wrenches (N x 6, each in its {a}), achieved Gamma_MM, residual, effort."""

    wrenches_ee: np.ndarray
    gamma_achieved: np.ndarray
    residual: float
    effort: float
    solver: str
    joint_torques: tuple[np.ndarray, ...] | None = None


def _as_contacts(contacts: Sequence) -> list[ContactSpec]:
    out = []
    for c in contacts:
        out.append(c if isinstance(c, ContactSpec) else ContactSpec(tuple(c)))
    if not out:
        raise WholeBodyError("at least one contact is needed")
    return out


class WrenchAllocator:
    """Cached QP of the wrench allocation for fixed contacts and limits; `solve(gamma_b)` per step."""

    def __init__(
        self,
        contacts: Sequence,
        limits: ArmLimits | Sequence[ArmLimits] = ArmLimits(),
        weights: EffortWeights = EffortWeights(),
        solver: str = "proxqp",
        only_motion_directions: bool = False,
        jacobians: Sequence[np.ndarray] | None = None,
        torque_limits: Sequence[np.ndarray] | None = None,
        fast_path: bool = True,
    ) -> None:
        self.contacts = _as_contacts(contacts)
        n = len(self.contacts)
        lims = [limits] * n if isinstance(limits, ArmLimits) else list(limits)
        if len(lims) != n:
            raise WholeBodyError(f"{len(lims)} arm limits given for {n} contacts")
        if solver not in qpsolvers.available_solvers:
            raise WholeBodyError(f"QP solver {solver!r} is not installed; available: {qpsolvers.available_solvers}")
        if torque_limits is not None and jacobians is None:
            raise WholeBodyError("joint torque limits need the arms' Jacobians")
        self.limits = lims
        self.weights = weights
        self.solver = solver
        self.fast_path = fast_path
        self.rows = np.array([0, 2]) if only_motion_directions else np.array([0, 1, 2])
        self.jacobians = None if jacobians is None else [np.asarray(J, dtype=float) for J in jacobians]
        if self.jacobians is not None:
            if len(self.jacobians) != n or any(J.ndim != 2 or J.shape[0] != 6 for J in self.jacobians):
                raise WholeBodyError("jacobians must be one (6 x n_joints) array per contact")
        self._build(torque_limits)

    # ------------------------------------------------------------------ build
    def _build(self, torque_limits) -> None:
        n = len(self.contacts)
        free = []  # indices into the stacked 6N wrench
        for i, lim in enumerate(self.limits):
            comps = PLANAR_COMPONENTS if lim.planar else range(6)
            free.extend(6 * i + k for k in comps)
        self.free = np.array(free)
        nx = len(free)
        E = np.zeros((6 * n, nx))
        E[self.free, np.arange(nx)] = 1.0
        self.E = E
        w = self.weights
        Q = np.zeros((6 * n, 6 * n))  # effort = w_full^T Q w_full
        for i in range(n):
            if self.jacobians is None:
                Q[6 * i : 6 * i + 3, 6 * i : 6 * i + 3] = w.force * np.eye(3)
                Q[6 * i + 3 : 6 * i + 6, 6 * i + 3 : 6 * i + 6] = w.torque * np.eye(3)
            else:
                J = self.jacobians[i]
                Q[6 * i : 6 * i + 6, 6 * i : 6 * i + 6] = w.joint * (J @ J.T)
        self.Q = Q
        reg = np.diag(np.tile(np.r_[[w.force] * 3, [w.torque] * 3], n)) * (1e-9 if self.jacobians is not None else 0.0)
        self.P = 2.0 * E.T @ (Q + reg) @ E
        self.q = np.zeros(nx)
        rows, rhs, labels = [], [], []

        def add(coef_full: np.ndarray, bound: float, label: str) -> None:
            rows.append(coef_full @ E)
            rhs.append(bound)
            labels.append(label)

        for i, lim in enumerate(self.limits):
            comps = PLANAR_COMPONENTS if lim.planar else range(6)
            for k in comps:
                bound = lim.max_force if k < 3 else lim.max_torque
                unit = "N" if k < 3 else "N m"
                for sgn in (1.0, -1.0):
                    c = np.zeros(6 * n)
                    c[6 * i + k] = sgn
                    add(c, bound, f"arm{i} {'force' if k < 3 else 'torque'} bound ({COMPONENTS[k]} {'<=' if sgn > 0 else '>='} {sgn * bound:g} {unit})")
            g = lim.grasp
            if g is not None:
                c = np.zeros(6 * n)
                c[6 * i] = -1.0
                add(c, g.pull_capacity, f"arm{i} grip pull limit ({g.pull_capacity:g} N at grip force {g.grip_force:g} N)")
                mu, sq = g.friction, 2.0 * g.grip_force
                if lim.planar:
                    dirs = [(1.0, 0.0, 1.0), (-1.0, 0.0, 1.0)]
                else:
                    ang = 2.0 * np.pi * np.arange(g.facets) / g.facets
                    shrink = np.cos(np.pi / g.facets)
                    dirs = [(np.cos(a), np.sin(a), shrink) for a in ang]
                for cy, cz, s in dirs:  # c.f_t <= mu * s * (2 Fg + fx)
                    c = np.zeros(6 * n)
                    c[6 * i + 1], c[6 * i + 2], c[6 * i] = cy, cz, -mu * s
                    add(c, mu * s * sq, f"arm{i} grip friction cone (tangential force, mu={mu:g})")
                for k in comps:
                    if k < 3:
                        continue
                    for sgn in (1.0, -1.0):
                        c = np.zeros(6 * n)
                        c[6 * i + k], c[6 * i] = sgn, -g.torque_arm
                        add(c, g.torque_arm * sq, f"arm{i} grip torque limit ({COMPONENTS[k]})")
            if torque_limits is not None:
                tl = np.asarray(torque_limits[i], dtype=float)
                J = self.jacobians[i]
                if tl.shape != (J.shape[1],) or np.any(tl <= 0):
                    raise WholeBodyError(f"arm{i} torque limits must be {J.shape[1]} positive numbers")
                for j in range(J.shape[1]):
                    for sgn in (1.0, -1.0):
                        c = np.zeros(6 * n)
                        c[6 * i : 6 * i + 6] = sgn * J[:, j]
                        add(c, tl[j], f"arm{i} joint {j} torque limit ({tl[j]:g} N m)")
        self.Gin = np.array(rows)
        self.hin = np.array(rhs)
        self.labels = labels
        sparse = self.solver in ("osqp", "scs", "clarabel", "highs", "piqp", "qpalm", "gurobi", "mosek")
        self._G_conv = sp.csc_matrix(self.Gin) if sparse else self.Gin
        self.set_points([c.point_b for c in self.contacts])

    def set_points(self, points_b: Sequence[Sequence[float]]) -> None:
        """Move the contacts to points_b (N x 3 in {b}); the limits and the cost are unchanged."""
        pts = [ContactSpec(tuple(p), c.name) for p, c in zip(points_b, self.contacts)]
        if len(pts) != len(self.contacts):
            raise WholeBodyError(f"{len(points_b)} points given for {len(self.contacts)} contacts")
        self.contacts = pts
        self.G_full = np.hstack([grasp_map(c.point_b) for c in pts])  # paper eq. (25)
        self.A = self.G_full[self.rows] @ self.E
        # closed-form optimum of the equality-only problem: x = K b
        Pinv_At = np.linalg.solve(self.P, self.A.T)
        S = self.A @ Pinv_At
        self.K = None if np.linalg.matrix_rank(S) < S.shape[0] else Pinv_At @ np.linalg.inv(S)
        sparse = self.solver in ("osqp", "scs", "clarabel", "highs", "piqp", "qpalm", "gurobi", "mosek")
        conv = (lambda M: sp.csc_matrix(M)) if sparse else (lambda M: M)
        self._mats = dict(P=conv(self.P), G=self._G_conv, A=conv(self.A))
        relax_scale = 1e6 * max(1.0, float(np.max(np.diag(self.P))))
        self._relax_P = conv(self.P / relax_scale + 2.0 * self.A.T @ self.A)

    # ------------------------------------------------------------------ solve
    def _solver_kwargs(self) -> dict:
        if self.solver == "proxqp":
            return dict(eps_abs=1e-9, eps_rel=0.0)
        if self.solver == "osqp":
            return dict(eps_abs=1e-9, eps_rel=1e-9, polish=True, max_iter=20000, verbose=False)
        return {}

    def _polish(self, x: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Return the exact KKT solution on the active set of x when x misses the equality by > 1e-11."""
        scale = max(1.0, float(np.max(np.abs(b))))
        if float(np.max(np.abs(self.A @ x - b))) <= 1e-11 * scale:
            return x
        active = self.Gin @ x >= self.hin - 1e-7 * np.maximum(1.0, np.abs(self.hin))
        Aeq = np.vstack([self.A, self.Gin[active]])
        beq = np.r_[b, self.hin[active]]
        nx, m = self.P.shape[0], Aeq.shape[0]
        K = np.zeros((nx + m, nx + m))
        K[:nx, :nx], K[:nx, nx:], K[nx:, :nx] = self.P, Aeq.T, Aeq
        sol = np.linalg.lstsq(K, np.r_[-self.q, beq], rcond=None)[0][:nx]
        ok_in = np.all(self.Gin @ sol <= self.hin + 1e-9 * np.maximum(1.0, np.abs(self.hin)))
        if ok_in and float(np.max(np.abs(self.A @ sol - b))) <= 1e-11 * scale:
            return sol
        return x

    def _result(self, x: np.ndarray, gamma: np.ndarray, solver: str) -> AllocationResult:
        w_full = self.E @ x
        achieved = self.G_full @ w_full
        residual = float(np.linalg.norm((achieved - gamma)[self.rows]))
        effort = float(w_full @ self.Q @ w_full)
        W = w_full.reshape(-1, 6)
        taus = None if self.jacobians is None else tuple(J.T @ W[i] for i, J in enumerate(self.jacobians))
        return AllocationResult(W, achieved, residual, effort, solver, taus)

    def solve(self, gamma_b: Sequence[float], raise_on_infeasible: bool = True) -> AllocationResult:
        """Return the minimum-effort wrenches producing gamma_b = (fx, fy, tau) in {b}.

        Raises `InfeasibleWrenchError` (binding limit, closest achievable wrench)
        if no wrench within the limits produces it, unless ``raise_on_infeasible``
        is False: then the closest achievable allocation is returned.
        """
        gamma = np.asarray(gamma_b, dtype=float).reshape(-1)
        if gamma.shape != (3,) or not np.all(np.isfinite(gamma)):
            raise WholeBodyError(f"cart wrench must be 3 finite numbers (fx, fy, tau), got {gamma_b!r}")
        b = gamma[self.rows]
        tol = 1e-7 * max(1.0, float(np.max(np.abs(gamma))))
        if self.fast_path and self.K is not None:
            x = self.K @ b
            if np.all(self.Gin @ x <= self.hin + 1e-12 * np.maximum(1.0, np.abs(self.hin))):
                return self._result(x, gamma, "closed-form")
        sol = qpsolvers.solve_problem(
            qpsolvers.Problem(self._mats["P"], self.q, self._mats["G"], self.hin, self._mats["A"], b),
            solver=self.solver,
            **self._solver_kwargs(),
        )
        if sol.found and sol.x is not None and np.all(np.isfinite(sol.x)):
            x = self._polish(sol.x, b)
            res = self._result(x, gamma, self.solver)
            if res.residual <= tol and np.all(self.Gin @ x <= self.hin + 1e-6 * np.maximum(1.0, np.abs(self.hin))):
                return res
        return self._closest(gamma, b, tol, raise_on_infeasible)

    def _closest(self, gamma: np.ndarray, b: np.ndarray, tol: float, raise_on_infeasible: bool) -> AllocationResult:
        """Solve min |A x - b|^2 + effort / rho under the limits (rho large); raise or return it."""
        sol = qpsolvers.solve_problem(
            qpsolvers.Problem(self._relax_P, -2.0 * self.A.T @ b, self._mats["G"], self.hin),
            solver=self.solver,
            **self._solver_kwargs(),
        )
        if not sol.found or sol.x is None:
            raise InfeasibleWrenchError(f"the QP solver {self.solver} failed on the relaxed allocation", binding="solver")
        x = sol.x
        res = self._result(x, gamma, self.solver)
        if res.residual <= tol:
            return res  # the first solve only stalled
        z = np.zeros(len(self.hin)) if sol.z is None else np.asarray(sol.z)
        slack = self.hin - self.Gin @ x
        score = np.where(slack <= 1e-5 * np.maximum(1.0, np.abs(self.hin)), np.abs(z) + 1e-12, 0.0)
        binding = self.labels[int(np.argmax(score))] if np.any(score > 0) else "unknown"
        if not raise_on_infeasible:
            return res
        closest = res.gamma_achieved
        raise InfeasibleWrenchError(
            f"cart wrench (fx, fy, tau) = ({gamma[0]:.4g}, {gamma[1]:.4g}, {gamma[2]:.4g}) is not achievable: "
            f"{binding} binds; closest achievable is ({closest[0]:.4g}, {closest[1]:.4g}, {closest[2]:.4g})",
            binding=binding,
            closest=tuple(float(v) for v in closest),
        )


def allocate(
    gamma_b: Sequence[float],
    contacts: Sequence,
    limits: ArmLimits | Sequence[ArmLimits] = ArmLimits(),
    weights: EffortWeights = EffortWeights(),
    solver: str = "proxqp",
    only_motion_directions: bool = False,
    jacobians: Sequence[np.ndarray] | None = None,
    torque_limits: Sequence[np.ndarray] | None = None,
    raise_on_infeasible: bool = True,
) -> AllocationResult:
    """Return the minimum-effort end-effector wrenches producing gamma_b (paper eq. 25).

    One-shot convenience around `WrenchAllocator`; build the allocator once and
    call `WrenchAllocator.solve` in a control loop instead.
    """
    alloc = WrenchAllocator(contacts, limits, weights, solver, only_motion_directions, jacobians, torque_limits)
    return alloc.solve(gamma_b, raise_on_infeasible=raise_on_infeasible)

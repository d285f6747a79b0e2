"""The resolved-rate QP composed from tasks and limits (the mink/pink layout); its solvers are `wholebody.qp`.

A `Task` contributes a quadratic cost ``1/2 u^T H u + c^T u`` over the input ``u = [arm rates, base input]``;
a `Limit` contributes a box ``lb <= u <= ub`` and/or inequalities ``G u <= h``. `solve_step` sums the
costs, intersects the boxes, stacks the inequalities and solves the QP (paper eq. 21 with limits)::

    min  sum_i (1/2 u^T H_i u + c_i^T u)   s.t.  max_j lb_j <= u <= min_j ub_j,  [G_1; G_2; ...] u <= [h_1; h_2; ...]

Limits marked `relaxable` (the safety band, §VI) are solved first as given and, if no solver finds a
solution, once more with their right-hand sides relaxed so that u = 0 is feasible.

Per step the costs and boxes are written in place into the buffers of a `QPWorkspace` (`Task.add_objective`,
`Limit.intersect_box`); boxes of limits marked `constant_box` are intersected once, not every step.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wholebody.motion.kernels import clip_to_box
from wholebody.motion.kinematics import WholeBody
from wholebody.qp import DaqpSolver, ProxQPSolver, solve_qpsolvers


@dataclass
class StepState:
    """What tasks and limits see of one control step.

    Attributes:
        wb: the robot.
        x: reduced state [x, y, theta, q_arm...].
        dt: step duration (s).
        T: end-effector placement at x.
        J: 6 x n_u combined Jacobian at x (paper eq. 21).
        v_ref: commanded end-effector twist (world-aligned, clipped).
        u_prev: input applied at the previous step.
        band_center, band_center_velocity: centre (2,) of the safety band and its velocity.
        base_target, base_target_velocity: base target pose (3,) and its world rates, or None.
    """

    wb: WholeBody
    x: np.ndarray
    dt: float
    T: pin.SE3 | None = None
    J: np.ndarray | None = None
    v_ref: np.ndarray | None = None
    u_prev: np.ndarray | None = None
    band_center: npt.ArrayLike | None = None
    band_center_velocity: npt.ArrayLike | None = None
    base_target: npt.ArrayLike | None = None
    base_target_velocity: npt.ArrayLike | None = None

    @cached_property
    def cos_sin(self) -> tuple[float, float]:
        """(cos theta, sin theta) of the base heading, computed once per state."""
        th = float(self.x[2])
        return math.cos(th), math.sin(th)


class Task:
    """A quadratic cost term over the input u."""

    @property
    def constant_hessian(self) -> bool:
        """True if the Hessian H added by `add_objective` does not depend on the step: a `QPWorkspace` then sums
        it once per task list and calls only `add_linear` each step (call `QPWorkspace.reset` after changing it).

        False here; a subclass overrides it (a class attribute, or a property when it depends on the task's state).
        """
        return False

    #: False if the cost has no linear term (a `constant_hessian` task is then not called each step)
    linear: bool = True

    def objective(self, s: StepState) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Return (H, c) of the cost 1/2 u^T H u + c^T u (n_u x n_u, n_u); None stands for zero.

        The arrays are read, never modified, by the caller; a task may reuse them from call to call.
        """
        raise NotImplementedError

    def add_objective(self, s: StepState, H: np.ndarray, c: np.ndarray) -> None:
        """Add the cost to (H, c) in place (default: from `objective`; built-in tasks write directly)."""
        Ht, ct = self.objective(s)
        if Ht is not None:
            H += Ht
        if ct is not None:
            c += ct

    def add_linear(self, s: StepState, H: np.ndarray, c: np.ndarray) -> None:
        """Add only the linear term to c in place (H untouched; called for `constant_hessian` tasks)."""
        ct = self.objective(s)[1]
        if ct is not None:
            c += ct


class Limit:
    """A constraint on the input u: a box, inequalities G u <= h, or both."""

    #: True if `inequality(s, relax=True)` returns a relaxed version containing u = 0
    relaxable: bool = False
    #: True if `box` does not depend on the step (its box is then read once per `QPWorkspace`, not every step)
    constant_box: bool = False
    #: True if `inequality` returns the same (G, h) arrays, never modified, at every step
    constant_inequality: bool = False

    def box(self, s: StepState) -> tuple[np.ndarray, np.ndarray] | None:
        """Return (lb, ub) (n_u,) each, +-inf where unbounded, or None (arrays may be reused by the next call)."""
        return None

    def inequality(self, s: StepState, relax: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
        """Return (G, h) of G u <= h, or None."""
        return None

    def intersect_box(self, s: StepState, lb: np.ndarray, ub: np.ndarray) -> None:
        """Intersect (lb, ub) in place with the limit's box (default: from `box`)."""
        b = self.box(s)
        if b is not None:
            np.maximum(lb, b[0], out=lb)
            np.minimum(ub, b[1], out=ub)

    def enforce(self, u: np.ndarray, s: StepState) -> None:
        """Make u satisfy the limit exactly after the solve (solver tolerance), in place; default: nothing."""

    @property
    def enforces(self) -> bool:
        """True if `enforce` may change u (default: the subclass overrides it); others are not called."""
        return type(self).enforce is not Limit.enforce

    @property
    def has_inequality(self) -> bool:
        """True if `inequality` may return rows (default: the subclass overrides it); others are not called."""
        return type(self).inequality is not Limit.inequality


def stack_objective(tasks: list[Task], s: StepState) -> tuple[np.ndarray, np.ndarray]:
    """Return (H, c): the sum of the tasks' costs, in task order (new arrays)."""
    return QPWorkspace(s.wb.n_u).objective(tasks, s)


def stack_box(limits: list[Limit], s: StepState) -> tuple[np.ndarray, np.ndarray]:
    """Return the intersection (lb, ub) of the limits' boxes (new arrays, +-inf where unbounded)."""
    return QPWorkspace(s.wb.n_u).box(limits, s)


def stack_inequalities(
    limits: list[Limit], s: StepState, relax: bool = False
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Return (G, h) stacking the limits' inequalities in order, or (None, None) if there are none.

    With a single inequality-producing limit its own arrays are returned (read them, do not modify them).
    """
    return QPWorkspace(s.wb.n_u).inequalities(limits, s, relax)[:2]


class QPWorkspace:
    """The QP's buffers (H, c, lb, ub and stacked G, h) over n_u inputs, written in place each step.

    Boxes of `constant_box` limits are intersected once per list of limits, Hessians of `constant_hessian`
    tasks summed once per list of tasks (again when a list changes, or after `reset`).
    The returned arrays are overwritten by the next step.
    """

    def __init__(self, n_u: int) -> None:
        self.H, self.c = np.zeros((n_u, n_u)), np.zeros(n_u)
        self._const_H = np.zeros((n_u, n_u))
        self._tasks: tuple[Task, ...] | None = None  # the tasks `_adders` was built for
        self._adders: list = []  # per-step (s, H, c) -> None calls of the tasks
        self._box = np.empty((2, n_u))  # rows lb, ub
        self.lb, self.ub = self._box[0], self._box[1]
        self._const_box = np.array([np.full(n_u, -np.inf), np.full(n_u, np.inf)])
        self._limits: tuple[Limit, ...] | None = None  # the limits the lists below were sorted for
        self._varying: list[Limit] = []
        self._with_rows: list[Limit] = []
        self.enforcing: list[Limit] = []
        self._G: np.ndarray | None = None
        self._h: np.ndarray | None = None
        self._G_parts: list[np.ndarray] = []

    def reset(self) -> None:
        """Forget the constant Hessians and boxes (read again at the next step)."""
        self._tasks = self._limits = None

    def objective(self, tasks: list[Task], s: StepState) -> tuple[np.ndarray, np.ndarray]:
        """Return (H, c): the constant Hessians, then the other tasks' costs added in task order."""
        if self._tasks is None or not _same_objects(self._tasks, tasks):
            self._refresh_tasks(tasks, s)
        H, c = self.H, self.c
        np.copyto(H, self._const_H)
        c.fill(0.0)
        for add in self._adders:
            add(s, H, c)
        return H, c

    def _refresh_tasks(self, tasks: list[Task], s: StepState) -> None:
        """Sum the constant Hessians once; list the per-step calls."""
        self._tasks = tuple(tasks)
        self._const_H.fill(0.0)
        scratch = np.zeros_like(self.c)
        self._adders = []
        for task in tasks:
            if task.constant_hessian:
                task.add_objective(s, self._const_H, scratch)
                if task.linear:
                    self._adders.append(task.add_linear)
            else:
                self._adders.append(task.add_objective)

    def _check(self, limits: list[Limit], s: StepState) -> None:
        """Re-sort the limits if the list changed."""
        if self._limits is None or not _same_objects(self._limits, limits):
            self._refresh(limits, s)

    def _refresh(self, limits: list[Limit], s: StepState) -> None:
        """Intersect the constant boxes once; sort out the limits read every step."""
        self._limits = tuple(limits)
        lb, ub = self._const_box
        lb.fill(-np.inf)
        ub.fill(np.inf)
        for limit in limits:
            if limit.constant_box:
                limit.intersect_box(s, lb, ub)
        self._varying = [limit for limit in limits if not limit.constant_box]
        self._with_rows = [limit for limit in limits if limit.has_inequality]
        self.enforcing = [limit for limit in limits if limit.enforces]

    def box(self, limits: list[Limit], s: StepState) -> tuple[np.ndarray, np.ndarray]:
        """Return the intersection (lb, ub) of the limits' boxes (see `stack_box`)."""
        self._check(limits, s)
        return self._box_of(s)

    def _box_of(self, s: StepState) -> tuple[np.ndarray, np.ndarray]:
        """`box` of the limits last checked."""
        np.copyto(self._box, self._const_box)
        lb, ub = self.lb, self.ub
        for limit in self._varying:
            limit.intersect_box(s, lb, ub)
        return lb, ub

    def inequalities(
        self, limits: list[Limit], s: StepState, relax: bool = False
    ) -> tuple[np.ndarray | None, np.ndarray | None, bool]:
        """Return (G, h, G unchanged since the previous call) stacking the limits' inequalities, in order.

        G is unchanged when every contributing limit is `constant_inequality` and returned the same
        arrays as at the previous call. A single limit's own arrays are returned (read them only).
        """
        self._check(limits, s)
        return self._inequalities_of(s, relax)

    def _inequalities_of(self, s: StepState, relax: bool) -> tuple[np.ndarray | None, np.ndarray | None, bool]:
        """`inequalities` of the limits last checked."""
        parts = []
        for limit in self._with_rows:
            gh = limit.inequality(s, relax)
            if gh is not None:
                parts.append((limit, gh[0], gh[1]))
        if not parts and not self._G_parts:
            return None, None, True
        G_parts = [p[1] for p in parts]
        same = all(p[0].constant_inequality for p in parts) and _same_objects(G_parts, self._G_parts)
        self._G_parts = G_parts
        if not parts:
            return None, None, same
        if len(parts) == 1:
            return parts[0][1], parts[0][2], same
        m = sum(G.shape[0] for G in G_parts)
        G_all, h_all = self._G, self._h
        if G_all is None or h_all is None or G_all.shape[0] != m:  # (both are allocated together)
            G_all, h_all = self._G, self._h = np.empty((m, self.c.shape[0])), np.empty(m)
        r = 0
        for _, G, h in parts:
            G_all[r : r + G.shape[0]] = G
            h_all[r : r + G.shape[0]] = h
            r += G.shape[0]
        return G_all, h_all, same


def _same_objects(a: Sequence[object], b: Sequence[object]) -> bool:
    """True if the two sequences hold the same objects in the same order (by identity: no `==` called)."""
    return len(a) == len(b) and all(map(operator.is_, a, b))


#: The solvers `SolverChoice` calls directly (any other `qpsolvers` name goes through `qpsolvers.solve_qp`).
DirectSolver = ProxQPSolver | DaqpSolver


@dataclass(frozen=True)
class SolverChoice:
    """Which solvers `solve_step` uses.

    Attributes:
        primary: a `DaqpSolver` or `ProxQPSolver` (called directly), or the name of a `qpsolvers` solver.
        fallback: `qpsolvers` solver tried when the primary returns nothing, or None.
        tolerance: eps_abs of proxqp through `qpsolvers` (other solvers use their defaults).
    """

    primary: DirectSolver | str
    fallback: str | None
    tolerance: float

    def solve(self, H, c, G, h, lb, ub, G_changed: bool = True) -> tuple[np.ndarray | None, bool]:
        """Return (solution or None, True if the fallback produced it); `G_changed` as in `ProxQPSolver.solve`."""
        if isinstance(self.primary, str):
            u = solve_qpsolvers(H, c, G, h, lb, ub, self.primary, self.tolerance)
        else:
            u = self.primary.solve(H, c, G, h, lb, ub, G_changed)
        if u is None and self.fallback is not None:
            u = solve_qpsolvers(H, c, G, h, lb, ub, self.fallback, self.tolerance)
            return u, u is not None
        return u, False


class QPSolution(NamedTuple):
    """Result of `solve_step`: the input and how it was obtained.

    Attributes:
        u: the input (zeros if unsolved), clipped to the box and passed through each limit's `enforce`.
        lb, ub: the box the input satisfies (the workspace's buffers: overwritten by the next step).
        solver_ok: False if every solver failed on every attempt (then u = 0).
        fallback_used: True if the fallback solver produced u.
    """

    u: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    solver_ok: bool
    fallback_used: bool


def solve_step(
    tasks: list[Task], limits: list[Limit], s: StepState, solvers: SolverChoice, workspace: QPWorkspace | None = None
) -> QPSolution:
    """Sum the tasks' costs and stack the limits' constraints (into `workspace`'s buffers), solve, and
    make the limits hold exactly. Without a workspace a fresh one is used (its arrays are then not shared)."""
    ws = QPWorkspace(s.wb.n_u) if workspace is None else workspace
    H, c = ws.objective(tasks, s)
    ws._check(limits, s)
    lb, ub = ws._box_of(s)
    G, h, G_same = ws._inequalities_of(s, False)
    u, fallback_used = solvers.solve(H, c, G, h, lb, ub, not G_same)
    if u is None and any(limit.relaxable for limit in limits):  # once more with u = 0 feasible
        G, h, G_same = ws._inequalities_of(s, True)
        u, fallback_used = solvers.solve(H, c, G, h, lb, ub, not G_same)
    solver_ok = u is not None
    u = np.zeros(s.wb.n_u) if u is None else u
    clip_to_box(u, lb, ub)  # solver tolerance: make the box exact
    for limit in ws.enforcing:
        limit.enforce(u, s)
    return QPSolution(u, lb, ub, solver_ok, fallback_used)

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
* joint torque limits ``|J_i^T w_i| <= tau_max`` when Jacobians are given, or, per control step,
  ``|J_i^T w_i + g_i| <= tau_max`` with each arm's Jacobian and bias torques at its current
  configuration (`WrenchAllocator.set_torque_limits` with `TorqueConstraint`s).

`WrenchAllocator` builds the QP once for a set of contacts and limits (fixed
dimensions and sparsity: only the equality matrix depends on the contact
points) and then solves for a new ``Gamma_MM`` per call (the hot path of a
control loop). With ``solver="proxqp"`` it calls ProxQP's dense solver directly,
initialized once, updated in place and warm-started from the previous solution;
every other backend (or ``direct=False``) goes through `qpsolvers`. An
unconstrained-optimum shortcut (closed-form KKT) is taken when it already
satisfies every inequality, which is then the exact QP optimum;
`WrenchAllocator.closed_form_batch` evaluates that shortcut for many contact
placements and wrenches at once (the vectorized effort sweep of
`wholebody.contacts.placement.effort_sweep`).
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, replace
from functools import lru_cache
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import qpsolvers
import scipy.sparse as sp

from robots.profiles import GRIP_FORCE_RANGE as GRIP_FORCE_RANGE  # the grasp's range (N), the 2F-85's
from wholebody.contacts.handle import ContactSpec, grasp_matrices
from wholebody.contacts.kernels import equality_optimum_effort
from wholebody.contacts.support import CartLoad, SupportPolygon, tip_geometry, tip_rhs
from wholebody.errors import InfeasibleWrenchError, WholeBodyError
from wholebody.qp import ProxQPSolver

if TYPE_CHECKING:
    pass

#: closed-form KKT matrices (Kx, Kl, h_active) of an active set; None: a degenerate active set
KKTEntry = tuple[np.ndarray, np.ndarray, np.ndarray]

#: Components of [f; tau]: index -> short name.
COMPONENTS = ("fx", "fy", "fz", "tau_x", "tau_y", "tau_z")
#: Components used by a planar contact (the others are fixed to zero).
PLANAR_COMPONENTS = (0, 1, 5)
#: qpsolvers backends that want sparse (CSC) matrices.
SPARSE_SOLVERS = ("osqp", "scs", "clarabel", "highs", "piqp", "qpalm", "gurobi", "mosek")
#: ProxQP's absolute tolerance (relative 0): the QP result is then polished on its active set.
PROXQP_EPS_ABS = 1e-9


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

    def with_torque_arm(self, torque_arm: float) -> ArmLimits:
        """Return these limits with the grasp's ``torque_arm`` (m) replaced (the default grasp when there is none)."""
        return replace(self, grasp=replace(self.grasp or GraspModel(), torque_arm=torque_arm))


@dataclass(frozen=True)
class EffortWeights:
    """Weights of the effort: force and torque components, or joint torques; and of the change from a reference.

    ``change`` > 0 adds ``change * (w - w_ref)^T W (w - w_ref)`` to the effort (``W`` the force and torque weights,
    ``w_ref`` the wrenches of `WrenchAllocator.set_reference`: a control loop's last allocation): the directions the
    cart wrench leaves free (the squeeze between hands, a hand's press on the handle, its split between a sideways
    force and a torque) then move from one period to the next by the share ``1 / (1 + change)`` of the way to their
    minimum-effort value where no limit binds (an implicit-Euler lag of time constant ``change`` control periods),
    while the limits and the cart wrench are kept exactly.
    """

    force: float = 1.0
    torque: float = 1.0
    joint: float = 1.0
    change: float = 0.0

    def __post_init__(self) -> None:
        if not (self.force > 0.0 and self.torque > 0.0 and self.joint > 0.0):
            raise WholeBodyError("effort weights must be positive")
        if not (self.change >= 0.0 and math.isfinite(self.change)):
            raise WholeBodyError(f"the change weight must be a finite number >= 0, got {self.change}")


@dataclass(frozen=True)
class AllocationResult:
    """End-effector wrenches (N x 6, each in its {a}), achieved Gamma_MM, residual, effort."""

    wrenches_ee: np.ndarray
    gamma_achieved: np.ndarray
    residual: float
    effort: float
    solver: str
    joint_torques: tuple[np.ndarray, ...] | None = None
    #: the limit that binds when the wrench is not achievable (the label of its QP row), else None
    binding: str | None = None


@dataclass(frozen=True)
class TorqueConstraint:
    """One arm's joint-torque limits as a constraint on its hand wrench w (in {a}): |J^T w + bias| <= limit.

    ``jacobian`` (6 x n): maps the wrench [f; n] the hand applies, in {a} at the contact, to joint torques;
    ``bias`` (n,): the torques with no wrench (gravity and velocity terms, `pinocchio.rnea(q, v, 0)`);
    ``limit`` (n,): the joints' torque limits (URDF effort); ``joints``: their names, for the report.
    """

    jacobian: np.ndarray
    bias: np.ndarray
    limit: np.ndarray
    joints: tuple[str, ...] = ()

    def torques(self, wrench: Sequence[float]) -> np.ndarray:
        """Return the joint torques J^T w + bias of a hand wrench."""
        return self.jacobian.T @ np.asarray(wrench, dtype=float) + self.bias


def _as_contacts(contacts: Sequence) -> list[ContactSpec]:
    out = []
    for c in contacts:
        out.append(c if isinstance(c, ContactSpec) else ContactSpec(tuple(c)))
    if not out:
        raise WholeBodyError("at least one contact is needed")
    return out


# ---------------------------------------------------------------------------------------------- QP structure
def _components(lim: ArmLimits) -> Sequence[int]:
    return PLANAR_COMPONENTS if lim.planar else range(6)


def _free_indices(limits: Sequence[ArmLimits]) -> np.ndarray:
    """Return the indices of the free components in the stacked 6N wrench (planar arms fix fz, tau_x, tau_y)."""
    return np.array([6 * i + k for i, lim in enumerate(limits) for k in _components(lim)])


def _effort_matrix(n: int, weights: EffortWeights, jacobians: list[np.ndarray] | None) -> np.ndarray:
    """Return Q (6N x 6N): effort = w^T Q w, block-diagonal per arm (wrench weights, or w_joint J J^T)."""
    Q = np.zeros((6 * n, 6 * n))
    for i in range(n):
        if jacobians is None:
            Q[6 * i : 6 * i + 3, 6 * i : 6 * i + 3] = weights.force * np.eye(3)
            Q[6 * i + 3 : 6 * i + 6, 6 * i + 3 : 6 * i + 6] = weights.torque * np.eye(3)
        else:
            J = jacobians[i]
            Q[6 * i : 6 * i + 6, 6 * i : 6 * i + 6] = weights.joint * (J @ J.T)
    return Q


class _Inequalities:
    """Rows ``c . w <= h`` over the stacked 6N wrench, each with a label naming the limit."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.rows: list[np.ndarray] = []
        self.rhs: list[float] = []
        self.labels: list[str] = []

    def add(self, entries: dict[int, float], bound: float, label: str) -> None:
        c = np.zeros(6 * self.n)
        for k, v in entries.items():
            c[k] = v
        self.rows.append(c)
        self.rhs.append(bound)
        self.labels.append(label)

    def box(self, i: int, lim: ArmLimits) -> None:
        """Per-component force/torque bounds of arm i."""
        for k in _components(lim):
            bound, unit, kind = (lim.max_force, "N", "force") if k < 3 else (lim.max_torque, "N m", "torque")
            for sgn in (1.0, -1.0):
                self.add(
                    {6 * i + k: sgn},
                    bound,
                    f"arm{i} {kind} bound ({COMPONENTS[k]} {'<=' if sgn > 0 else '>='} {sgn * bound:g} {unit})",
                )

    def grasp(self, i: int, lim: ArmLimits) -> None:
        """Grip pull limit, friction cone and torque limits of arm i's `GraspModel` (normal load 2 Fg + fx)."""
        g = lim.grasp
        if g is None:
            raise WholeBodyError(f"arm{i} has no grasp model to bound")
        self.add(
            {6 * i: -1.0},
            g.pull_capacity,
            f"arm{i} grip pull limit ({g.pull_capacity:g} N at grip force {g.grip_force:g} N)",
        )
        mu, sq = g.friction, 2.0 * g.grip_force
        if lim.planar:
            dirs = [(1.0, 0.0, 1.0), (-1.0, 0.0, 1.0)]
        else:
            ang = 2.0 * np.pi * np.arange(g.facets) / g.facets
            dirs = [(np.cos(a), np.sin(a), np.cos(np.pi / g.facets)) for a in ang]
        for cy, cz, sh in dirs:  # c.f_t <= mu * s * (2 Fg + fx)
            self.add(
                {6 * i + 1: cy, 6 * i + 2: cz, 6 * i: -mu * sh},
                mu * sh * sq,
                f"arm{i} grip friction cone (tangential force, mu={mu:g})",
            )
        for k in (k for k in _components(lim) if k >= 3):
            for sgn in (1.0, -1.0):
                self.add(
                    {6 * i + k: sgn, 6 * i: -g.torque_arm},
                    g.torque_arm * sq,
                    f"arm{i} grip torque limit ({COMPONENTS[k]})",
                )

    def joint_torques(self, i: int, J: np.ndarray, torque_limit: np.ndarray) -> None:
        """``|J_i^T w_i| <= tau_max`` per joint of arm i."""
        tl = np.asarray(torque_limit, dtype=float)
        if tl.shape != (J.shape[1],) or np.any(tl <= 0):
            raise WholeBodyError(f"arm{i} torque limits must be {J.shape[1]} positive numbers")
        for j in range(J.shape[1]):
            for sgn in (1.0, -1.0):
                self.add(
                    {6 * i + k: sgn * J[k, j] for k in range(6)},
                    tl[j],
                    f"arm{i} joint {j} torque limit ({tl[j]:g} N m)",
                )


def _torque_rows(
    n: int, constraints: Sequence[TorqueConstraint | None], margin: float
) -> tuple[np.ndarray, np.ndarray, list[str], list[str]]:
    """Return (rows over the stacked 6N wrench, right-hand sides, labels, joints whose bias alone exceeds its limit).

    ``|J^T w + g| <= (1 - margin) tau_max`` is ``+-J_j . w <= (1 - margin) tau_max_j -+ g_j`` per joint; a
    right-hand side below 0 (the bias alone breaks the limit) is held at 0 so that w = 0 stays feasible.
    """
    rows: list[np.ndarray] = []
    rhs: list[np.ndarray] = []
    labels: list[str] = []
    over: list[str] = []
    for i, c in enumerate(constraints):
        if c is None:
            continue
        J = np.asarray(c.jacobian, dtype=float)
        g = np.asarray(c.bias, dtype=float)
        lim = np.asarray(c.limit, dtype=float)
        if J.ndim != 2 or J.shape[0] != 6 or g.shape != (J.shape[1],) or lim.shape != (J.shape[1],):
            raise WholeBodyError(f"arm{i} torque constraint: jacobian must be 6 x n with n biases and limits")
        if (lim <= 0).any() or not (np.isfinite(J).all() and np.isfinite(g).all()):
            raise WholeBodyError(f"arm{i} torque limits must be positive and the Jacobian and bias finite")
        names = c.joints if len(c.joints) == J.shape[1] else tuple(f"joint {j}" for j in range(J.shape[1]))
        cap = (1.0 - margin) * lim
        over += [f"arm{i} {names[j]}" for j in np.flatnonzero(np.abs(g) > cap)]
        block = np.zeros((2 * J.shape[1], 6 * n))  # per joint j: the row of +J_j, then of -J_j
        block[0::2, 6 * i : 6 * i + 6] = J.T
        block[1::2, 6 * i : 6 * i + 6] = -J.T
        rows.append(block)
        rhs.append(np.maximum(np.column_stack((cap - g, cap + g)).reshape(-1), 0.0))
        labels += _torque_labels(i, tuple(names), tuple(lim.tolist()))
    if not rows:
        return np.zeros((0, 6 * n)), np.zeros(0), labels, over
    return np.vstack(rows), np.concatenate(rhs), labels, over


@lru_cache(maxsize=64)
def _torque_labels(i: int, names: tuple[str, ...], limits: tuple[float, ...]) -> list[str]:
    """Return the two rows' labels of each joint of arm i (`_torque_rows`); the caller copies them."""
    return [f"arm{i} {name} torque limit ({lim:g} N m)" for name, lim in zip(names, limits) for _ in (1.0, -1.0)]


def _inequalities(
    limits: Sequence[ArmLimits], jacobians: list[np.ndarray] | None, torque_limits: Sequence[np.ndarray] | None
) -> _Inequalities:
    """Return every limit row of the allocation QP (boxes, grasp model, joint torques), arm by arm."""
    out = _Inequalities(len(limits))
    for i, lim in enumerate(limits):
        out.box(i, lim)
        if lim.grasp is not None:
            out.grasp(i, lim)
        if torque_limits is not None:
            if jacobians is None:
                raise WholeBodyError("joint torque limits need the arms' Jacobians")
            out.joint_torques(i, jacobians[i], torque_limits[i])
    return out


class WrenchAllocator:
    """The wrench allocation QP for fixed limits, built once; `set_points` moves the contacts, `solve` per step."""

    #: active set -> its closed-form KKT matrices (None: degenerate), cleared by `set_points`
    _kkt_cache: dict[tuple[int, ...], KKTEntry | None]
    #: qpsolvers' matrices (dense, or CSC for a sparse backend), built when first needed
    _mats: dict[str, np.ndarray | sp.csc_matrix] | None

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
        direct: bool = True,
    ) -> None:
        """``direct``: with ``solver="proxqp"``, call ProxQP's dense API (warm-started) rather than qpsolvers."""
        specs = _as_contacts(contacts)
        n = len(specs)
        self._names = [c.name for c in specs]
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
        self._direct = ProxQPSolver(PROXQP_EPS_ABS) if solver == "proxqp" and direct else None
        self._points: np.ndarray = np.full((n, 3), np.nan)  # none yet: `set_points` builds the matrices
        self.set_points([c.point_b for c in specs])

    # ------------------------------------------------------------------ build
    def _build(self, torque_limits: Sequence[np.ndarray] | None) -> None:
        """Build the point-independent parts: free components, cost P, inequalities Gin x <= hin."""
        n = len(self._names)
        self.free = _free_indices(self.limits)
        nx = len(self.free)
        self.E = np.zeros((6 * n, nx))
        self.E[self.free, np.arange(nx)] = 1.0
        w = self.weights
        self.Q = _effort_matrix(n, w, self.jacobians)
        diag = np.diag(np.tile(np.r_[[w.force] * 3, [w.torque] * 3], n))
        reg = diag * (1e-9 if self.jacobians is not None else 0.0)
        #: the change term's weights on the free components (`EffortWeights.change`)
        self._W_change = w.change * (self.E.T @ diag @ self.E)
        self.P = 2.0 * (self.E.T @ (self.Q + reg) @ self.E + self._W_change)
        self._Pinv = np.linalg.inv(self.P)
        self._Q_free = self.E.T @ self.Q @ self.E  # effort = x^T Q_free x on the free components
        self._active: tuple[int, ...] = ()  # active limits of the last QP solution (the shortcut's guess)
        self.q = np.zeros(nx)
        #: the cost's unconstrained minimum -P^-1 q (zero without a reference): the closed forms are taken about it
        self._x0 = np.zeros(nx)
        rows = _inequalities(self.limits, self.jacobians, torque_limits)
        self._static = (np.array(rows.rows) @ self.E, np.array(rows.rhs), list(rows.labels))
        self.torque_constraints: tuple[TorqueConstraint | None, ...] = ()
        #: arms' joints whose bias torque alone exceeds its limit at the last `set_torque_limits`
        self.bias_over_limit: tuple[str, ...] = ()
        self._torque_part: tuple[np.ndarray, np.ndarray, list[str]] | None = None
        self._tip_part: tuple[np.ndarray, np.ndarray, list[str]] | None = None
        #: `set_tip_bound`'s load-free part: (support, contact points' bytes, rows over x, labels, hands inside)
        self._tip_geometry: tuple[SupportPolygon, bytes, np.ndarray, list[str], np.ndarray] | None = None
        self._set_inequalities(*self._static)
        col = {int(k): j for j, k in enumerate(self.free)}  # stacked-wrench index -> free-variable index
        self._fx_cols = np.array([col[6 * i] for i in range(n)])
        self._fy_cols = np.array([col[6 * i + 1] for i in range(n)])
        self._A_template = self._equality_batch(np.zeros((1, n, 3)))[1][0]  # tau row: lever arms filled per call

    def _set_inequalities(self, Gin: np.ndarray, hin: np.ndarray, labels: list[str]) -> None:
        """Take the limit rows Gin x <= hin (free components) and their labels; derived tolerances and caches."""
        self.Gin, self.hin, self.labels = Gin, hin, labels
        slack = np.maximum(1.0, np.abs(self.hin))
        self._h_exact = self.hin + 1e-12 * slack  # the closed form is the QP optimum within this
        self._h_ok = self.hin + 1e-6 * slack  # a QP result within this is accepted
        self._h_polish = self.hin + 1e-9 * slack  # a polished solution within this is kept
        self._h_active = self.hin - 1e-7 * slack  # rows of a QP result taken as active
        self._G_conv = sp.csc_matrix(self.Gin) if self.solver in SPARSE_SOLVERS else self.Gin

    def set_reference(self, wrenches_ee: npt.ArrayLike | None) -> None:
        """Take the wrenches (N x 6, each in its {a}: a loop's last `AllocationResult.wrenches_ee`) the change term
        of `EffortWeights.change` pulls toward; None drops the reference (the minimum-effort allocation)."""
        nx = len(self.free)
        if wrenches_ee is None or not self.weights.change:
            self.q, self._x0 = np.zeros(nx), np.zeros(nx)
            return
        w = np.asarray(wrenches_ee, dtype=float).reshape(-1)
        if w.shape != (6 * len(self._names),) or not np.isfinite(w).all():
            raise WholeBodyError(
                f"the reference must be {len(self._names)} finite wrenches of 6 numbers, got {w.shape}"
            )
        self.q = -2.0 * self._W_change @ w[self.free]
        self._x0 = -self._Pinv @ self.q

    def set_torque_limits(
        self, constraints: Sequence[TorqueConstraint | None], margin: float = 0.0, stack: bool = True
    ) -> None:
        """Bound each arm's joint torques at its current configuration: |J_i^T w_i + g_i| <= (1 - margin) tau_max.

        One `TorqueConstraint` per contact (None: that arm's joints unbounded); call it every control step
        with the arms' Jacobians and bias torques (`wholebody.push.robot.MobileManipulator.torque_constraint`).
        The rows replace those of the previous call; ``margin`` (0..1) keeps room for the dynamic terms the
        bias leaves out. A joint whose bias alone exceeds its limit is listed in `bias_over_limit` (its row
        then allows no wrench that adds to the excess). An unachievable wrench's `AllocationResult.binding`
        names the joint limit that binds (``"arm0 arm_5_joint torque limit (3 N m)"``). ``stack=False`` leaves the
        QP's rows as they were until the next `set_tip_bound` (which the caller then must make) takes these.
        """
        n = len(self._names)
        if len(constraints) != n:
            raise WholeBodyError(f"{len(constraints)} torque constraints given for {n} contacts")
        if not 0.0 <= margin < 1.0:
            raise WholeBodyError(f"torque margin must be in [0, 1), got {margin}")
        rows, rhs, labels, over = _torque_rows(n, constraints, margin)
        self.torque_constraints = tuple(constraints)
        self.bias_over_limit = tuple(over)
        self._torque_part = (rows @ self.E, rhs, labels)
        if stack:
            self._stack_inequalities()

    def set_tip_bound(self, support: SupportPolygon | None, load: CartLoad | None = None) -> None:
        """Keep every support contact of the cart loaded (`wholebody.contacts.support.tip_rows`), or drop the bound.

        ``support``: the cart's floor contacts (None: no bound); ``load``: its estimated mass, CoM and CoM
        acceleration now. Uses the current contact points: call it after `set_points`, every control step. A
        planar arm (`ArmLimits.planar`) can only push sideways less; a spatial one may also press down on the
        handle to hold the cart on the edge it would roll over.
        """
        if support is None or load is None:
            self._tip_part = None
        else:
            key = self._points.tobytes()
            if self._tip_geometry is None or self._tip_geometry[0] is not support or self._tip_geometry[1] != key:
                rows, labels, inside = tip_geometry(support, self._points)  # the same at the same points
                self._tip_geometry = (support, key, rows @ self.E, labels, inside)
            rows_e, labels, inside = self._tip_geometry[2:]
            self._tip_part = (rows_e, tip_rhs(support, load, inside), labels)
        self._stack_inequalities()

    @contextmanager
    def tip_bound_kept(self) -> Iterator[None]:
        """Within: `set_tip_bound` may be called for probes (a motion ahead); after: the tip-over rows as before."""
        saved = self._tip_part
        try:
            yield
        finally:
            self._tip_part = saved
            self._stack_inequalities()

    def _stack_inequalities(self) -> None:
        """Take the static limit rows, the joint-torque rows and the tip-over rows as the QP's inequalities."""
        parts = [p for p in (self._static, self._torque_part, self._tip_part) if p is not None]
        labels = [lab for p in parts for lab in p[2]]
        same_rows = labels == self.labels  # the same limits with new values: the last active set stays a guess
        self._set_inequalities(np.vstack([p[0] for p in parts]), np.concatenate([p[1] for p in parts]), labels)
        self._kkt_cache = {(): self._kkt_cache[()]} if hasattr(self, "_kkt_cache") else {}
        self._active = self._active if same_rows else ()
        self._mats = None
        if self._direct is not None:  # new inequalities: the next solve starts cold on them
            self._direct.reset()
            self._A_new = True

    def _equality_batch(self, points_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return (G_full (M, 3, 6N), A (M, r, nx)) of the equality rows for contact sets points_b (M, N, 3)."""
        G = grasp_matrices(points_b)  # paper eq. (25)
        return G, G[:, self.rows][:, :, self.free]

    @property
    def contacts(self) -> list[ContactSpec]:
        """Return the current contacts (points in {b}, names)."""
        return [ContactSpec(tuple(p), name) for p, name in zip(self._points.tolist(), self._names)]

    def set_points(self, points_b: Sequence[npt.ArrayLike]) -> None:
        """Move the contacts to points_b (N x 3 in {b}); the limits and the cost are unchanged."""
        pts = np.array(points_b, dtype=float)
        if pts.shape != (len(self._names), 3):
            raise WholeBodyError(f"{len(points_b)} points given for {len(self._names)} contacts (3 numbers each)")
        if not np.isfinite(pts).all():
            raise WholeBodyError(f"contact points must be finite, got {points_b!r}")
        if np.array_equal(pts, self._points):  # the same matrices as before
            self._kkt_cache = {(): self._kkt_cache[()]}
        else:
            self._points = pts
            G, A = self._equality_batch(pts[None])
            self.G_full, self.A = G[0], A[0]
            Pinv_At = self._Pinv @ self.A.T  # closed-form optimum of the equality-only problem: x = K b
            K = Pinv_At @ np.linalg.inv(self.A @ Pinv_At)
            self._kkt_cache = {(): (K, np.zeros((0, len(self.rows))), np.zeros(0))}
        self._A_new = True  # the direct QP takes the new equality matrix at its next solve
        self._mats = None  # qpsolvers' matrices, built when first needed

    def _qpsolvers_mats(self) -> dict[str, np.ndarray | sp.csc_matrix]:
        if self._mats is None:
            conv = sp.csc_matrix if self.solver in SPARSE_SOLVERS else (lambda M: M)
            relax_scale = self._relax_scale()
            self._mats = dict(
                P=conv(self.P),
                G=self._G_conv,
                A=conv(self.A),
                relax_P=conv(self.P / relax_scale + 2.0 * self.A.T @ self.A),
            )
        return self._mats

    # ------------------------------------------------------------------ batch
    def closed_form_batch(self, points_b: np.ndarray, gammas: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the equality-only optimum for every contact set and wrench at once.

        ``points_b``: (M, N, 3) contact sets; ``gammas``: (T, 3). Returns ``x`` (M, T, nx), ``exact``
        (M, T): where it satisfies every limit (then it is the QP optimum, as in `solve`), and its effort
        (M, T): the effort of the QP optimum where exact, a lower bound on it elsewhere (no joint-torque
        weights).
        """
        self._check_no_change_term("closed_form_batch")
        _, A = self._equality_batch(np.asarray(points_b, dtype=float))
        Pinv_At = self._Pinv @ np.swapaxes(A, 1, 2)  # (M, nx, r)
        B = np.asarray(gammas, dtype=float)[:, self.rows].T  # (r, T)
        X = np.swapaxes(Pinv_At @ np.linalg.solve(A @ Pinv_At, B), 1, 2)
        exact = np.all(X @ self.Gin.T <= self._h_exact, axis=-1)
        return X, exact, np.sum((X @ self._Q_free) * X, axis=-1)

    def closed_form_effort(self, points_b: np.ndarray, gamma: np.ndarray) -> float | None:
        """Return the effort of the equality-only optimum at contacts points_b (N, 3) if it keeps every limit.

        One problem of `closed_form_batch` without the batch's overhead (the hot call of a local search): the
        equality matrix is the cached one with the torque row's lever arms (-p_y, p_x; eq. 24) filled in.
        None when the closed form breaks a limit or A P^-1 A^T is not positive definite (the QP is needed).
        """
        self._check_no_change_term("closed_form_effort")
        effort, ok = equality_optimum_effort(
            self._A_template,
            self._fx_cols,
            self._fy_cols,
            np.asarray(points_b, dtype=float),
            self._Pinv,
            np.asarray(gamma, dtype=float)[self.rows],
            self.Gin,
            self._h_exact,
            self._Q_free,
        )
        return effort if ok else None

    def _check_no_change_term(self, name: str) -> None:
        if self.weights.change:
            raise WholeBodyError(f"{name} gives minimum-effort allocations: build the allocator with change = 0")

    # ------------------------------------------------------------------ solve
    def _relax_scale(self) -> float:
        """Return the factor the effort is divided by in the closest-wrench QP (`_closest`)."""
        return 1e6 * max(1.0, float(np.max(np.diag(self.P))))

    def _solver_kwargs(self) -> dict:
        if self.solver == "proxqp":
            return dict(eps_abs=PROXQP_EPS_ABS, eps_rel=0.0)
        if self.solver == "osqp":
            return dict(eps_abs=1e-9, eps_rel=1e-9, polish=True, max_iter=20000, verbose=False)
        return {}

    def _qp(self, b: np.ndarray) -> np.ndarray | None:
        """Return the QP solution for right-hand side b (None when the solver fails)."""
        if self._direct is not None:
            # the cost's linear term moves with the reference: the solver then starts cold on it
            fresh = self._A_new or bool(self.weights.change)
            x = self._direct.solve_equality(self.P, self.q, self.A, b, self.Gin, self.hin, fresh)
            self._A_new = False
        else:
            m = self._qpsolvers_mats()
            sol = qpsolvers.solve_problem(
                qpsolvers.Problem(m["P"], self.q, m["G"], self.hin, m["A"], b),
                solver=self.solver,
                **self._solver_kwargs(),
            )
            x = sol.x if sol.found else None
        return x if x is not None and np.isfinite(x).all() else None

    def _kkt(self, active: tuple[int, ...]) -> KKTEntry | None:
        """Return (Kx, Kl, h_active) of the equality-constrained QP with rows ``active`` of Gin held tight.

        With ``A_eq = [A; G_active]``, ``b_eq = [b; h_active]`` and ``S = A_eq P^-1 A_eq^T`` (q = 0), the KKT
        point is ``x = Kx b_eq``, ``Kx = P^-1 A_eq^T S^-1``, with multipliers ``lambda = Kl b_eq``,
        ``Kl = -(S^-1)[n_eq:]`` of the active rows; it is the QP optimum when x satisfies every limit and
        lambda >= 0. None for a degenerate active set (dependent rows). Cached until `set_points`.
        """
        if active in self._kkt_cache:
            return self._kkt_cache[active]
        idx = list(active)
        Aeq = np.vstack([self.A, self.Gin[idx]])
        entry: KKTEntry | None = None
        if Aeq.shape[0] <= Aeq.shape[1]:
            Pinv_At = self._Pinv @ Aeq.T
            S = Aeq @ Pinv_At
            try:
                T = np.linalg.inv(S)
            except np.linalg.LinAlgError:
                T = None
            if T is not None and np.abs(S @ T - np.eye(len(S))).max() < 1e-9:  # not numerically degenerate
                entry = (Pinv_At @ T, -T[len(self.rows) :], self.hin[idx])
        self._kkt_cache[active] = entry
        return entry

    def _on_active_set(
        self, b: np.ndarray, active: tuple[int, ...], h_max: np.ndarray, scale: float
    ) -> np.ndarray | None:
        """Return the KKT point of ``active`` if it is the QP optimum (limits within h_max, lambda >= 0)."""
        entry = self._kkt(active)
        if entry is None:
            return None
        Kx, Kl, h_act = entry
        beq = np.concatenate([b, h_act]) if active else b
        if self.weights.change:  # about the cost's unconstrained minimum x0: x = x0 + Kx (b_eq - A_eq x0)
            x0 = self._x0
            beq = beq - (np.concatenate([self.A @ x0, self.Gin[list(active)] @ x0]) if active else self.A @ x0)
            x = x0 + Kx @ beq
        else:
            x = Kx @ beq
        if (self.Gin @ x <= h_max).all() and (not active or (Kl @ beq >= -1e-9 * scale).all()):
            return x
        return None

    def _shortcut(self, b: np.ndarray, scale: float) -> tuple[np.ndarray, str] | None:
        """Return the exact optimum from the closed form, or on the last QP's active set, if either certifies."""
        x = self._on_active_set(b, (), self._h_exact, scale)
        if x is not None:
            return x, "closed-form"
        if self._active:
            x = self._on_active_set(b, self._active, self._h_exact, scale)
            if x is not None:
                return x, "active-set"
        return None

    def _polish(self, x: np.ndarray, b: np.ndarray, scale: float) -> np.ndarray:
        """Return the exact KKT point on the active set of the QP result x (x itself if that does not certify).

        A degenerate active set (dependent rows) falls back to least squares on the full KKT system when x
        misses the equality by more than 1e-11 scale.
        """
        active = tuple(np.flatnonzero(self.Gin @ x >= self._h_active).tolist())
        sol = self._on_active_set(b, active, self._h_polish, scale)
        if sol is not None:
            self._active = active
            return sol if np.abs(self.A @ sol - b).max() <= 1e-11 * scale else x
        if np.abs(self.A @ x - b).max() <= 1e-11 * scale:
            return x
        Aeq = np.vstack([self.A, self.Gin[list(active)]])
        nx, m = self.P.shape[0], Aeq.shape[0]
        K = np.zeros((nx + m, nx + m))
        K[:nx, :nx], K[:nx, nx:], K[nx:, :nx] = self.P, Aeq.T, Aeq
        sol = np.linalg.lstsq(K, np.r_[-self.q, b, self.hin[list(active)]], rcond=None)[0][:nx]
        if (self.Gin @ sol <= self._h_polish).all() and np.abs(self.A @ sol - b).max() <= 1e-11 * scale:
            return sol
        return x

    def _polish_relaxed(self, x: np.ndarray, P: np.ndarray | sp.csc_matrix, q: np.ndarray) -> np.ndarray:
        """Return the exact KKT point of the closest-wrench QP (min x'Px/2 + q'x, Gin x <= hin) on the active set of
        its solution x, or x itself when that point is not the optimum (a limit broken or a negative multiplier).

        Besides the accuracy, this makes the answer a function of the QP alone: ProxQP's last bits depend on the
        process's heap (the same problem solved 40 times after other allocations gives two answers 7e-15 apart),
        and a saturated closed loop amplifies that into runs that cannot be repeated.
        """
        active = np.flatnonzero(self.Gin @ x >= self._h_active)
        P = sp.csc_matrix(P).toarray()  # dense or sparse alike (a few variables)
        n, m = len(x), len(active)
        K = np.zeros((n + m, n + m))
        K[:n, :n], K[:n, n:], K[n:, :n] = P, self.Gin[active].T, self.Gin[active]
        try:
            sol = np.linalg.solve(K, np.concatenate([-q, self.hin[active]]))
        except np.linalg.LinAlgError:  # dependent active rows
            return x
        p, lam = sol[:n], sol[n:]
        scale = max(1.0, float(np.abs(lam).max(initial=0.0)))
        if np.isfinite(sol).all() and (self.Gin @ p <= self._h_polish).all() and (lam >= -1e-9 * scale).all():
            return p
        return x

    def _result(self, x: np.ndarray, gamma: np.ndarray, solver: str) -> AllocationResult:
        w_full = self.E @ x
        achieved = self.G_full @ w_full
        d = achieved[self.rows] - gamma[self.rows]
        residual = math.sqrt(d @ d)  # = np.linalg.norm(d)
        effort = float(w_full @ self.Q @ w_full)
        W = w_full.reshape(-1, 6)
        taus = None if self.jacobians is None else tuple(J.T @ W[i] for i, J in enumerate(self.jacobians))
        if taus is None and self.torque_constraints:
            taus = tuple(np.zeros(0) if c is None else c.torques(W[i]) for i, c in enumerate(self.torque_constraints))
        return AllocationResult(W, achieved, residual, effort, solver, taus)

    def optimum(self, gamma_b: npt.ArrayLike) -> AllocationResult | None:
        """Return the minimum-effort allocation of gamma_b, or None when the QP finds none (no closest-wrench QP).

        The same result as `solve` whenever gamma_b is achievable; for a search that only needs to know
        that a request is not achievable (contact placement), not by how much.
        """
        return self._solve(gamma_b, False, closest=False)

    def solve(self, gamma_b: npt.ArrayLike, raise_on_infeasible: bool = True) -> AllocationResult:
        """Return the minimum-effort wrenches producing gamma_b = (fx, fy, tau) in {b}.

        Raises `InfeasibleWrenchError` (binding limit, closest achievable wrench)
        if no wrench within the limits produces it, unless ``raise_on_infeasible``
        is False: then the closest achievable allocation is returned.
        """
        res = self._solve(gamma_b, raise_on_infeasible, closest=True)
        if res is None:  # _solve with closest=True returns the closest allocation or raises
            raise WholeBodyError(f"no allocation returned for cart wrench {gamma_b!r}")
        return res

    def _solve(self, gamma_b: npt.ArrayLike, raise_on_infeasible: bool, closest: bool) -> AllocationResult | None:
        """`solve`; with ``closest=False`` None instead of the closest allocation of an unachievable wrench."""
        gamma = np.array(gamma_b, dtype=float).reshape(-1)
        values = gamma.tolist()
        if len(values) != 3 or not all(map(math.isfinite, values)):
            raise WholeBodyError(f"cart wrench must be 3 finite numbers (fx, fy, tau), got {gamma_b!r}")
        b = gamma[self.rows]
        scale = max(1.0, abs(values[0]), abs(values[1]), abs(values[2]))
        b_scale = max(1.0, float(np.abs(b).max()))
        hot = self._shortcut(b, b_scale) if self.fast_path else None
        if hot is not None:
            return self._result(hot[0], gamma, hot[1])
        x = self._qp(b)
        if x is not None:
            x = self._polish(x, b, b_scale)
            res = self._result(x, gamma, self.solver)
            if res.residual <= 1e-7 * scale and (self.Gin @ x <= self._h_ok).all():
                return res
        if not closest:
            return None
        return self._closest(gamma, b, 1e-7 * scale, raise_on_infeasible)

    def _closest(self, gamma: np.ndarray, b: np.ndarray, tol: float, raise_on_infeasible: bool) -> AllocationResult:
        """Solve min |A x - b|^2 + effort / rho under the limits (rho large); raise or return it."""
        m = self._qpsolvers_mats()
        problem = qpsolvers.Problem(m["relax_P"], self.q / self._relax_scale() - 2.0 * self.A.T @ b, m["G"], self.hin)
        # x = 0 is feasible, so a failure is numerical: retry with the active-set solver daqp (a runtime dependency)
        for solver in dict.fromkeys((self.solver, "daqp")):
            sol = qpsolvers.solve_problem(
                problem, solver=solver, **(self._solver_kwargs() if solver == self.solver else {})
            )
            if sol.found and sol.x is not None and np.isfinite(sol.x).all():
                break
        else:
            raise InfeasibleWrenchError(
                f"the QP solvers {self.solver} and daqp failed on the relaxed allocation of ({gamma[0]:.4g}, "
                f"{gamma[1]:.4g}, {gamma[2]:.4g}); check the arm limits and the contact points",
                binding="solver",
            )
        x = self._polish_relaxed(sol.x, problem.P, problem.q)
        res = self._result(x, gamma, self.solver)
        if res.residual <= tol:
            return res  # the first solve only stalled
        z = np.zeros(len(self.hin)) if sol.z is None else np.asarray(sol.z)
        slack = self.hin - self.Gin @ x
        score = np.where(slack <= 1e-5 * np.maximum(1.0, np.abs(self.hin)), np.abs(z) + 1e-12, 0.0)
        binding = self.labels[int(np.argmax(score))] if np.any(score > 0) else "unknown"
        if not raise_on_infeasible:
            return replace(res, binding=binding)
        closest = res.gamma_achieved
        raise InfeasibleWrenchError(
            f"cart wrench (fx, fy, tau) = ({gamma[0]:.4g}, {gamma[1]:.4g}, {gamma[2]:.4g}) is not achievable: "
            f"{binding} binds; closest achievable is ({closest[0]:.4g}, {closest[1]:.4g}, {closest[2]:.4g})",
            binding=binding,
            closest=tuple(float(v) for v in closest),
        )


def allocate(
    gamma_b: npt.ArrayLike,
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


@dataclass(frozen=True)
class SaturationSpan:
    """A stretch of consecutive control periods over which one limit kept the allocation from the desired wrench."""

    #: the binding limit's label (`AllocationResult.binding`)
    limit: str
    #: first and last sample time (s)
    start: float
    end: float
    #: number of periods
    steps: int
    #: duration (s): steps x dt
    duration: float

    def as_dict(self) -> dict:
        """Return the span as a JSON-ready dict."""
        return {
            "limit": self.limit,
            "start_s": self.start,
            "end_s": self.end,
            "steps": self.steps,
            "duration_s": self.duration,
        }


def saturation_spans(t: npt.ArrayLike, binding: Sequence[str | None], dt: float) -> tuple[SaturationSpan, ...]:
    """Return the stretches of consecutive samples with the same binding limit (None: not saturated), in time order."""
    t = np.asarray(t, dtype=float)
    spans: list[SaturationSpan] = []
    start = None
    for k, label in enumerate(list(binding) + [None]):
        prev = binding[start] if start is not None else None
        if start is not None and label != prev:
            n = k - start
            spans.append(SaturationSpan(str(prev), float(t[start]), float(t[k - 1]), n, n * float(dt)))
            start = None
        if label is not None and start is None:
            start = k
    return tuple(spans)


def saturation_summary(spans: Sequence[SaturationSpan]) -> dict[str, dict]:
    """Return per binding limit: total time (s), number of spans and the longest span (s) -- "which limit binds,
    where and for how long"."""
    out: dict[str, dict] = {}
    for s in spans:
        e = out.setdefault(s.limit, {"total_s": 0.0, "spans": 0, "longest_s": 0.0, "first_s": s.start})
        e["total_s"] += s.duration
        e["spans"] += 1
        e["longest_s"] = max(e["longest_s"], s.duration)
    return out

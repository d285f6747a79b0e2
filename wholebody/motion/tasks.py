"""Cost terms (`Task`s) of the resolved-rate QP: end-effector pose, damping, posture, manipulability, base.

Each returns (H, c) of ``1/2 u^T H u + c^T u`` over ``u = [arm rates, base input]`` (see `wholebody.motion.qp`);
the factor 1/2 is the solver's, so a task ``w ||A u - b||^2`` contributes ``H = w A^T A, c = -w A^T b``.
`add_objective` adds the same terms in place into the controller's buffers (what the controller calls).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wholebody.errors import WholeBodyError
from wholebody.motion.kernels import add_scaled_difference, add_weighted_gram, pose_difference, reference_twist
from wholebody.motion.kinematics import WholeBody
from wholebody.motion.qp import StepState, Task


def pose_error(T: pin.SE3, T_des: pin.SE3) -> np.ndarray:
    """Return the world-aligned error [p_d - p, log3(R_d R^T)] (6,)."""
    e, R = pose_difference(T.homogeneous, T_des.homogeneous)
    e[3:] = pin.log3(R)
    return e


def manipulability(wb: WholeBody, x: npt.ArrayLike) -> float:
    """Return the arm's manipulability sqrt(det(J_arm J_arm^T)) at x."""
    J = wb.combined_jacobian(x)[:, : wb.n_arm]
    return float(np.sqrt(max(np.linalg.det(J @ J.T), 0.0)))


def manipulability_gradient(wb: WholeBody, x: npt.ArrayLike, eps: float = 1e-6) -> np.ndarray:
    """Return d manipulability / d q_arm by central differences (n_arm,)."""
    x = np.asarray(x, dtype=float)
    g = np.zeros(wb.n_arm)
    for i in range(wb.n_arm):
        dx = np.zeros_like(x)
        dx[3 + i] = eps
        g[i] = (manipulability(wb, x + dx) - manipulability(wb, x - dx)) / (2 * eps)
    return g


class _DiagonalView:
    """Writable views, cached per buffer, of the first k diagonal entries of an n x n C-contiguous matrix."""

    def __init__(self, k: int) -> None:
        self.k = k
        self._buffer: np.ndarray | None = None
        self._view: np.ndarray | None = None

    def __call__(self, H: np.ndarray) -> np.ndarray:
        view = self._view
        if H is not self._buffer or view is None:  # (view is None only before the first buffer)
            n = H.shape[0]
            view = H.reshape(-1)[: self.k * (n + 1) : n + 1]
            if not np.shares_memory(view, H):
                raise WholeBodyError("add_objective needs a C-contiguous n_u x n_u Hessian buffer")
            self._buffer, self._view = H, view
        return view


class EndEffectorTask(Task):
    """||J u - v_ref||_W^2: track the commanded end-effector twist (paper eq. 21), W = diag(weights)."""

    def __init__(self, weights: Sequence[float]) -> None:
        self.weights = weights

    @property
    def weights(self) -> np.ndarray:
        """Task weights (6,): [position x3, orientation x3] (read-only array: assign new weights to change them)."""
        return self._weights

    @weights.setter
    def weights(self, value: Sequence[float]) -> None:
        weights = np.array(value, dtype=float)
        if weights.shape != (6,):
            raise WholeBodyError(f"end-effector task weights must have 6 entries, got shape {weights.shape}")
        weights.flags.writeable = False
        self._weights = weights

    def objective(self, s: StepState) -> tuple[np.ndarray, np.ndarray]:
        n = _jacobian_and_twist(s)[0].shape[1]
        H, c = np.zeros((n, n)), np.zeros(n)
        self.add_objective(s, H, c)
        return H, c

    def add_objective(self, s: StepState, H: np.ndarray, c: np.ndarray) -> None:
        J, v_ref = _jacobian_and_twist(s)
        add_weighted_gram(J, self._weights, v_ref, H, c)


def _jacobian_and_twist(s: StepState) -> tuple[np.ndarray, np.ndarray]:
    """Return (J, v_ref) of the step; raise WholeBodyError if the step state lacks them."""
    J, v_ref = s.J, s.v_ref
    if J is None or v_ref is None:
        raise WholeBodyError("the end-effector task needs the step's Jacobian J and commanded twist v_ref")
    return J, v_ref


class DampingTask(Task):
    """damping ||u||^2 (Levenberg damping: keeps singular steps bounded).

    Its Hessian is `constant_hessian`: call `QPWorkspace.reset` after changing `damping` between steps.
    """

    constant_hessian = True
    linear = False

    def __init__(self, n_u: int, damping: float) -> None:
        self.damping = damping
        self._H = damping * np.eye(n_u)
        self._diag = _DiagonalView(n_u)

    def objective(self, s: StepState) -> tuple[np.ndarray, None]:
        return self._H, None

    def add_objective(self, s: StepState, H: np.ndarray, c: np.ndarray) -> None:
        d = self._diag(H)
        d += self.damping


class PostureTask(Task):
    """weight ||q_dot - gain (posture - q)||^2 over the arm rates (pulls the arm to `posture`).

    `posture` None: the task is off until set (the controller sets it to the first state's arm posture).
    Once set, its Hessian is `constant_hessian`: call `QPWorkspace.reset` after changing `weight` or setting
    `posture` back to None between steps (`ResolvedRateController.posture` does so).
    """

    def __init__(self, wb: WholeBody, weight: float, gain: float, posture: npt.ArrayLike | None = None) -> None:
        self.weight, self.gain = weight, gain
        self._n_arm, self._n_u = wb.n_arm, wb.n_u
        self.posture = posture
        self._diag = _DiagonalView(wb.n_arm)

    @property
    def posture(self) -> np.ndarray | None:
        """The arm posture pulled to (n_arm,), or None (task off)."""
        return self._posture

    @posture.setter
    def posture(self, value: npt.ArrayLike | None) -> None:
        if value is None:
            self._posture = None
            return
        posture = np.asarray(value, dtype=float)
        if posture.shape != (self._n_arm,):
            raise WholeBodyError(f"posture must have {self._n_arm} arm joint values, got shape {posture.shape}")
        self._posture = posture

    def objective(self, s: StepState) -> tuple[np.ndarray | None, np.ndarray | None]:
        if self.posture is None:
            return None, None
        H, c = np.zeros((self._n_u, self._n_u)), np.zeros(self._n_u)
        self.add_objective(s, H, c)
        return H, c

    @property
    def constant_hessian(self) -> bool:
        """True once `posture` is set (then the Hessian is weight on the arm's diagonal)."""
        return self.posture is not None

    def add_objective(self, s: StepState, H: np.ndarray, c: np.ndarray) -> None:
        if self.posture is None:
            return
        self.add_linear(s, H, c)
        d = self._diag(H)
        d += self.weight

    def add_linear(self, s: StepState, H: np.ndarray, c: np.ndarray) -> None:
        if self.posture is None:
            return
        add_scaled_difference(c, -self.weight * self.gain, self.posture, s.x, 3)


class ManipulabilityTask(Task):
    """Linear cost -weight grad(manipulability) . q_dot: ascend the arm's manipulability."""

    def __init__(self, weight: float) -> None:
        self.weight = weight

    def objective(self, s: StepState) -> tuple[None, np.ndarray]:
        c = np.zeros(s.wb.n_u)
        c[: s.wb.n_arm] = -self.weight * manipulability_gradient(s.wb, s.x)
        return None, c


class BaseTask(Task):
    """weight ||M u_b - t*||^2: pull the base to `StepState.base_target` (off when it is None).

    M maps the base input to the body twist (paper eq. 19-20) and t* = vb_d + gain e_b (heading error
    wrapped). With `lookahead` > 0 the term tracks the look-ahead point at body offset (lookahead, 0)
    towards the same point of the target pose (paper 2 section VI, eq. 12 with (L2, L3) = (lookahead, 0)).
    """

    def __init__(self, weight: float, gain: float, lookahead: float = 0.0) -> None:
        self.weight, self.gain, self.lookahead = weight, gain, lookahead

    def objective(self, s: StepState) -> tuple[np.ndarray | None, np.ndarray | None]:
        return (None, None) if s.base_target is None else _added_objective(self, s)

    def add_objective(self, s: StepState, H: np.ndarray, c: np.ndarray) -> None:
        if s.base_target is None:
            return
        M, ref = self._map_and_reference(s)
        n_arm = s.wb.n_arm
        H[n_arm:, n_arm:] += (self.weight * M.T).dot(M)
        c[n_arm:] += (-self.weight * M.T).dot(ref)

    def _map_and_reference(self, s: StepState) -> tuple[np.ndarray, np.ndarray]:
        """Return (M, t*): the base input -> tracked velocity map and the velocity reference."""
        x = s.x
        pose_d = np.asarray(s.base_target, dtype=float)
        rates = np.zeros(3) if s.base_target_velocity is None else np.asarray(s.base_target_velocity, dtype=float)
        th, ell = x[2], self.lookahead
        c, sn = s.cos_sin
        if ell > 0:  # look-ahead point P = base + ell (cos th, sin th) towards the target's P*
            cd, sd = np.cos(pose_d[2]), np.sin(pose_d[2])
            p = x[:2] + ell * np.array([c, sn])
            p_d = pose_d[:2] + ell * np.array([cd, sd])
            pdot_d = rates[:2] + ell * rates[2] * np.array([-sd, cd])
            M = np.array([[c, -sn, -ell * sn], [sn, c, ell * c]]) @ s.wb.twist_map
            return M, pdot_d + self.gain * (p_d - p)
        e = np.array([pose_d[0] - x[0], pose_d[1] - x[1], (pose_d[2] - th + np.pi) % (2 * np.pi) - np.pi])
        w = rates + self.gain * e
        twist = np.array([c * w[0] + sn * w[1], -sn * w[0] + c * w[1], w[2]])  # world rates -> body twist
        return s.wb.twist_map, twist


class FrameTask(Task):
    """weight ||J_f u - v_ref||^2 for another frame than the end effector (a second hand), with its own target.

    Set `target` (SE3) and `target_velocity` (feed-forward twist, world-aligned) before each step; v_ref is
    gain x pose error + feed-forward, clipped like the end-effector task's (`reference_twist`). Off while
    `target` is None. `position_error` holds the last step's error (m).
    """

    def __init__(
        self, wb: WholeBody, frame_id: int, weight: float, gain: float, max_linear: float, max_angular: float
    ) -> None:
        self.wb, self.frame_id = wb, frame_id
        self.weights = np.full(6, float(weight))
        self.gain, self.max_linear, self.max_angular = gain, max_linear, max_angular
        self.target: pin.SE3 | None = None
        self.target_velocity = np.zeros(6)
        self.position_error = 0.0

    def objective(self, s: StepState) -> tuple[np.ndarray | None, np.ndarray | None]:
        return (None, None) if self.target is None else _added_objective(self, s)

    def add_objective(self, s: StepState, H: np.ndarray, c: np.ndarray) -> None:
        if self.target is None:
            return
        T, J = self.wb.frame_and_jacobian(s.x, self.frame_id)
        v_ref, self.position_error, _ = reference_twist(
            pose_error(T, self.target), self.gain, self.target_velocity, self.max_linear, self.max_angular
        )
        add_weighted_gram(J, self.weights, v_ref, H, c)


def _added_objective(task: Task, s: StepState) -> tuple[np.ndarray, np.ndarray]:
    """Return (H, c) of a task that writes its cost with `add_objective` (summed into zeros)."""
    n = s.wb.n_u
    H, c = np.zeros((n, n)), np.zeros(n)
    task.add_objective(s, H, c)
    return H, c

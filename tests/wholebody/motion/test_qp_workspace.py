"""`QPWorkspace` sums constant Hessians once and still equals the plain sum of the tasks' costs."""

from __future__ import annotations

import numpy as np

import robots
from wholebody.motion.experiments import initial_state
from wholebody.motion import ResolvedRateController
from wholebody.motion.kinematics import wholebody_for
from wholebody.motion.qp import QPWorkspace, StepState, Task


class QuadraticPull(Task):
    """1/2 u^T (w I) u - w (x[3:] target pull) . u: constant Hessian, state-dependent linear term."""

    constant_hessian = True

    def __init__(self, n_u: int, n_arm: int, weight: float) -> None:
        self.n_u, self.n_arm, self.weight = n_u, n_arm, weight

    def objective(self, s: StepState) -> tuple[np.ndarray, np.ndarray]:
        c = np.zeros(self.n_u)
        c[: self.n_arm] = -self.weight * (0.3 - s.x[3:])
        return self.weight * np.eye(self.n_u), c


def _plain_sum(tasks: list[Task], s: StepState) -> tuple[np.ndarray, np.ndarray]:
    H, c = np.zeros((s.wb.n_u, s.wb.n_u)), np.zeros(s.wb.n_u)
    for task in tasks:
        Ht, ct = task.objective(s)
        H += 0.0 if Ht is None else Ht
        c += 0.0 if ct is None else ct
    return H, c


def test_workspace_equals_the_sum_of_objectives_with_a_constant_hessian_task() -> None:
    wb = wholebody_for(robots.load("wmra"))
    ctrl = ResolvedRateController(wb)
    pull = QuadraticPull(wb.n_u, wb.n_arm, 0.5)
    tasks = [*ctrl.tasks, pull]
    ws = QPWorkspace(wb.n_u)
    rng = np.random.default_rng(3)
    x0 = initial_state(wb)
    for _ in range(4):  # the constant part is summed once, the linear parts every step
        x = x0 + np.r_[np.zeros(3), 0.05 * rng.standard_normal(wb.n_arm)]
        T, J = wb.ee_and_jacobian(x)
        s = StepState(wb, x, 0.01, T=T, J=J, v_ref=rng.standard_normal(6), u_prev=np.zeros(wb.n_u))
        H, c = ws.objective(tasks, s)
        H0, c0 = _plain_sum(tasks, s)
        np.testing.assert_allclose(H, H0, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(c, c0, rtol=1e-13, atol=1e-13)
    pull.weight = 2.0  # a changed constant Hessian is read again after reset
    ws.reset()
    H, _ = ws.objective(tasks, s)
    np.testing.assert_allclose(H, _plain_sum(tasks, s)[0], rtol=1e-13, atol=1e-13)

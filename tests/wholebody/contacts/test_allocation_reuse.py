"""One allocator kept over a loop's periods answers as a fresh one built for each period.

The push controller keeps one `WrenchAllocator` and, every period, moves its contacts, gives it the arms' torque
limits and the cart's load, and solves; the allocator reuses what did not change (the equality matrices at
unchanged points, the tip-over rows' geometry, the last QP's active set as a guess). A fresh allocator per period
has nothing to reuse: both must give the same rows and the same allocation.
"""

from __future__ import annotations

import numpy as np

from wholebody.contacts.allocation import ArmLimits, GraspModel, TorqueConstraint, WrenchAllocator
from wholebody.contacts.support import CartLoad, SupportPolygon

WHEELS = ((0.0, 0.25), (0.0, -0.25), (0.75, 0.2), (0.75, -0.2))
SUPPORT = SupportPolygon(WHEELS, -0.06, 0.5)
LIMITS = ArmLimits(grasp=GraspModel(), planar=False)


def _period(rng: np.random.Generator, y_prev: float) -> tuple[float, TorqueConstraint, CartLoad, np.ndarray]:
    """Return one period's contact y (often the last one), torque constraint, cart load and desired wrench."""
    y = y_prev if rng.random() < 0.5 else float(rng.uniform(-0.25, 0.25))
    jac = rng.normal(scale=0.4, size=(6, 7))
    torque = TorqueConstraint(jac, rng.normal(scale=5.0, size=7), np.full(7, 60.0))
    load = CartLoad(20.0, (0.3, 0.1), tuple(rng.normal(scale=1.0, size=2)), 1.0, (0.02, 0.02), 1.0)
    gamma = np.array([rng.normal(scale=20.0), 0.0, rng.normal(scale=12.0)])
    return y, torque, load, gamma


def _fresh(y: float, torque: TorqueConstraint, load: CartLoad) -> WrenchAllocator:
    alloc = WrenchAllocator([(-0.15, y, 0.94)], LIMITS, only_motion_directions=True)
    alloc.set_torque_limits([torque], margin=0.1)
    alloc.set_tip_bound(SUPPORT, load)
    return alloc


def test_a_kept_allocator_answers_as_a_fresh_one_every_period() -> None:
    rng = np.random.default_rng(3)
    kept = WrenchAllocator([(-0.15, 0.0, 0.94)], LIMITS, only_motion_directions=True)
    y, solvers = 0.0, []
    for _ in range(60):
        y, torque, load, gamma = _period(rng, y)
        kept.set_points([(-0.15, y, 0.94)])
        kept.set_torque_limits([torque], margin=0.1, stack=False)  # set_tip_bound takes them in
        kept.set_tip_bound(SUPPORT, load)
        fresh = _fresh(y, torque, load)
        assert np.array_equal(kept.Gin, fresh.Gin) and np.array_equal(kept.hin, fresh.hin)
        assert kept.labels == fresh.labels
        got = kept.solve(gamma, raise_on_infeasible=False)
        want = fresh.solve(gamma, raise_on_infeasible=False)
        scale = max(1.0, float(np.abs(want.wrenches_ee).max()))
        assert np.abs(got.wrenches_ee - want.wrenches_ee).max() <= 1e-9 * scale
        assert abs(got.residual - want.residual) <= 1e-9 * scale
        solvers.append(got.solver)
    assert "active-set" in solvers  # the last active set was reused, and answered as the QP does

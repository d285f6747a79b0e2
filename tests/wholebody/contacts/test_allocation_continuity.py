"""The allocation (eq. 25) is a function of the demand: unique, solver-independent and continuous in it.

The push loop's hand wrench jumps between control periods only where its demanded wrench jumps: the QP's
effort is strictly convex, so its optimum is unique whatever the solver, the warm start or the active-set
shortcut, and it moves continuously with the demand (piecewise affinely: steeply where a lateral force or a
downward press takes over from a saturated grip torque, docs/mujoco.md "Wrench error"). The cases are the push
loop's: a spatial grip of 150 N per finger behind a shopping cart's rear axle, its yaw torque saturating in a
turn, the tip-over bound of the turn's outer edge, and a push beyond the hand's force bound (closest wrench).
"""

from __future__ import annotations

import numpy as np
import pytest

from wholebody.contacts.allocation import ArmLimits, GraspModel, WrenchAllocator
from wholebody.contacts.support import CartLoad, SupportPolygon, tip_rows

#: a shopping cart's wheels in {b} (rear axle at x = 0), its floor 0.06 m below {b}, one hand behind the axle
WHEELS = ((0.0, 0.25), (0.0, -0.25), (0.75, 0.2), (0.75, -0.2))
HANDLE = [(-0.15, -0.2, 0.94)]
#: the push loop's hands: a 150 N grip, spatial wrenches (the tip-over bound lets them press down)
LIMITS = ArmLimits(grasp=GraspModel(grip_force=150.0), planar=False)
#: a 20 kg cart with its CoM toward +y, accelerating toward -y (a turn loading its -y edge)
LOAD = CartLoad(20.0, (0.3, 0.15), (0.0, -1.0))


def allocator(tip: bool, solver: str = "proxqp", fast_path: bool = True) -> WrenchAllocator:
    """Return the push loop's one-hand allocator (fx and tau rows), with the tip-over bound when `tip`."""
    alloc = WrenchAllocator(HANDLE, LIMITS, solver=solver, only_motion_directions=True, fast_path=fast_path)
    if tip:
        alloc.set_tip_bound(SupportPolygon(WHEELS, -0.06, 0.5), LOAD)
    return alloc


def demands(case: str, step: float) -> np.ndarray:
    """Return a path of demands (fx, fy, tau) in {b} with the given step along its varying component."""
    if case == "saturated":  # a push past the hand's 150 N force bound
        fx = np.arange(140.0, 170.0, step)
        return np.c_[fx, np.zeros_like(fx), np.full_like(fx, 1.0)]
    tau = np.arange(4.0, 20.0, step)  # through the grip's 6 N m yaw torque, the lateral force, then the press
    return np.c_[np.full_like(tau, -2.0), np.zeros_like(tau), tau]


def wrenches(alloc: WrenchAllocator, gammas: np.ndarray) -> np.ndarray:
    """Return the hand wrench (6,) of each demand, solved in sequence by one allocator (warm-started)."""
    return np.array([alloc.solve(g, raise_on_infeasible=False).wrenches_ee[0] for g in gammas])


def test_the_effort_is_strictly_convex_so_the_optimum_is_unique() -> None:
    alloc = allocator(tip=True)
    assert np.linalg.eigvalsh(alloc.P).min() > 0.0


@pytest.mark.parametrize("tip", [False, True])
def test_warm_start_cold_start_and_another_solver_give_the_same_wrench(tip: bool) -> None:
    gammas = demands("turn", 0.25)
    warm = wrenches(allocator(tip), gammas)
    cold = np.array([allocator(tip).solve(g, raise_on_infeasible=False).wrenches_ee[0] for g in gammas])
    daqp = wrenches(allocator(tip, solver="daqp", fast_path=False), gammas)
    assert np.abs(warm - cold).max() < 1e-6
    assert np.abs(warm - daqp).max() < 1e-5
    if tip:  # the path reaches the press: the tip-over row binds and the hand pushes down
        assert warm[:, 2].min() < -50.0


@pytest.mark.parametrize("case,tip", [("turn", False), ("turn", True), ("saturated", False)])
def test_the_wrench_moves_continuously_with_the_demand(case: str, tip: bool) -> None:
    """A jump J between neighbouring demands would show as the slope J / step at every step: ten times steeper
    at a tenth of the step. A continuous, piecewise affine allocation keeps its steepest slope."""
    coarse, fine = 0.05, 0.005
    slopes = []
    for step in (coarse, fine):
        gammas = demands(case, step)
        w = wrenches(allocator(tip), gammas)
        slopes.append(np.linalg.norm(np.diff(w, axis=0), axis=1).max() / step)
    assert slopes[1] <= 1.5 * slopes[0]
    if case == "saturated":
        res = allocator(tip).solve(demands(case, coarse)[-1], raise_on_infeasible=False)
        assert res.binding is not None and "force bound" in res.binding


@pytest.mark.parametrize("tip", [False, True])
def test_past_the_grip_torque_the_gain_is_the_handle_lever(tip: bool) -> None:
    """Past the grip's yaw torque a N m more of demand is a lateral force over the handle's lever |p_x| about the
    rear axle; with the tip-over row binding, each N of it a press of c_fy / c_fz N (the row's coefficients: the
    handle's height over the edge against its 6 cm horizontal distance inside it): 111 N per N m here."""
    step = 0.005
    w = wrenches(allocator(tip), demands("turn", step))
    slope = np.linalg.norm(np.diff(w, axis=0), axis=1).max() / step
    lateral = 1.0 / abs(HANDLE[0][0])
    if not tip:
        assert slope == pytest.approx(lateral, rel=1e-6)
        return
    rows, _, labels = tip_rows(SupportPolygon(WHEELS, -0.06, 0.5), LOAD, np.array(HANDLE))
    edge = rows[next(i for i, lab in enumerate(labels) if "[0.0, -0.25]" in lab)]
    assert slope == pytest.approx(lateral * np.hypot(1.0, edge[1] / edge[2]), rel=1e-4)

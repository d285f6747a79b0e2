"""Contact-point optimization: the paper's CoM-line claim and globality against brute-force grids."""

import numpy as np
import pytest

from cart.model import mass_matrix, generalized_to_body
from cart.params import CartParams
from wholebody.contacts.allocation import ArmLimits, GraspModel
from wholebody.contacts.handle import HandleSegment
from wholebody.contacts.placement import effort_profile, optimal_contact_points
from wholebody.errors import InfeasibleWrenchError, WholeBodyError

HANDLE = HandleSegment.default()


def _straight_push_gamma_b(params: CartParams, accel: float, theta: float) -> np.ndarray:
    """Cart wrench in {b} for a pure forward acceleration from rest (M qdd, paper eq. 4)."""
    q = np.array([0.3, -0.2, theta])
    qdd = accel * np.array([np.cos(theta), np.sin(theta), 0.0])
    return generalized_to_body(q, mass_matrix(q, params) @ qdd)


@pytest.mark.parametrize("dy", [-0.18, -0.05, 0.0, 0.12])
@pytest.mark.parametrize("motion_only", [False, True])
def test_straight_push_is_cheapest_through_the_com_line(dy, motion_only):
    params = CartParams(m=25.0, dx=0.35, dy=dy, I=2.0)
    gamma = _straight_push_gamma_b(params, 0.6, theta=0.7)
    plan = optimal_contact_points(gamma, HANDLE, only_motion_directions=motion_only)
    assert plan.points_b[0, 1] == pytest.approx(dy, abs=1e-5)
    # the hand pushes straight along x with (almost) no lateral force or torque
    w = plan.allocation.wrenches_ee[0]
    assert w[0] == pytest.approx(25.0 * 0.6, rel=1e-9)
    assert np.allclose(w[1:], 0.0, atol=1e-4)
    assert plan.effort == pytest.approx((25.0 * 0.6) ** 2, rel=1e-7)
    # anywhere else on the handle costs strictly more
    others = effort_profile(
        gamma, [s for s in np.linspace(0, 0.5, 26) if abs(s - 0.25 - dy) > 0.01], only_motion_directions=motion_only
    )
    assert np.all(others > plan.effort + 1e-3)


def test_single_arm_matches_fine_brute_force_on_random_requests():
    rng = np.random.default_rng(7)
    lim = ArmLimits(max_force=80.0, max_torque=4.0, grasp=GraspModel(grip_force=60.0, friction=0.4, torque_arm=0.02))
    fine = np.linspace(0.0, 0.5, 2001)  # 0.25 mm
    checked = 0
    for _ in range(8):
        gamma = rng.uniform([5, -10, -4], [70, 10, 4])
        brute = effort_profile(gamma, fine, HANDLE, lim)
        if not np.any(np.isfinite(brute)):
            with pytest.raises(InfeasibleWrenchError):
                optimal_contact_points(gamma, HANDLE, limits=lim)
            continue
        plan = optimal_contact_points(gamma, HANDLE, limits=lim)
        assert plan.effort <= np.min(brute) + 1e-9 * max(1.0, np.min(brute))
        assert plan.effort == pytest.approx(np.min(brute), rel=1e-5)
        checked += 1
    assert checked >= 5


def _brute_two_arms(gamma, lim, spacing, n=101):
    grid = np.linspace(0.0, 0.5, n)
    best = np.inf
    from wholebody.contacts.allocation import WrenchAllocator

    alloc = WrenchAllocator([HANDLE.point(0.0)] * 2, lim)
    for i in range(n):
        for j in range(i + 1, n):
            if grid[j] - grid[i] < spacing - 1e-12:
                continue
            alloc.set_points([HANDLE.point(grid[i]), HANDLE.point(grid[j])])
            res = alloc.solve(gamma, raise_on_infeasible=False)
            if res.residual < 1e-6:
                best = min(best, res.effort)
    return best


def test_two_arms_match_brute_force_and_keep_spacing():
    rng = np.random.default_rng(11)
    lim = ArmLimits(max_force=60.0, max_torque=3.0, grasp=GraspModel(grip_force=50.0, friction=0.4, torque_arm=0.02))
    for _ in range(3):
        gamma = rng.uniform([20, -10, -6], [100, 10, 6])
        brute = _brute_two_arms(gamma, lim, 0.2)
        plan = optimal_contact_points(gamma, HANDLE, n_arms=2, min_spacing=0.2, limits=lim, resolution=0.025)
        assert plan.s[1] - plan.s[0] >= 0.2 - 1e-9
        assert np.all((plan.s >= 0) & (plan.s <= 0.5))
        assert plan.effort <= brute * (1 + 1e-6) + 1e-9
        assert np.allclose(plan.allocation.gamma_achieved, gamma, atol=1e-8)


def test_bad_requests():
    with pytest.raises(WholeBodyError):
        optimal_contact_points([10, 0, 0], HANDLE, n_arms=3, min_spacing=0.3)
    with pytest.raises(InfeasibleWrenchError) as err:
        optimal_contact_points([-500.0, 0, 0], HANDLE)
    assert "pull" in err.value.binding or "force bound" in err.value.binding

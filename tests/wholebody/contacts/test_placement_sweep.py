"""The vectorized effort sweep, the pruned grid search and the allocator's shortcuts against one-QP-at-a-time."""

import numpy as np
import pytest

from wholebody.contacts.allocation import ArmLimits, GraspModel, WrenchAllocator
from wholebody.contacts.handle import HandleSegment
from wholebody.contacts.placement import _grid, _Objective, _refine, effort_sweep, optimal_contact_points

HANDLE = HandleSegment.default()
TIGHT = ArmLimits(max_force=80.0, max_torque=4.0, grasp=GraspModel(grip_force=60.0, friction=0.4, torque_arm=0.02))


def _one_at_a_time(alloc: WrenchAllocator, points: np.ndarray, gammas: np.ndarray):
    """Return effort, residual, wrenches of every (contact set, wrench) by `solve` one call at a time."""
    M, T = len(points), len(gammas)
    eff, res, W = np.zeros((M, T)), np.zeros((M, T)), np.zeros((M, T, points.shape[1], 6))
    for m in range(M):
        alloc.set_points(points[m])
        for t in range(T):
            r = alloc.solve(gammas[t], raise_on_infeasible=False)
            eff[m, t], res[m, t], W[m, t] = r.effort, r.residual, r.wrenches_ee
    return eff, res, W


@pytest.mark.parametrize("n_arms", [1, 2])
@pytest.mark.parametrize("motion_only", [False, True])
def test_sweep_equals_one_allocation_at_a_time(n_arms, motion_only):
    rng = np.random.default_rng(3 + n_arms)
    s = np.sort(rng.uniform(0.0, 0.5, (12, n_arms)), axis=1)
    points = np.asarray(HANDLE.start_b) + s[..., None] * HANDLE.direction
    gammas = rng.uniform([-100, -30, -15], [160, 30, 15], (15, 3))  # easy, binding and unachievable requests
    eff, res, W = _one_at_a_time(WrenchAllocator(points[0], TIGHT, only_motion_directions=motion_only), points, gammas)
    sweep = effort_sweep(WrenchAllocator(points[0], TIGHT, only_motion_directions=motion_only), points, gammas)
    assert sweep.solved.all()
    assert np.any(res > 1e-3) and np.any(res < 1e-9)  # both kinds occur
    assert np.allclose(sweep.effort, eff, rtol=1e-7, atol=1e-7)
    assert np.allclose(sweep.residual, res, rtol=1e-6, atol=1e-7)
    assert np.allclose(sweep.wrenches_ee, W, atol=1e-5)


def test_closed_form_effort_is_a_lower_bound_and_exact_where_it_keeps_the_limits():
    rng = np.random.default_rng(8)
    s = np.sort(rng.uniform(0.0, 0.5, (30, 2)), axis=1)
    points = np.asarray(HANDLE.start_b) + s[..., None] * HANDLE.direction
    gammas = rng.uniform([0, -10, -8], [130, 10, 8], (10, 3))
    alloc = WrenchAllocator(points[0], TIGHT)
    _, exact, lower = alloc.closed_form_batch(points, gammas)
    eff, res, _ = _one_at_a_time(alloc, points, gammas)
    ok = res < 1e-7
    assert exact.any() and (~exact & ok).any()
    assert np.all(lower[ok] <= eff[ok] * (1 + 1e-9) + 1e-9)
    assert np.allclose(lower[exact], eff[exact], rtol=1e-10)


@pytest.mark.parametrize("motion_only", [False, True])
def test_compiled_closed_form_effort_equals_the_batch_closed_form(motion_only):
    """`closed_form_effort` (one compiled call) against `closed_form_batch` (numpy), point set by point set."""
    rng = np.random.default_rng(9)
    s = np.sort(rng.uniform(0.0, 0.5, (25, 2)), axis=1)
    points = np.asarray(HANDLE.start_b) + s[..., None] * HANDLE.direction
    gammas = rng.uniform([0, -10, -8], [130, 10, 8], (8, 3))
    alloc = WrenchAllocator(points[0], TIGHT, only_motion_directions=motion_only)
    _, exact, lower = alloc.closed_form_batch(points, gammas)
    assert exact.any() and not exact.all()
    for i, pts in enumerate(points):
        for t, gamma in enumerate(gammas):
            got = alloc.closed_form_effort(pts, gamma)
            if exact[i, t]:
                assert got == pytest.approx(lower[i, t], rel=1e-10)
            else:
                assert got is None


@pytest.mark.parametrize("n_arms", [1, 2])
def test_pruned_grid_keeps_the_brute_force_best_candidates(n_arms):
    rng = np.random.default_rng(20 + n_arms)
    cands, _ = _grid(HANDLE.length, n_arms, 0.2, 0.025)
    checked = 0
    for _ in range(12):
        gamma = rng.uniform([-30, -10, -4], [75, 10, 4]) * n_arms
        brute = _Objective(gamma, HANDLE, WrenchAllocator([HANDLE.point(0.0)] * n_arms, TIGHT))
        values = np.array([brute(c) for c in cands])
        pruned = _Objective(gamma, HANDLE, WrenchAllocator([HANDLE.point(0.0)] * n_arms, TIGHT))
        got = pruned.grid_values(cands, 3)
        if not np.isfinite(values).any():
            assert not np.isfinite(got).any()
            continue
        top = np.argsort(values, kind="stable")[:3]
        top = top[np.isfinite(values[top])]
        assert np.allclose(got[top], values[top], rtol=1e-9)
        assert list(np.argsort(got, kind="stable")[: len(top)]) == list(top)
        assert pruned.count <= brute.count
        checked += 1
    assert checked >= 6


@pytest.mark.parametrize("n_arms", [1, 2])
def test_plan_equals_brute_force_grid_then_refinement(n_arms):
    rng = np.random.default_rng(40 + n_arms)
    cands, step = _grid(HANDLE.length, n_arms, 0.2, 0.02)
    for _ in range(4):
        gamma = rng.uniform([10, -10, -6], [120, 10, 6]) * n_arms
        obj = _Objective(gamma, HANDLE, WrenchAllocator([HANDLE.point(0.0)] * n_arms, TIGHT))
        values = np.array([obj(c) for c in cands])
        if not np.isfinite(values).any():
            continue
        best = float(np.min(values))
        for k in np.argsort(values, kind="stable")[:3]:
            if np.isfinite(values[k]):
                best = min(best, _refine(obj, cands[k], step, HANDLE.length, 0.2)[1])
        plan = optimal_contact_points(gamma, HANDLE, n_arms=n_arms, limits=TIGHT, resolution=0.02)
        assert plan.effort == pytest.approx(best, rel=1e-9, abs=1e-9)
        assert plan.effort <= np.min(values) * (1 + 1e-12) + 1e-12


def test_shortcuts_equal_the_forced_qp_on_a_stream():
    pts = [HANDLE.point(0.05), HANDLE.point(0.45)]
    t = np.linspace(0.0, 2 * np.pi, 60)
    gammas = np.stack([60 + 25 * np.sin(t), 3 * np.cos(3 * t), 14 * np.cos(t)], axis=1)
    fast = WrenchAllocator(pts, only_motion_directions=True)
    forced = WrenchAllocator(pts, only_motion_directions=True, fast_path=False)
    via_qpsolvers = WrenchAllocator(pts, only_motion_directions=True, fast_path=False, direct=False)
    labels = set()
    for g in gammas:
        a, b, c = fast.solve(g), forced.solve(g), via_qpsolvers.solve(g)
        labels.add(a.solver)
        assert a.effort == pytest.approx(b.effort, rel=1e-9)
        assert np.allclose(a.wrenches_ee, b.wrenches_ee, atol=1e-7)
        assert np.allclose(c.wrenches_ee, b.wrenches_ee, atol=1e-6)
        assert np.max(np.abs(a.gamma_achieved - g)[[0, 2]]) < 1e-9
    assert {"closed-form", "active-set"} <= labels

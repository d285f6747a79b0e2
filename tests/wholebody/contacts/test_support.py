"""The tip-over bound against an independent statics computation: a box on four floor contacts (LP)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from wholebody.contacts.allocation import ArmLimits, GraspModel, WrenchAllocator
from wholebody.contacts.support import GRAVITY, CartLoad, SupportPolygon, hands_inside, tip_rows
from wholebody.errors import WholeBodyError

#: a shopping cart's wheels in {b} (rear axle at x = 0), floor 0.06 m below {b}, a handle behind the axle
WHEELS = ((0.0, 0.25), (0.0, -0.25), (0.75, 0.2), (0.75, -0.2))
FLOOR_Z = -0.06
HANDLE = np.array([[-0.15, -0.2, 0.94]])
MASS, COM = 20.0, (0.3, 0.15)


def min_normal_load(
    wrench: np.ndarray, point: np.ndarray, com: tuple[float, float], com_z: float, accel: tuple[float, float]
) -> float:
    """Return the largest possible smallest normal force over the wheels (< 0: no loading keeps all of them down).

    Statics with d'Alembert's force: the wheels' normal forces N_k balance the vertical force and the moments
    about the floor's horizontal axes (the floor's friction lies in the floor: it balances the rest). An LP
    maximizes s subject to N_k >= s.
    """
    P = np.c_[np.asarray(WHEELS), np.full(4, FLOOR_Z)]
    f, tau = wrench[:3], wrench[3:]
    c = np.array([com[0], com[1], FLOOR_Z + com_z])
    F_in = np.array([0.0, 0.0, -MASS * GRAVITY]) - MASS * np.r_[accel, 0.0]
    o = np.array([0.0, 0.0, FLOOR_Z])
    moment = np.cross(point - o, f) + tau + np.cross(c - o, F_in)
    force = f + F_in
    # unknowns N_1..N_4, s: sum N = -force_z; sum (P - o) x (N z) = -moment (x and y rows); N_k - s >= 0
    A_eq = np.zeros((3, 5))
    A_eq[0, :4] = 1.0
    A_eq[1, :4] = P[:, 1] - o[1]  # (r x N z)_x = r_y N
    A_eq[2, :4] = -(P[:, 0] - o[0])  # (r x N z)_y = -r_x N
    b_eq = np.array([-force[2], -moment[0], -moment[1]])
    A_ub = np.c_[-np.eye(4), np.ones(4)]
    res = linprog(
        np.r_[np.zeros(4), -1.0], A_ub=A_ub, b_ub=np.zeros(4), A_eq=A_eq, b_eq=b_eq, bounds=[(None, None)] * 5
    )
    assert res.status == 0
    return float(res.x[4])


def support(com_height: float = 0.5) -> SupportPolygon:
    return SupportPolygon(WHEELS, FLOOR_Z, com_height)


@pytest.mark.parametrize("seed", range(6))
def test_bound_holds_exactly_where_every_wheel_stays_loaded(seed: int) -> None:
    rng = np.random.default_rng(seed)
    C, h, _ = tip_rows(support(), CartLoad(MASS, COM), HANDLE)
    for _ in range(50):
        w = rng.normal(scale=[40, 40, 40, 5, 5, 5])
        inside = bool(np.all(C @ w <= h))
        assert inside == (min_normal_load(w, HANDLE[0], COM, 0.5, (0.0, 0.0)) >= -1e-9)


def test_bound_is_active_where_a_normal_load_reaches_zero() -> None:
    C, h, _ = tip_rows(support(), CartLoad(MASS, COM), HANDLE)
    for direction in ([0.0, 1.0, 0, 0, 0, 0], [0.0, -1.0, 0, 0, 0, 0], [-1.0, 0, 0, 0, 0, 0], [0, 0.3, 0, 0.2, 0, 0]):
        d = np.asarray(direction)
        scale = float(np.min(np.where(C @ d > 0, h / np.maximum(C @ d, 1e-300), np.inf)))  # where the bound binds
        assert abs(min_normal_load(scale * d, HANDLE[0], COM, 0.5, (0.0, 0.0))) < 1e-6
        assert min_normal_load(1.01 * scale * d, HANDLE[0], COM, 0.5, (0.0, 0.0)) < 0.0


def test_lateral_push_toward_the_near_edge_matches_the_moment_balance() -> None:
    # the CoM 0.08 m inside the +y edge (rear wheel (0, 0.25) to caster (0.75, 0.2)): m g d / height
    C, h, _ = tip_rows(support(), CartLoad(MASS, COM), HANDLE)
    n = np.array([0.05, 0.75]) / np.hypot(0.05, 0.75)
    d = (np.array([0.0, 0.25]) - np.array(COM)) @ n
    edge = np.argmax(C @ np.r_[0, 1.0, 0, 0, 0, 0])
    expected = MASS * GRAVITY * d / (HANDLE[0, 2] - FLOOR_Z)
    assert h[edge] / C[edge, 1] == pytest.approx(expected, rel=0.02)  # the edge's lever to the handle is slanted


@pytest.mark.parametrize("accel", [(0.0, 1.5), (-1.0, -0.5), (1.0, 0.5)])
def test_inertia_bound_is_safe_for_any_com_height_up_to_the_bound(accel: tuple[float, float]) -> None:
    rng = np.random.default_rng(7)
    C, h, _ = tip_rows(support(com_height=0.8), CartLoad(MASS, COM, accel), HANDLE)
    kept = 0
    for _ in range(60):
        w = rng.normal(scale=[30, 30, 30, 3, 3, 3])
        if np.all(C @ w <= h):
            kept += 1
            for z in (0.0, 0.4, 0.8):
                assert min_normal_load(w, HANDLE[0], COM, z, accel) >= -1e-9
    assert kept > 5


def test_a_cart_its_own_inertia_tips_allows_no_hand_moment_toward_that_edge() -> None:
    # 1.2 m/s^2 toward the inside of the +y edge at a 0.8 m CoM: 19 N m of tipping against 15.7 N m of holding
    C, h, _ = tip_rows(support(com_height=0.8), CartLoad(MASS, COM, (0.0, -1.2)), HANDLE)
    edge = int(np.argmax(C @ np.r_[0, 1.0, 0, 0, 0, 0]))
    assert h[edge] == 0.0 and np.all(h >= 0.0)


def test_margins_shrink_the_bound_and_swivel_radius_moves_the_edges_in() -> None:
    base = tip_rows(support(), CartLoad(MASS, COM), HANDLE)[1]
    std = tip_rows(support(), CartLoad(MASS, COM, mass_std=1.0, com_std=(0.02, 0.02), std_factor=2.0), HANDLE)[1]
    caster = tip_rows(SupportPolygon(WHEELS, FLOOR_Z, 0.5, (0, 0, 0.03, 0.03)), CartLoad(MASS, COM), HANDLE)[1]
    inside = hands_inside(support(), HANDLE)  # the handle is behind the rear axle: no margin on that edge
    assert inside.sum() == 3 and np.all(std[:-1][inside] < base[:-1][inside])
    assert np.allclose(std[:-1][~inside], base[:-1][~inside])
    assert np.all(caster[:-1] <= base[:-1]) and np.any(caster[:-1] < base[:-1])


def test_bad_polygons_are_refused() -> None:
    with pytest.raises(WholeBodyError):
        SupportPolygon(((0, 0), (1, 0), (2, 0)), 0.0, 0.5)
    with pytest.raises(WholeBodyError):
        SupportPolygon(((0, 0), (1, 0)), 0.0, 0.5)


def test_allocation_presses_down_to_turn_the_cart_without_tipping_it() -> None:
    """A yaw torque the grip's wrist cannot make alone: fy at the handle; the bound keeps all wheels loaded."""
    limits = ArmLimits(grasp=GraspModel(), planar=False)
    gamma = np.array([3.0, 0.0, -10.0])  # a right turn: fy toward +y, the near edge
    free = WrenchAllocator([tuple(HANDLE[0])], limits, only_motion_directions=True).solve(gamma)
    assert min_normal_load(free.wrenches_ee[0], HANDLE[0], COM, 0.5, (0.0, 0.0)) < 0.0  # unbounded: it tips
    alloc = WrenchAllocator([tuple(HANDLE[0])], limits, only_motion_directions=True)
    alloc.set_tip_bound(support(), CartLoad(MASS, COM))
    res = alloc.solve(gamma)
    assert res.residual < 1e-6
    assert res.wrenches_ee[0, 2] < -1.0  # it presses down
    assert min_normal_load(res.wrenches_ee[0], HANDLE[0], COM, 0.5, (0.0, 0.0)) >= -1e-6
    alloc.set_tip_bound(None)
    assert alloc.solve(gamma).wrenches_ee[0] == pytest.approx(free.wrenches_ee[0], abs=1e-6)


def test_probes_of_the_tip_bound_leave_the_allocators_own_bound_as_it_was() -> None:
    limits = ArmLimits(grasp=GraspModel(), planar=False)
    gamma = np.array([3.0, 0.0, -10.0])
    alloc = WrenchAllocator([tuple(HANDLE[0])], limits, only_motion_directions=True)
    alloc.set_tip_bound(support(), CartLoad(MASS, COM))
    bounded = alloc.solve(gamma).wrenches_ee[0]
    with alloc.tip_bound_kept():
        alloc.set_tip_bound(None)  # a probe without the bound: the cart-tipping answer
        assert min_normal_load(alloc.solve(gamma).wrenches_ee[0], HANDLE[0], COM, 0.5, (0.0, 0.0)) < 0.0
    assert alloc.solve(gamma).wrenches_ee[0] == pytest.approx(bounded, abs=1e-6)

"""The push controller bounds what it asks of the allocation: a diverged cart controller's 1e13 N is scaled down
to a demand the allocation's solvers take (it saturates), a non-finite one is dropped."""

from __future__ import annotations

import numpy as np

from wholebody.contacts.allocation import ArmLimits, WrenchAllocator
from wholebody.push.controller import DEMAND_BOUND_FACTOR, bounded_demand
from wholebody.push.robot import handle_point


def test_small_demands_pass_unchanged():
    g = np.array([12.0, -3.0, 4.0])
    np.testing.assert_array_equal(bounded_demand(g, 150.0), g)


def test_huge_demand_keeps_its_direction_at_the_bound():
    g = np.array([-8.7e13, -3.9e-3, -2.7e12])
    b = bounded_demand(g, 150.0)
    assert np.abs(b).max() == DEMAND_BOUND_FACTOR * 150.0
    np.testing.assert_allclose(b / np.linalg.norm(b), g / np.linalg.norm(g))


def test_non_finite_demand_is_dropped():
    assert not bounded_demand(np.array([np.nan, 1.0, 0.0]), 150.0).any()


def test_the_allocation_takes_the_bounded_demand():
    alloc = WrenchAllocator([handle_point(-0.2)], ArmLimits(), only_motion_directions=True)
    res = alloc.solve(bounded_demand(np.array([-8.7e13, -3.9e-3, -2.7e12]), 150.0), raise_on_infeasible=False)
    assert np.all(np.isfinite(res.wrenches_ee)) and res.residual > 0  # saturated, not failed

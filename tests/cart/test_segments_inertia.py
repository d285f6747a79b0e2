"""The load's yaw inertia as evidence of a change (cart.segments.load_z, change_stats)."""

from __future__ import annotations

import math
import pathlib
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # `studies` is not an installed package
    sys.path.insert(0, str(ROOT))

from cart import segments  # noqa: E402
from cart.estimate_report import estimate_log  # noqa: E402
from cart.identify import identify  # noqa: E402
from studies.testbeds import rigid_sim  # noqa: E402
from studies.testbeds.log_recorders import load_change_case  # noqa: E402


def _side(m: float, j: float, sd_m: float, sd_j: float, rho: float = 0.0) -> segments._Side:
    return segments._Side(m, sd_m**2, j, sd_j**2, rho * sd_m * sd_j)


def test_the_joint_evidence_is_the_standardised_sum_of_mass_and_inertia():
    # two sides, each difference 3 of its std, correlation 0.2 between the differences: the sum of the two
    # z over the std of that sum, by sampling the two sides' estimates
    left, right = (
        _side(10.0, 2.0, 0.5, 0.1, 0.4),
        _side(10.0 + 3 * 0.5 * math.sqrt(2), 2.0 + 3 * 0.1 * math.sqrt(2), 0.5, 0.1, 0.0),
    )
    z_m, joint = segments.load_z(left, right)
    assert z_m == pytest.approx(3.0)
    rng = np.random.default_rng(0)
    cov = np.array([[0.25, 0.4 * 0.05], [0.4 * 0.05, 0.01]])
    draws = rng.multivariate_normal([0, 0], cov, 200_000) - rng.multivariate_normal(
        [0, 0], np.diag([0.25, 0.01]), 200_000
    )
    stat = draws[:, 0] / math.sqrt(0.5) + draws[:, 1] / math.sqrt(0.02)
    assert joint == pytest.approx(6.0 / float(np.std(stat)), rel=0.01)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_an_inertia_moving_against_the_mass_adds_nothing(sign):
    # a load adds both mass and yaw inertia: a J that falls as the mass grows is not a load's
    left, right = _side(10.0, 2.0, 0.5, 0.1), _side(10.0 + sign * 1.0, 2.0 - sign * 1.0, 0.5, 0.1)
    z_m, joint = segments.load_z(left, right)
    assert z_m == pytest.approx(1.0 / math.sqrt(0.5))
    assert joint == z_m


def test_a_light_cart_whose_mass_alone_falls_short_is_found_by_its_inertia():
    # simulator seed 5000: 5.9 -> 8.3 kg at 18.77 s under 3 N of F/T noise; the mass differs by less than
    # CHANGE_Z std, the yaw inertia (the load's, scaled with the mass) by many more
    case = load_change_case(5000)
    log, truth = rigid_sim.simulate(case)
    tc = float(case.load_time or 0.0)
    res = identify(log)
    got = segments.change_stats(res, tc, 1.0 / res.cutoff_hz)
    assert got.z < segments.CHANGE_Z < got.z_load
    segs = estimate_log(log).segments
    assert len(segs) == 2 and abs(segs[1]["t0"] - tc) < 1.0
    assert abs(segs[1]["mass"] / truth["load_change"]["m_after"] - 1) < 0.05

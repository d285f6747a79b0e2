"""What a load-change log lets any estimator date and weigh (studies.testbeds.dating), on the independent
simulator's load draw (studies.online_estimation_study.rigid_load_case)."""

from __future__ import annotations

import math

from studies import online_estimation_study as oes
from studies.testbeds import dating


def test_the_chances_are_the_closed_forms():
    assert dating.p_date(0.0) == 1.0 and dating.p_date(1.5) == 1.0
    assert abs(dating.p_date(8.0) - 0.25) < 1e-15
    # within 5 % of an unbiased estimate with a 5 % std: one sigma, 68.27 %
    assert abs(dating.p_mass(5.0) - 0.682689492) < 1e-8
    assert dating.p_mass(0.0) == 1.0 and dating.p_mass(50.0) < 0.1
    rows = [
        {"seed": 1, "width": 0.5, "p_date": 1.0, "p_mass": 0.5},
        {"seed": 2, "width": 4.0, "p_date": 0.5, "p_mass": 1.0},
    ]
    got = dating.share(rows)
    assert got["expected_dated"] == 1.5 and got["expected_dated_and_weighed"] == 1.0 and got["wider_than_2s"] == [2]


def test_a_mass_change_in_a_cruise_is_not_datable_and_one_in_an_acceleration_is():
    """Seed 7024: 11.3 -> 7.9 kg with the velocity carried on, in a stretch the motion does not excite: the
    stretch holds the change and is wider than 2 s. Seed 7021: 76 -> 121.5 kg where the cart accelerates: the
    stretch is a few samples wide and the heavy cart's after-mass is well identified."""
    wide, sharp = oes.rigid_dating(7024), oes.rigid_dating(7021)
    lo, hi = wide["stretch"]
    assert lo < 0.0 < hi and wide["width"] > dating.WIDE_STRETCH_S
    assert math.isclose(wide["p_date"], dating.WIDE_STRETCH_S / wide["width"])
    assert sharp["width"] < 0.5 and sharp["p_date"] == 1.0
    assert sharp["after_std_pct"] < 2.0 and sharp["p_mass"] > 0.99

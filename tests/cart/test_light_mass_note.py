"""A wrench logged in kN fits as well as in N with the mass 1e3 times smaller: `estimate` cannot refuse it, but a mass
lighter than a cart (`LIGHT_MASS_KG`) is said with the unit to check (55.2 g for a 55.2 kg cart with exit 0 and
no word before)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from cart.estimate_report import LIGHT_MASS_KG, estimate_log
from studies.testbeds import rigid_sim


@pytest.fixture(scope="module")
def log():
    return rigid_sim.simulate(rigid_sim.random_case(19, duration=40.0, rate_hz=100.0))[0]


def test_a_wrench_in_kn_gives_a_mass_in_grams_and_the_warning_names_the_unit(log):
    est = estimate_log(replace(log, gamma=log.gamma * 1e-3))
    assert est.params.m < LIGHT_MASS_KG
    (note,) = [w for w in est.warnings if "lighter than a cart" in w]
    assert "in kN" in note and f"{1e3 * est.params.m:.3g} g" in note


def test_a_cart_in_newtons_has_no_such_warning(log):
    assert not [w for w in estimate_log(log).warnings if "lighter than a cart" in w]

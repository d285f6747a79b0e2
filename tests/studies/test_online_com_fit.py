"""Tests of the batch fit of paper eq. 4 behind ``studies.online_estimation_study --part mujoco_com``."""

from __future__ import annotations

import pathlib
import sys
from dataclasses import replace

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # `studies` is not an installed package
    sys.path.insert(0, str(ROOT))

from studies.online_estimation_study import eq4_fit  # noqa: E402
from tests.cart.test_online_estimator import TRUTH, _sim  # noqa: E402


def test_eq4_fit_recovers_a_cart_that_obeys_eq4():
    """On the true log of a cart that obeys paper eq. 4 (turns, no casters) the batch fit finds its mass and CoM,
    and the caster columns change next to nothing: the fit is what the data say, not the columns."""
    log = _sim(40.0, True).true
    plain = eq4_fit(log.t, log.q, log.qd, log.gamma, casters=False)
    assert abs(plain["m"] - TRUTH.m) < 0.02 * TRUTH.m
    assert abs(plain["dx"] - TRUTH.dx) < 0.01 and abs(plain["dy"] - TRUTH.dy) < 0.01
    with_casters = eq4_fit(log.t, log.q, log.qd, log.gamma, casters=True)
    assert with_casters["geometry"] is not None
    assert abs(with_casters["dy"] - plain["dy"]) < 0.01
    assert with_casters["rms"] <= plain["rms"]


def test_eq4_fit_sees_a_wrong_com():
    """A wrench made for a CoM 10 cm to the side is fitted as that CoM: the fit can fail."""
    log = _sim(40.0, True, truth=replace(TRUTH, dy=TRUTH.dy - 0.1)).true
    fit = eq4_fit(log.t, log.q, log.qd, log.gamma, casters=False)
    assert abs(fit["dy"] - (TRUTH.dy - 0.1)) < 0.01
    assert np.isfinite(fit["rms"])

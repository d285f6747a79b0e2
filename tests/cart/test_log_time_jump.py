"""A log whose time stamps jump far beyond its data (two recordings joined, a time column that jumps) is refused with
the jump named, before the uniform grid is built: a 1e5 s jump in a 20 s log took 5 GB (issue 30, long recordings)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cart.errors import LogFormatError
from cart.estimate_report import estimate_log
from studies.testbeds import rigid_sim


def _jumped(log, jump: float):
    t = log.t.copy()
    t[t > 10.0] += jump
    return replace(log, t=t)


@pytest.fixture(scope="module")
def log():
    return rigid_sim.simulate(rigid_sim.random_case(3, duration=20.0, rate_hz=100.0))[0]


def test_a_jump_far_beyond_the_data_is_refused_with_the_jump_named(log):
    with pytest.raises(LogFormatError, match=r"jump by 1e\+04 s between t = 10 and 10010 s.*split the log"):
        estimate_log(_jumped(log, 1e4))


def test_a_logging_gap_the_grid_can_hold_is_estimated_around(log):
    whole = estimate_log(log)
    gapped = estimate_log(_jumped(log, 60.0))
    assert np.isfinite(gapped.params.m) and abs(gapped.params.m / whole.params.m - 1.0) < 0.15

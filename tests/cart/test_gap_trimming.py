"""Issue 30, dropouts: the estimate drops only the samples a gap's linear fill reaches through the filter.

A gap in the pose stream is filled linearly; the low-pass filter spreads the fill's error around it. A
long gap reaches as far as the log's ends (the filter's settling, 2 / fc), a short dropout much less: its
fill is off by a L^2 / 8 under an acceleration a. Every grid sample within 2 / fc of a gap of any length
was dropped (rigid_sim seed 3, 100 Hz, cut-off 1.32 Hz: a 0.12 s dropout cost 316 samples, now 102; 0.3 s
334, now 260; 1 s 404 either way).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from cart.identify import identify
from cart.log_signals import filter_support_keep
from studies.testbeds import rigid_sim


def test_a_short_gap_is_trimmed_less_than_a_long_one():
    fc, dt = 0.5, 0.01
    end = math.ceil(2.0 / (fc * dt))
    trims = {}
    for seconds in (0.1, 0.3, 20.0):
        valid = np.ones(20000, dtype=bool)
        valid[9000 : 9000 + int(seconds / dt)] = False
        keep = filter_support_keep(valid, fc, dt)
        assert not keep[:end].any() and not keep[-end:].any() and not keep[~valid].any()
        trims[seconds] = (int((~keep).sum()) - 2 * end - int((~valid).sum())) / 2
    assert trims[0.1] < trims[0.3] < 0.5 * end and trims[20.0] == end


def test_a_dropout_costs_little_more_than_itself():
    """A 0.12 s pose dropout in a 40 s log costs at most the dropout and one filter settling time (was two)."""
    log, _ = rigid_sim.simulate(rigid_sim.random_case(3, duration=40.0, rate_hz=100.0))
    fit0 = identify(log)
    gap = (log.t > 20.0) & (log.t < 20.12)
    fit1 = identify(replace(log, t=log.t[~gap], q=log.q[~gap], gamma=log.gamma[~gap], qd=None))
    assert fit1.gaps == 1
    settle = 2.0 / (fit0.cutoff_hz * fit0.grid_dt)
    assert fit0.samples_used - fit1.samples_used < int(gap.sum()) + settle
    assert abs(fit1.params.m / fit0.params.m - 1) < 0.01

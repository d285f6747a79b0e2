"""Issue 30: a stuck force sensor's stretch (excluded, its wrench filled) must not change what `diagnose` reads
elsewhere in the log.

An outside tester's pink-noise multi-rate log with the wrench frozen for 10 s named a 2 kg `payload_change`
(Delta BIC 14.7) and flagged windows 10 s from the stretch; the same recording without the stuck sensor named
nothing and flagged one window. Two causes: the fill (a line, no noise) lowered the force's noise std, and the
fill-driven replays' near-zero p-values relaxed the Benjamini-Hochberg threshold of all the others.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from cart.diagnose import _replay_mask
from cart.diagnose_replay import Replay, chi2_sf_3
from cart.log_signals import signals_from_log
from studies.testbeds import rigid_sim


def _frozen(log, t0: float, t1: float):
    g = log.gamma.copy()
    i0, i1 = np.searchsorted(log.t, [t0, t1])
    g[i0:i1] = g[i0]
    return replace(log, gamma=g)


def test_the_noise_levels_leave_out_a_filled_stretch():
    log, _ = rigid_sim.simulate(rigid_sim.random_case(5, duration=50.0, rate_hz=200.0))
    stuck = _frozen(log, 20.0, 30.0)
    clean = signals_from_log(log)
    blind = signals_from_log(stuck)
    told = signals_from_log(stuck, filled=[(20.0, 30.0)])
    assert blind.sigma_force < 0.9 * clean.sigma_force  # the fill read as noise-free samples
    assert abs(told.sigma_force / clean.sigma_force - 1.0) < 0.05
    assert abs(told.sigma_torque / clean.sigma_torque - 1.0) < 0.05
    assert told.wrench_measured is not None and not told.wrench_measured[np.searchsorted(log.t, 25.0)]
    assert signals_from_log(log, filled=[(100.0, 110.0)]).wrench_measured is None  # a span outside the log


def _replay(chi2: np.ndarray, starts: np.ndarray) -> Replay:
    k = len(starts)
    z = np.zeros((k, 2, 3))
    return Replay(starts=starts, tau=np.array([0.0, 1.0]), sim=z, meas=z, rms=np.zeros(k), chi2=chi2, floor=np.ones(k))


def test_the_replays_driven_by_a_fill_do_not_relax_the_false_discovery_threshold_of_the_others():
    starts = np.arange(0.0, 60.0, 0.25)
    chi2 = np.full(len(starts), 1.0)
    marginal = np.flatnonzero((starts >= 5.0) & (starts < 6.0))
    chi2[marginal] = 15.5  # p 0.0014: significant only ranked behind the fill's 40 near-zero p-values
    hole = (starts >= 20.0) & (starts < 30.0)
    chi2[hole] = 1e4  # driven by the fill
    p = chi2_sf_3(np.array([15.5]))[0]
    assert 0.01 * len(marginal) / (len(starts) - hole.sum()) < p < 0.01 * (hole.sum() + len(marginal)) / len(starts)
    flagged, _ = _replay_mask(_replay(chi2, starts), 1.0, [(20.0, 30.0)])
    assert not flagged[marginal].any()
    assert not flagged[hole].any()

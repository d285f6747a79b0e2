"""A clipped (saturated) F/T axis names no effect in `diagnose`; a real payload change is still named.

The streams exclude a clipped channel's samples (``cart.streams.saturated_channels``), and `estimate` leaves the
gap they leave out of its fit. `diagnose` merged the wrench onto the pose samples by filling that gap: across a
clipped peak the fill reads the clip level, the window fits took the fill for a measured wrench, and the
h31 tester's sat_heavy_fx80 and sat_mr_fx60 (fx, fy clipped at 80 N / 60 N) named a ``payload_change``. The
windows and the replays that reach the gap (``Prepared.wrench_holes``) are now left out, as estimate does.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cart.diagnose import diagnose
from cart.diagnose_prep import prepare_log
from cart.logs import CartLog
from studies.testbeds.hidden_effects import random_case

#: Forces clipped at this share of the log's peak |fx|, |fy| (the h31 logs: 60-80 N on pushes of 100-150 N).
CLIP = 0.6


def _log(effect: str | None, seed: int) -> CartLog:
    """Return a log of the hidden-effect test bed (its pose columns only)."""
    return replace(random_case(effect, np.random.default_rng(seed)).measured, qd=None)


def _clipped(effect: str | None, seed: int) -> tuple[CartLog, np.ndarray]:
    """Return a hidden-effect test-bed log with fx, fy clipped at CLIP of their peak, and the clipped rows' times."""
    log = _log(effect, seed)
    g = log.gamma.copy()
    lim = CLIP * float(np.max(np.abs(g[:, :2])))
    g[:, :2] = np.clip(g[:, :2], -lim, lim)
    at = np.any(np.abs(g[:, :2]) == lim, axis=1)
    return replace(log, gamma=g), log.t[at]


def test_the_wrench_holes_cover_every_clipped_sample():
    log, times = _clipped(None, 2)
    prep = prepare_log(log)
    holes = np.asarray(prep.wrench_holes) + prep.time_offset
    assert len(times) > 50 and len(holes) < len(times)  # runs of clipped samples, one hole each
    inside = np.any((times[:, None] > holes[None, :, 0]) & (times[:, None] < holes[None, :, 1]), axis=1)
    assert np.all(inside)
    assert prepare_log(_log(None, 2)).wrench_holes == ()  # unclipped: none


@pytest.mark.parametrize("seed", [2, 5])
def test_a_clipped_effect_free_log_names_nothing(seed):
    # before the fix both named a payload_change (seed 2: 41.1 -> 18.9 mm; seed 5: 31.9 -> 10.8 mm)
    log, _ = _clipped(None, seed)
    rep = diagnose(log)
    assert rep.names == [], (rep.names, rep.gap_before, rep.gap_after)
    assert any("clipped" in w for w in rep.warnings)
    assert rep.gap_before < 0.01  # the replays through the filled wrench are not counted


def test_a_real_payload_change_is_still_named_with_a_clipped_axis():
    log, times = _clipped("payload_change", 4)
    assert len(times) > 50
    assert "payload_change" in diagnose(log).names

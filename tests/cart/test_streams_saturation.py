"""Issue 30, robust fitting: a force sensor axis clipped at a fixed value (saturation) is found and its samples are
excluded with a warning. Fitted as read, the clipped forward force at the pushes' peaks reads a lighter or heavier
cart with no warning (a 12.3 kg cart with fx, fy clipped at 60 % of their peak: 11.55 +- 2.32 kg, model_fits false;
the axis clipped for a second at a time was taken for a stuck sensor).
"""

from __future__ import annotations


import numpy as np

from cart.estimate_report import estimate_log
from cart.logs import CartLog
from cart.streams import WRENCH_CHANNELS, saturated_channels, split_streams
from tests.cart.test_streams_jumps import _push as push


def _push(seconds: float = 40.0, hz: float = 100.0, seed: int = 5) -> tuple[CartLog, float]:
    """The push of test_streams_jumps with a forward force of 15 N + 25.0 N sin 2.1 t; (log, true mass)."""
    return push(seconds, hz, seed, amplitude=25.0)


def test_a_clipped_force_axis_is_found_and_its_samples_excluded():
    log, m_true = _push()
    g = log.gamma.copy()
    lim = 0.8 * float(np.max(np.abs(g[:, 0])))
    g[:, 0] = np.clip(g[:, 0], -lim, lim)
    clipped = int(np.sum(np.abs(g[:, 0]) == lim))
    assert clipped > 50
    found = saturated_channels(g, WRENCH_CHANNELS)
    assert {(name, abs(value)) for name, value, _ in found} <= {("fx", lim)} and found
    assert sum(len(rows) for _, _, rows in found) == clipped
    st = split_streams(CartLog(t=log.t, q=log.q, gamma=g))
    assert len(st.wrench.t) == len(log.t) - clipped
    assert st.to_dict()["saturated_channels"] == ["fx"] and not st.stuck
    assert any("clipped" in w for w in st.warnings())
    clean = estimate_log(log)
    est = estimate_log(CartLog(t=log.t, q=log.q, gamma=g))
    assert abs(est.params.m - clean.params.m) < 0.01 * m_true
    assert any("clipped" in w for w in est.warnings)


def test_an_unclipped_or_quantised_wrench_is_not_saturated():
    log, _ = _push()
    assert saturated_channels(log.gamma, WRENCH_CHANNELS) == []
    coarse = np.round(log.gamma * 2.0) / 2.0  # a sensor read in steps of 0.5 N: its extremes repeat, no clipping
    assert saturated_channels(coarse, WRENCH_CHANNELS) == []
    assert split_streams(log).saturated == ()


def test_a_recording_repeated_end_to_end_is_not_saturated():
    """Tiled copies reach the same peak once per copy: isolated samples, not a force held beyond a limit."""
    log, _ = _push(seconds=10.0)
    g = np.tile(log.gamma, (8, 1))
    assert saturated_channels(g, WRENCH_CHANNELS) == []

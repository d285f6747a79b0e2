"""Tests of the change time's likelihood-ratio confidence set (cart.segments.confidence_set, confidence_drop)."""

from __future__ import annotations

import numpy as np
import pytest

from cart import segments
from tests.cart.test_segments_stretch import _switching_regression


def test_the_drop_is_the_two_sided_random_walk_quantile():
    # max_s (2 W(s) - |s|) over a two-sided Brownian motion, simulated: its 95 % quantile is the drop
    rng = np.random.default_rng(5)
    dt, n, paths = 0.01, 3000, 3000  # 30 time units each side: the drift -|s| leaves exp(-15) beyond
    sides = []
    for _ in range(2):
        walk = np.cumsum(2.0 * np.sqrt(dt) * rng.standard_normal((paths, n)) - dt, axis=1)
        sides.append(np.maximum(walk.max(axis=1), 0.0))
    stat = np.maximum(*sides)
    assert np.quantile(stat, 0.95) == pytest.approx(segments.confidence_drop(0.95), abs=0.6)
    assert np.quantile(stat, 0.5) == pytest.approx(segments.confidence_drop(0.5), abs=0.3)


def test_a_level_outside_zero_one_is_refused():
    with pytest.raises(ValueError, match="between 0 and 1"):
        segments.confidence_drop(1.0)


def _noisy(i_c: int, seed: int, sigma: float = 2e-3):
    """The switching regression of test_segments_stretch with white noise of ``sigma`` added on every row; the scale
    is the rows' whole noise (the regression's own 1e-3 with it)."""
    t, x, y, kernels = _switching_regression(i_c)
    y = y + sigma * np.random.default_rng(seed).standard_normal(y.shape)
    return t, x, y, np.full(2, np.hypot(sigma, 1e-3)), kernels


def test_a_change_in_an_excited_stretch_gets_a_narrow_set_holding_it():
    t, x, y, scale, kernels = _noisy(3200, 0)
    lo, hi = segments.confidence_set(t, x, y, scale, 5.0, 1.0, kernels)
    assert lo <= t[3200] <= hi and hi - lo < 0.5


def test_the_set_holds_the_change_in_most_noise_draws():
    # the nominal level is 95 %: 20 draws of the noise, the change 0.4 s into an excited stretch
    held = 0
    for seed in range(20):
        t, x, y, scale, kernels = _noisy(3040, 100 + seed, sigma=6e-3)
        lo, hi = segments.confidence_set(t, x, y, scale, 5.0, 1.0, kernels)
        held += lo <= t[3040] <= hi
    assert held >= 17

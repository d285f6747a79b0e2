"""The GLR's change time and the stretch of onsets the data cannot tell from it (issue 27: a load lifted out while
the cart cruises shows only at the next acceleration)."""

from __future__ import annotations

import numpy as np

from cart.change_detection import ChangeDetector


def _scores(excited: np.ndarray, start: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Return the scores and information of samples whose regressor rows are random where ``excited`` (zero
    elsewhere: a cruise that says nothing of the inertial parameters), the mass stepped by 5 from ``start`` on."""
    n = len(excited)
    phi = rng.standard_normal((n, 2, 4)) * excited[:, None, None]
    delta = np.array([5.0, 0.0, 0.0, 0.0])
    r = np.einsum("nij,j->ni", phi, delta) * (np.arange(n) >= start)[:, None] + rng.standard_normal((n, 2))
    return np.einsum("nij,ni->nj", phi, r), np.einsum("nij,nik->njk", phi, phi)


def test_an_excited_change_is_dated_to_a_few_samples():
    """Rows excited throughout, the change at sample 150: the best start and its stretch lie within 3 samples."""
    scores, infos = _scores(np.ones(300), 150, np.random.default_rng(0))
    best, lo, hi = ChangeDetector.onset_range(ChangeDetector.profile(scores, infos, np.zeros((4, 4))))
    assert best == ChangeDetector.onset(scores, infos, np.zeros((4, 4)))
    assert 147 <= lo <= 150 <= hi <= 153


def test_a_change_in_a_cruise_spans_the_cruise():
    """Excited up to 100 and from 250 on, the change at 180 in between: every start in the cruise fits as well, and
    the stretch spans it (100-250), the true onset inside; with the residuals 3 times the noise model's (the misfit
    given) it stays as wide."""
    excited = np.r_[np.ones(100), np.zeros(150), np.ones(100)].astype(float)
    scores, infos = _scores(excited, 180, np.random.default_rng(1))
    g = ChangeDetector.profile(scores, infos, np.zeros((4, 4)))
    for misfit in (1.0, 3.0):
        best, lo, hi = ChangeDetector.onset_range(g, misfit)
        assert lo <= 101 and hi >= 249 and lo <= best <= hi
        assert hi <= 252

"""Tests of the load-change search's robust row weights (cart.segments.robust_weights, reweighted): a local misfit
far from the change (a caster's swing as the cart turns in place) must not date it."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cart import segments
from cart._kernels_identify import butter_lowpass_sos
from cart.identify import _filtfilt

DT, FC, N = 0.01, 2.0, 4000
SCALE = np.full(2, 3e-2)
I_CHANGE = 1200  # the load is taken out after this row (12 s)
BURST = (3000, 3150)  # rows of a local misfit (30-31.5 s)


def _search(amp: float) -> segments._Search:
    """Return the split search of a filtered regression [m, m dx, m dy, J, c_v, c_w] whose mass drops from 1.6 to
    1 after ``I_CHANGE``, with a misfit on ``BURST`` that reads as ``amp`` more mass there (none elsewhere)."""
    rng = np.random.default_rng(3)
    sos = butter_lowpass_sos(4, FC * 2.0 * DT)
    raw = _filtfilt(butter_lowpass_sos(2, 0.3 * 2.0 * DT), rng.standard_normal((N, 2, 6)))
    p = np.where((np.arange(N) <= I_CHANGE)[:, None], [1.6, 0.2, 0.1, 0.4, 0.3, 0.2], [1.0, 0.2, 0.1, 0.4, 0.3, 0.2])
    y = _filtfilt(sos, np.einsum("krp,kp->kr", raw, p)) + 1e-2 * rng.standard_normal((N, 2))
    x = _filtfilt(sos, raw.reshape(N, -1)).reshape(raw.shape)
    y[BURST[0] : BURST[1]] += amp * x[BURST[0] : BURST[1], :, 0]
    kernels = segments.split_kernels(SimpleNamespace(cutoff_hz=FC, grid_dt=DT), 1)  # type: ignore[arg-type]
    t = np.arange(N) * DT
    return segments._Search(t, x, y, SCALE, 5.0, 1.0, kernels, np.zeros(0, dtype=int), DT)


def _split(s: segments._Search) -> tuple[float, float, float] | None:
    return segments.best_split(s.t, s.x, s.y, s.scale, s.min_len, s.tol, s.kernels, shared=s.shared)


def test_a_strong_local_misfit_far_from_the_change_does_not_date_it():
    s = _search(4.0)
    plain, robust = _split(s), _split(segments.reweighted(s))
    assert plain is not None and robust is not None
    assert BURST[0] * DT - 0.5 <= plain[0] <= BURST[1] * DT + 0.5  # the unweighted split fits the misfit
    assert abs(robust[0] - I_CHANGE * DT) < 0.1


@pytest.mark.parametrize("amp", [0.0, 1.0])
def test_a_log_without_a_strong_misfit_keeps_its_weights_and_its_split(amp):
    s = _search(amp)
    assert np.all(segments.robust_weights(s) == 1.0)
    assert _split(segments.reweighted(s)) == _split(s)


def test_the_weight_falls_as_the_misfit_grows():
    # inside the burst the misfit dominates the window's residual: its RMS grows with the misfit's size and the
    # weight falls (not as its inverse: the burst is shorter than the window, and the single fit takes a share of
    # it); away from the burst (farther than the window) the weight stays one
    w4, w8 = (segments.robust_weights(_search(amp)) for amp in (4.0, 8.0))
    mid = slice((BURST[0] + BURST[1]) // 2 - 10, (BURST[0] + BURST[1]) // 2 + 10)
    assert np.all(w4[mid] < 1.0)
    assert np.all(w8[mid] < 0.8 * w4[mid])
    far = int(segments.ROBUST_WINDOW_S / DT) + 1
    assert np.all(w8[: BURST[0] - far] == 1.0) and np.all(w8[BURST[1] + far :] == 1.0)
    assert np.all((w8 > 0.0) & (w8 <= 1.0))


def test_a_search_shorter_than_the_window_gets_a_weight_per_row():
    # a short log (a real recording of a few seconds) has fewer search rows than the window holds
    s = _search(4.0)
    n = int(segments.ROBUST_WINDOW_S / DT)
    short = s._replace(t=s.t[:n], x=s.x[:n], y=s.y[:n])
    w = segments.robust_weights(short)
    assert w.shape == (n, 2) and np.all((w > 0.0) & (w <= 1.0))

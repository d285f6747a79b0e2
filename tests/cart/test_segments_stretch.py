"""Tests of the load-change segments' time stretch (cart.segments.information_stretch) and of the re-check that
joins two segments of the same load (cart.segments._joined)."""

from __future__ import annotations

import pathlib
import sys
from types import SimpleNamespace

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # `studies` is not an installed package
    sys.path.insert(0, str(ROOT))

from cart import segments  # noqa: E402
from cart._kernels_identify import butter_lowpass_sos  # noqa: E402
from cart.identify import _filtfilt  # noqa: E402

DT, FC, N = 0.01, 2.0, 4000
SCALE = np.full(2, 3e-2)  # the rows' noise level, about the 60 % change's share of a row
CRUISE = (1800, 2600)  # rows where the load's columns are not excited (a cruise: no acceleration, no turn)


def _switching_regression(i_c: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, SimpleNamespace]:
    """Return (t, x, y, kernels) of a filtered regression [m, m dx, m dy, J, c_v, c_w] whose first parameter drops
    from 1.6 to 1 after row ``i_c`` (a load taken out: no momentum exchange); the load's columns vanish on
    ``CRUISE`` (the damping columns do not)."""
    rng = np.random.default_rng(3)
    sos = butter_lowpass_sos(4, FC * 2.0 * DT)
    raw = _filtfilt(butter_lowpass_sos(2, 0.3 * 2.0 * DT), rng.standard_normal((N, 2, 6)))
    raw[CRUISE[0] : CRUISE[1], :, :4] = 0.0
    raw[CRUISE[0] : CRUISE[1], :, 4:] = 0.5  # a steady speed and turn rate: damping rows, no inertia rows
    p = np.where((np.arange(N) <= i_c)[:, None], [1.6, 0.2, 0.1, 0.4, 0.3, 0.2], [1.0, 0.2, 0.1, 0.4, 0.3, 0.2])
    y = _filtfilt(sos, np.einsum("krp,kp->kr", raw, p)) + 1e-3 * rng.standard_normal((N, 2))
    x = _filtfilt(sos, raw.reshape(N, -1)).reshape(raw.shape)
    kernels = segments.split_kernels(SimpleNamespace(cutoff_hz=FC, grid_dt=DT), 1)
    return np.arange(N) * DT, x, y, kernels


@pytest.mark.parametrize("i_c", [1850, 2000, 2300])
def test_a_change_in_a_cruise_is_reported_with_the_whole_cruise(i_c):
    # the load's inertia is not excited in the cruise: any split there fits the motion alike, whichever the log's
    # misfit favours; the stretch reaches the motions either side, less the filtered motions' tails (a cut-off
    # period: where the low-passed inertia columns still carry the motion), wherever in the cruise the change is
    t, x, y, kernels = _switching_regression(i_c)
    lo, hi = segments.information_stretch(t, x, y, SCALE, 5.0, 1.0, kernels, t[i_c])
    tail = 1.0 / FC
    assert t[CRUISE[0]] <= lo <= t[CRUISE[0]] + tail
    assert t[CRUISE[1]] - tail <= hi <= t[CRUISE[1]]


def test_a_change_in_an_excited_stretch_is_dated_narrowly():
    t, x, y, kernels = _switching_regression(3200)
    lo, hi = segments.information_stretch(t, x, y, SCALE, 5.0, 1.0, kernels, t[3200])
    assert lo - 0.1 <= t[3200] <= hi + 0.1 and hi - lo < 0.2  # candidates 0.08 s apart


def test_the_split_prediction_fits_the_switching_regression():
    # the switched split's own prediction at the true change reproduces the noise-free regression
    t, x, y, kernels = _switching_regression(3200)
    pred = segments.split_prediction(x, y, np.ones(2), 3200, kernels)
    assert np.sqrt(np.mean((pred - y) ** 2)) < 3e-3


def _seg(t0: float, t1: float, m: float, t0_range=None) -> dict:
    return {"t0": t0, "t1": t1, "t0_range": t0_range, "params": SimpleNamespace(m=m)}


@pytest.fixture(scope="module")
def change_log():
    """A simulator log (seed 3000 of the load-change study): 30 % of the mass taken off at 21.85 s."""
    from tests.cart.test_segments import _load_case

    return _load_case(3000)


def test_segments_of_the_same_load_either_side_of_a_split_are_joined(change_log):
    # the first split fell after the change (say at 35 s), the left side's search then found the change: the two
    # segments next to the first split hold the same load and are one segment, identified again
    log, tc, truth = change_log
    left = [_seg(0.0, tc, 80.0), _seg(tc, 35.0, 57.0, (tc - 0.2, tc + 0.2))]
    right = [_seg(35.0, float(log.t[-1]), 58.5, (34.0, 36.0))]
    got = segments._joined(log, left, right, 1.0, None)
    assert len(got) == 2 and got[0] is left[0]
    assert got[1]["t0"] == tc and got[1]["t0_range"] == [tc - 0.2, tc + 0.2]
    assert got[1]["t1"] == pytest.approx(float(log.t[-1]))
    assert abs(got[1]["params"].m / truth["load_change"]["m_after"] - 1) < 0.05


def test_segments_that_differ_are_not_joined(change_log):
    log, tc, _ = change_log
    left = [_seg(0.0, tc, 80.0), _seg(tc, 35.0, 57.0)]
    right = [_seg(35.0, float(log.t[-1]), 61.0)]  # 6.6 % apart
    assert segments._joined(log, left, right, 1.0, None) == left + right
    one = [_seg(0.0, 35.0, 57.0)]
    assert segments._joined(log, one, [_seg(35.0, 50.0, 57.5)], 1.0, None) == one + [_seg(35.0, 50.0, 57.5)]

"""`estimate` is linear in the log's length (issue 30, item 3): no step grows faster than the number of samples.

Two effect-free 200 Hz logs, 1 and 4 minutes (neither long enough to be fitted on every k-th row), written from the cart model's inverse dynamics (paper eq. 4,
:func:`cart.dynamics.regressor`) along a smooth turning path. Within one run:

- the samples run through the zero-phase filter's sections and the rows of the normal equations
  (counted): at most 4 times as many for 4 times the samples (a fixed part plus a linear part);
- the CPU time of :func:`cart.estimate_report.estimate_log`: at most 5 times as long (4 for a cost
  linear in the samples, with a quarter for timing noise; a step quadratic in the length that costs
  0.4 s on 1 minute costs 6.4 s on 4 and fails it).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

import cart._kernels_identify as kernels
import cart.identify as identify_module
from cart.dynamics import regressor
from cart.estimate_report import estimate_log
from cart.logs import CartLog

RATE_HZ = 200.0
#: the cart of the synthetic logs: m, CoM (dx, dy), inertia about the CoM, c_v, c_w
CART = (40.0, 0.3, 0.05, 3.0, 8.0, 2.0)


def _waves(t: np.ndarray, parts: list[tuple[float, float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Return (f, df/dt) of f = sum a sin(2 pi nu t + phase) over ``parts`` (a, nu, phase)."""
    f = sum(a * np.sin(2.0 * math.pi * nu * t + ph) for a, nu, ph in parts)
    fd = sum(a * 2.0 * math.pi * nu * np.cos(2.0 * math.pi * nu * t + ph) for a, nu, ph in parts)
    return np.asarray(f), np.asarray(fd)


def synthetic_log(minutes: float, seed: int = 0) -> CartLog:
    """Return an effect-free 200 Hz log of ``minutes``: a turning path and the wrench eq. 4 needs along it, noisy."""
    n = int(round(minutes * 60.0 * RATE_HZ))
    t = np.arange(n) / RATE_HZ
    v, vd = _waves(t, [(0.4, 0.05, 0.0), (0.25, 0.13, 1.0), (0.1, 0.41, 2.0)])
    v = v + 0.2
    om, od = _waves(t, [(0.5, 0.037, 0.5), (0.3, 0.19, 2.5), (0.15, 0.53, 1.0)])
    dt = np.diff(t)
    th = np.r_[0.0, np.cumsum(0.5 * (om[1:] + om[:-1]) * dt)]
    vx, vy = v * np.cos(th), v * np.sin(th)
    x = np.r_[0.0, np.cumsum(0.5 * (vx[1:] + vx[:-1]) * dt)]
    y = np.r_[0.0, np.cumsum(0.5 * (vy[1:] + vy[:-1]) * dt)]
    m, dx, dy, i_c, c_v, c_w = CART
    p = np.array([m, m * dx, m * dy, i_c + m * (dx * dx + dy * dy), c_v, c_w])
    fu, tau = np.moveaxis(regressor(v, om, vd, od) @ p, -1, 0)
    rng = np.random.default_rng(seed)
    q = np.column_stack([x, y, th]) + rng.normal(0.0, [1e-3, 1e-3, 2e-3], (n, 3))
    gamma = np.column_stack([fu * np.cos(th), fu * np.sin(th), tau]) + rng.normal(0.0, [1.0, 1.0, 0.2], (n, 3))
    return CartLog(t=t, q=q, gamma=gamma, source=f"synthetic_{minutes:g}min")


def _counted_run(log: CartLog, monkeypatch: pytest.MonkeyPatch) -> tuple[float, dict[str, int], float]:
    """Return (CPU seconds of estimate_log, rows through the filter sections and the normal equations, mass)."""
    counts = {"filtered": 0, "normal": 0}
    section, normal = kernels._section_filter, identify_module._normal

    def counted_section(sec, x, z0):
        counts["filtered"] += int(np.size(x))
        return section(sec, x, z0)

    def counted_normal(x, y, wts):
        counts["normal"] += int(x.shape[0])
        return normal(x, y, wts)

    monkeypatch.setattr(kernels, "_section_filter", counted_section)
    monkeypatch.setattr(identify_module, "_normal", counted_normal)
    t0 = time.process_time()
    report = estimate_log(log)
    seconds = time.process_time() - t0
    monkeypatch.undo()
    return seconds, counts, float(report.params.m)


def test_estimate_grows_at_most_linearly_with_the_log(monkeypatch):
    short, long_ = synthetic_log(1.0), synthetic_log(4.0)
    estimate_log(synthetic_log(0.25))  # first-call costs (lazy imports) out of the timed runs
    t_short, n_short, m_short = _counted_run(short, monkeypatch)
    t_long, n_long, m_long = _counted_run(long_, monkeypatch)
    ratio = len(long_) / len(short)
    assert m_short == pytest.approx(CART[0], rel=0.01) and m_long == pytest.approx(CART[0], rel=0.01)
    for name in n_short:
        assert n_short[name] > 0
        assert n_long[name] <= ratio * n_short[name], (name, n_short[name], n_long[name])
    assert t_long <= 1.25 * ratio * t_short, (t_short, t_long)


@pytest.mark.parametrize("n", [identify_module.CUTOFF_SAMPLES - 1000, identify_module.CUTOFF_SAMPLES + 2000])
def test_cutoff_accelerations_on_grids_longer_than_the_unit_noise(n):
    """A grid between the unit noise's 20000 samples and `CUTOFF_SAMPLES` (one stretch longer than the noise: a 55 s
    log at 400 Hz) and a chunked longer one give the accelerations and the noise gain of filtering each stretch and
    the noise on their own (`_pose_kinematics`, `_noise_gains`), the independent computation."""
    rng = np.random.default_rng(4)
    t = np.arange(n) * 0.0025
    q = np.column_stack([0.3 * np.sin(0.2 * t), 0.1 * np.cos(0.3 * t), 0.2 * np.sin(0.1 * t)])
    q += rng.normal(0.0, 1e-3, q.shape)
    grid = identify_module._Grid(t, q, np.zeros((n, 3)), np.ones(n, dtype=bool), 0.0025, 0)
    sos = identify_module.butter_lowpass_sos(4, 0.02)
    chunks = identify_module._cutoff_chunks(n)
    e = identify_module._unit_noise(max(i1 - i0 for i0, i1 in chunks))
    vd, od, gain = identify_module._chunk_accelerations(grid, sos, e, chunks)
    size = chunks[0][1] - chunks[0][0]
    vds, ods = [], []
    for i0, i1 in chunks:
        _, _, _, v1, o1 = identify_module._pose_kinematics(identify_module._filtfilt(sos, q[i0:i1]), grid.dt)
        keep = np.ones(i1 - i0, dtype=bool)
        if len(chunks) > 1:
            k = (i1 - i0) // 10
            keep[:k] = keep[-k:] = False
        vds.append(v1[keep])
        ods.append(o1[keep])
    np.testing.assert_allclose(vd, np.concatenate(vds), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(od, np.concatenate(ods), rtol=1e-9, atol=1e-12)
    assert gain == pytest.approx(identify_module._noise_gains(min(size, 20000), grid.dt, sos)[0], rel=1e-9)

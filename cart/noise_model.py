"""Sensor noise measured from a log: level *and* colour (a first-order autoregressive model).

F/T sensors have coloured noise: filtered inside the sensor, with drifts, it keeps its power at the low
frequencies where the cart's dynamics live, while third differences of the signal (the white-noise
level estimate) only see its high-frequency tail. The model here is the AR(1) process
``e_i = a e_(i-1) + sigma sqrt(1 - a^2) w_i`` (variance ``sigma^2``, lag-k correlation ``a^k``),
fitted to the variogram of the model's residual at lags up to ``HORIZON`` (a quarter second):
the log's unexplained wrench, whose fast part is the sensor's noise; its level at the lowest
frequencies (where the cart's dynamics live) follows from the fitted correlation, and slower
parts of the residual (a model misfit) are not taken for noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cart._kernels_identify import sosfilt

#: Longest lag (s) of the variogram: sensor noise decorrelates faster; slower residual is misfit.
HORIZON = 0.25
#: The horizon is at most this share of the log: on a short log slow misfit would look like noise.
MIN_HORIZONS = 50


@dataclass(frozen=True)
class AR1Noise:
    """An AR(1) noise: total std ``sigma`` and lag-one correlation ``a`` (0 for white noise)."""

    sigma: float
    a: float

    @property
    def low_frequency_std(self) -> float:
        """Return the std of the white noise with the same low-frequency power, sigma sqrt((1 + a) / (1 - a))."""
        return self.sigma * math.sqrt((1.0 + self.a) / max(1.0 - self.a, 1e-12))

    def unit_series(self, n: int, seed: int = 0) -> np.ndarray:
        """Return ``n`` samples of the unit-variance process (stationary start), from ``seed``."""
        burn = 0 if self.a <= 0.0 else min(int(10.0 / (1.0 - self.a)), 5000)
        w = np.random.default_rng(seed).standard_normal(n + burn)
        if self.a <= 0.0:
            return w
        sos = np.array([[math.sqrt(1.0 - self.a * self.a), 0.0, 0.0, 1.0, -self.a, 0.0]])
        return sosfilt(sos, w[:, None], np.zeros((1, 2, 1)))[burn:, 0]


def _robust_var(d: np.ndarray) -> float:
    """Return the variance of d from its median absolute deviation (Gaussian-consistent)."""
    if len(d) == 0:
        return 0.0
    return float((1.4826 * np.median(np.abs(d - np.median(d)))) ** 2)


def fit_ar1(r: np.ndarray, dt: float, horizon: float = HORIZON) -> AR1Noise:
    """Return the AR(1) model of the noise ``r`` (uniform period ``dt``) from its variogram up to ``horizon`` s.

    Fits ``sigma^2 (1 - a^L)`` to half the robust variance of ``r_(i+L) - r_i`` at lags L = 1 ... horizon / dt
    (log-spaced; at most a fiftieth of the log), with the correlation time ``-dt / ln a`` at most half the horizon: slower parts of ``r``
    (a model misfit) are not taken for sensor noise.
    """
    r = np.asarray(r, float)
    max_lag = max(2, min(int(round(horizon / dt)), len(r) // MIN_HORIZONS))
    lags = np.unique(np.round(np.geomspace(1, max_lag, 14)).astype(int))
    gam = np.array([0.5 * _robust_var(r[lag:] - r[:-lag]) for lag in lags])
    if not np.all(gam > 0):
        return AR1Noise(sigma=math.sqrt(max(float(np.max(gam)), 0.0)), a=0.0)
    a_max = math.exp(-2.0 / max_lag)
    a_grid = np.concatenate([[0.0], 1.0 - np.geomspace(1.0 - 1e-3, 1.0 - a_max, 80)])
    model = 1.0 - a_grid[:, None] ** lags[None, :]
    log_s2 = np.mean(np.log(gam)[None, :] - np.log(model), axis=1)
    err = np.sum((np.log(gam)[None, :] - np.log(model) - log_s2[:, None]) ** 2, axis=1)
    k = int(np.argmin(err))
    return AR1Noise(sigma=float(math.sqrt(math.exp(log_s2[k]))), a=float(a_grid[k]))

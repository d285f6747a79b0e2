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

from cart._kernels_identify import median, sosfilt

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
    return float((1.4826 * median(np.abs(d - median(d)))) ** 2)


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


#: Power-law exponents the spectral model may take: white (0) to flicker / pink (1). Steeper tails above the
#: regression's band are the cart's own wrench (its accelerations' spectrum falls as 1 / f^2 or faster), a
#: misfit's (a dry-friction step) or an AR(1) noise's beyond its corner: extrapolated down they would
#: call any misfit noise.
ALPHAS = np.linspace(0.0, 1.0, 21)
#: Log-spaced frequency bins of the periodogram the spectral model is fitted on.
FIT_BINS = 12
#: The flicker component is kept when it lowers the bins' weighted log-spectral error, below both white noise's
#: and the AR(1) model's, by this much: the chi-square quantile of one degree of freedom at 1e-3 (a small slope
#: of the band, extrapolated down by decades, would otherwise multiply the low-frequency noise).
FLICKER_CHI2 = 10.83
#: Below this weight (`flicker_weight`) the flicker component is dropped.
FLICKER_WEIGHT_MIN = 1e-3


@dataclass(frozen=True)
class SpectralNoise:
    """A stationary noise by its one-sided power spectral density ``S(f) = white + power (f / f_ref)^-alpha``.

    ``white``, ``power``: PSD levels (units^2 / Hz); ``S`` is held at ``S(f_min)`` below ``f_min``, the lowest
    frequency the log shows (one over its length); ``f_max``: the Nyquist frequency. Covers white noise
    (power 0), flicker (pink, 1 / f) noise, a random-walk drift (1 / f^2) and an AR(1) process above its corner.
    """

    white: float
    power: float
    alpha: float
    f_ref: float
    f_min: float
    f_max: float
    #: the AR(1) model of the same noise (:func:`fit_ar1`, fitted at the period ``0.5 / f_max``): the PSD is the
    #: larger of the two at each frequency
    ar1: AR1Noise | None = None

    def psd(self, f: np.ndarray) -> np.ndarray:
        """Return the one-sided PSD at the frequencies ``f`` (Hz)."""
        f = np.maximum(np.asarray(f, float), self.f_min)
        s = self.white + self.power * (f / self.f_ref) ** (-self.alpha)
        if self.ar1 is None:
            return s
        a, dt = self.ar1.a, 0.5 / self.f_max
        s_ar = 2.0 * dt * self.ar1.sigma**2 * (1.0 - a * a) / np.abs(1.0 - a * np.exp(-2j * math.pi * f * dt)) ** 2
        return np.maximum(s, s_ar)

    def variance(self, gain2: np.ndarray | None = None, f: np.ndarray | None = None) -> float:
        """Return the variance of the noise through a filter of power gain ``gain2`` at ``f`` (None: unfiltered)."""
        if f is None:
            f = np.geomspace(self.f_min, self.f_max, 4000)
        s = self.psd(f) * (1.0 if gain2 is None else gain2)
        return float(np.sum(0.5 * (s[1:] + s[:-1]) * np.diff(f)) + s[0] * self.f_min)

    @property
    def sigma(self) -> float:
        """Return the std of the raw noise."""
        return math.sqrt(max(self.variance(), 0.0))

    def band_white_std(self, f_hi: float) -> float:
        """Return the std of white noise (sampled at 2 f_max) with this noise's mean PSD over [f_min, f_hi]."""
        f = np.geomspace(self.f_min, max(f_hi, 1.001 * self.f_min), 400)
        mean_psd = self.variance(np.ones_like(f), f) / (f[-1] - f[0] + self.f_min)
        return math.sqrt(max(mean_psd * self.f_max, 0.0))


def periodogram(r: np.ndarray, dt: float, seg: int) -> tuple[np.ndarray, np.ndarray]:
    """Return (f, one-sided PSD) of ``r`` by Welch's method: Hann-windowed halves-overlapping segments of ``seg`` samples."""
    r = np.asarray(r, float)
    seg = max(8, min(seg, len(r)))
    starts = np.arange(0, len(r) - seg + 1, max(seg // 2, 1))
    win = np.hanning(seg)
    segs = np.stack([r[i : i + seg] for i in starts])
    segs = (segs - segs.mean(axis=1, keepdims=True)) * win
    p = np.mean(np.abs(np.fft.rfft(segs, axis=1)) ** 2, axis=0) * 2.0 * dt / np.sum(win**2)
    return np.fft.rfftfreq(seg, dt), p


def fit_spectrum(
    r: np.ndarray, dt: float, band: tuple[float, float], f_min: float, with_ar1: bool = True
) -> SpectralNoise:
    """Return the :class:`SpectralNoise` fitted to the periodogram of ``r`` (period ``dt``) over ``band`` (Hz).

    The band lies above the regression's cut-off, where the model's residual is the sensor's noise (the
    cart's dynamics, and a misfit of them, live below the cut-off). The periodogram (:func:`periodogram`,
    segments resolving the band's low edge) is averaged in ``FIT_BINS`` log-spaced bins; for each exponent
    of ``ALPHAS`` the non-negative levels (white, power) minimise the relative error, and the exponent with
    the least weighted log-spectral error is kept; the PSD is the larger of it, scaled by its weight
    against the better of the white fit (alpha 0) and the AR(1) model (:func:`flicker_weight`: 1/2 where the
    power law's error is ``FLICKER_CHI2`` below theirs), and the AR(1) model's (:func:`fit_ar1`); the AR(1)
    model's alone when that weight is below ``FLICKER_WEIGHT_MIN``.
    Below the band the power law is extrapolated down to ``f_min``. ``with_ar1=False``: the power law alone
    (white when the flicker component does not pass ``FLICKER_CHI2``), for an ``r`` whose slow part is not
    noise (a raw wrench, which carries the cart's own dynamics below the band).
    """
    f_max = 0.5 / dt
    lo, hi = max(band[0], 2.0 * f_min), min(band[1], f_max)
    seg = int(2 ** math.ceil(math.log2(max(8.0 / (lo * dt), 16.0))))
    seg = min(seg, max(len(r) // 4, 16))
    f, p = periodogram(r, dt, seg)
    edges = np.geomspace(lo, max(hi, 1.01 * lo), FIT_BINS + 1)
    idx = np.digitize(f, edges) - 1
    used = [i for i in range(FIT_BINS) if np.any(idx == i)]
    fb = np.array([np.mean(f[idx == i]) for i in used])
    pb = np.array([np.mean(p[idx == i]) for i in used])
    # log of a mean of K chi-square(2) / 2 values has a variance of about 1 / K (half-overlapping segments)
    kb = np.array([np.sum(idx == i) for i in used]) * max(len(r) // seg, 1)
    ar1 = fit_ar1(r, dt) if with_ar1 else None
    only_ar1 = SpectralNoise(0.0, 0.0, 0.0, lo, f_min, f_max, ar1)
    if len(fb) < 4 or not np.all(pb > 0):
        return only_ar1
    best, err_white, white_level = (math.inf, 0.0, 0.0, 0.0), math.inf, float(np.mean(pb))
    for alpha in ALPHAS:
        g = (fb / lo) ** (-alpha)
        basis = np.column_stack([np.ones_like(fb), g]) / pb[:, None]
        coef = np.linalg.lstsq(basis, np.ones_like(fb), rcond=None)[0]
        if coef[0] < 0 or coef[1] < 0:
            coef = np.array([float(np.mean(pb)), 0.0]) if coef[1] < 0 else np.array([0.0, float(np.mean(pb / g))])
        model = coef[0] + coef[1] * g
        err = float(np.sum(kb * np.log(np.maximum(model, 1e-300) / pb) ** 2))
        if alpha == 0.0:
            err_white, white_level = err, float(coef[0] + coef[1])
        if err < best[0] - 1e-12:
            best = (err, float(coef[0]), float(coef[1]), float(alpha))
    if not with_ar1:
        if err_white <= best[0] + FLICKER_CHI2 or best[2] <= 0:
            return SpectralNoise(white_level, 0.0, 0.0, lo, f_min, f_max)
        return SpectralNoise(best[1], best[2], best[3], lo, f_min, f_max)
    err_ar1 = float(np.sum(kb * np.log(only_ar1.psd(fb) / pb) ** 2))
    w = flicker_weight(best[0], min(err_ar1, err_white))
    if w < FLICKER_WEIGHT_MIN or best[2] <= 0:
        return only_ar1  # the AR(1) model describes the band about as well: no flicker component
    return SpectralNoise(w * best[1], w * best[2], best[3], lo, f_min, f_max, ar1)


def flicker_weight(err_flicker: float, err_other: float) -> float:
    """Return the weight (0-1) of the flicker component against the better of the white and AR(1) models.

    The two models' weighted log-spectral errors are chi-square-like; the flicker fit pays ``FLICKER_CHI2`` for its
    extra freedom, and the weight is its relative likelihood, ``1 / (1 + exp((err_flicker + FLICKER_CHI2 -
    err_other) / 2))``: 1/2 where a hard choice would switch, near 1 (or 0) a few units of error away. A hard
    switch let one noise model give way to the other on a small change of the log (an outside tester's log with
    a stuck F/T stretch left out: flicker 21.0 against AR(1) 31.6, then 22.5 against 38.0 with the rows cut
    instead; the mass moved by 4 %).
    """
    x = (err_flicker + FLICKER_CHI2 - err_other) / 2.0
    return 1.0 / (1.0 + math.exp(min(max(x, -50.0), 50.0)))


def lag_correlation(model: SpectralNoise, lag_s: float) -> float:
    """Return the noise's autocorrelation at a lag of ``lag_s`` seconds (Wiener-Khinchin)."""
    f = np.geomspace(model.f_min, model.f_max, 4000)
    var = model.variance(None, f)
    return model.variance(np.cos(2.0 * math.pi * f * lag_s), f) / var if var > 0 else 0.0


def sos_power_gain(sos: np.ndarray, f: np.ndarray, dt: float) -> np.ndarray:
    """Return |H(f)|^2 of the second-order sections ``sos`` (sampling period ``dt``) at the frequencies ``f``."""
    z1 = np.exp(-2j * math.pi * np.asarray(f, float) * dt)
    h = np.ones_like(z1)
    for b0, b1, b2, a0, a1, a2 in sos:
        h = h * (b0 + b1 * z1 + b2 * z1 * z1) / (a0 + a1 * z1 + a2 * z1 * z1)
    return np.abs(h) ** 2

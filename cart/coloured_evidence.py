"""An effect's evidence under coloured F/T noise: how far correlated window residuals inflate its Delta BIC.

The diagnosis scores an effect by the drop of -2 log L of window rows it treats as independent, each with
its profiled variance ``V_r`` (:func:`cart.diagnose._solve`). For an effect that changes the window rows by
``s`` (its fitted contribution) that drop is about ``sum_r s_r^T s_r / V_r``, and under independence its
null spread is the same. Flicker (1 / f) or slowly correlated F/T noise is correlated from window to
window: the score's real variance is ``s^T Sigma s`` with ``Sigma`` the windows' noise covariance, larger by
the factor :func:`evidence_inflation` returns for a slowly varying ``s`` (a floor slope, a bias, a payload
step), about 1 for a fast one (a time delay). ``Sigma``'s wrench part comes from the log's measured noise
spectrum (:func:`fit_wrench_noise`): ``s^T Sigma s = integral S(f) |W(f)|^2 df``, ``W`` the
Fourier transform of the piecewise-constant weight ``w(t) = s_k`` over window ``k``; the rest of ``V_r``
(the pose noise in the regressors) is taken as independent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cart.log_signals import Signals, window_integrals
from cart.noise_model import SpectralNoise, fit_spectrum

#: ``Signals.extras`` key of the log's :class:`WrenchNoise` (a "motion" key: it survives a time shift)
NOISE_KEY = ("motion", "wrench_noise")


@dataclass(frozen=True)
class WrenchNoise:
    """The measured spectra of the forward-force and yaw-torque noise of a log (:func:`fit_wrench_noise`)."""

    force: SpectralNoise
    torque: SpectralNoise


def fit_wrench_noise(sig: Signals) -> WrenchNoise | None:
    """Return the spectra of the forward-force and yaw-torque noise, fitted to the raw rows above the cart's band.

    The band is from four times the smoother's cut-off (about 1 / (2 half_window); the cart's own wrench lives
    below it) to a quarter of the sample rate; the power law found there (white or flicker,
    :func:`cart.noise_model.fit_spectrum`) is extrapolated down. None when the log's rate leaves no such band.
    The raw rows, not the model's residual: that carries the pose noise differentiated twice (the regressors'
    noise, which the fits model apart) and the smoother's lag.
    """
    dt = float(np.median(np.diff(sig.t)))
    fs, f_min = 1.0 / dt, 1.0 / max(float(sig.t[-1] - sig.t[0]), dt)
    band = (4.0 / (2.0 * sig.half_window), 0.25 * fs)
    if band[1] < 2.0 * band[0]:
        return None
    raw = np.column_stack([sig.f_fwd, sig.tau])
    if sig.wrench_measured is not None:  # a fill (a stuck sensor's stretch) has no noise: its samples are left out
        raw = raw[sig.wrench_measured]
    return WrenchNoise(*(fit_spectrum(raw[:, k], dt, band, f_min, with_ar1=False) for k in range(2)))


def _score_variance(model: SpectralNoise, t: np.ndarray, w: np.ndarray) -> float:
    """Return var(integral w(t) n(t) dt) for the noise ``n`` of spectrum ``model`` (samples ``t``, weights ``w``)."""
    dt = float(np.median(np.diff(t)))
    m = 2 * len(w)
    f = np.fft.rfftfreq(m, dt)
    z = np.abs(np.fft.rfft(w * dt, n=m)) ** 2
    s = model.psd(f)
    s[0] *= 0.5  # the one-sided sum stands for +-f: the zero frequency once
    return float(np.sum(s * z) / (m * dt))


def _window_noise_variance(model: SpectralNoise, t: np.ndarray, edges: np.ndarray) -> float:
    """Return the variance of one window's integral of the noise (the median window)."""
    length = int(np.median(np.diff(edges)))
    return _score_variance(model, t[: length + 1], np.ones(length + 1))


def evidence_inflation(sig: Signals, edges: np.ndarray, contribution: np.ndarray, var_rows: np.ndarray) -> float:
    """Return the factor (>= 1) by which window correlations inflate the evidence of an effect's ``contribution``.

    ``contribution`` (N, 3): the effect's forward force, yaw torque and lateral speed along the log (what it
    adds to the model's rows); ``var_rows`` (3,): the fit's profiled variance of each window row. 1 when the
    log has no measured noise spectrum (``NOISE_KEY`` in ``sig.extras``) or the contribution is zero.
    """
    noise = sig.extras.get(NOISE_KEY)
    if not isinstance(noise, WrenchNoise) or len(edges) < 3:
        return 1.0
    s_win = window_integrals(sig.t, contribution, edges)  # (K, 3)
    i0, i1 = int(edges[0]), int(edges[-1])
    which = np.clip(np.searchsorted(edges, np.arange(i0, i1 + 1), side="right") - 1, 0, len(s_win) - 1)
    t = sig.t[i0 : i1 + 1]
    assumed, real = 0.0, 0.0
    for r in range(3):
        ss = float(np.sum(s_win[:, r] ** 2))
        v = max(float(var_rows[r]), 1e-300)
        assumed += ss / v
        if r == 2 or ss == 0.0:
            real += ss / v
            continue
        model = noise.force if r == 0 else noise.torque
        v_wrench = min(_window_noise_variance(model, sig.t, edges), v)
        real += ((v - v_wrench) * ss + _score_variance(model, t, s_win[which, r])) / (v * v)
    return max(real / assumed, 1.0) if assumed > 0.0 else 1.0

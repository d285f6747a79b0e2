"""Batch identification of the cart's parameters from a whole log: filtered-regressor least squares.

The cart's equations of motion are linear in ``p = [m, m dx, m dy, J, c_v, c_w]``
(:func:`cart.dynamics.regressor`, the body-frame form of paper eq. 4), so a
whole log gives the over-determined system ``Y(q, qd, qdd) p = [F_u, tau]``.
The logged wrench is noisy, but here it is the *output* of the regression
(noise on the right-hand side leaves least squares unbiased), whereas the EKF
of paper eq. (8-20) takes it as an exact input (errors in variables: its mass
comes out high by the wrench-noise power over the excitation power).

Steps (robot identification practice: Gautier's IDIM-LS with parallel
filtering):

1. Resample on a uniform grid at the log's median period (linear
   interpolation; samples inside long gaps are masked out).
2. Low-pass the pose with a zero-phase Butterworth filter; differentiate
   twice; build Y. The same filter is applied to the wrench ("parallel
   filtering"), so both sides see the same band.
3. The cut-off is chosen from the log itself: the highest frequency at which
   the differentiated pose noise (the log's own noise level, propagated
   through the same filter numerically) stays below ``attenuation`` of the
   filtered acceleration's power in both rows. No metres, seconds or
   kilograms appear in the choice.
4. Weighted least squares with Huber weights (outliers), per-row scales from
   the residuals, bias-compensated: the (known) power of the differentiated
   pose noise is removed from the normal matrix.
5. Uncertainty: the larger of a heteroscedasticity-and-autocorrelation
   consistent (Newey-West) covariance and a block jackknife over contiguous
   stretches of the log (which also sees misfit that changes along the log);
   when a Coulomb-like resistance is significant, the shift it causes in the
   inertial parameters is added to their variance, and the share of the
   wrench that the model leaves unexplained beyond the noise is added as a
   relative uncertainty of every parameter (model uncertainty).
6. Model check: the residual RMS against what the wrench noise alone explains
   (``residual_ratio``, 1 for a model that fits).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from collections.abc import Callable
from typing import NamedTuple, TypedDict

import numpy as np

from cart import identify_casters as casters_model
from cart._kernels_identify import butter_lowpass_sos, median, sosfiltfilt, student_t_quantile
from cart.dynamics import regressor
from cart.errors import CartError, LogFormatError
from cart.log_signals import filter_support_keep
from cart.logs import CartLog
from cart.noise_model import SpectralNoise, fit_spectrum, sos_power_gain
from cart.params import CartParams
from cart.physical import constrained_fit
from cart.standing import pose_stands
from cart.streams import Streams, box_average, split_streams

#: Largest share of the filtered acceleration's power that differentiated pose noise may have (the
#: attenuation bias of the inertial parameters is about this share).
ATTENUATION = 0.005
#: RMS force (N) and torque (N m) below which a logged wrench says nothing (:func:`check_estimable`): far below the
#: noise of any F/T sensor (millinewtons at best); a wrench of subnormal numbers also breaks LAPACK's scaling.
NEGLIGIBLE_FORCE = 1e-6
NEGLIGIBLE_TORQUE = 1e-6
#: A model "fits" when the residual RMS is at most this many times what the wrench noise explains.
FIT_RATIO = 1.6
#: Significance of the Coulomb-resistance check (Wald test, two dof).
COULOMB_ALPHA = 1e-3
#: A residual whose excess over the noise lies below this share of the cut-off is read as slow sensor noise
#: (an offset's drift, a slowly decorrelating noise) when no Coulomb-like resistance is significant
#: (:func:`_slow_excess`); the spectral model, fitted above the cut-off, does not reach it.
SLOW_SHARE = 0.25
JACKKNIFE_BLOCKS = 10
#: Smallest residual (share of the filtered wrench RMS) that counts as misfit on a noise-free log.
FIT_FLOOR = 0.02
#: Samples x lags up to which the HAC sum runs lag by lag (beyond: the equal one-pass window form).
HAC_DIRECT = 2_000_000
#: Grid samples beyond which the cut-off is chosen on CUTOFF_CHUNKS evenly spaced stretches of the log.
CUTOFF_SAMPLES = 24_000
CUTOFF_CHUNKS = 4
#: Rows of the filtered regression beyond which they are decimated to DECIMATED_OVERSAMPLING per cut-off period:
#: at 4 rows per period the decimated rows' Nyquist frequency is 2 fc, where the forward-backward 4th-order
#: Butterworth passes |H|^2 = 1 / (1 + 2^8) (-48 dB) of what would alias.
DECIMATE_ABOVE = 60_000
DECIMATED_OVERSAMPLING = 4.0
#: Rows of the raw residual the wrench noise model is fitted on (the first ones: the noise is stationary).
NOISE_ROWS = 60_000


class IdentifiabilityError(CartError):
    """The log does not excite the parameters enough for any estimate (says what is missing)."""


class PhysicalStd(TypedDict):
    """1-sigma std of the physical parameters (`Identification.std`)."""

    mass: float
    com: list[float]
    inertia: float
    sigma: float
    sigma_yaw: float


class FitData(TypedDict):
    """The filtered regression ``x p = y`` (rows weighted by ``1 / scale^2``) at times ``t``, every ``step``-th row."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    scale: np.ndarray
    step: int


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify`: parameters, 1-sigma std, fit diagnostics and warnings.

    ``p`` / ``cov``: ``[m, m dx, m dy, J, c_v, c_w]`` and its covariance;
    ``std``: physical std (mass kg, com [dx, dy] m, inertia kg m^2 about the CoM,
    sigma N s/m, sigma_yaw N m s/rad); ``residual_ratio``: residual RMS / what
    the wrench noise explains, forward and yaw rows; ``coulomb``: the
    Coulomb-like resistance (N, N m) of the extended fit and its Wald statistic.
    """

    params: CartParams
    std: PhysicalStd
    p: np.ndarray = field(repr=False)
    cov: np.ndarray = field(repr=False)
    cutoff_hz: float
    residual_ratio: tuple[float, float]
    model_fits: bool
    coulomb: dict[str, float]
    noise: dict[str, float]
    warnings: tuple[str, ...]
    samples_used: int
    gaps: int
    streams: Streams | None = field(default=None, repr=False)
    wrench_noise: tuple[SpectralNoise, SpectralNoise] | None = None
    offsets: dict[str, float] = field(default_factory=dict)
    grid_dt: float = float("nan")
    fit_data: FitData | None = field(default=None, repr=False)
    casters: casters_model.Casters | None = None
    #: (forward residual ratio, mass, forward ratio above the slow band) of the same regression with the wrench
    #: (fx, fy) read in the cart frame {b} (:func:`_cart_frame_reading`)
    cart_frame: tuple[float, float, float] | None = None
    #: yaw residual ratio of the same regression with the torque moved from the world origin to {b}'s origin
    #: (:func:`_torque_origin_reading`); None when the model fits (only a misfit is checked)
    torque_origin: float | None = None


@dataclass(frozen=True)
class _Grid:
    t: np.ndarray
    q: np.ndarray
    gamma: np.ndarray
    valid: np.ndarray
    dt: float
    gaps: int


def _mark_gaps(valid: np.ndarray, tg: np.ndarray, t: np.ndarray, limit: float) -> int:
    """Mark grid points strictly inside intervals of ``t`` longer than ``limit`` invalid; return their number."""
    big = np.flatnonzero(np.diff(t) > limit)
    for i in big:
        valid[(tg > t[i]) & (tg < t[i + 1])] = False
    return int(len(big))


#: A uniform grid over the log's span with more than this many points per pose sample, and more than
#: ``GRID_POINTS_MAX`` points, holds mostly gaps: the log joins separate recordings (or its time column jumps),
#: and the grid's memory would grow with the gap, not the data (a 1e5 s jump in a 20 s log took 5 GB).
GRID_POINTS_PER_SAMPLE = 20.0
#: ... the grid of a 20-minute log at 200 Hz (about 0.35 GB of working memory): a shorter grid is always built
GRID_POINTS_MAX = 240_000


def _check_grid_span(source: str, t_pose: np.ndarray, n_grid: int, dt: float) -> None:
    """Raise LogFormatError when the grid of ``n_grid`` points at ``dt`` is ``GRID_POINTS_PER_SAMPLE`` times longer
    than the pose samples ``t_pose`` and longer than ``GRID_POINTS_MAX``: name the longest gap and say to split
    the log there."""
    if n_grid <= max(GRID_POINTS_PER_SAMPLE * len(t_pose), GRID_POINTS_MAX):
        return
    i = int(np.argmax(np.diff(t_pose)))
    gap = float(t_pose[i + 1] - t_pose[i])
    raise LogFormatError(
        f"{source}: the log spans {n_grid * dt:.4g} s but holds {len(t_pose)} pose samples at {1.0 / dt:.4g} Hz: "
        f"its time stamps jump by {gap:.4g} s between t = {t_pose[i]:.6g} and {t_pose[i + 1]:.6g} s; it joins "
        "separate recordings or its time column jumps: split the log at the jump (or fix the time stamps) and "
        "estimate each part"
    )


def _uniform_grid(log: CartLog, streams: Streams | None = None, gap_factor: float = 5.0) -> _Grid:
    """Return the log resampled on a uniform grid; grid points inside gaps > gap_factor periods are invalid.

    Single-rate logs: the grid is the log's median period, pose and wrench interpolated linearly.
    Multi-rate logs (:mod:`cart.streams`): the grid is the pose stream's period, the pose interpolated
    at its own instants, a faster wrench averaged over each grid cell.
    """
    st = streams if streams is not None else split_streams(log)
    t = log.t
    dt = float(median(np.diff(t)))
    if st.multi_rate or st.wrench.period < dt / 1.5 or st.pose.period > 1.5 * dt:
        dt = st.pose.period
    t0, t1 = max(st.pose.t[0], st.wrench.t[0]), min(st.pose.t[-1], st.wrench.t[-1])
    if not (math.isfinite(dt) and dt > 0 and t1 - t0 >= 12 * dt):
        raise IdentifiabilityError(
            f"{log.source}: the pose and the wrench overlap for {max(t1 - t0, 0.0):.3g} s only: nothing to estimate"
        )
    n = int(math.floor((t1 - t0) / dt + 1e-9)) + 1
    _check_grid_span(log.source, st.pose.t, n, dt)
    tg = t0 + dt * np.arange(n)
    q = np.column_stack([np.interp(tg, st.pose.t, st.pose.values[:, i]) for i in range(3)])
    if st.wrench.period < dt / 1.5:
        g = box_average(st.wrench.t, st.wrench.values, tg, dt)
    else:
        g = np.column_stack([np.interp(tg, st.wrench.t, st.wrench.values[:, i]) for i in range(3)])
    valid = np.ones(n, dtype=bool)
    gaps = _mark_gaps(valid, tg, st.pose.t, gap_factor * dt)
    gaps = max(gaps, _mark_gaps(valid, tg, st.wrench.t, gap_factor * max(dt, st.wrench.period)))
    return _Grid(tg, q, g, valid, dt, gaps)


def white_noise_std(y: np.ndarray) -> float:
    """Return the std of white noise on a smooth signal from its third differences (robust, MAD)."""
    d3 = np.diff(np.asarray(y, float), 3)
    if len(d3) == 0:
        return 0.0
    return float(1.4826 * median(np.abs(d3 - median(d3))) / math.sqrt(20.0))


def _filtfilt(sos: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Return the zero-phase filtered y (along axis 0), edge padding shortened for short signals."""
    return sosfiltfilt(sos, y, padlen=min(15, len(y) - 1))


def _pose_kinematics(qs: np.ndarray, dt: float) -> tuple[np.ndarray, ...]:
    """Return (theta, v, omega, vdot, omegadot) of the filtered pose qs (body frame, constraint w = 0)."""
    qd = np.gradient(qs, dt, axis=0)
    th = qs[:, 2]
    c, s = np.cos(th), np.sin(th)
    v = c * qd[:, 0] + s * qd[:, 1]
    om = qd[:, 2]
    return th, v, om, np.gradient(v, dt), np.gradient(om, dt)


def _kinematics(q: np.ndarray, dt: float, sos: np.ndarray) -> tuple[np.ndarray, ...]:
    """Return (theta, v, omega, vdot, omegadot) of the pose filtered by ``sos``."""
    return _pose_kinematics(_filtfilt(sos, q), dt)


def _unit_noise(n: int, seed: int = 0) -> np.ndarray:
    """Return the white unit noise (at most 20000 samples) whose filtered version gives the pipeline's noise gains."""
    return np.random.default_rng(seed).standard_normal(min(n, 20000))


def _gains_of(ef: np.ndarray, dt: float) -> tuple[float, float, float]:
    """Return (acceleration std, output std, rate std) of filtered unit noise ``ef``, away from its ends."""
    m = len(ef)
    rate = np.gradient(ef, dt)
    acc = np.gradient(rate, dt)
    k = m // 10
    core = slice(k, m - k) if m > 50 else slice(None)
    return float(np.std(acc[core])), float(np.std(ef[core])), float(np.std(rate[core]))


def _noise_gains(n: int, dt: float, sos: np.ndarray, seed: int = 0) -> tuple[float, float, float]:
    """Return (acceleration std per unit pose noise, filtered-output std per unit input noise, rate std per unit
    pose noise) of the pipeline."""
    return _gains_of(_filtfilt(sos, _unit_noise(n, seed)), dt)


def _cutoff_chunks(n: int) -> list[tuple[int, int]]:
    """Return the grid stretches the cut-off is chosen on: the whole grid, or evenly spaced chunks of a long one."""
    if n <= CUTOFF_SAMPLES:
        return [(0, n)]
    size = CUTOFF_SAMPLES // CUTOFF_CHUNKS
    starts = np.linspace(0, n - size, CUTOFF_CHUNKS).astype(int)
    return [(int(i0), int(i0) + size) for i0 in starts]


def _chunk_accelerations(
    grid: _Grid, sos: np.ndarray, e: np.ndarray, chunks: list[tuple[int, int]]
) -> tuple[np.ndarray, np.ndarray, float]:
    """Return (vdot, omegadot on the valid samples of the chunks, acceleration noise gain) at one filter."""
    vds, ods = [], []
    size = chunks[0][1] - chunks[0][0]  # the chunks have one length: one pass filters them all, the noise once
    poses = [grid.q[i0:i1] for i0, i1 in chunks]
    if len(e) >= size:
        both = _filtfilt(sos, np.column_stack(poses + [e[:size]]))
        ef = both[:, -1]
    else:  # one stretch longer than the unit noise (20000 < n <= CUTOFF_SAMPLES): the noise filtered on its own
        both = _filtfilt(sos, np.column_stack(poses))
        ef = _filtfilt(sos, e)
    for c, (i0, i1) in enumerate(chunks):
        _, _, _, vd, od = _pose_kinematics(both[:, 3 * c : 3 * c + 3], grid.dt)
        valid = grid.valid[i0:i1]
        if len(chunks) > 1:  # away from the chunk's own ends
            k = (i1 - i0) // 10
            valid = valid.copy()
            valid[:k] = valid[-k:] = False
        vds.append(vd[valid])
        ods.append(od[valid])
    acc_gain = _gains_of(ef, grid.dt)[0]
    return np.concatenate(vds), np.concatenate(ods), acc_gain


def _choose_cutoff(grid: _Grid, pos_std: float, th_std: float, attenuation: float) -> tuple[float, list[str]]:
    """Return the highest cut-off (Hz) whose acceleration noise stays below ``attenuation`` of the signal power."""
    fs = 1.0 / grid.dt
    warnings: list[str] = []
    top = 0.4 * fs / 2.0
    duration = grid.t[-1] - grid.t[0]
    low = max(4.0 / max(duration, 1e-9), 1e-3 * fs)
    candidates = np.geomspace(top, low, 40) if top > low else np.array([top])
    best = None
    chunks = _cutoff_chunks(len(grid.t))
    e = _unit_noise(max(i1 - i0 for i0, i1 in chunks))
    for fc in candidates:
        sos = butter_lowpass_sos(4, fc / (fs / 2.0))
        vd, od, acc_gain = _chunk_accelerations(grid, sos, e, chunks)
        noise_v, noise_o = (pos_std * acc_gain) ** 2, (th_std * acc_gain) ** 2
        share_v = noise_v / max(float(np.var(vd)), 1e-300)
        share_o = noise_o / max(float(np.var(od)), 1e-300)
        if share_v <= attenuation and share_o <= attenuation:
            best = fc
            break
        if best is None and share_v <= attenuation:
            best = fc  # the yaw row may never be clean; keep looking a little for both
    if best is None:
        best = candidates[-1]
        warnings.append(
            "the pose noise dominates the accelerations at every cut-off: the log barely "
            "excites the inertia (push harder or longer, or log the pose with less noise)"
        )
    return float(best), warnings


def _offset_columns(th: np.ndarray) -> np.ndarray:
    """Return the (k, 2, 4) regressor of the wrench sensor's offsets.

    Forward row: a constant forward force (offset in the sensor's frame, which moves with the cart)
    and the world-frame offsets (fx0, fy0) projected on the heading; yaw row: a constant torque.
    """
    z, one = np.zeros_like(th), np.ones_like(th)
    return np.stack([np.stack([one, np.cos(th), np.sin(th), z], -1), np.stack([z, z, z, one], -1)], -2)


def _design(grid: _Grid, sos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (X (k, 2, N_P), y (k, 2), v, omega, raw y (k, 2)) of the filtered regression on the grid.

    X: the dynamics' regressor (paper eq. 4, ``cart.dynamics.regressor``) and the sensor offsets.
    """
    th, v, om, vd, od = _kinematics(grid.q, grid.dt, sos)
    c, s = np.cos(th), np.sin(th)
    fu = c * grid.gamma[:, 0] + s * grid.gamma[:, 1]
    y_raw = np.column_stack([fu, grid.gamma[:, 2]])
    y = _filtfilt(sos, y_raw)
    x = np.concatenate([regressor(v, om, vd, od), _offset_columns(th)], axis=-1)
    return x, y, v, om, y_raw


def _with_coulomb_columns(x: np.ndarray, v: np.ndarray, om: np.ndarray, eps: tuple[float, float]) -> np.ndarray:
    """Return X with two more columns: Coulomb-like forward force tanh(v / eps_v) and yaw torque tanh(omega / eps_w)."""
    z = np.zeros_like(v)
    extra = np.stack([np.stack([np.tanh(v / eps[0]), z], -1), np.stack([z, np.tanh(om / eps[1])], -1)], -2)
    return np.concatenate([x, extra], axis=-1)


def _keep_mask(grid: _Grid, fc: float) -> np.ndarray:
    """Return the grid samples away from the ends (one filter settling time) and from gaps (the filter's reach)."""
    return filter_support_keep(grid.valid, fc, grid.dt)


def _noise_correction(wts: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """Return sum_k sum_rows wts[k, r] diag(noise[r]): the regressor-noise part of the weighted normal matrix."""
    return np.diag(wts[:, 0].sum() * noise[0] + wts[:, 1].sum() * noise[1])


def _normal(x: np.ndarray, y: np.ndarray, wts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (sum_k X_k^T W_k X_k, sum_k X_k^T W_k y_k) of rows x (k, 2, P), y (k, 2), diagonal weights (k, 2)."""
    sw = np.sqrt(wts)
    xs = (x * sw[:, :, None]).reshape(-1, x.shape[-1])
    return xs.T @ xs, xs.T @ (y * sw).reshape(-1)


def _predict(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Return X p (k, 2) of rows x (k, 2, P)."""
    return (x.reshape(-1, x.shape[-1]) @ p).reshape(x.shape[0], 2)


def _wls(
    x: np.ndarray, y: np.ndarray, noise: np.ndarray, iterations: int = 4
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (p, row scales (2,), weights (k, 2)) of Huber-weighted, bias-compensated least squares.

    ``noise`` (2, n_p): variance of the white part of each regressor entry, per row; its
    contribution is removed from the normal matrix (bias-compensated least squares for errors in
    the regressor).
    """
    k, _, n_p = x.shape
    scale = np.array([np.std(y[:, 0]) + 1e-300, np.std(y[:, 1]) + 1e-300])
    w = np.ones((k, 2))
    p = np.zeros(n_p)
    for _ in range(iterations):
        wts = w / scale**2
        a, b = _normal(x, y, wts)
        a = a - _noise_correction(wts, noise)
        p = np.linalg.lstsq(a, b, rcond=None)[0]
        r = y - _predict(x, p)
        scale = np.array([1.4826 * median(np.abs(r[:, i])) + 1e-300 for i in range(2)])
        u = np.abs(r) / (1.5 * scale)
        w = np.where(u <= 1.0, 1.0, 1.0 / np.maximum(u, 1e-300))
    return p, scale, w


def _hac_cov(x: np.ndarray, r: np.ndarray, wts: np.ndarray, noise: np.ndarray, lag: int) -> np.ndarray:
    """Return the Newey-West covariance of the weighted least-squares estimate (Bartlett kernel, ``lag``)."""
    xw = x * wts[:, :, None]
    a = _normal(x, r, wts)[0] - _noise_correction(wts, noise)
    score = xw[:, 0, :] * r[:, :1] + xw[:, 1, :] * r[:, 1:]  # (k, n_p)
    lag = min(lag, len(score) - 1)
    if len(score) * lag <= HAC_DIRECT:
        s = score.T @ score
        for l in range(1, lag + 1):
            g = score[l:].T @ score[:-l]
            s += (1.0 - l / (lag + 1.0)) * (g + g.T)
    else:  # the same Bartlett sum in one pass: sums over every window of lag + 1 samples (zero-padded ends)
        pad = np.zeros((lag, score.shape[1]))
        c = np.cumsum(np.concatenate([pad, score, pad]), axis=0)
        c = np.concatenate([np.zeros((1, score.shape[1])), c])
        w = c[lag + 1 :] - c[: -lag - 1]
        s = w.T @ w / (lag + 1.0)
    a_inv = np.linalg.pinv(a)
    return a_inv @ s @ a_inv


def _jackknife_cov(x: np.ndarray, y: np.ndarray, wts: np.ndarray, noise: np.ndarray, blocks: int) -> np.ndarray:
    """Return the delete-one-block jackknife covariance of the weighted least-squares estimate."""
    k, _, n_p = x.shape
    edges = np.linspace(0, k, blocks + 1).astype(int)
    ab = [_normal(x[i0:i1], y[i0:i1], wts[i0:i1]) for i0, i1 in zip(edges[:-1], edges[1:])]
    a_blocks = [a_i - _noise_correction(wts[i0:i1], noise) for (a_i, _), i0, i1 in zip(ab, edges[:-1], edges[1:])]
    b_blocks = [b_i for _, b_i in ab]
    a_all, b_all = sum(a_blocks), sum(b_blocks)
    ests = np.array([np.linalg.lstsq(a_all - a_i, b_all - b_i, rcond=None)[0] for a_i, b_i in zip(a_blocks, b_blocks)])
    d = ests - ests.mean(axis=0)
    # blocks - 1 degrees of freedom: scale to the Student-t 95 % quantile so that 2 std cover ~95 %
    t_scale = (student_t_quantile(0.975, blocks - 1) / 1.959964) ** 2
    return t_scale * (blocks - 1) / blocks * d.T @ d


def _held_out_ssr(x: np.ndarray, y: np.ndarray, wts: np.ndarray, noise: np.ndarray, blocks: int) -> float:
    """Return the weighted squared error summed over ``blocks`` contiguous stretches, each predicted by the others' fit.

    Cross-validation by blocks (as in :func:`_jackknife_cov`): columns nearly collinear with the others fit
    the log's misfit rather than an effect and predict a held-out stretch worse, however large their Wald
    statistic.
    """
    k = x.shape[0]
    edges = np.linspace(0, k, blocks + 1).astype(int)
    spans = list(zip(edges[:-1], edges[1:]))
    ab = [_normal(x[i0:i1], y[i0:i1], wts[i0:i1]) for i0, i1 in spans]
    a_blocks = [a_i - _noise_correction(wts[i0:i1], noise) for (a_i, _), (i0, i1) in zip(ab, spans)]
    a_all, b_all = sum(a_blocks), sum(b for _, b in ab)
    total = 0.0
    for (i0, i1), a_i, (_, b_i) in zip(spans, a_blocks, ab):
        p = np.linalg.lstsq(a_all - a_i, b_all - b_i, rcond=None)[0]
        total += float(np.sum(wts[i0:i1] * (y[i0:i1] - _predict(x[i0:i1], p)) ** 2))
    return total


def _physical_std(p: np.ndarray, cov: np.ndarray) -> PhysicalStd:
    """Return the std of (m, dx, dy, I about the CoM, c_v, c_w) by linearising the phi -> physical map."""
    m, a, b, j = p[:4]
    jac = np.zeros((6, 6))
    jac[:4, :4] = [
        [1.0, 0.0, 0.0, 0.0],
        [-a / m**2, 1.0 / m, 0.0, 0.0],
        [-b / m**2, 0.0, 1.0 / m, 0.0],
        [(a * a + b * b) / m**2, -2.0 * a / m, -2.0 * b / m, 1.0],
    ]
    jac[4, 4] = jac[5, 5] = 1.0
    std = np.sqrt(np.maximum(np.diag(jac @ cov[:6, :6] @ jac.T), 0.0))
    return {
        "mass": float(std[0]),
        "com": [float(std[1]), float(std[2])],
        "inertia": float(std[3]),
        "sigma": float(std[4]),
        "sigma_yaw": float(std[5]),
    }


def _fit(
    x: np.ndarray, y: np.ndarray, noise: np.ndarray, lag: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (p, cov, row scales, residuals) of one weighted fit with its HAC / jackknife covariance."""
    n_p = x.shape[-1]
    noise = np.pad(noise, ((0, 0), (0, n_p - noise.shape[1])))
    p, scale, w = _wls(x, y, noise)
    wts = w / scale**2
    r = y - _predict(x, p)
    cov_hac = _hac_cov(x, r, wts, noise, lag)
    cov_jk = _jackknife_cov(x, y, wts, noise, JACKKNIFE_BLOCKS)
    sd = np.sqrt(np.maximum(np.maximum(np.diag(cov_hac), np.diag(cov_jk)), 0.0))
    sd_hac = np.sqrt(np.maximum(np.diag(cov_hac), 1e-300))
    corr = cov_hac / np.outer(sd_hac, sd_hac)
    return p, corr * np.outer(sd, sd), scale, r


@dataclass(frozen=True)
class _Noise:
    """White-noise stds the log shows: pose (position m, heading rad), wrench (force N, torque N m); pose span (m)."""

    pos: float
    theta: float
    force: float
    torque: float
    span: float


def _noise_levels(log: CartLog, streams: Streams) -> _Noise:
    """Return the log's noise levels (floored, scale-free) of a log :func:`check_estimable` passed.

    Pose noise: white, measured on the pose stream at its own instants; wrench: the white level here,
    replaced by the residual's coloured-noise model (:mod:`cart.noise_model`) after the fit.
    """
    q, g = streams.pose.values, streams.wrench.values
    pos_std = max(white_noise_std(q[:, 0]), white_noise_std(q[:, 1]))
    th_std = white_noise_std(q[:, 2])
    f_std = max(white_noise_std(g[:, 0]), white_noise_std(g[:, 1]))
    tau_std = white_noise_std(g[:, 2])
    span = float(np.max(np.ptp(q[:, :2], axis=0)))
    # floors: a noise-free log still has rounding; keep the choice scale-free
    return _Noise(pos=max(pos_std, 1e-9 * span), theta=max(th_std, 1e-9), force=f_std, torque=tau_std, span=span)


@dataclass(frozen=True)
class _Regression:
    """The filtered regression kept for the fit: X (k, 2, 6), y (k, 2), v and omega on the kept samples."""

    x: np.ndarray
    y: np.ndarray
    v: np.ndarray
    om: np.ndarray
    keep: np.ndarray
    y_raw: np.ndarray
    #: v and omega on every grid sample (the caster lanes run along the whole grid)
    vo_grid: tuple[np.ndarray, np.ndarray] | None = None


def _regression(log: CartLog, grid: _Grid, fc: float, sos: np.ndarray) -> _Regression:
    """Return the filtered regression at cut-off ``fc`` away from the ends and gaps; raise when too short or not finite."""
    x, y, v, om, y_raw = _design(grid, sos)
    keep = _keep_mask(grid, fc)
    if keep.sum() < 8:
        raise IdentifiabilityError(
            f"{log.source}: the log is too short for its own bandwidth "
            f"({grid.t[-1] - grid.t[0]:.3g} s at a {fc:.3g} Hz cut-off)"
        )
    x, y = x[keep], y[keep]
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise IdentifiabilityError(f"{log.source}: the filtered log is not finite (values out of range)")
    return _Regression(x=x, y=y, v=v[keep], om=om[keep], keep=keep, y_raw=y_raw[keep], vo_grid=(v, om))


def _verdict(
    reg: _Regression,
    noise_lag: tuple[np.ndarray, int],
    fit: tuple[np.ndarray, np.ndarray, np.ndarray],
    noise_terms: tuple,
    warnings: list[str],
    rows_fc: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, float], bool]:
    """Return (p, cov, residual ratio, explained RMS, Coulomb dict, model fits) of the fit ``fit`` (p, cov,
    residuals): the fit with a rolling resistance when that explains its misfit (:func:`_rolling_resistance_fit`),
    else the fit with its model uncertainty (:func:`_model_uncertainty`); appends the warnings."""
    p, cov, r = fit
    out_std, sv, so = noise_terms
    ratio, expected = _residual_ratio(out_std, sv, so, p, r, reg.y)
    check = _coulomb_check(reg, *noise_lag, p)
    rolling = _rolling_resistance_fit(reg, noise_lag, (p, cov), noise_terms, check)
    if rolling is not None:  # a rolling (Coulomb-like) resistance the viscous model lacks, and with it the model fits
        warnings.append(_rolling_note(check.coulomb))
        return (*rolling, check.coulomb, True)
    cov, fits = _model_uncertainty(reg, p, cov, (ratio, expected), warnings, rows_fc, check)
    return p, cov, ratio, expected, check.coulomb, fits


def _rolling_resistance_fit(
    reg: _Regression,
    noise_lag: tuple[np.ndarray, int],
    fit: tuple[np.ndarray, np.ndarray],
    noise_terms: tuple,
    check: CoulombCheck,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Return (p, cov, residual ratio, explained RMS) of the fit with Coulomb-like forward and yaw resistances
    (``check.extended``, :func:`_coulomb_check`) when they are significant and with them the model fits (every
    row within FIT_RATIO); None otherwise (the nominal ``fit`` (p, cov) stands, their shift counted as model
    uncertainty by :func:`_model_uncertainty`).

    A cart's casters and wheels resist rolling with a force that does not grow with the speed: a viscous-only
    model misfits it and would report a log of a plain cart as not fitting, its std 25 times the error (an outside
    tester's change-free carts with 0.09-0.12 N/kg of rolling resistance: 57.76 +- 7.8 kg for 57.46). The
    parameters are the extended fit's; each std is the nominal (generalised) fit's widened by the extended fit's
    variance inflation (the Coulomb columns' collinearity with the others). ``noise_terms``: (out_std, sv, so) of
    :func:`_residual_ratio`.
    """
    if check.shift is None or check.extended is None:
        return None
    (p, cov), (pc, covc, rc) = fit, check.extended
    out_std, sv, so = noise_terms
    ratio, expected = _residual_ratio(out_std, sv, so, pc, rc, reg.y)
    if not np.all(ratio <= FIT_RATIO):
        return None
    try:
        _, cov_plain, _, _ = _fit(reg.x, reg.y, *noise_lag)
    except np.linalg.LinAlgError:
        return None
    n = len(p)
    inflation = np.maximum(np.diag(covc)[:n] / np.maximum(np.diag(cov_plain), 1e-300), 1.0)
    scale = np.sqrt(inflation)
    return pc[:n], cov * np.outer(scale, scale), ratio, expected


def _rolling_note(coulomb: dict[str, float]) -> str:
    """Return the warning that a Coulomb-like resistance is part of the fitted model."""
    return (
        f"a Coulomb-like resistance ({coulomb['force']:.3g} N forward, {coulomb['torque']:.3g} N m yaw: rolling "
        "resistance, bearing friction) is fitted beside the viscous model, and with it the model fits; the "
        "parameters and their std are that fit's (`cartpush diagnose` names the effect)"
    )


def _coulomb_eps(reg: _Regression) -> tuple[float, float]:
    """Return the speeds (forward, yaw) below which the Coulomb-like columns' tanh turns linear."""
    return 0.05 * float(np.std(reg.v)) + 1e-12, 0.05 * float(np.std(reg.om)) + 1e-12


def _coulomb_check(reg: _Regression, noise: np.ndarray, lag: int, p: np.ndarray) -> CoulombCheck:
    """Return the Coulomb-like resistance of the extended fit (force, torque, Wald), its shift when significant
    (the change of the six parameters the extra columns cause: model uncertainty) and that fit (p, cov, residuals;
    None when it is singular)."""
    eps = _coulomb_eps(reg)
    try:
        pc, covc, _, rc = _fit(_with_coulomb_columns(reg.x, reg.v, reg.om, eps), reg.y, noise, lag)
        ext: tuple[np.ndarray, np.ndarray, np.ndarray] | None = (pc, covc, rc)
    except np.linalg.LinAlgError:
        pc, covc, ext = np.r_[p, 0.0, 0.0], np.full((len(p) + 2, len(p) + 2), np.nan), None
    cc = covc[-2:, -2:]
    wald = float(pc[-2:] @ np.linalg.pinv(cc) @ pc[-2:]) if np.all(np.isfinite(cc)) else 0.0
    coulomb = {"force": float(pc[-2]), "torque": float(pc[-1]), "wald": wald}
    return CoulombCheck(coulomb, pc[:-2] - p if wald > -2.0 * math.log(COULOMB_ALPHA) else None, ext)


class CoulombCheck(NamedTuple):
    """The Coulomb-like resistance test (:func:`_coulomb_check`)."""

    coulomb: dict[str, float]
    shift: np.ndarray | None
    extended: tuple[np.ndarray, np.ndarray, np.ndarray] | None


def _misfit_scale(
    p: np.ndarray, ratio: np.ndarray, expected: np.ndarray, y: np.ndarray, fits: bool, slow: bool = False
) -> np.ndarray:
    """Return the model-uncertainty std of each parameter: the unexplained share of the wrench times its scale.

    The share the model leaves unexplained beyond the noise could bias each parameter by up to that
    share of its own scale (scale-free; zero when the model fits); forward row: m, c_v; yaw row: J,
    c_w; both: the first moments. An excess read as slow sensor noise (``slow``, :func:`_slow_excess`: the
    model fits) is counted beyond the verdict's bound (``ratio^2 - FIT_RATIO^2``), so the std grows from that
    of a fitting model as the ratio passes FIT_RATIO instead of jumping there: with ``ratio^2 - 1`` an outside
    tester's recording read 36.94 +- 1.21 kg as a held-pose table (ratio 1.59) and 36.95 +- 3.32 kg as mocap
    rows (1.61). A misfit counts all of it.
    """
    y_rms = np.sqrt(np.mean(y**2, axis=0)) + 1e-300
    floor = FIT_RATIO**2 if slow else 1.0
    sh = np.sqrt(np.maximum(ratio**2 - floor, 0.0)) * expected / y_rms if not fits else np.zeros(2)
    m_, a_, b_, j_, cv_, cw_ = p[:6]
    gyr = math.sqrt(abs(j_) / abs(m_)) if m_ != 0 else 0.0
    out = np.zeros(len(p))
    out[:6] = [sh[0] * m_, sh.max() * abs(m_) * gyr, sh.max() * abs(m_) * gyr, sh[1] * j_, sh[0] * cv_, sh[1] * cw_]
    return out


def _physical_params(log: CartLog, p: np.ndarray, cov: np.ndarray) -> tuple[CartParams, float]:
    """Return the CartParams of p = [m, m dx, m dy, J, c_v, c_w] and the inertia about the CoM; raise if unphysical."""
    m, a, b, j, c_v, c_w = p[:6]
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(np.diag(cov)))):
        raise IdentifiabilityError(
            f"{log.source}: the least-squares problem is singular: the log does not excite "
            "the parameters (no acceleration or turning above the noise)"
        )
    if not (m > 0):
        raise IdentifiabilityError(
            f"{log.source}: the fit gives a non-positive mass ({m:.3g} kg): the log does "
            "not excite the mass (no forward acceleration above the noise)"
        )
    inertia = j - (a * a + b * b) / m
    return CartParams(
        m=m, dx=a / m, dy=b / m, I=max(inertia, 1e-3 * abs(j), 1e-8), sigma=max(c_v, 0.0), sigma_yaw=max(c_w, 0.0)
    ), inertia


def _decimation(rows: int, fs: float, fc: float) -> int:
    """Return the step by which the filtered regression's rows are taken: 1, or for a long log the step that
    keeps DECIMATED_OVERSAMPLING samples per period of the cut-off (the rows are band-limited by the filter)."""
    if rows <= DECIMATE_ABOVE:
        return 1
    return max(1, int(fs / (DECIMATED_OVERSAMPLING * fc)))


def _every(reg: _Regression, step: int) -> _Regression:
    """Return every ``step``-th row of the regression (``keep``, the grid mask, unchanged)."""
    if step == 1:
        return reg
    return replace(reg, x=reg.x[::step], y=reg.y[::step], v=reg.v[::step], om=reg.om[::step], y_raw=reg.y_raw[::step])


def _wrench_noise(
    reg: _Regression, p: np.ndarray, dt: float, sos: np.ndarray
) -> tuple[SpectralNoise, SpectralNoise, np.ndarray]:
    """Return the spectral noise models of the forward and yaw rows and their filtered-output std (2,).

    Measured on the raw (unfiltered) wrench minus the model's prediction (:func:`cart.noise_model.fit_spectrum`)
    over the band from twice the cut-off (where the filtered regression leaves no signal and a misfit of the
    cart's dynamics has little power) to a quarter of the sample rate (below the attenuation of a wrench
    averaged over each sample); the output std integrates the model's PSD times the zero-phase filter's
    power gain |H|^4 from the log's lowest frequency.
    """
    n_rows = min(len(reg.y_raw), NOISE_ROWS)
    r_raw = reg.y_raw[:n_rows] - _predict(reg.x[:n_rows], p)
    fs, f_min = 1.0 / dt, 1.0 / (len(reg.y_raw) * dt)
    fc = _cutoff_of(sos, dt)
    band = (min(4.0 * fc, 0.125 * fs), min(max(0.25 * fs, 8.0 * fc), 0.5 * fs))
    models = (fit_spectrum(r_raw[:, 0], dt, band, f_min), fit_spectrum(r_raw[:, 1], dt, band, f_min))
    f = np.geomspace(f_min, 0.5 * fs, 4000)
    gain = sos_power_gain(sos, f, dt) ** 2
    out = np.array([math.sqrt(max(mdl.variance(gain, f), 0.0)) for mdl in models])
    return models[0], models[1], out


def _cutoff_of(sos: np.ndarray, dt: float) -> float:
    """Return the -3 dB frequency (Hz) of the low-pass ``sos`` (bisection on its power gain)."""
    lo, hi = 0.0, 0.5 / dt
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if sos_power_gain(sos, np.array([mid]), dt)[0] > 0.5 else (lo, mid)
    return 0.5 * (lo + hi)


def _spectral_cov(x: np.ndarray, wts: np.ndarray, a: np.ndarray, psds: tuple, sos_dt: tuple) -> np.ndarray:
    """Return the covariance of the weighted least-squares estimate under the noise spectra ``psds``.

    The score ``sum_k X_k^T W_k e_k`` of filtered noise ``e`` (PSD ``S(f) |H(f)|^4``, :func:`_wrench_noise`;
    ``psds``: one callable ``f -> S(f)`` per row) has the variance ``sum_rows integral |Z(f)|^2 S(f) |H(f)|^4 df``,
    ``Z`` the Fourier transform of the weighted regressor column (rows spaced ``dt_rows``, zero-padded to twice
    their length: no wrap-around); the covariance is ``A^-1 V A^-1`` with ``A`` the (noise-compensated) normal
    matrix. Honest for any stationary noise the spectra describe, however slowly it decorrelates (a Newey-West
    window does not reach a 1 / f noise's correlations).
    """
    sos, dt, dt_rows = sos_dt
    m = 2 * x.shape[0]
    f = np.fft.rfftfreq(m, dt_rows)
    gain = sos_power_gain(sos, f, dt) ** 2
    v = np.zeros((x.shape[-1], x.shape[-1]))
    for row, psd in enumerate(psds):
        z = np.fft.rfft(x[:, row, :] * wts[:, row, None], n=m, axis=0)
        s = psd(f) * gain / (m * dt_rows)
        s[0] *= 0.5
        v += np.real((z.conj() * s[:, None]).T @ z)
    a_inv = np.linalg.pinv(a)
    return a_inv @ v @ a_inv


def _with_spectral_cov(reg: _Regression, fit: tuple, noise: np.ndarray, psds: tuple, sos_dt: tuple) -> np.ndarray:
    """Return the fit's covariance with each std at least the spectral one (:func:`_spectral_cov`, ``psds``).

    ``fit``: (p, cov, row scales, residuals) of :func:`_fit`; the Huber weights are those of its residuals.
    """
    _, cov, scale, r = fit
    u = np.abs(r) / (1.5 * scale)
    wts = np.where(u <= 1.0, 1.0, 1.0 / np.maximum(u, 1e-300)) / scale**2
    pad = np.pad(noise, ((0, 0), (0, reg.x.shape[-1] - noise.shape[1])))
    a = _normal(reg.x, reg.y, wts)[0] - _noise_correction(wts, pad)
    cov_sp = _spectral_cov(reg.x, wts, a, psds, sos_dt)
    sd_old = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    sd = np.maximum(sd_old, np.sqrt(np.maximum(np.diag(cov_sp), 0.0)))
    return cov / np.outer(sd_old, sd_old) * np.outer(sd, sd)


def _whitening(model: SpectralNoise, f_ref: float) -> Callable[[np.ndarray], np.ndarray]:
    """Return the amplitude response ``sqrt(S(f_ref) / S(f))`` that makes the noise ``model`` white (level at ``f_ref``)."""
    return lambda f: np.sqrt(model.psd(np.array([f_ref]))[0] / model.psd(f))


def _generalised_fit(
    reg: _Regression, models: tuple[SpectralNoise, SpectralNoise], noise_lag: tuple, sos_step: tuple, fit: tuple
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (p, cov, row scales, residuals of the unwhitened rows) of generalised least squares.

    ``fit``: the least-squares fit (:func:`_fit`), returned with each std at least the spectral one when neither
    noise model has a flicker component (the Newey-West and jackknife covariances read the noise from the
    residual, and the fit's offset and damping columns take up the slow part of an AR(1) noise, so they fall
    below what the noise gives); ``noise_lag``: the regressor noise and the HAC lag; ``sos_step``: the filter, the grid's
    step and the rows' decimation step.

    Each row's ``x`` and ``y`` pass through the same zero-phase filter ``sqrt(S(fc) / S(f))`` of its noise
    model (applied by FFT, zero-padded to twice the length): the model stays exact (a linear filter on both
    sides) and the noise becomes white below the cut-off, so the frequencies where flicker noise is weak
    weigh more (the efficient estimator, as in the Cramer-Rao bound of ``log_recorders``). The regressor
    noise's power in each row scales by the filter's mean power gain over its spectrum (``f^4 |H|^4``). The
    covariance: :func:`_fit`'s on the whitened rows, each std at least the spectral one.
    """
    noise, lag = noise_lag
    sos, dt, step = sos_step
    sos_dt, dt_rows = (sos, dt, dt * step), dt * step
    if all(mdl.power <= 0.0 for mdl in models):
        return fit[0], _with_spectral_cov(reg, fit, noise, tuple(mdl.psd for mdl in models), sos_dt), fit[2], fit[3]
    fc = _cutoff_of(sos, dt)
    k, m = len(reg.y), 2 * len(reg.y)
    f = np.fft.rfftfreq(m, dt_rows)
    acc = f**4 * sos_power_gain(sos, f, dt) ** 2
    xw, yw, scaled = np.empty_like(reg.x), np.empty_like(reg.y), noise.copy()
    psds = []
    for row, model in enumerate(models):
        g = _whitening(model, fc)
        gf = g(f)
        xw[:, row, :] = np.fft.irfft(np.fft.rfft(reg.x[:, row, :], n=m, axis=0) * gf[:, None], n=m, axis=0)[:k]
        yw[:, row] = np.fft.irfft(np.fft.rfft(reg.y[:, row], n=m) * gf, n=m)[:k]
        scaled[row] *= float(np.sum(acc * gf**2) / max(float(np.sum(acc)), 1e-300))
        psds.append(lambda ff, mdl=model, gg=g: mdl.psd(ff) * gg(ff) ** 2)
    p, cov, scale, rw = _fit(xw, yw, scaled, lag)
    wreg = replace(reg, x=xw, y=yw)
    cov = _with_spectral_cov(wreg, (p, cov, scale, rw), scaled, tuple(psds), sos_dt)
    return p, cov, scale, reg.y - _predict(reg.x, p)


def _physical_fit(
    p: np.ndarray, cov: np.ndarray, turn_share: float, warnings: list[str]
) -> tuple[np.ndarray, np.ndarray]:
    """Return (p, cov) made physical (:func:`_physical`) after the yaw-rate noise's attenuation of dx is added to
    the covariance (:func:`_with_turn_attenuation`, ``turn_share``); append the projection's note."""
    p, cov, note = _physical(p, _with_turn_attenuation(cov, p, turn_share))
    warnings += note
    return p, cov


def _physical(p: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Return (p with [m, m dx, m dy, J] made physical (:func:`cart.physical.constrained_fit`), its covariance, a note).

    The projection's move ``d`` is a misfit of the unconstrained fit that its covariance did not cover (a
    log that never turns leaves the CoM and the yaw damping nearly collinear, and the fit can land far
    outside the physical bodies with a small std): the covariance is widened by ``d d^T`` so that every
    reported std covers at least the distance the projection moved that parameter.
    """
    m, a, b, j = p[:4]
    if m > 0 and j - (a * a + b * b) / m > 1e-6 * abs(j):
        return p, cov, []
    fixed = p.copy()
    fixed[:6] = constrained_fit(p[:6], cov[:6, :6])
    move = np.zeros(len(p))
    move[:6] = fixed[:6] - p[:6]
    cov = cov + np.outer(move, move)
    about_com = (
        f"I about the CoM = {j - (a * a + b * b) / m:.3g} kg m^2" if m > 0 else f"J about {{b}} = {j:.3g} kg m^2"
    )
    note = (
        f"the unconstrained fit is not a physical body (m = {m:.3g} kg, {about_com}); "
        "the closest physical parameters (m > 0, I > 0) are reported, their std widened by the distance moved"
    )
    return fixed, cov, [note]


def _residual_ratio(
    out_std: np.ndarray, sv: float, so: float, p: np.ndarray, r: np.ndarray, y: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Return (residual RMS / what the noise explains, the explained RMS) of the forward and yaw rows.

    The explained part: the filtered wrench noise (its spectrum included: ``out_std`` per row) plus the
    regressor's acceleration noise times the parameters; at least FIT_FLOOR of the wrench (a model
    "fits" to within it on a noise-free log).
    """
    m_, _, b_, j_ = p[:4]
    expected = (
        np.sqrt(
            [
                out_std[0] ** 2 + (m_ * sv) ** 2 + (b_ * so) ** 2,
                out_std[1] ** 2 + (j_ * so) ** 2 + (b_ * sv) ** 2,
            ]
        )
        + 1e-300
    )
    rms = np.sqrt(np.mean(r**2, axis=0))
    expected = np.maximum(expected, FIT_FLOOR * np.sqrt(np.mean(y**2, axis=0)))
    return rms / expected, expected


def _fast_ratio(reg: _Regression, p: np.ndarray, expected: np.ndarray, rows_fc: tuple[float, float]) -> np.ndarray:
    """Return the residual's RMS per row above SLOW_SHARE of the cut-off, over what the noise explains
    (``expected``); ``rows_fc``: the rows' period (s) and the cut-off (Hz). The slow part is removed by FFT
    (zero-padded to twice the length)."""
    dt_rows, fc = rows_fc
    r = reg.y - _predict(reg.x, p)
    m = 2 * len(r)
    keep = (np.fft.rfftfreq(m, dt_rows) > SLOW_SHARE * fc).astype(float)
    fast = np.fft.irfft(np.fft.rfft(r, n=m, axis=0) * keep[:, None], n=m, axis=0)[: len(r)]
    return np.sqrt(np.mean(fast**2, axis=0)) / expected


def _slow_excess(
    reg: _Regression,
    p: np.ndarray,
    expected: np.ndarray,
    rows_fc: tuple[float, float],
    ratio: np.ndarray,
    warnings: list[str],
) -> bool:
    """Return whether the residual's excess over the noise is slow: within FIT_RATIO once its part below
    SLOW_SHARE of the cut-off is removed; append a note when it is.

    Slow sensor noise (an offset's random walk, noise decorrelating over seconds) leaves its excess at the
    lowest frequencies; the cart's misfits (a time delay, a wrong model) leave theirs across the band of the
    dynamics. A Coulomb-like resistance is slow too (its caller tests it first: its Wald statistic separates it).
    ``rows_fc``: the rows' period (s) and the cut-off (Hz) (:func:`_fast_ratio`).
    """
    _, fc = rows_fc
    above = _fast_ratio(reg, p, expected, rows_fc)
    if not np.all(above <= FIT_RATIO):
        return False
    warnings.append(
        f"the residual wrench is {ratio[0]:.1f}x (force) and {ratio[1]:.1f}x (torque) what the sensor noise "
        f"explains, {above[0]:.1f}x and {above[1]:.1f}x above {SLOW_SHARE * fc:.2g} Hz: read as slow sensor noise "
        "(an offset's drift; no Coulomb-like resistance is significant); the std covers it. A slow misfit can also "
        "be a time offset between the wrench and the pose or a load change: `cartpush diagnose` tests those"
    )
    return True


def _model_uncertainty(
    reg: _Regression,
    p: np.ndarray,
    cov: np.ndarray,
    ratio_expected: tuple[np.ndarray, np.ndarray],
    warnings: list[str],
    rows_fc: tuple[float, float],
    check: CoulombCheck,
) -> tuple[np.ndarray, bool]:
    """Return (covariance with the model uncertainty added, model fits); append warnings.

    A significant Coulomb-like resistance (``check``, :func:`_coulomb_check`: rolling resistance, dry friction,
    a nuisance term) adds the shift it causes; a misfit adds the unexplained share of the wrench
    (:func:`_misfit_scale`), also when the excess is slow sensor noise (:func:`_slow_excess`: the model fits).
    ``ratio_expected``: :func:`_residual_ratio`'s; ``rows_fc``: the rows' period and the cut-off (Hz).
    """
    ratio, expected = ratio_expected
    coulomb, shift = check.coulomb, check.shift
    if shift is not None:
        cov = cov + np.diag(shift**2)
        warnings.append(
            f"a Coulomb-like resistance is significant ({coulomb['force']:.3g} N forward, "
            f"{coulomb['torque']:.3g} N m yaw): the nominal viscous model misses it; the std includes "
            "its effect on the estimate (`cartpush diagnose` names the effect)"
        )
    within = bool(np.all(ratio <= FIT_RATIO))
    slow = not within and shift is None and _slow_excess(reg, p, expected, rows_fc, ratio, warnings)
    cov = cov + np.diag(_misfit_scale(p, ratio, expected, reg.y, within, slow) ** 2)
    fits = within or slow
    if not fits:
        warnings.append(
            f"the model does not fit: residual wrench {ratio[0]:.1f}x (force) and {ratio[1]:.1f}x "
            "(torque) what the sensor noise explains; the std covers the misfit seen along the log "
            "(jackknife); run `cartpush diagnose`"
        )
    return cov, fits


def _caster_geometry(
    grid: _Grid, sos: np.ndarray, reg: _Regression, noise: np.ndarray, v: np.ndarray, om: np.ndarray
) -> tuple[float, float, np.ndarray, float]:
    """Return (axle, trail, filtered columns on the first kept rows, half-turns) of the least weighted residual.

    The geometries of :mod:`cart.identify_casters` are searched on the first ``SEARCH_SAMPLES`` grid samples
    (the columns returned are those rows'), with the nominal fit's (Huber) row weights held, regressor noise
    compensated as in :func:`_wls`.
    """
    n = min(len(grid.t), casters_model.SEARCH_SAMPLES)
    keep, n_c = reg.keep[:n], casters_model.N_COLUMNS
    k = int(keep.sum())
    x0, y0 = reg.x[:k], reg.y[:k]
    pad = np.pad(noise, ((0, 0), (0, x0.shape[-1] + n_c - noise.shape[1])))
    _, scale, w = _wls(x0, y0, pad[:, : x0.shape[-1]])
    wts = w / scale**2
    alpha, rate = casters_model.lanes(grid.t[:n], v[:n], om[:n], casters_model.AXLES, casters_model.TRAILS)
    best, where, cols_best = math.inf, (0, 0), x0[:, :, :0]
    for i, axle in enumerate(casters_model.AXLES):
        units = [
            casters_model.unit_rows(alpha[:, i, j], rate[:, i, j], v[:n], om[:n], axle, e)
            for j, e in enumerate(casters_model.TRAILS)
        ]
        filtered = _filtfilt(sos, np.concatenate([u.reshape(n, -1) for u in units], axis=1))[keep]
        for j in range(len(casters_model.TRAILS)):
            cols = filtered[:, 2 * n_c * j : 2 * n_c * (j + 1)].reshape(k, 2, n_c)
            x = np.concatenate([x0, cols], axis=-1)
            a, b = _normal(x, y0, wts)
            p = np.linalg.lstsq(a - _noise_correction(wts, pad), b, rcond=None)[0]
            ssr = float(np.sum(wts * (y0 - _predict(x, p)) ** 2))
            if ssr < best:
                best, where, cols_best = ssr, (i, j), cols
    turns = casters_model.half_turns(alpha[:, where[0], where[1]])
    return casters_model.AXLES[where[0]], casters_model.TRAILS[where[1]], cols_best, turns


def _with_columns(reg: _Regression, cols: np.ndarray, rows: int | None = None) -> _Regression:
    """Return the first ``rows`` (None: all) rows of the regression with the columns ``cols`` appended."""
    k = len(reg.y) if rows is None else rows
    return replace(
        reg, x=np.concatenate([reg.x[:k], cols], axis=-1), y=reg.y[:k], v=reg.v[:k], om=reg.om[:k], y_raw=reg.y_raw[:k]
    )


def _full_columns(
    grid: _Grid, sos: np.ndarray, keep: np.ndarray, vo: tuple[np.ndarray, np.ndarray], axle: float, trail: float
) -> np.ndarray:
    """Return the filtered caster columns of one geometry on the kept rows of the whole grid."""
    v, om = vo
    alpha, rate = casters_model.lanes(grid.t, v, om, (axle,), (trail,))
    full = casters_model.unit_rows(alpha[:, 0, 0], rate[:, 0, 0], v, om, axle, trail)
    return _filtfilt(sos, full.reshape(len(grid.t), -1)).reshape(full.shape)[keep]


_CasterFit = tuple[_Regression, _Regression, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]


def _caster_fit(
    grid: _Grid,
    sos: np.ndarray,
    full: _Regression,
    noise: np.ndarray,
    step_lag: tuple[int, int],
    given: casters_model.Casters | None = None,
) -> tuple[_CasterFit | None, casters_model.Casters]:
    """Return ((full and decimated regressions with the caster columns, their fit) or None, the caster model's test).

    None unless the log swings the modelled casters round (``MIN_HALF_TURNS``) and the four caster
    coefficients are jointly significant beyond a Coulomb-like forward force and yaw torque (rolling
    resistance, dry friction: tested with those columns in the fit too, so that a dry-friction sliding
    object is not read as casters): Wald test on their covariance, :func:`cart.identify_casters.wald_threshold`,
    corrected for the degrees of freedom the fit uses; searched and tested on the first ``SEARCH_SAMPLES``
    grid samples (a long log pays for the whole-log columns only when they are kept). ``given``: a caster
    model already established for this cart (e.g. on the whole log, for a segment of it): its geometry is
    used and kept without a new test.
    """
    step, lag = step_lag
    v, om = full.vo_grid if full.vo_grid is not None else _kinematics(grid.q, grid.dt, sos)[1:3]
    if given is None:
        if int(full.keep[: casters_model.SEARCH_SAMPLES].sum()) < 8 * casters_model.N_COLUMNS:  # nothing to search on
            return None, casters_model.Casters(casters_model.AXLES[0], casters_model.TRAILS[0], 0.0, math.inf, False)
        axle, trail, cols, turns = _caster_geometry(grid, sos, full, noise, v, om)
        casters = _caster_test(_with_columns(full, cols, len(cols)), noise, lag * step, (axle, trail, turns))
        if not casters.kept:
            return None, casters
        if len(cols) < len(full.y):
            cols = _full_columns(grid, sos, full.keep, (v, om), axle, trail)
    else:
        casters = given
        cols = _full_columns(grid, sos, full.keep, (v, om), given.axle, given.trail)
    ext = _with_columns(full, cols)
    reg = _every(ext, step)
    try:
        return (ext, reg, _fit(reg.x, reg.y, noise, lag)), casters
    except np.linalg.LinAlgError:
        return None, casters_model.Casters(casters.axle, casters.trail, 0.0, math.inf, False, casters.half_turns)


def _caster_test(
    reg: _Regression, noise: np.ndarray, lag: int, found: tuple[float, float, float]
) -> casters_model.Casters:
    """Return the caster model's test on the regression ``reg`` whose last columns are the casters' (see `_caster_fit`)."""
    axle, trail, turns = found
    k = casters_model.N_COLUMNS
    # the rows are band-limited to the cut-off fc: about 2 fc T = 4 rows / lag of them are independent; the
    # HAC covariance of n_p fitted parameters is low by n_eff / (n_eff - n_p) (degrees of freedom)
    n_eff, n_p = 4.0 * len(reg.y) / max(lag, 1), reg.x.shape[-1] + 2
    if n_eff <= n_p or turns < casters_model.MIN_HALF_TURNS:
        return casters_model.Casters(axle, trail, 0.0, math.inf, False, turns)
    threshold = casters_model.wald_threshold() * n_eff / (n_eff - n_p)
    try:
        eps = (0.05 * float(np.std(reg.v)) + 1e-12, 0.05 * float(np.std(reg.om)) + 1e-12)
        pt, covt, _, _ = _fit(_with_coulomb_columns(reg.x, reg.v, reg.om, eps), reg.y, noise, lag)
    except np.linalg.LinAlgError:
        return casters_model.Casters(axle, trail, 0.0, threshold, False, turns)
    tail, cc = pt[-2 - k : -2], covt[-2 - k : -2, -2 - k : -2]
    wald = casters_model.resisting_statistic(tail, cc)
    return casters_model.Casters(axle, trail, wald, threshold, wald > threshold and _predicts_better(reg, eps), turns)


def _predicts_better(reg: _Regression, eps: tuple[float, float]) -> bool:
    """Return whether the caster columns (the last ones of ``reg``) predict held-out stretches of the log better.

    Both models carry the Coulomb-like columns (:func:`_with_coulomb_columns`) and the nominal fit's Huber
    weights; :func:`_held_out_ssr` over ``JACKKNIFE_BLOCKS`` stretches.
    """
    k = casters_model.N_COLUMNS
    ext = _with_coulomb_columns(reg.x, reg.v, reg.om, eps)
    base = _with_coulomb_columns(reg.x[:, :, :-k], reg.v, reg.om, eps)
    zero = np.zeros((2, ext.shape[-1]))
    _, scale, w = _wls(base, reg.y, zero[:, : base.shape[-1]])
    wts = w / scale**2
    with_casters = _held_out_ssr(ext, reg.y, wts, zero, JACKKNIFE_BLOCKS)
    return with_casters < _held_out_ssr(base, reg.y, wts, zero[:, : base.shape[-1]], JACKKNIFE_BLOCKS)


def identify(
    log: CartLog,
    attenuation: float = ATTENUATION,
    streams: Streams | None = None,
    casters: casters_model.Casters | None = None,
) -> Identification:
    """Return the filtered-regressor least-squares estimate of the cart's parameters on a whole log.

    ``streams``: the log's pose and wrench streams (:func:`cart.streams.split_streams`, computed here
    when None). ``casters``: a caster model kept on a longer log of the same cart (``Identification.casters``;
    a segment of it): its geometry is used without a new search or test (:mod:`cart.identify_casters`).
    Raises :class:`IdentifiabilityError` when the log cannot say anything (too short, no motion above the noise).
    """
    streams = check_estimable(log, streams)
    grid = _uniform_grid(log, streams)
    lv = _noise_levels(log, streams)
    fc, warnings = _choose_cutoff(grid, lv.pos, lv.theta, attenuation)
    sos, reg, lag, (sv, so, sw), noise = _filtered_regression(log, grid, fc, lv)
    full, step = reg, _decimation(len(reg.y), 1.0 / grid.dt, fc)
    reg, lag = _every(reg, step), int(math.ceil(lag / step))
    _check_independent_rows(log, reg, lag, (fc, grid.dt))
    ext_fit, casters = _caster_fit(grid, sos, full, noise, (step, lag), casters)
    if ext_fit is not None:
        full, reg, (p, cov, scale, r) = ext_fit
        warnings.append(_caster_warning(casters))
    else:
        p, cov, scale, r = _fit_or_raise(log, reg, noise, lag)
    f_noise, t_noise, out_std = _wrench_noise(full, p, grid.dt, sos)
    p, cov, scale, r = _generalised_fit(reg, (f_noise, t_noise), (noise, lag), (sos, grid.dt, step), (p, cov, scale, r))
    lv = _Noise(pos=lv.pos, theta=lv.theta, force=f_noise.sigma, torque=t_noise.sigma, span=lv.span)
    p, cov, ratio, expected, coulomb, fits = _verdict(
        reg, (noise, lag), (p, cov, r), (out_std, sv, so), warnings, (grid.dt * step, fc)
    )
    cart_frame = _cart_frame_reading(grid, sos, (full, step), noise, (lv, sv, so), fc)
    origin = None if fits else _torque_origin_reading(grid, sos, (full, step), noise, float(expected[1]))
    p, cov = _physical_fit(p, cov, _turn_noise_share(full.om, sw), warnings)
    (params, inertia), std = _physical_params(log, p, cov), _physical_std(p, cov)
    warnings += _excitation_warnings(p, std, inertia if inertia > 0 else params.I)
    return Identification(
        params=params,
        std=std,
        p=p[:6],
        cov=cov[:6, :6],
        cutoff_hz=fc,
        residual_ratio=(float(ratio[0]), float(ratio[1])),
        model_fits=fits,
        coulomb=coulomb,
        noise={"position": lv.pos, "theta": lv.theta, "force": lv.force, "torque": lv.torque},
        warnings=tuple(warnings),
        samples_used=int(reg.keep.sum()),
        gaps=grid.gaps,
        streams=streams,
        wrench_noise=(f_noise, t_noise),
        offsets={"forward": float(p[6]), "fx": float(p[7]), "fy": float(p[8]), "torque": float(p[9])},
        grid_dt=grid.dt,
        fit_data={"t": grid.t[reg.keep][::step], "x": reg.x, "y": reg.y, "scale": scale, "step": step},
        casters=casters,
        cart_frame=cart_frame,
        torque_origin=origin,
    )


def _torque_origin_reading(
    grid: _Grid, sos: np.ndarray, full_step: tuple[_Regression, int], noise: np.ndarray, explained: float
) -> float:
    """Return the yaw residual RMS of the regression ``full`` with the torque read as taken about the world origin,
    in units of ``explained``, what the noise explains of the yaw row as logged (:func:`_residual_ratio`).

    LOG_FORMAT's torque is about {b}'s origin; one taken about the world origin holds the moment of the
    force at the cart's position, x fy - y fx, which grows with the distance travelled. Read that way the
    torque row's y is tau - (x fy - y fx); the rest is :func:`_cart_frame_reading`'s fit. Both readings are
    measured against the logged reading's noise: the moved torque carries the force's noise times the distance
    (and its floor grows with the moment), so its own noise level would hide the residual the moment adds.
    """
    full, step = full_step
    q, g = grid.q, grid.gamma
    tau_b = g[:, 2] - (q[:, 0] * g[:, 1] - q[:, 1] * g[:, 0])
    y_raw, y = full.y_raw.copy(), full.y.copy()
    y_raw[:, 1] = tau_b[full.keep]
    y[:, 1] = _filtfilt(sos, tau_b)[full.keep]
    alt = replace(full, y=y, y_raw=y_raw)
    reg = _every(alt, step)
    p, _, _ = _wls(reg.x, reg.y, np.pad(noise, ((0, 0), (0, reg.x.shape[-1] - noise.shape[1]))))
    r = reg.y[:, 1] - _predict(reg.x, p)[:, 1]
    return float(np.sqrt(np.mean(r**2)) / max(explained, 1e-300))


def _cart_frame_reading(
    grid: _Grid, sos: np.ndarray, full_step: tuple[_Regression, int], noise: np.ndarray, lv_acc: tuple, fc: float
) -> tuple[float, float, float]:
    """Return (forward residual ratio, mass, forward ratio above the slow band) of the regression ``full`` with the
    wrench read in the cart frame {b}; the last as :func:`_fast_ratio` at cut-off ``fc``.

    The regressor comes from the pose and is the same in both readings; read in {b}, the forward force
    is fx itself. The rows' y is filtered and fitted as in :func:`_wls` (every ``step``-th row), the wrench
    noise measured on that fit's residual (:func:`_wrench_noise`) and the ratio taken as
    :func:`_residual_ratio`. ``lv_acc``: the log's noise levels and the regressor's acceleration noise (sv, so).
    """
    full, step = full_step
    _, sv, so = lv_acc
    y_raw, y = full.y_raw.copy(), full.y.copy()  # the torque row is the same in both readings
    y_raw[:, 0] = grid.gamma[full.keep, 0]
    y[:, 0] = _filtfilt(sos, grid.gamma[:, 0])[full.keep]
    alt = replace(full, y=y, y_raw=y_raw)
    reg = _every(alt, step)
    p, _, _ = _wls(reg.x, reg.y, np.pad(noise, ((0, 0), (0, reg.x.shape[-1] - noise.shape[1]))))
    _, _, out_std = _wrench_noise(alt, p, grid.dt, sos)
    ratio, expected = _residual_ratio(out_std, sv, so, p, reg.y - _predict(reg.x, p), reg.y)
    fast = _fast_ratio(reg, p, expected, (grid.dt * step, fc))
    return float(ratio[0]), float(p[0]), float(fast[0])


def _filtered_regression(
    log: CartLog, grid: _Grid, fc: float, lv: _Noise
) -> tuple[np.ndarray, _Regression, int, tuple[float, float, float], np.ndarray]:
    """Return (sos, regression, lag, (sv, so, sw), noise): the low-passed regression at cut-off ``fc`` and its noise.

    ``sv``, ``so``: the acceleration noise of the regressor; ``sw``: the yaw rate's noise (the heading's white
    noise through the filter and the derivative); ``noise``: the white parts of the regressor
    entries (vdot in (row 1, m) and (row 2, m dy), omegadot in (1, m dy), (2, J)).
    """
    fs = 1.0 / grid.dt
    sos = butter_lowpass_sos(4, fc / (fs / 2.0))
    reg = _regression(log, grid, fc, sos)
    lag = int(math.ceil(2.0 * fs / fc))
    acc_gain, _, rate_gain = _noise_gains(len(grid.t), grid.dt, sos)
    sv, so = lv.pos * acc_gain, lv.theta * acc_gain
    noise = np.array([[sv * sv, 0.0, so * so, 0.0, 0.0, 0.0], [0.0, 0.0, sv * sv, so * so, 0.0, 0.0]])
    return sos, reg, lag, (sv, so, lv.theta * rate_gain), noise


def _turn_noise_share(om: np.ndarray, rate_noise: float) -> float:
    """Return the share of the filtered yaw rate's power that the heading's white noise alone makes (0-1);
    ``rate_noise``: that noise's std on the yaw rate (`_filtered_regression`).

    The CoM's forward coordinate enters the regression only through the yaw rate (``m dx`` multiplies
    ``-omega^2`` and ``omega v``, paper eq. 4); a yaw rate made of heading noise is an error in the variables
    that pulls ``m dx`` towards 0 by about this share, which the regression's std does not see (a cart pushed
    straight: dx read as 0 +- a few cm).
    """
    return float(min(1.0, rate_noise**2 / max(float(np.var(om)), 1e-300)))


def _with_turn_attenuation(cov: np.ndarray, p: np.ndarray, share: float) -> np.ndarray:
    """Return ``cov`` with the variance of ``m dx`` raised by the attenuation bias the yaw rate's noise allows.

    The bias is at most ``share`` times ``m dx``, and ``|dx|`` at most the body's half-size: a uniform bar's,
    ``sqrt(3)`` radii of gyration from the largest yaw inertia the fit allows (``J`` plus 2 std), at most 1 m
    (`cart.estimate_report.MAX_HALF_SIZE`, the largest cart). With a yaw rate of noise alone (``share`` 1) the
    std of dx covers the whole body, and the report says dx is not identified.
    """
    m, j = float(p[0]), float(p[3])
    if not (m > 0 and share > 0):
        return cov
    half = min(1.0, math.sqrt(3.0 * max(j + 2.0 * math.sqrt(max(float(cov[3, 3]), 0.0)), 0.0) / m))
    cov = cov.copy()
    cov[1, 1] += (share * m * half) ** 2
    return cov


def _fit_or_raise(
    log: CartLog, reg: _Regression, noise: np.ndarray, lag: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return `_fit` of the regression; `IdentifiabilityError` when its least-squares problem is singular."""
    try:
        return _fit(reg.x, reg.y, noise, lag)
    except np.linalg.LinAlgError as exc:
        raise IdentifiabilityError(
            f"{log.source}: the least-squares problem is singular ({exc}): the log does not excite the parameters"
        ) from None


def _caster_warning(casters: casters_model.Casters) -> str:
    """Return the warning that says the casters' swivel resistance is modelled, and where they are."""
    return (
        f"the casters' swivel resistance is modelled (swivel axes about {casters.axle:.2g} m ahead of the axle, "
        f"trail about {100 * casters.trail:.2g} cm; Wald {casters.wald:.0f} > {casters.threshold:.0f}): "
        "without it the casters' swings read as mass"
    )


def _check_independent_rows(log: CartLog, reg: _Regression, lag: int, fc_dt: tuple[float, float]) -> None:
    """Raise `IdentifiabilityError` when the kept rows hold no more independent samples than there are parameters.

    ``fc_dt``: the cut-off and the grid's step. The rows are band-limited to the cut-off: about
    ``2 fc T = 4 rows / lag`` of them are independent (as in :func:`_caster_test`). With no more of them than
    parameters the fit interpolates the wrench and its covariance (HAC, jackknife) has no degrees of freedom
    left: every std it gives is meaningless.
    """
    fc, dt = fc_dt
    n_eff, n_p = 4.0 * len(reg.y) / max(lag, 1), reg.x.shape[-1]
    if n_eff <= n_p:
        seconds = float(reg.keep.sum()) * dt
        gappy = reg.keep.mean() < 0.8  # gaps (or ends) took a fifth of the grid: the stretches are short
        fix = "log longer stretches without gaps" if gappy else "push longer, with more speed changes and turns"
        raise IdentifiabilityError(
            f"{log.source}: the rows kept away from the log's ends and gaps ({int(reg.keep.sum())} grid samples, "
            f"about {seconds:.3g} s) hold about {n_eff:.2g} independent samples at the cut-off {fc:.3g} Hz for "
            f"{n_p} parameters: nothing can be identified ({fix})"
        )


def _rms(values: np.ndarray) -> float:
    """Return the RMS of ``values``, scaled by the largest magnitude (no underflow of subnormal values' squares)."""
    a = np.abs(np.asarray(values, float))
    top = float(np.max(a)) if a.size else 0.0
    if not (top > 0.0 and math.isfinite(top)):
        return top
    return top * float(np.sqrt(np.mean((a / top) ** 2)))


def _silent_wrench(log: CartLog) -> str:
    """Return why the logged wrench says nothing ("" when it says something): zero throughout, or an RMS force
    and torque below ``NEGLIGIBLE_FORCE`` / ``NEGLIGIBLE_TORQUE`` (below any F/T sensor's noise)."""
    g = log.gamma
    if not np.any(g):  # else read as a wrench stream of missing (zero) samples, "too few"
        return "the wrench is zero throughout"
    force, torque = _rms(np.hypot(g[:, 0], g[:, 1])), _rms(g[:, 2])
    if force < NEGLIGIBLE_FORCE and torque < NEGLIGIBLE_TORQUE:
        return (
            f"the wrench is numerically zero throughout (RMS force {force:.3g} N, torque {torque:.3g} N m: far below "
            "any F/T sensor's noise); fx, fy and tau must hold the wrench on the cart in N and N m"
        )
    return ""


def check_estimable(log: CartLog, streams: Streams | None = None) -> Streams:
    """Return the log's pose and wrench streams; raise `IdentifiabilityError` when the log says nothing.

    The checks every estimate runs before any fit (least squares, :func:`identify`; the EKF,
    :mod:`cart.estimate_report`): too few samples in the table or either stream, a wrench zero or negligible
    throughout (:func:`_silent_wrench`), a cart that does not move beyond the pose noise (:func:`pose_stands`).
    """
    if len(log) < 12:
        raise IdentifiabilityError(
            f"{log.source}: {len(log)} samples are too few to estimate anything (need a push of many samples)"
        )
    why = _silent_wrench(log)
    if why:
        raise IdentifiabilityError(f"{log.source}: nothing can be estimated: {why}")
    streams = split_streams(log) if streams is None else streams
    if len(streams.pose.t) < 12 or len(streams.wrench.t) < 12:
        raise IdentifiabilityError(
            f"{log.source}: {len(streams.pose.t)} pose and {len(streams.wrench.t)} wrench samples are too few"
        )
    q = streams.pose.values
    if pose_stands(q, max(white_noise_std(q[:, 0]), white_noise_std(q[:, 1]), 1e-12)):
        raise IdentifiabilityError(
            f"{log.source}: nothing can be estimated: the cart does not move beyond the pose noise"
        )
    return streams


def _excitation_warnings(p: np.ndarray, std: PhysicalStd, inertia: float) -> list[str]:
    """Return warnings for parameters the log excites weakly (relative std above a half)."""
    m, a, b, j = p[:4]
    out = []
    if std["mass"] > 0.5 * m:
        out.append(
            f"mass weakly excited (std {std['mass']:.3g} kg for {m:.3g} kg): "
            "little forward acceleration above the noise"
        )
    gyr = math.sqrt(max(j, 1e-300) / m)
    if max(std["com"]) > 0.5 * gyr:
        out.append(
            f"centre of mass weakly excited (std {max(std['com']):.3g} m, radius of gyration {gyr:.3g} m): "
            "turn the cart more"
        )
    if inertia <= 0 or std["inertia"] > 0.5 * abs(inertia):
        out.append(
            f"inertia weakly excited (I = {inertia:.3g} +- {std['inertia']:.3g} kg m^2): "
            "little yaw acceleration above the noise"
        )
    return out


def innovation_check(log: CartLog, params: CartParams, noise: dict[str, float] | None = None) -> tuple[float, int]:
    """Return (mean NIS, rejected samples) of the paper's EKF (eq. 8-20) over the log with ``params`` held.

    The mean NIS is about 6 (the measurement dimension) when the model with
    these parameters explains the log at its own noise level, much larger when
    it does not; samples the EKF's outlier gate rejects are counted, not averaged. ``noise``:
    the wrench noise already measured (``Identification.noise``), else measured here.
    """
    from cart.ekf import EKFConfig, measurement_std_from_log, run_ekf

    meas_std = measurement_std_from_log(log.t, log.q, log.qd)
    if noise is None:
        noise = {
            "force": max(white_noise_std(log.gamma[:, 0]), white_noise_std(log.gamma[:, 1])),
            "torque": white_noise_std(log.gamma[:, 2]),
        }
    f_std, tau_std = noise["force"], noise["torque"]
    dt = float(median(np.diff(log.t)))
    cfg = EKFConfig.from_noise(
        meas_std,
        estimate_params=False,
        q_vel=max(EKFConfig.q_vel, (f_std / params.m) ** 2 * dt),
        q_omega=max(EKFConfig.q_omega, (tau_std / params.inertia_b) ** 2 * dt),
    )
    z = np.hstack([log.q, log.velocities()])
    ekf, _, nis = run_ekf(
        log.t, log.gamma, z, phi0=params.phi, sigma=params.sigma, config=cfg, sigma_yaw=params.sigma_yaw
    )
    nis = nis[np.isfinite(nis)]
    kept = nis[nis <= ekf.gate_threshold]
    return (float(np.mean(kept)) if len(kept) else float("nan")), int(len(nis) - len(kept))

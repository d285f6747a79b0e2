"""Smoothed motion signals of a cart log in the body frame, for fitting and replay (diagnose workflow).

Velocities and accelerations come from local polynomial fits of the pose
(irregular sampling allowed), never from the log's velocity columns, so logs
with and without those columns are treated alike. Noise levels of the pose and
the wrench are estimated from the residuals of the same fits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from collections.abc import Sequence

import numpy as np

from cart._kernels_identify import median
from cart.errors import LogFormatError
from cart.logs import CartLog


#: rows of the local polynomial fits computed at once (bounds the working memory of long logs)
CHUNK_ROWS = 4096

#: an interval between samples longer than this (s), and than GAP_PERIODS median periods, splits the log
GAP_SECONDS = 1.0
GAP_PERIODS = 20.0


def segment_breaks(t: np.ndarray) -> tuple[int, ...]:
    """Return the indices where a new contiguous segment starts: after a gap of > GAP_SECONDS and GAP_PERIODS periods."""
    t = np.asarray(t, float)
    if len(t) < 3:
        return ()
    dt = np.diff(t)
    lim = max(GAP_SECONDS, GAP_PERIODS * float(median(dt)))
    return tuple(int(i) + 1 for i in np.flatnonzero(dt > lim))


def _segment_bounds(n: int, breaks: tuple[int, ...] | None) -> list[tuple[int, int]]:
    """Return [(a, b)] sample ranges of the segments cut at ``breaks``."""
    cuts = [0] + [int(b) for b in (breaks or ()) if 0 < b < n] + [n]
    return [(a, b) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]


def local_poly(
    t: np.ndarray,
    y: np.ndarray,
    half_window: float,
    degree: int = 2,
    breaks: tuple[int, ...] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (value, d1, d2, leverage): local least-squares polynomial fits of y (N, k) at every t_i.

    Each fit uses the ``2 k + 1`` samples around t_i, ``k = round(half_window / median dt)`` (windows
    shift inwards at the ends, as :func:`cart.logs.local_fit`); ``leverage`` is the weight of sample i
    on its own fitted value (used to unbias residual variances). Fits never cross ``breaks`` (the first
    indices of contiguous segments, :func:`segment_breaks`); a segment too short for a fit keeps its
    samples with zero derivatives. Computed in chunks of ``CHUNK_ROWS`` samples: the working memory
    is linear in the log's length and bounded per chunk.
    """
    t = np.asarray(t, float)
    n = len(t)
    if n < degree + 2:
        raise LogFormatError(f"need at least {degree + 2} samples to differentiate the pose, got {n}")
    y2 = np.asarray(y, float).reshape(n, -1)
    med_dt = float(median(np.diff(t)))
    k = max(degree // 2 + 1, int(round(half_window / med_dt)))
    value = y2.copy()
    d1 = np.zeros_like(y2)
    d2 = np.zeros_like(y2)
    leverage = np.ones(n)
    for a, b in _segment_bounds(n, breaks):
        ns = b - a
        if ns < degree + 2:
            continue
        ts, ys = t[a:b], y2[a:b]
        width = min(2 * k + 1, ns)
        start = np.clip(np.arange(ns) - width // 2, 0, ns - width)
        scale = max(float(np.max(np.maximum(ts[start + width - 1] - ts, ts - ts[start]))), 1e-12)
        for c0 in range(0, ns, CHUNK_ROWS):
            rows = np.arange(c0, min(c0 + CHUNK_ROWS, ns))
            idx = start[rows, None] + np.arange(width)[None, :]
            u = (ts[idx] - ts[rows, None]) / scale
            vt = np.empty((len(rows), degree + 1, width))  # transposed Vandermonde rows
            vt[:, 0] = 1.0
            for p in range(1, degree + 1):
                vt[:, p] = vt[:, p - 1] * u
            ninv = np.linalg.inv(vt @ vt.transpose(0, 2, 1))  # (c, degree+1, degree+1)
            coef = ninv @ (vt @ ys[idx])
            value[a + rows] = coef[:, 0, :]
            d1[a + rows] = coef[:, 1, :] / scale
            if degree >= 2:
                d2[a + rows] = 2.0 * coef[:, 2, :] / scale**2
            leverage[a + rows] = ninv[:, 0, 0]  # own sample: tau = 0, its Vandermonde row is e_0
    return value, d1, d2, leverage


def derivative_gain(
    t: np.ndarray, half_window: float, degree: int = 2, breaks: tuple[int, ...] | None = None
) -> tuple[float, float]:
    """Return (g0, g1): noise gains of the smoothed value and first derivative (std out / std in), RMS."""
    n = len(t)
    rng = np.random.default_rng(12345)
    e = rng.standard_normal((n, 8))
    v, d1, _, _ = local_poly(t, e, half_window, degree, breaks)
    return float(np.sqrt(np.mean(v**2))), float(np.sqrt(np.mean(d1**2)))


def robust_std(r: np.ndarray) -> float:
    """Return 1.4826 * median absolute deviation of r (a robust standard deviation)."""
    r = np.asarray(r, float).ravel()
    return float(1.4826 * median(np.abs(r - median(r))))


@dataclass(frozen=True)
class Signals:
    """Body-frame signals of a log at its sample times (all arrays (N,)).

    ``v``, ``w_lat``: forward and lateral speed of the {b} origin; ``omega``;
    ``vdot``, ``omegadot``; ``f_fwd``, ``f_lat``, ``tau``: the measured wrench in
    {b} axes (shifted by ``shift`` seconds, see :meth:`shifted`); noise stds.
    ``extras``: a cache for derived arrays; entries whose key is a tuple
    starting with ``"motion"`` depend on the motion only and survive :meth:`shifted`.
    """

    t: np.ndarray
    q_raw: np.ndarray
    q: np.ndarray
    gamma_raw: np.ndarray
    v: np.ndarray
    w_lat: np.ndarray
    omega: np.ndarray
    vdot: np.ndarray
    omegadot: np.ndarray
    f_fwd: np.ndarray
    f_lat: np.ndarray
    tau: np.ndarray
    sigma_pos: float
    sigma_theta: float
    sigma_force: float
    sigma_torque: float
    sigma_v: float
    sigma_omega: float
    gain_value: float
    half_window: float
    shift: float = 0.0
    extras: dict = field(default_factory=dict, compare=False)
    #: first sample index of every contiguous segment after the first (a logging gap before it)
    breaks: tuple[int, ...] = ()
    #: the samples whose wrench was measured (False: filled across a stuck sensor or a clipped axis); None: all
    wrench_measured: np.ndarray | None = None

    @property
    def n(self) -> int:
        """Return the number of samples."""
        return len(self.t)

    def wrench_at(self, times: np.ndarray) -> np.ndarray:
        """Return the measured (fx, fy, tau) in {s} linearly interpolated at ``times`` + shift, (len, 3)."""
        tt = np.asarray(times, float) + self.shift
        return np.column_stack([np.interp(tt, self.t, self.gamma_raw[:, k]) for k in range(3)])

    def shifted(self, delay: float) -> Signals:
        """Return the signals with the wrench read ``delay`` s later: gamma_true(t) = gamma_meas(t + delay)."""
        g = np.column_stack([np.interp(self.t + delay, self.t, self.gamma_raw[:, k]) for k in range(3)])
        c, s = np.cos(self.q[:, 2]), np.sin(self.q[:, 2])
        return replace(
            self,
            f_fwd=c * g[:, 0] + s * g[:, 1],
            f_lat=-s * g[:, 0] + c * g[:, 1],
            tau=g[:, 2],
            shift=self.shift + delay,
            extras={k: v for k, v in self.extras.items() if isinstance(k, tuple) and k[0] == "motion"},
        )


def signals_from_log(
    log: CartLog, half_window: float | None = None, filled: Sequence[tuple[float, float]] = ()
) -> Signals:
    """Return the smoothed body-frame :class:`Signals` of ``log`` (pose differentiated by local quadratics);
    ``filled``: spans (t0, t1) whose wrench is a fill, left out of its noise levels (:func:`_measured`)."""
    t = np.asarray(log.t, float)
    if len(t) < 20:
        raise LogFormatError(f"{log.source}: {len(t)} samples are too few to diagnose (need at least 20)")
    dur = float(t[-1] - t[0])
    q = np.asarray(log.q, float)
    med_dt = float(median(np.diff(t)))
    # 0.15 s for a cart log; a short log (a quick push of a small object) gets windows in proportion
    hw = min(0.15, dur / 30.0) if half_window is None else float(half_window)
    if dur < 60.0 * med_dt:
        raise LogFormatError(
            f"{log.source}: the log has {len(t)} samples over {dur:.3g} s; diagnosing needs at least 60 sample periods"
        )
    hw = max(hw, 3.0 * med_dt)
    breaks = segment_breaks(t)
    val, d1, d2, lev = local_poly(t, q, hw, degree=2, breaks=breaks)
    # noise levels from the residuals of a shorter cubic fit (little bias), unbiased by the leverage
    v3, _, _, lev3 = local_poly(t, q, max(0.06, 3.0 * med_dt), degree=3, breaks=breaks)
    corr = np.sqrt(np.clip(1.0 - lev3, 0.05, 1.0))
    res = (q - v3) / corr[:, None]
    sigma_pos = robust_std(np.concatenate([res[:, 0], res[:, 1]]))
    sigma_theta = robust_std(res[:, 2])
    g0, g1 = derivative_gain(t, hw, 2, breaks)
    th = val[:, 2]
    c, s = np.cos(th), np.sin(th)
    xd, yd, om = d1[:, 0], d1[:, 1], d1[:, 2]
    v = c * xd + s * yd
    w = -s * xd + c * yd
    vdot = c * d2[:, 0] + s * d2[:, 1] + om * w
    g = np.asarray(log.gamma, float)
    measured = _measured(t, filled)
    sigma_force, sigma_torque = _wrench_noise_levels(t, g, max(0.06, 3.0 * med_dt), breaks, measured)
    return Signals(
        t=t,
        q_raw=q,
        q=val,
        gamma_raw=g,
        v=v,
        w_lat=w,
        omega=om,
        vdot=vdot,
        omegadot=d2[:, 2],
        f_fwd=c * g[:, 0] + s * g[:, 1],
        f_lat=-s * g[:, 0] + c * g[:, 1],
        tau=g[:, 2],
        sigma_pos=max(sigma_pos, 1e-5),
        sigma_theta=max(sigma_theta, 1e-5),
        sigma_force=max(sigma_force, 1e-3),
        sigma_torque=max(sigma_torque, 1e-4),
        sigma_v=max(sigma_pos, 1e-5) * g1,
        sigma_omega=max(sigma_theta, 1e-5) * g1,
        gain_value=g0,
        half_window=hw,
        breaks=breaks,
        wrench_measured=measured,
    )


def _wrench_noise_levels(
    t: np.ndarray, g: np.ndarray, half_window: float, breaks: tuple[int, ...], measured: np.ndarray | None
) -> tuple[float, float]:
    """Return the robust noise stds of the force (fx, fy pooled) and the torque: the residuals of a local cubic
    fit, unbiased by the leverage, over the ``measured`` samples (None: all)."""
    gs, _, _, glev = local_poly(t, g, half_window, degree=3, breaks=breaks)
    gcorr = np.sqrt(np.clip(1.0 - glev, 0.05, 1.0))
    gres = (g - gs) / gcorr[:, None]
    if measured is not None:
        gres = gres[measured]
    return robust_std(np.concatenate([gres[:, 0], gres[:, 1]])), robust_std(gres[:, 2])


def _measured(t: np.ndarray, filled: Sequence[tuple[float, float]]) -> np.ndarray | None:
    """Return the mask of the samples outside every ``filled`` span (None when there is none, or none is hit).

    A fill (a stuck sensor's stretch, a clipped axis) has no noise: kept in, a stuck 10 s of a 60 s log lowered
    the force's noise std and flagged windows 10 s away.
    """
    spans = np.asarray(filled, float).reshape(-1, 2)
    if len(spans) == 0:
        return None
    inside = np.zeros(len(t), bool)
    for a, b in spans:
        inside |= (t >= a) & (t <= b)
    if not inside.any() or inside.all():
        return None
    return ~inside


def window_edges(t: np.ndarray, length: float, breaks: tuple[int, ...] | None = None) -> np.ndarray:
    """Return sample indices [i0, i1, ...] cutting t into consecutive windows of about ``length`` seconds.

    With ``breaks`` (:func:`segment_breaks`) every segment is cut on its own and both samples around
    each gap are edges: the window across a gap is :func:`window_keep`'s one to drop.
    """
    t = np.asarray(t, float)
    parts = []
    for a, b in _segment_bounds(len(t), breaks):
        ts = t[a:b]
        n_w = max(1, int((ts[-1] - ts[0]) // length))
        targets = ts[0] + np.arange(n_w + 1) * (ts[-1] - ts[0]) / n_w
        parts.append(a + np.searchsorted(ts, targets).clip(0, b - a - 1))
    return np.unique(np.concatenate(parts))


def window_keep(edges: np.ndarray, breaks: tuple[int, ...] | None = None) -> np.ndarray:
    """Return a boolean mask of the windows of ``edges`` that lie within one segment (False across a gap)."""
    edges = np.asarray(edges)
    keep = np.ones(max(len(edges) - 1, 0), bool)
    for b in breaks or ():
        keep &= ~((edges[:-1] < b) & (edges[1:] >= b))
    return keep


def cache_bounded(sig: Signals, group: str, key: tuple, value: np.ndarray, budget: int) -> None:
    """Keep ``value`` in ``sig.extras`` under ``key``; drop the oldest entries of ``group`` beyond ``budget`` bytes.

    For caches whose entries grow with the log (one per grid point or per swing choice): their memory
    stays bounded however long the log is (a dropped entry is recomputed when asked for again).
    """
    order = sig.extras.setdefault(("bounded", group), [])
    sig.extras[key] = value
    order.append((key, value.nbytes))
    total = sig.extras.get(("bounded_bytes", group), 0) + value.nbytes  # the bytes of ``order``, kept
    while total > budget and len(order) > 1:
        old, nb = order.pop(0)
        sig.extras.pop(old, None)
        total -= nb
    sig.extras[("bounded_bytes", group)] = total


def window_integrals(t: np.ndarray, y: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Return the trapezoid integrals of y (N, ...) over [t[e_k], t[e_{k+1}]], shape (len(edges)-1, ...).

    ``edges``: strictly increasing sample indices (:func:`window_edges`).
    """
    y = np.asarray(y, float)
    edges = np.asarray(edges)
    if len(edges) < 2:
        return np.zeros((0,) + y.shape[1:])
    i0, i1 = int(edges[0]), int(edges[-1])
    half_dt = (0.5 * np.diff(t[i0 : i1 + 1])).reshape((-1,) + (1,) * (y.ndim - 1))
    trapezoids = y[i0 + 1 : i1 + 1] + y[i0:i1]
    trapezoids *= half_dt  # in place: one temporary of y's size, not two
    return np.add.reduceat(trapezoids, edges[:-1] - i0, axis=0)


def lateral_displacements(sig: Signals, edges: np.ndarray) -> np.ndarray:
    """Return the sideways travel of the {b} origin over each window, from the raw pose increments.

    Sum over samples of ``-sin(theta) dx + cos(theta) dy`` with the smoothed
    heading at mid-step: zero when the no-slip constraint (paper eq. 3) holds,
    and free of the smoothing bias of differentiated velocities.
    """
    d = np.diff(sig.q_raw[:, :2], axis=0)
    th = 0.5 * (sig.q[1:, 2] + sig.q[:-1, 2])
    inc = -np.sin(th) * d[:, 0] + np.cos(th) * d[:, 1]
    cum = np.concatenate([[0.0], np.cumsum(inc)])
    return cum[edges[1:]] - cum[edges[:-1]]


def velocity_change_noise(sig: Signals, edges: np.ndarray, replicates: int = 4, seed: int = 7) -> tuple[float, float]:
    """Return the variances of the window integrals of vdot and omegadot due to pose noise alone.

    Propagates white noise of the estimated std (``sigma_pos``, ``sigma_theta``)
    through the same local-polynomial differentiation (exact: it is linear).
    """
    rng = np.random.default_rng(seed)
    n = sig.n
    acc_v, acc_w = [], []
    for _ in range(replicates):
        e = rng.standard_normal((n, 3)) * np.array([sig.sigma_pos, sig.sigma_pos, sig.sigma_theta])
        _, _, d2, _ = local_poly(sig.t, e, sig.half_window, degree=2, breaks=sig.breaks)
        c, s = np.cos(sig.q[:, 2]), np.sin(sig.q[:, 2])
        keep = window_keep(edges, sig.breaks)
        acc_v.append(window_integrals(sig.t, c * d2[:, 0] + s * d2[:, 1], edges)[keep])
        acc_w.append(window_integrals(sig.t, d2[:, 2], edges)[keep])
    return float(np.mean(np.concatenate(acc_v) ** 2)), float(np.mean(np.concatenate(acc_w) ** 2))


def _support_tail(fc: float, dt: float) -> np.ndarray:
    """Return tail[d]: the share of the pipeline filter's weight at least d samples to one side.

    The filter is the estimator's: a 4th-order Butterworth low-pass at ``fc`` run forwards and backwards,
    then differentiated twice (the accelerations of :mod:`cart.identify`, whose impulse response is the
    longest of its signals); its absolute impulse response, both sides summed to one.
    """
    half = int(math.ceil(6.0 / (fc * dt)))
    pulse = np.zeros(2 * half + 1)
    pulse[half] = 1.0
    acc = np.abs(_filtered_acceleration(pulse, fc, dt))
    return np.r_[np.cumsum(acc[half:][::-1])[::-1], 0.0] / float(acc.sum())


def _filtered_acceleration(y: np.ndarray, fc: float, dt: float) -> np.ndarray:
    """Return the second derivative of ``y`` low-passed forwards and backwards (4th-order Butterworth at fc)."""
    from cart._kernels_identify import butter_lowpass_sos, sosfiltfilt

    sos = butter_lowpass_sos(4, min(fc * 2.0 * dt, 0.99))
    return np.gradient(np.gradient(sosfiltfilt(sos, y, padlen=0), dt), dt)


def _gap_reach(length: int, fc: float, dt: float, end: int, tolerance: float) -> int:
    """Return how many samples beyond a gap of ``length`` samples its linear fill moves the filtered acceleration
    by more than ``tolerance`` of the acceleration the cart has there (at most ``end``).

    The pose is filled linearly across a gap; under a constant acceleration ``a`` the fill is off by
    ``a (s - s0)(s1 - s) / 2`` inside it, and the filter spreads that error out (:func:`_filtered_acceleration`).
    """
    pad = 2 * end
    s = np.arange(length + 1) * dt
    err = np.zeros(length + 1 + 2 * pad)
    err[pad : pad + length + 1] = 0.5 * s * (s[-1] - s)
    beyond = np.abs(_filtered_acceleration(err, fc, dt))[pad + length + 1 :]
    above = np.flatnonzero(beyond > tolerance)
    return min(int(above[-1]) + 1 if len(above) else 0, end)


def filter_support_keep(valid: np.ndarray, fc: float, dt: float) -> np.ndarray:
    """Return the samples of a uniform grid whose filtered values the missing stretches do not reach.

    The log's ends are trimmed by ``ceil(2 / (fc dt))`` samples (the filter's settling), which leaves a share
    ``tolerance`` of its weight (:func:`_support_tail`, about 1 %) beyond the end. A stretch of missing samples
    (``~valid``, filled linearly) is trimmed on each side by the distance beyond which its fill moves the
    filtered acceleration by less than that share of the cart's acceleration (:func:`_gap_reach`): a long gap
    as much as an end, a short dropout much less (its fill error grows with the square of its length).
    """
    end = int(math.ceil(2.0 / (fc * dt)))
    tail = _support_tail(fc, dt)
    tolerance = float(tail[min(end, len(tail) - 1)])
    bad = ~valid
    bad[:end] = True
    bad[-end:] = True
    d = np.diff(np.r_[0, (~valid).astype(np.int8), 0])
    reach: dict[int, int] = {}
    for s0, s1 in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
        length = int(s1 - s0) + 1  # the fill spans the gap and its two edge intervals
        if length not in reach:
            reach[length] = _gap_reach(length, fc, dt, end, tolerance)
        bad[max(s0 - reach[length], 0) : s1 + reach[length]] = True
    return ~bad

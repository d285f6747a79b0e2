"""Smoothed motion signals of a cart log in the body frame, for fitting and replay (diagnose workflow).

Velocities and accelerations come from local polynomial fits of the pose
(irregular sampling allowed), never from the log's velocity columns, so logs
with and without those columns are treated alike. Noise levels of the pose and
the wrench are estimated from the residuals of the same fits.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from cart.errors import LogFormatError
from cart.logs import CartLog, local_fit


def local_poly(
    t: np.ndarray, y: np.ndarray, half_window: float, degree: int = 2
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (value, d1, d2, leverage): local least-squares polynomial fits of y (N, k) at every t_i.

    Each fit uses the samples with |t_j - t_i| <= ``half_window`` (windows shift
    inwards at the ends); ``leverage`` is the weight of sample i on its own
    fitted value (used to unbias residual variances).
    """
    n = len(t)
    if n < degree + 2:
        raise LogFormatError(f"need at least {degree + 2} samples to differentiate the pose, got {n}")
    coef, scale, pinv, start, _ = local_fit(t, y, half_window, degree)
    value = coef[:, 0, :]
    d1 = coef[:, 1, :] / scale
    d2 = 2.0 * coef[:, 2, :] / scale**2 if degree >= 2 else np.zeros_like(d1)
    leverage = pinv[np.arange(n), 0, np.arange(n) - start]
    return value, d1, d2, leverage


def derivative_gain(t: np.ndarray, half_window: float, degree: int = 2) -> tuple[float, float]:
    """Return (g0, g1): noise gains of the smoothed value and first derivative (std out / std in), median."""
    n = len(t)
    rng = np.random.default_rng(12345)
    e = rng.standard_normal((n, 8))
    v, d1, _, _ = local_poly(t, e, half_window, degree)
    return float(np.sqrt(np.mean(v**2))), float(np.sqrt(np.mean(d1**2)))


def robust_std(r: np.ndarray) -> float:
    """Return 1.4826 * median absolute deviation of r (a robust standard deviation)."""
    r = np.asarray(r, float).ravel()
    return float(1.4826 * np.median(np.abs(r - np.median(r))))


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


def signals_from_log(log: CartLog, half_window: float | None = None) -> Signals:
    """Return the smoothed body-frame :class:`Signals` of ``log`` (pose differentiated by local quadratics)."""
    t = np.asarray(log.t, float)
    if len(t) < 20:
        raise LogFormatError(f"{log.source}: {len(t)} samples are too few to diagnose (need at least 20)")
    dur = float(t[-1] - t[0])
    q = np.asarray(log.q, float)
    med_dt = float(np.median(np.diff(t)))
    # 0.15 s for a cart log; a short log (a quick push of a small object) gets windows in proportion
    hw = min(0.15, dur / 30.0) if half_window is None else float(half_window)
    if dur < 60.0 * med_dt:
        raise LogFormatError(
            f"{log.source}: the log has {len(t)} samples over {dur:.3g} s; diagnosing needs at least 60 sample periods"
        )
    hw = max(hw, 3.0 * med_dt)
    val, d1, d2, lev = local_poly(t, q, hw, degree=2)
    # noise levels from the residuals of a shorter cubic fit (little bias), unbiased by the leverage
    v3, _, _, lev3 = local_poly(t, q, max(0.06, 3.0 * med_dt), degree=3)
    corr = np.sqrt(np.clip(1.0 - lev3, 0.05, 1.0))
    res = (q - v3) / corr[:, None]
    sigma_pos = robust_std(np.concatenate([res[:, 0], res[:, 1]]))
    sigma_theta = robust_std(res[:, 2])
    g0, g1 = derivative_gain(t, hw, 2)
    th = val[:, 2]
    c, s = np.cos(th), np.sin(th)
    xd, yd, om = d1[:, 0], d1[:, 1], d1[:, 2]
    v = c * xd + s * yd
    w = -s * xd + c * yd
    vdot = c * d2[:, 0] + s * d2[:, 1] + om * w
    g = np.asarray(log.gamma, float)
    gs, _, _, glev = local_poly(t, g, max(0.06, 3.0 * med_dt), degree=3)
    gcorr = np.sqrt(np.clip(1.0 - glev, 0.05, 1.0))
    gres = (g - gs) / gcorr[:, None]
    sigma_force = robust_std(np.concatenate([gres[:, 0], gres[:, 1]]))
    sigma_torque = robust_std(gres[:, 2])
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
    )


def window_edges(t: np.ndarray, length: float) -> np.ndarray:
    """Return sample indices [i0, i1, ...] cutting t into consecutive windows of about ``length`` seconds."""
    n_w = max(1, int((t[-1] - t[0]) // length))
    targets = t[0] + np.arange(n_w + 1) * (t[-1] - t[0]) / n_w
    edges = np.unique(np.searchsorted(t, targets).clip(0, len(t) - 1))
    return edges


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
    trapezoids = (y[i0 + 1 : i1 + 1] + y[i0:i1]) * half_dt
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
        _, _, d2, _ = local_poly(sig.t, e, sig.half_window, degree=2)
        c, s = np.cos(sig.q[:, 2]), np.sin(sig.q[:, 2])
        acc_v.append(window_integrals(sig.t, c * d2[:, 0] + s * d2[:, 1], edges))
        acc_w.append(window_integrals(sig.t, d2[:, 2], edges))
    return float(np.mean(np.concatenate(acc_v) ** 2)), float(np.mean(np.concatenate(acc_w) ** 2))

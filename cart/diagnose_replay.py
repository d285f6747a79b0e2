"""Short-horizon replay of a (nominal or augmented) cart model against a log, and the discrepancy test.

From every start time (every ``stride`` s) the model is integrated for
``horizon`` s from the smoothed measured state with the measured wrench
(vectorised RK4 over all starts) and compared with the measured pose. The
end-of-horizon error (forward, lateral, heading, in {b} of the start) is
normalised by its standard deviation predicted from the estimated noise
levels, giving a chi-square (3 dof) per start; starts whose error is
significant after Benjamini-Hochberg control of the false discovery rate are
flagged and merged into windows.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from collections.abc import Callable

import math

import numpy as np

from cart.dynamics import body_accelerations
from cart.log_signals import Signals, local_poly


@dataclass(frozen=True)
class Replay:
    """Replay output: start times (K,), horizon grid (J,), simulated/measured poses (K, J, 3), chi2 (K,)."""

    starts: np.ndarray
    tau: np.ndarray
    sim: np.ndarray
    meas: np.ndarray
    rms: np.ndarray
    chi2: np.ndarray
    floor: np.ndarray

    @property
    def finite(self) -> bool:
        """Return True when every replay stayed finite (a blown-up replay means a non-physical model).

        A replay that left the finite range has an infinite (or NaN) RMS error (:func:`replay`).
        """
        return bool(np.all(np.isfinite(self.rms)))

    def without_paths(self) -> Replay:
        """Return this replay without its simulated and measured paths (K, 0, 3): the scores only.

        The paths are 2 x 8 bytes x 3 x (J + 1) per start (2.4 kB for a 1 s horizon at 50 Hz, every 0.25 s):
        a candidate's replay is kept for its gap and chi2, the paths only for the report's two plotted replays.
        """
        empty = np.empty((len(self.starts), 0, 3))
        return replace(self, sim=empty, meas=empty.copy())

    def rms_error(self, mask: np.ndarray | None = None) -> float:
        """Return the RMS position error (m) over the starts in ``mask`` (all when None)."""
        r = self.rms if mask is None or not np.any(mask) else self.rms[mask]
        return float(np.sqrt(np.mean(r**2)))

    def noise_floor(self, mask: np.ndarray | None = None) -> float:
        """Return the RMS position error (m) the noise alone predicts over the starts in ``mask``."""
        f = self.floor if mask is None or not np.any(mask) else self.floor[mask]
        return float(np.sqrt(np.mean(f**2)))

    def gap(self, mask: np.ndarray | None = None) -> float:
        """Return the RMS excess position error (m) over the noise floor: sqrt(max(mean(rms^2 - floor^2), 0)).

        The part of the replay error the noise cannot explain, over the starts
        in ``mask`` (all when None); 0 when the error is at the noise level.
        """
        sel = slice(None) if mask is None or not np.any(mask) else mask
        return float(np.sqrt(max(float(np.mean(self.rms[sel] ** 2 - self.floor[sel] ** 2)), 0.0)))


def _interp_cols(times: np.ndarray, t: np.ndarray, cols: np.ndarray) -> list[np.ndarray]:
    return [np.interp(times, t, cols[:, k]) for k in range(cols.shape[1])]


def simulate_replays(
    sig: Signals,
    x: np.ndarray,
    extra: np.ndarray | None = None,
    dphi: np.ndarray | None = None,
    horizon: float = 1.0,
    stride: float = 0.25,
    h: float = 0.02,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (starts (K,), tau (J,), simulated poses (K, J, 3), measured poses (K, J, 3)) of the short replays.

    The model x = [m, m dx, m dy, J, sigma, sigma_yaw] (eq. 4-7) plus ``extra`` (N, 3):
    effect generalized force (forward, yaw) and lateral speed of {b} along the
    measured motion, and ``dphi`` (N, 4): change of phi over time; integrated
    by RK4 (step ``h``) from the smoothed measured state at every start, all
    starts at once, with the measured (possibly time-shifted) wrench. The
    inputs are interpolated once on the RK4 time grid. Non-finite replays
    (a non-physical model) are returned as they are.
    """
    t = sig.t
    starts_all = np.arange(t[0], t[-1] - horizon + 1e-9, stride)
    for b in sig.breaks:  # no replay across a logging gap
        starts_all = starts_all[(starts_all >= t[b] - 1e-9) | (starts_all + horizon <= t[b - 1] + 1e-9)]
    if len(starts_all) == 0:
        starts_all = np.array([t[0]])
        horizon = float(t[-1] - t[0])
    k_steps = max(1, int(round(horizon / h)))
    h = horizon / k_steps
    tau = np.arange(k_steps + 1) * h
    sim = np.empty((len(starts_all), k_steps + 1, 3))
    meas = np.empty_like(sim)
    # the starts in chunks: the inputs on the RK4 stage grid (10 arrays of K x (2 k + 1)) stay bounded
    for c0 in range(0, len(starts_all), REPLAY_CHUNK):
        starts = starts_all[c0 : c0 + REPLAY_CHUNK]
        f = _replay_dynamics(sig, x, extra, dphi, starts, h, k_steps)
        state = np.array(
            [np.interp(starts, t, col) for col in (sig.q[:, 0], sig.q[:, 1], sig.q[:, 2], sig.v, sig.omega)]
        )
        sim[c0 : c0 + len(starts)] = _rk4_replays(f, state, h, k_steps)
        times = starts[:, None] + tau[None, :]
        for k in range(3):
            meas[c0 : c0 + len(starts), :, k] = np.interp(times, t, sig.q_raw[:, k])
    return starts_all, tau, sim, meas


#: replay starts integrated at once (bounded working memory however long the log)
REPLAY_CHUNK = 1024


def _replay_dynamics(
    sig: Signals,
    x: np.ndarray,
    extra: np.ndarray | None,
    dphi: np.ndarray | None,
    starts: np.ndarray,
    h: float,
    k_steps: int,
) -> Callable[[int, np.ndarray], np.ndarray]:
    """Return f(i, s): the time derivative of the states s (5, K) = (x, y, theta, v, omega) at RK4 stage i.

    The inputs (wrench, effect terms, phi over time) are interpolated once on the stage grid
    (K, 2 k + 1), half steps apart; the accelerations are :func:`cart.dynamics.body_accelerations`.
    """
    t = sig.t
    extra = np.zeros((sig.n, 3)) if extra is None else extra
    phi_t = np.tile(np.asarray(x[:4], float), (sig.n, 1)) + (0.0 if dphi is None else dphi)
    sigma, sigma_yaw = float(x[4]), float(x[5])
    grid = starts[:, None] + 0.5 * h * np.arange(2 * k_steps + 1)[None, :]  # (K, 2 k + 1): RK4 stages
    g = [np.interp(grid + sig.shift, t, sig.gamma_raw[:, k]) for k in range(3)]
    e = [np.interp(grid, t, extra[:, k]) for k in range(3)]
    m, a, b, j = (np.interp(grid, t, phi_t[:, k]) for k in range(4))

    def f(i: int, s: np.ndarray) -> np.ndarray:
        th, v, om = s[2], s[3], s[4]
        c, sn = np.cos(th), np.sin(th)
        fu = c * g[0][:, i] + sn * g[1][:, i]
        vdot, odot = body_accelerations(
            v,
            om,
            fu + e[0][:, i],
            g[2][:, i] + e[1][:, i],
            m[:, i],
            a[:, i],
            b[:, i],
            j[:, i],
            sigma,
            sigma_yaw,
            min_det=1e-9,
        )
        w = e[2][:, i]
        return np.array([c * v - sn * w, sn * v + c * w, om, vdot, odot])

    return f


def _rk4_replays(f: Callable[[int, np.ndarray], np.ndarray], state: np.ndarray, h: float, k_steps: int) -> np.ndarray:
    """Return the poses (K, k_steps + 1, 3) of classical RK4 from the states (5, K); stage i of step n is 2 n + i."""
    sim = np.empty((state.shape[1], k_steps + 1, 3))
    # a non-physical model (tiny or negative mass/inertia) may blow up: no warnings
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for jj in range(k_steps + 1):
            sim[:, jj, :] = state[:3].T
            if jj == k_steps:
                break
            k1 = f(2 * jj, state)
            k2 = f(2 * jj + 1, state + 0.5 * h * k1)
            k3 = f(2 * jj + 1, state + 0.5 * h * k2)
            k4 = f(2 * jj + 2, state + h * k3)
            state = state + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return sim


def replay(
    sig: Signals,
    x: np.ndarray,
    extra: np.ndarray | None = None,
    dphi: np.ndarray | None = None,
    horizon: float = 1.0,
    stride: float = 0.25,
    h: float = 0.02,
) -> Replay:
    """Return the replay of the model x = [m, m dx, m dy, J, sigma, sigma_yaw] plus effect terms over short horizons.

    ``extra`` (N, 3): effect generalized force (forward, yaw) and lateral speed
    of {b}, evaluated along the measured motion; ``dphi`` (N, 4): change of phi
    over time. The wrench is read from the (possibly time-shifted) signals.
    Non-finite starts get an infinite error (callers reject such models, see
    :attr:`Replay.finite`).
    """
    starts_all, tau, sim, meas = simulate_replays(sig, x, extra, dphi, horizon, stride, h)
    horizon = float(tau[-1])
    with np.errstate(over="ignore", invalid="ignore"):
        err = sim - meas
        rms = np.sqrt(np.mean(err[:, :, 0] ** 2 + err[:, :, 1] ** 2, axis=1))
        chi2 = _end_chi2(sig, x, starts_all, err[:, -1, :], horizon)
    bad = ~np.all(np.isfinite(sim), axis=(1, 2))
    rms[bad] = np.inf
    chi2[bad] = np.inf
    floor = _noise_floor(sig, x, starts_all, tau)
    return Replay(starts=starts_all, tau=tau, sim=sim, meas=meas, rms=rms, chi2=chi2, floor=floor)


def _noise_floor(
    sig: Signals, x: np.ndarray, starts: np.ndarray, tau: np.ndarray, replicates: int = 4, seed: int = 11
) -> np.ndarray:
    """Return the noise-predicted RMS position error (K,) of each replay (the noise terms of the chi2, no model floor).

    Pose noise (estimated stds) is propagated exactly through the same local
    polynomial smoother (Monte Carlo, it is linear): the error of the smoothed
    initial position, speed, heading and yaw rate, carried over the horizon,
    minus the noise of the measured pose it is compared with. The measured
    force and torque noise, integrated twice, is added in closed form.
    Averaged over the horizon like the RMS error.
    """
    t = sig.t
    dt = float(np.median(np.diff(t)))
    m = max(float(x[0]), 1.0)
    j = max(float(x[3]), 0.1)
    H = float(tau[-1]) if len(tau) > 1 else 1.0
    vbar = np.interp(starts + 0.5 * H, t, sig.v)[:, None]
    tt = tau[None, :]
    # the Monte Carlo part depends on the motion and noise levels only: cached on the signals
    key = ("motion", "replay_floor_mc", len(starts), float(starts[0]), float(H), len(tau), replicates, seed)
    acc = sig.extras.get(key)
    if acc is None:
        rng = np.random.default_rng(seed)
        th0 = np.interp(starts, t, sig.q[:, 2])[:, None]
        c, s = np.cos(th0), np.sin(th0)
        times = starts[:, None] + tt
        acc = np.zeros((len(starts), len(tau)))
        for _ in range(replicates):
            e = rng.standard_normal((sig.n, 3)) * np.array([sig.sigma_pos, sig.sigma_pos, sig.sigma_theta])
            val, d1, _, _ = local_poly(t, e, sig.half_window, degree=2, breaks=sig.breaks)
            p0 = [np.interp(starts, t, val[:, k])[:, None] for k in range(3)]
            v0 = [np.interp(starts, t, d1[:, k])[:, None] for k in range(3)]
            dv = c * v0[0] + s * v0[1]
            lat = vbar * (p0[2] * tt + v0[2] * tt**2 / 2.0)
            ex = p0[0] + dv * tt * c - lat * s - np.interp(times, t, e[:, 0])
            ey = p0[1] + dv * tt * s + lat * c - np.interp(times, t, e[:, 1])
            acc += ex**2 + ey**2
        sig.extras[key] = acc
    var_f = sig.sigma_force**2 * dt * tt**3 / (3.0 * m * m)
    var_l = vbar**2 * sig.sigma_torque**2 * dt * tt**5 / (20.0 * j * j)
    return np.sqrt(np.mean(acc / replicates + var_f + var_l, axis=1))


def _end_chi2(sig: Signals, x: np.ndarray, starts: np.ndarray, err_end: np.ndarray, horizon: float) -> np.ndarray:
    """Return chi2 (3 dof) of the end errors normalised by the std predicted from the noise levels."""
    th0 = np.interp(starts, sig.t, sig.q[:, 2])
    c, s = np.cos(th0), np.sin(th0)
    e_f = c * err_end[:, 0] + s * err_end[:, 1]
    e_l = -s * err_end[:, 0] + c * err_end[:, 1]
    e_h = err_end[:, 2]
    H = horizon
    dt = float(np.median(np.diff(sig.t)))
    m = max(float(x[0]), 1.0)
    j = max(float(x[3]), 0.1)
    vbar = np.abs(np.interp(starts + 0.5 * H, sig.t, sig.v)) + 0.05
    sp, sp0, sv0 = sig.sigma_pos, sig.sigma_pos * sig.gain_value, sig.sigma_v
    st, st0, sw0 = sig.sigma_theta, sig.sigma_theta * sig.gain_value, sig.sigma_omega
    force_term = sig.sigma_force**2 * dt * H**3 / (3.0 * m * m)
    torque_term = sig.sigma_torque**2 * dt * H**3 / (3.0 * j * j)
    var_f = sp**2 + sp0**2 + (sv0 * H) ** 2 + force_term
    var_h = st**2 + st0**2 + (sw0 * H) ** 2 + torque_term
    var_l = (
        sp**2
        + sp0**2
        + vbar**2 * (st0**2 * H**2 + sw0**2 * H**4 / 4.0 + sig.sigma_torque**2 * dt * H**5 / (20.0 * j * j))
    )
    # a relative model-error floor: 2 cm/s^2 and 0.02 rad/s^2 of unexplained acceleration
    var_f = var_f + (0.5 * 0.02 * H**2) ** 2
    var_h = var_h + (0.5 * 0.02 * H**2) ** 2
    var_l = var_l + (0.5 * 0.02 * H**2) ** 2
    return e_f**2 / var_f + e_l**2 / var_l + e_h**2 / var_h


def chi2_sf_3(x: np.ndarray) -> np.ndarray:
    """Return P(X > x) of the chi-square distribution with 3 dof: erfc(sqrt(x/2)) + sqrt(2x/pi) exp(-x/2).

    Closed form (no scipy.stats import: it costs ~0.5 s of start-up); 0 at x = inf, NaN stays NaN.
    """
    x = np.asarray(x, float)
    out = np.full(x.shape, np.nan)
    flat, res = x.ravel(), out.ravel()
    for k, v in enumerate(flat):
        if v == math.inf:
            res[k] = 0.0
        elif v <= 0.0:
            res[k] = 1.0
        elif v == v:
            res[k] = math.erfc(math.sqrt(0.5 * v)) + math.sqrt(2.0 * v / math.pi) * math.exp(-0.5 * v)
    return res.reshape(x.shape)


def flag_starts(rep: Replay, fdr: float = 0.01) -> np.ndarray:
    """Return a boolean mask of starts whose chi2 is significant (Benjamini-Hochberg at ``fdr``)."""
    p = chi2_sf_3(rep.chi2)
    k = len(p)
    order = np.argsort(p)
    thresh = fdr * (np.arange(1, k + 1) / k)
    below = p[order] <= thresh
    mask = np.zeros(k, bool)
    if np.any(below):
        last = int(np.nonzero(below)[0][-1])
        mask[order[: last + 1]] = True
    return mask


def merge_windows(starts: np.ndarray, mask: np.ndarray, horizon: float) -> list[tuple[float, float]]:
    """Return the union of [start, start + horizon] over the masked starts, as sorted disjoint intervals."""
    out: list[tuple[float, float]] = []
    for s in starts[mask]:
        if out and s <= out[-1][1] + 1e-9:
            out[-1] = (out[-1][0], float(s + horizon))
        else:
            out.append((float(s), float(s + horizon)))
    return out

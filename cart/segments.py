"""Load changes found offline: the log split where the cart's parameters change (a load added or removed).

The filtered regression of :mod:`cart.identify` (paper eq. 4, linear in the parameters) is split in two
at every candidate instant; the split that lowers the weighted residual sum of squares most is the
candidate change (cumulative sums of the normal equations: one pass over the log). Each side is then
estimated on its own (:func:`cart.identify.identify`, with its own noise model and std, misfit included);
the change is kept when the two masses differ by more than ``CHANGE_Z`` combined std and by more than
``MIN_RELATIVE_CHANGE``. Binary segmentation: each kept side is searched again, ``MAX_DEPTH`` levels.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from cart.logs import CartLog

if TYPE_CHECKING:
    from cart.identify import FitData

#: Combined std by which the masses of two sides must differ for a load change.
CHANGE_Z = 5.0
#: Smallest relative mass change reported.
MIN_RELATIVE_CHANGE = 0.05
#: Shortest segment (s).
MIN_SEGMENT_S = 5.0
MAX_DEPTH = 2
_CANDIDATES = 400


def slice_log(log: CartLog, t0: float, t1: float) -> CartLog:
    """Return the rows of ``log`` with t0 <= t <= t1."""
    m = (log.t >= t0) & (log.t <= t1)
    return CartLog(
        t=log.t[m],
        q=log.q[m],
        gamma=log.gamma[m],
        qd=None if log.qd is None else log.qd[m],
        contact_b=None if log.contact_b is None else log.contact_b[m],
        metadata=log.metadata,
        source=f"{log.source} [{t0:.3f} s, {t1:.3f} s]",
    )


def best_split(
    t: np.ndarray, x: np.ndarray, y: np.ndarray, scale: np.ndarray, min_len: float, tol: float = 0.0
) -> float | None:
    """Return the time that splits the regression ``x p = y`` into the two fits of least total residual.

    ``x`` (k, 2, P), ``y`` (k, 2) at times ``t`` (k,), rows weighted by ``1 / scale^2``; candidates at
    least ``min_len`` s from either end (None when the log is too short). Splits whose residual is within
    ``tol`` of the least (the regression cannot tell them apart: the cart stands still) are alike: the
    middle of that stretch around the best one is returned.
    """
    ok = np.flatnonzero((t - t[0] >= min_len) & (t[-1] - t >= min_len))
    if len(ok) == 0:
        return None
    idx = ok[:: max(1, len(ok) // _CANDIDATES)]
    sw = 1.0 / scale
    xs, ys = x * sw[None, :, None], y * sw[None, :]
    edges = np.r_[0, idx + 1]
    blocks = [(xs[i0:i1].reshape(-1, x.shape[-1]), ys[i0:i1].reshape(-1)) for i0, i1 in zip(edges[:-1], edges[1:])]
    tail = (xs[edges[-1] :].reshape(-1, x.shape[-1]), ys[edges[-1] :].reshape(-1))
    a = np.cumsum([xb.T @ xb for xb, _ in blocks], axis=0)
    b = np.cumsum([xb.T @ yb for xb, yb in blocks], axis=0)
    c = np.cumsum([yb @ yb for _, yb in blocks])
    a_all, b_all, c_all = a[-1] + tail[0].T @ tail[0], b[-1] + tail[0].T @ tail[1], c[-1] + tail[1] @ tail[1]
    p_dim = x.shape[-1]
    ridge = 1e-12 * np.trace(a_all) / p_dim * np.eye(p_dim)

    def ssr(aa: np.ndarray, bb: np.ndarray, cc: np.ndarray) -> np.ndarray:
        sol = np.linalg.solve(aa + ridge, bb[..., None])[..., 0]
        return cc - np.einsum("kj,kj->k", bb, sol)

    left = ssr(a, b, c)
    right = ssr(a_all - a, b_all - b, c_all - c)
    total = left + right
    k = int(np.argmin(total))
    near = total <= total[k] + tol
    lo, hi = k, k
    while lo > 0 and near[lo - 1]:
        lo -= 1
    while hi < len(near) - 1 and near[hi + 1]:
        hi += 1
    return float(0.5 * (t[idx[lo]] + t[idx[hi]]))


def _sides_differ(data: FitData, tc: float, res) -> bool:
    """Return True when the masses of the regression's two sides differ enough to be worth estimating each.

    A quick screen on the whole log's filtered regression (its fit and covariance on each side, no
    re-filtering): half the thresholds of the final test.
    """
    from cart.identify import _fit

    left = data["t"] < tc
    n_p = data["x"].shape[-1]
    lag = int(math.ceil(2.0 / (res.cutoff_hz * res.grid_dt)))
    noise = np.zeros((2, n_p))
    try:
        pl, cl, _, _ = _fit(data["x"][left], data["y"][left], noise, lag)
        pr, cr, _, _ = _fit(data["x"][~left], data["y"][~left], noise, lag)
    except np.linalg.LinAlgError:
        return False
    z = abs(pl[0] - pr[0]) / max(math.sqrt(max(cl[0, 0], 0.0) + max(cr[0, 0], 0.0)), 1e-300)
    return bool(z >= 0.5 * CHANGE_Z and abs(pl[0] - pr[0]) >= 0.5 * MIN_RELATIVE_CHANGE * max(pl[0], pr[0]))


def _summary(res, t0: float, t1: float) -> dict[str, Any]:
    return {
        "t0": float(t0),
        "t1": float(t1),
        "params": res.params,
        "std": res.std,
        "model_fits": res.model_fits,
        "residual_ratio": res.residual_ratio,
    }


def _split(log: CartLog, res, t0: float, t1: float, depth: int) -> list[dict[str, Any]]:
    """Return the segments of [t0, t1] (whose identification is ``res``), searched ``depth`` more levels."""
    from cart.identify import IdentifiabilityError, identify

    here = [_summary(res, t0, t1)]
    data = res.fit_data
    if depth <= 0 or data is None:
        return here
    min_len = max(MIN_SEGMENT_S, 10.0 / res.cutoff_hz)
    lag = 2.0 / (res.cutoff_hz * res.grid_dt)  # samples per independent residual (the filter's memory)
    tc = best_split(data["t"], data["x"], data["y"], data["scale"], min_len, tol=lag)
    if tc is None:
        return here
    if not _sides_differ(data, tc, res):
        return here
    try:
        left = identify(slice_log(log, t0, tc))
        right = identify(slice_log(log, tc, t1))
    except (IdentifiabilityError, np.linalg.LinAlgError):
        return here
    ml, mr = left.params.m, right.params.m
    z = abs(ml - mr) / max(math.hypot(left.std["mass"], right.std["mass"]), 1e-300)
    if z < CHANGE_Z or abs(ml - mr) < MIN_RELATIVE_CHANGE * max(ml, mr):
        return here
    return _split(log, left, t0, tc, depth - 1) + _split(log, right, tc, t1, depth - 1)


def find_segments(log: CartLog, streams, res) -> tuple[list[dict[str, Any]], list[str]]:
    """Return (segments of constant load, notes) of a log whose whole-log identification is ``res``.

    Each segment: ``t0``, ``t1``, ``params``, ``std``, ``model_fits``, ``residual_ratio``. A log without a
    load change gives one segment with the whole-log numbers.
    """
    t0, t1 = float(log.t[0]), float(log.t[-1])
    segs = _split(log, res, t0, t1, MAX_DEPTH)
    if len(segs) == 1:
        return segs, []
    changes = ", ".join(
        f"t = {b['t0']:.2f} s ({a['params'].m:.4g} -> {b['params'].m:.4g} kg)" for a, b in zip(segs, segs[1:])
    )
    return segs, [
        f"the load changes at {changes}: the log is reported in {len(segs)} segments; the parameters shown "
        "are the last segment's (the cart as it is at the end of the log)"
    ]

"""Load changes found offline: the log split where the cart's parameters change (a load added or removed).

The filtered regression of :mod:`cart.identify` (paper eq. 4, linear in the parameters) is split in two
at every candidate instant; the split that lowers the weighted residual sum of squares most is the
candidate change (cumulative sums of the normal equations: one pass over the log; Coulomb-like columns
added, so that rolling resistance, which grows with the load, is not taken for mass). The regression is
low-passed zero-phase, so the rows within the filter's reach of a change mix the two carts: the split model
predicts ``filt(Y p(t))`` with ``p(t)`` switching at the split (each side's regressor filtered after it is
switched, :func:`_switched_rows`) rather than ``p_side filt(Y)``, so the filtered tail of a motion that the
change cuts counts for the change's time. A load put on a moving cart at rest takes its share of the cart's
momentum with no force at the handle: each candidate is also fitted with that exchange
(:func:`exchange_corrections`, no extra parameter), and the better of the two counts (a load lifted out, or
put in at the cart's speed, exchanges nothing). The two sides share the F/T offsets and the casters'
resistances (:func:`shared_columns`). The change is kept
when the two sides' masses, fitted on the whole log's filtered regression away from the change (regressor
noise compensated; std the larger of Newey-West and a block jackknife, so a misfit that varies along the
log counts while one common to both sides cancels), differ by more than ``CHANGE_Z`` combined std and by
more than ``MIN_RELATIVE_CHANGE`` (:func:`change_z`), or where the yaw inertia moves with the mass (a load adds
both), their joint evidence reaches ``CHANGE_Z`` (:func:`load_z`); a mass that grows by less than ``CHANGE_Z`` std is kept
when the pose shows the momentum exchange of a load put in there (:func:`exchange_shown`: the speed drops at
once, with no force at the handle, by what the two sides' masses predict). Each side is then estimated on its own
(:func:`cart.identify.identify`) for the report. Binary segmentation: each kept side is searched again,
``MAX_DEPTH`` levels. Where the motion does not excite the mass (cruise, standstill) the change time is
only known to lie in a stretch (:func:`information_stretch`: the splits the motion cannot tell apart, whatever
the log's misfit makes of them): ``t0`` is the middle of the splits within one independent residual of the
least (:func:`best_split`), the whole stretch is ``t0_range``, with a
note that the time is not identified; each side is identified up to ``t0`` (the stretch's rows say little of
the mass but much of the damping). A split whose
two sides' own searches split them further is checked again (:func:`_joined`: two segments of the same load
next to it are joined). The search weighs its rows down where the whole log's single fit misfits several times
more than it does typically over a second or two (:func:`reweighted`: a caster's swing as the cart turns in
place, which a split far from the change can fit better than the change itself); when the change found so is
not kept, the unweighted search is tried too.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from cart._kernels_identify import median, median_columns
from cart.logs import CartLog

if TYPE_CHECKING:
    from cart.identify import Identification

#: Combined std by which the masses of two sides (or their mass and yaw inertia jointly, :func:`load_z`) must differ
#: for a load change (:func:`change_stats`; no change is
#: reported on the change-free logs of the independent simulator, the MuJoCo cart and the validation set,
#: docs/estimation.md "Load changes").
CHANGE_Z = 3.5
#: Each side's mass must be this many of its std (a side that does not excite the mass, e.g. a cart turning
#: in place then standing, says nothing about a change).
IDENTIFIED_Z = 3.0
#: Smallest relative mass change reported.
MIN_RELATIVE_CHANGE = 0.05
#: Shortest segment (s).
MIN_SEGMENT_S = 5.0
MAX_DEPTH = 2
_CANDIDATES = 400
#: Rows per period of the cut-off the split search keeps (the filtered regression is band-limited).
_ROWS_PER_PERIOD = 10.0
#: Columns of the cart's dynamics in the filtered regression ([m, m dx, m dy, J, c_v, c_w]); the rest are nuisance.
N_DYNAMIC = 6
#: The columns a load on the deck changes by its own inertia ([m, m dx, m dy, J]).
_N_LOAD = 4
#: Half-width (s) of the windows whose misfit weighs the split search's rows (:func:`robust_weights`).
ROBUST_WINDOW_S = 1.0
#: A window's misfit (RMS) above this many times the typical one lowers its rows' weight (:func:`robust_weights`).
ROBUST_MISFIT = 3.0
#: Level of the likelihood-ratio confidence set of a change's time that ``t0_range`` holds (:func:`confidence_set`).
CONFIDENCE_LEVEL = 0.95


def shared_columns(p_dim: int) -> np.ndarray:
    """Return the columns of the split search's regression (``p_dim`` wide) that both sides of a split share.

    The columns between the cart's dynamics (``N_DYNAMIC``) and the two Coulomb-like ones of
    :func:`_with_coulomb`: the F/T sensor's offsets, which are the sensor's, and the casters' swivel resistances
    (:mod:`cart.identify_casters`), which are the cart's: a load on the deck changes the mass, CoM, inertia and
    rolling resistance, not these. Free on each side they let a split far from the change fit a caster event
    with one side's caster coefficients (MuJoCo 211, 311: loads lifted out while cruising, dated 5.9 and 1.9 s off).
    """
    return np.arange(N_DYNAMIC, p_dim - 2)


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


#: Cumulative normal equations of a split search: ``a``, ``b`` at each candidate, and the whole log's ``a``, ``b``, ``c``.
_Normal = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]


class SplitKernels(NamedTuple):
    """The zero-phase low-pass on the split search's rows (every ``step`` grid samples), ``half`` rows each side.

    ``k`` (2 half + 1,): the filter's response at the rows to a unit impulse of the sampled signal (sums to 1:
    ``filt(u)_r = sum_j k[half + r - j] u_j`` for a band-limited ``u``); ``h``: its response to a unit step of
    velocity (the acceleration impulse ``1 / dt``): centred, symmetric, its sum times the rows' period one.
    """

    k: np.ndarray
    h: np.ndarray
    half: int


def split_kernels(res: Identification, step: int) -> SplitKernels:
    """Return the :class:`SplitKernels` of ``res``'s low-pass on rows ``step`` grid samples apart.

    Three periods of the cut-off each side (the filter's response is negligible beyond).
    """
    from cart._kernels_identify import butter_lowpass_sos
    from cart.identify import _filtfilt

    half = int(math.ceil(3.0 / (res.cutoff_hz * res.grid_dt)))
    half += (-half) % step
    unit = np.zeros(2 * half + 1)
    unit[half] = 1.0
    sos = butter_lowpass_sos(4, res.cutoff_hz * 2.0 * res.grid_dt)
    resp = _filtfilt(sos, unit)[::step]
    return SplitKernels(k=resp / resp.sum(), h=resp / res.grid_dt, half=half // step)


def _switched_rows(xs: np.ndarray, idx: np.ndarray, k: np.ndarray, half: int) -> np.ndarray:
    """Return ``filt(x 1[r > i])`` on the rows ``i - half .. i + half`` of each candidate ``i`` (n, 2 half + 1, ...).

    The filtered regression of a cart whose parameters switch after row ``i``: the right side's regressor is
    the low-passed regressor switched on at ``i`` (it rises over the filter's reach, not at once), the left
    side's the rest.
    """
    n_w = 2 * half + 1
    a = np.arange(n_w)[:, None] - np.arange(2 * half)[None, :] - 1  # row i - half + a, source i + 1 + b
    kmat = np.where((a >= 0) & (a <= 2 * half), k[np.clip(a, 0, 2 * half)], 0.0)
    src = xs[idx[:, None] + 1 + np.arange(2 * half)[None, :]]  # (n, 2 half, 2, P)
    n, _, rows, p_dim = src.shape
    return (kmat @ src.reshape(n, 2 * half, rows * p_dim)).reshape(n, n_w, rows, p_dim)


def _shared_map(p_dim: int, shared: np.ndarray) -> np.ndarray:
    """Return ``T`` (2 p_dim, q): both sides' parameters ``[p_L, p_R] = T q``, the ``shared`` columns' alike."""
    free = np.setdiff1d(np.arange(p_dim), shared)
    t = np.zeros((2 * p_dim, p_dim + len(free)))
    t[:p_dim, :p_dim] = np.eye(p_dim)
    t[p_dim + shared, shared] = 1.0
    t[p_dim + free, p_dim + np.arange(len(free))] = 1.0
    return t


def _solve_split(m: np.ndarray, v: np.ndarray, t: np.ndarray, c_all: float) -> tuple[np.ndarray, np.ndarray]:
    """Return (residual, both sides' parameters) of the normal equations ``m``, ``v`` in [p_L, p_R] with ``T``."""
    mq, vq = t.T @ m @ t, v @ t
    ridge = 1e-12 * float(np.trace(mq[-1])) / mq.shape[-1] * np.eye(mq.shape[-1])
    sol = np.linalg.solve(mq + ridge, vq[..., None])[..., 0]
    return c_all - np.einsum("ni,ni->n", vq, sol), sol @ t.T


def _window_fit(
    ys: np.ndarray,
    idx: np.ndarray,
    outside: tuple[np.ndarray, ...],
    rows: np.ndarray,
    c_all: float,
    put_in: bool,
    t: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Return (residual, both sides' parameters (n, 2P)) of each candidate's split when the rows within ``half`` of
    its split take the regressors ``rows``.

    ``rows`` (n, 2 half + 1, 2, 2P): the window's rows of each candidate ``idx``, the left side's parameters'
    columns then the right side's; ``outside``: the normal equations (``a``, ``b`` left, ``a``, ``b`` right)
    of the rows outside the window, which are each side's own; ``t`` (:func:`_shared_map`). ``put_in``: a
    candidate whose right side's mass is not above the left's (the momentum exchange of a load put in) gets ``inf``.
    """
    a_left, b_left, a_right, b_right = outside
    n, half, n_p = len(idx), rows.shape[1] // 2, a_left.shape[-1]
    win = idx[:, None] + np.arange(-half, half + 1)[None, :]
    flat, yv = rows.reshape(n, -1, 2 * n_p), ys[win].reshape(n, -1)
    flat_t = flat.transpose(0, 2, 1)
    m = flat_t @ flat  # batched BLAS: an einsum of this contraction is ten times slower
    m[:, :n_p, :n_p] += a_left
    m[:, n_p:, n_p:] += a_right
    v = np.concatenate([b_left, b_right], axis=-1) + (flat_t @ yv[:, :, None])[:, :, 0]
    out, sol = _solve_split(m, v, t, c_all)
    return (np.where(sol[:, n_p] > sol[:, 0], out, math.inf) if put_in else out), sol


def _window_system(
    xs: np.ndarray, ys: np.ndarray, idx: np.ndarray, kernels: SplitKernels, filtered: bool
) -> tuple[tuple[np.ndarray, ...], np.ndarray, float]:
    """Return (the normal equations outside each candidate's window, the window's rows, the log's ``c``).

    The weighted regression ``xs``, ``ys``; the rows as :func:`_window_fit` takes them: switched
    (:func:`_switched_rows`) or, ``filtered`` False, split at the candidate as they are.
    """
    half = kernels.half
    a_all, b_all, c_all = _cumulative_normal(xs, ys, idx)[2:]
    a_left, b_left = _cumulative_normal(xs, ys, idx - half - 1)[:2]
    a_to, b_to = _cumulative_normal(xs, ys, idx + half)[:2]
    outside = (a_left, b_left, a_all[None] - a_to, b_all[None] - b_to)
    win_rows = xs[idx[:, None] + np.arange(-half, half + 1)[None, :]]
    if filtered:
        right = _switched_rows(xs, idx, kernels.k, half)
    else:
        right = win_rows * (np.arange(-half, half + 1) > 0)[None, :, None, None]
    return outside, np.concatenate([win_rows - right, right], axis=-1), c_all


def _split_residuals(
    x: np.ndarray,
    y: np.ndarray,
    scale: np.ndarray,
    idx: np.ndarray,
    kernels: SplitKernels | None,
    exchange: bool,
    shared: np.ndarray | None = None,
    filtered: bool = True,
) -> np.ndarray:
    """Return the weighted residual of the split after each candidate row ``idx`` (see :func:`best_split`).

    ``filtered`` False: the window's rows are split at the candidate as they are (the plain split, with the
    exchange when ``exchange``) instead of :func:`_switched_rows`.
    """
    sw = 1.0 / scale
    xs, ys = x * sw[None, :, None], y * sw[None, :]
    p_dim = x.shape[-1]
    t = _shared_map(p_dim, np.zeros(0, dtype=int) if shared is None else shared)
    a, b, a_all, b_all, c_all = _cumulative_normal(xs, ys, idx)
    if kernels is None:
        m = np.zeros((len(idx), 2 * p_dim, 2 * p_dim))
        m[:, :p_dim, :p_dim], m[:, p_dim:, p_dim:] = a, a_all[None] - a
        return _solve_split(m, np.concatenate([b, b_all[None] - b], axis=-1), t, c_all)[0]
    outside, rows, c_all = _window_system(xs, ys, idx, kernels, filtered)
    switched = _window_fit(ys, idx, outside, rows, c_all, False, t)[0]
    if not exchange:
        return switched
    corr = exchange_corrections(x, idx, sw, kernels)
    moved = rows + np.concatenate([-corr, corr], axis=-1)
    return np.minimum(switched, _window_fit(ys, idx, outside, moved, c_all, True, t)[0])


def split_prediction(
    x: np.ndarray, y: np.ndarray, scale: np.ndarray, i: int, kernels: SplitKernels, shared: np.ndarray | None = None
) -> np.ndarray:
    """Return the prediction ``y`` (k, 2) of the switched split after row ``i`` (with the momentum exchange when
    that fits better), both sides' parameters fitted (:func:`_split_residuals`): the log as the split says it is."""
    sw = 1.0 / scale
    xs, ys = x * sw[None, :, None], y * sw[None, :]
    p_dim, half = x.shape[-1], kernels.half
    t = _shared_map(p_dim, np.zeros(0, dtype=int) if shared is None else shared)
    idx = np.array([i])
    outside, rows, c_all = _window_system(xs, ys, idx, kernels, True)
    ssr, sol = _window_fit(ys, idx, outside, rows, c_all, False, t)
    corr = exchange_corrections(x, idx, sw, kernels)
    ssr_x, sol_x = _window_fit(ys, idx, outside, rows + np.concatenate([-corr, corr], axis=-1), c_all, True, t)
    if ssr_x[0] < ssr[0]:
        rows, sol = rows + np.concatenate([-corr, corr], axis=-1), sol_x
    sol = sol.copy()
    common = 0.5 * (sol[0, _N_LOAD:p_dim] + sol[0, p_dim + _N_LOAD :])
    sol[0, _N_LOAD:p_dim], sol[0, p_dim + _N_LOAD :] = common, common
    pred = np.concatenate(
        [xs[: i - half] @ sol[0, :p_dim], rows[0] @ sol[0], xs[i + half + 1 :] @ sol[0, p_dim:]], axis=0
    )
    return pred / sw[None, :]


def best_split(
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    scale: np.ndarray,
    min_len: float,
    tol: float = 0.0,
    kernels: SplitKernels | None = None,
    exchange: bool = True,
    shared: np.ndarray | None = None,
) -> tuple[float, float, float] | None:
    """Return (time, earliest, latest) of the split of the regression ``x p = y`` into two fits of least residual.

    ``x`` (k, 2, P), ``y`` (k, 2) at times ``t`` (k,), rows weighted by ``1 / scale^2``; candidates at
    least ``min_len`` s from either end (None when the log is too short). Splits whose residual is within
    ``tol`` of the least (the regression cannot tell them apart: the cart stands still or cruises) are
    alike: the time is the middle of that stretch around the best one, earliest and latest its ends.
    ``kernels`` (:func:`split_kernels`): the split model is the filtered regression of a cart whose
    parameters switch at the split (:func:`_switched_rows`: the rows within the filter's reach mix the two
    carts) and, with ``exchange``, each candidate's residual is the lesser of that and the momentum
    exchange's (:func:`exchange_corrections`); None: the rows are split at the candidate as they are. With
    ``kernels`` the split is sought within the stretch the plain split finds (the rows split as they are,
    with the exchange too: a put-in's drop of velocity is otherwise a force the plain split has not got),
    widened by the filter's reach: the switched rows near a split add a term ``(p_R - p_L) filt(Y 1[t > t_c])``
    that can fit a local misfit (a caster event) far from the change when the two sides differ much.
    ``shared``: columns whose parameter both sides share (:func:`shared_columns`); None: each side has all its own.
    """
    idx = _candidates(t, min_len, kernels)
    if len(idx) == 0:
        return None
    total = _split_residuals(x, y, scale, idx, kernels, exchange, shared)
    if kernels is not None:  # within the plain split's stretch, widened by the filter's reach
        lo, hi = _near(_split_residuals(x, y, scale, idx, kernels, exchange, shared, filtered=False), tol)
        reach_t = kernels.half * float(median(np.diff(t)))
        total = np.where((t[idx] >= t[idx[lo]] - reach_t) & (t[idx] <= t[idx[hi]] + reach_t), total, np.inf)
    lo, hi = _near(total, tol)
    return float(0.5 * (t[idx[lo]] + t[idx[hi]])), float(t[idx[lo]]), float(t[idx[hi]])


def information_stretch(
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    scale: np.ndarray,
    min_len: float,
    tol: float,
    kernels: SplitKernels,
    tc: float,
    shared: np.ndarray | None = None,
) -> tuple[float, float]:
    """Return (earliest, latest) split the motion cannot tell from the split at ``tc`` (see :func:`best_split`).

    The split's own prediction (:func:`split_prediction`), with both sides' parameters alike but for the
    columns a load changes by its inertia ([m, m dx, m dy, J]), searched again: its residual at each other
    candidate is the evidence the motion gives against it (the rows it puts on the wrong side: no noise, no
    misfit), so the stretch within ``tol`` of it is where the change may lie, a cruise or a standstill
    between two motions that excite the load's inertia, whatever the log's misfit makes of that stretch.
    A sharp change (an acceleration, a put-in's momentum exchange) gives a narrow stretch.
    """
    idx = _candidates(t, min_len, kernels)
    k = int(np.argmin(np.abs(t[idx] - tc)))
    pred = split_prediction(x, y, scale, int(idx[k]), kernels, shared)
    lo, hi = _near(_split_residuals(x, pred, scale, idx, kernels, True, shared), tol, k)
    return float(t[idx[lo]]), float(t[idx[hi]])


def information_stretch_of(res: Identification, t_change: float) -> tuple[float, float]:
    """Return :func:`information_stretch` at ``t_change`` on the split search's rows of ``res`` (the whole log's
    :func:`cart.identify.identify`): where the motion cannot date a change at ``t_change``."""
    s = _search_rows(res)
    return information_stretch(s.t, s.x, s.y, s.scale, s.min_len, s.tol, s.kernels, t_change, s.shared)


def confidence_drop(level: float = CONFIDENCE_LEVEL) -> float:
    """Return the rise of the split residual, in independent residuals, that bounds the change time's confidence set.

    Twice the log-likelihood ratio of the best split against the true one tends to ``max_s (2 W(s) - |s|)``
    (``W`` a two-sided Brownian motion, the time in units where the change's signal grows by one noise variance
    per unit; Hinkley 1970): each side's maximum is exponential with mean 2, so
    ``P(> x) = 1 - (1 - exp(-x / 2))^2`` and the ``level`` quantile is ``-2 ln(1 - sqrt(level))`` (7.35 at 95 %).
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f"confidence level {level} must lie strictly between 0 and 1")
    return -2.0 * math.log(1.0 - math.sqrt(level))


def confidence_set(
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    scale: np.ndarray,
    min_len: float,
    tol: float,
    kernels: SplitKernels,
    shared: np.ndarray | None = None,
) -> tuple[float, float]:
    """Return (earliest, latest) split whose residual lies within :func:`confidence_drop` independent residuals
    (``tol`` rows each) of the least, over the whole search (the switched split with the exchange, unrestricted).

    The likelihood-ratio confidence set of the change time: it need not be one stretch. A local misfit (a
    caster's swing as the cart starts turning in place) can give a minimum of its own seconds away from the
    motion that dates the change (MuJoCo 707: lifted out at 23.89 s in a yaw reversal, 6.9 independent
    residuals above a minimum at 29.3 s); the set's hull then holds both, widened by one candidate each side.
    """
    idx = _candidates(t, min_len, kernels)
    total = _split_residuals(x, y, scale, idx, kernels, True, shared)
    inside = np.flatnonzero(total <= float(np.min(total)) + confidence_drop() * tol)
    # the candidates sample the split time: the set's edge lies between the last one out and the first one in
    return float(t[idx[max(inside[0] - 1, 0)]]), float(t[idx[min(inside[-1] + 1, len(idx) - 1)]])


def _candidates(t: np.ndarray, min_len: float, kernels: SplitKernels | None) -> np.ndarray:
    """Return the rows a split may follow: ``min_len`` s and the filter's reach from either end, at most
    ``_CANDIDATES`` of them evenly spaced."""
    reach = 0 if kernels is None else 2 * kernels.half + 1
    ok = np.flatnonzero((t - t[0] >= min_len) & (t[-1] - t >= min_len))
    ok = ok[(ok >= reach) & (ok < len(t) - reach)]
    return ok[:: max(1, len(ok) // _CANDIDATES)] if len(ok) else ok


def _near(total: np.ndarray, tol: float, k: int | None = None) -> tuple[int, int]:
    """Return the first and last candidate of the stretch around the least ``total`` (or candidate ``k``) within
    ``tol`` of it."""
    k = int(np.argmin(total)) if k is None else k
    near = total <= total[k] + tol
    lo, hi = k, k
    while lo > 0 and near[lo - 1]:
        lo -= 1
    while hi < len(near) - 1 and near[hi + 1]:
        hi += 1
    return lo, hi


def _cumulative_normal(xs: np.ndarray, ys: np.ndarray, idx: np.ndarray) -> _Normal:
    """Return the normal equations of the rows up to each candidate (``a``, ``b``) and of the whole log's
    (``a``, ``b``, ``c``)."""
    edges = np.r_[0, idx + 1]
    p_dim = xs.shape[-1]
    blocks = [(xs[i0:i1].reshape(-1, p_dim), ys[i0:i1].reshape(-1)) for i0, i1 in zip(edges[:-1], edges[1:])]
    a = np.cumsum([xb.T @ xb for xb, _ in blocks], axis=0)
    b = np.cumsum([xb.T @ yb for xb, yb in blocks], axis=0)
    xf, yf = xs.reshape(-1, p_dim), ys.reshape(-1)
    return a, b, xf.T @ xf, xf.T @ yf, float(yf @ yf)


def exchange_corrections(x: np.ndarray, idx: np.ndarray, sw: np.ndarray, kernels: SplitKernels) -> np.ndarray:
    """Return, for each candidate ``i``, the momentum exchange's change of the rows within ``half`` of it.

    A load of zero velocity put on the cart shares the cart's momentum: the momentum coordinates
    ``g . p`` (:func:`momentum_rows`) are continuous while the velocity drops, so the filtered regression
    sees no force for the velocity's step: the prediction near the split gains ``(p_R - p_L) . g h(t - t_i)``
    (``h`` the filtered velocity step, :class:`SplitKernels`). No parameter is added: the two sides' own
    parameters set the exchange. ``sw`` the rows' weights (1 / scale).
    """
    g = np.stack([momentum_rows(x[i]) * sw[:, None] for i in idx])  # (n, 2, P)
    return kernels.h[None, :, None, None] * g[:, None]


def momentum_rows(x_row: np.ndarray) -> np.ndarray:
    """Return the momentum coordinates ``g`` (2, P) of one row of the regression (its v and w columns).

    Forward ``g . p = m v - m dy w``, yaw ``-m dy v + J w``: the integrals of the acceleration columns of the
    regressor (paper eq. 4: vdot and -wdot in the forward row, -vdot and wdot in the yaw row).
    """
    g = np.zeros_like(x_row)
    v, om = x_row[0, 4], x_row[1, 5]
    g[0, 0], g[0, 2], g[1, 2], g[1, 3] = v, -om, -v, om
    return g


def _with_coulomb(x: np.ndarray) -> np.ndarray:
    """Return the filtered regression ``x`` (k, 2, P) with a Coulomb-like forward force and yaw torque added.

    ``tanh(v / eps)``, ``tanh(omega / eps)`` (eps 5 % of their std; the c_v column of the forward row is v, the
    c_w column of the yaw row omega): rolling resistance, which grows with the load, is then not taken for mass.
    """
    v, om = x[:, 0, 4], x[:, 1, 5]
    eps_v, eps_w = 0.05 * float(np.std(v)) + 1e-12, 0.05 * float(np.std(om)) + 1e-12
    z = np.zeros_like(v)
    coulomb = np.stack([np.stack([np.tanh(v / eps_v), z], -1), np.stack([z, np.tanh(om / eps_w)], -1)], -2)
    return np.concatenate([x, coulomb], axis=-1)


def regressor_noise(res: Identification) -> np.ndarray:
    """Return the white-noise variance (2, 6) of the filtered regressor's acceleration entries of ``res``'s fit.

    As :func:`cart.identify.identify` removes it (bias-compensated least squares): the pose noise it measured,
    differentiated twice through its filter. Without it a quiet stretch (the cart spinning in place, stopped)
    reads the noise as excitation and its mass shrinks towards zero.
    """
    from cart._kernels_identify import butter_lowpass_sos
    from cart.identify import _noise_gains

    data = res.fit_data
    assert data is not None
    sos = butter_lowpass_sos(4, res.cutoff_hz * 2.0 * res.grid_dt)
    acc_gain = _noise_gains(len(data["t"]) * data["step"], res.grid_dt, sos)[0]
    sv, so = res.noise["position"] * acc_gain, res.noise["theta"] * acc_gain
    return np.array([[sv * sv, 0.0, so * so, 0.0, 0.0, 0.0], [0.0, 0.0, sv * sv, so * so, 0.0, 0.0]])


def change_z(res: Identification, tc: float, guard: float) -> tuple[float, float, float, float]:
    """Return (z, mass before, mass after, least mass / its std of the two) of a change at ``tc`` in ``res``'s fit.

    ``z`` is :func:`change_stats`'s mass ``z``.
    """
    got = change_stats(res, tc, guard)
    return got.z, got.m_before, got.m_after, got.identified


class ChangeStats(NamedTuple):
    """:func:`change_stats`: the two sides' masses and how far apart their fits put them and the load's inertia."""

    z: float
    z_load: float
    m_before: float
    m_after: float
    identified: float


def change_stats(res: Identification, tc: float, guard: float) -> ChangeStats:
    """Return the :class:`ChangeStats` of a change at ``tc`` in ``res``'s fit.

    Each side fitted on its own rows of the whole log's filtered regression (with the Coulomb-like columns of
    :func:`_with_coulomb` and the noise compensation of :func:`regressor_noise`), the rows within ``guard`` s of
    ``tc`` left out (the zero-phase filter mixes the two sides there, and a load dropped in gives the cart an
    impulse the model has not got). ``z`` is the mass difference over its std, each side's the larger of its
    Newey-West and block-jackknife std (:func:`cart.identify._fit`: misfit that varies along a side counts;
    the Newey-West std alone reached z = 4.2 on logs without a change), the lesser of two fits: each side
    with all its own parameters, and with the columns both sides share (:func:`shared_columns`: sensor
    offsets, caster resistances) held at the two sides' joint fit (:func:`_shared_parameters`), as in the
    split search. The first is weak where caster columns and mass trade on a short side, the second
    overconfident where the casters' share of the load is not the same on both sides (their scrub grows with
    the load) and it leaves out the shared parameters' own uncertainty: a change must show in both.
    ``z_load`` (:func:`load_z`) adds the yaw inertia's evidence where it moves with the mass, the lesser of
    the two fits too. The masses are the first fit's; ``identified`` the least mass over its std of the two.
    """
    data = res.fit_data
    assert data is not None
    lag = int(math.ceil(2.0 / (res.cutoff_hz * res.grid_dt * data["step"])))
    t = data["t"]
    noise = regressor_noise(res)
    sides = ((t < tc - guard), (t >= tc + guard))
    if min(int(side.sum()) for side in sides) < 4 * lag:
        return ChangeStats(0.0, 0.0, math.nan, math.nan, 0.0)
    x = _with_coulomb(data["x"])
    shared = shared_columns(x.shape[-1])
    try:
        own = _side_fits(x, data["y"], sides, noise, lag)
        p_sh = _shared_parameters(x, data["y"], data["scale"], sides, noise, shared)
        y_free = data["y"] - np.einsum("krp,p->kr", x[..., shared], p_sh)
        held = _side_fits(np.delete(x, shared, axis=-1), y_free, sides, noise, lag)
    except np.linalg.LinAlgError:
        return ChangeStats(0.0, 0.0, math.nan, math.nan, 0.0)
    (z_own, zl_own), (z_held, zl_held) = load_z(*own), load_z(*held)
    left, right = own
    ident = min(left.m / math.sqrt(left.var_m), right.m / math.sqrt(right.var_m))
    return ChangeStats(min(z_own, z_held), min(zl_own, zl_held), left.m, right.m, ident)


class _Side(NamedTuple):
    """One side's fit: its mass and yaw inertia (the ``J`` column), their variances and covariance."""

    m: float
    var_m: float
    j: float
    var_j: float
    cov: float


def _side_fits(x: np.ndarray, y: np.ndarray, sides: tuple[np.ndarray, ...], noise: np.ndarray, lag: int) -> list[_Side]:
    """Return each side's own fit (:func:`cart.identify._fit`) of the regression ``x``, ``y`` (:class:`_Side`)."""
    from cart.identify import _fit

    out = []
    for side in sides:
        p, cov, _, _ = _fit(x[side], y[side], noise, lag)
        var_m, var_j = max(float(cov[0, 0]), 1e-300), max(float(cov[3, 3]), 1e-300)
        out.append(_Side(float(p[0]), var_m, float(p[3]), var_j, float(cov[0, 3])))
    return out


def load_z(left: _Side, right: _Side) -> tuple[float, float]:
    """Return (the mass difference over its std, the load's joint evidence) between two sides' fits.

    A load on the deck adds its mass and its yaw inertia (about the composite CoM the parts' own inertias and
    their parallel-axis terms add; about any fixed point too): the mass and the ``J`` column move the same way.
    Where they do, the joint evidence is the sum of their differences over their std, over that sum's std
    (``sqrt(2 + 2 rho)``, ``rho`` the two differences' correlation); where they do not, the mass's alone.
    The yaw inertia is often the better identified of the two on a light cart that turns (the F/T noise on the
    forward force hides a few kilograms that the torque's response to the turns shows).
    """
    var_m, var_j = left.var_m + right.var_m, left.var_j + right.var_j
    z_m = (right.m - left.m) / math.sqrt(var_m)
    z_j = (right.j - left.j) / math.sqrt(var_j)
    rho = (left.cov + right.cov) / math.sqrt(var_m * var_j)
    joint = abs(z_m + z_j) / math.sqrt(max(2.0 + 2.0 * rho, 1e-12)) if z_m * z_j > 0.0 else 0.0
    return abs(z_m), max(abs(z_m), joint)


def _shared_parameters(
    x: np.ndarray,
    y: np.ndarray,
    scale: np.ndarray,
    sides: tuple[np.ndarray, ...],
    noise: np.ndarray,
    shared: np.ndarray,
) -> np.ndarray:
    """Return the ``shared`` columns' parameters of the two sides' joint weighted least-squares fit.

    Each side has its own parameters for the other columns; the regressor noise (``noise`` (2, n), of the
    first columns, :func:`regressor_noise`) is removed from each side's own normal matrix.
    """
    p_dim = x.shape[-1]
    t = _shared_map(p_dim, shared)
    w = 1.0 / scale**2
    noise = np.pad(noise, ((0, 0), (0, p_dim - noise.shape[1])))
    m, v = np.zeros((2 * p_dim, 2 * p_dim)), np.zeros(2 * p_dim)
    for k, side in enumerate(sides):
        xs, ys = x[side] * np.sqrt(w)[None, :, None], y[side] * np.sqrt(w)[None, :]
        block = slice(k * p_dim, (k + 1) * p_dim)
        m[block, block] = np.einsum("nri,nrj->ij", xs, xs) - np.diag(int(side.sum()) * (w @ noise))
        v[block] = np.einsum("nri,nr->i", xs, ys)
    sol = np.linalg.solve(t.T @ m @ t, t.T @ v)
    return (t @ sol)[shared]


def _summary(res, t0: float, t1: float, t0_range: tuple[float, float] | None = None) -> dict[str, Any]:
    return {
        "t0": float(t0),
        "t0_range": None if t0_range is None else [float(t0_range[0]), float(t0_range[1])],
        "t1": float(t1),
        "params": res.params,
        "std": res.std,
        "model_fits": res.model_fits,
        "residual_ratio": res.residual_ratio,
        "warnings": tuple(res.warnings),
    }


class _Search(NamedTuple):
    """The split search's regression (:func:`best_split`'s arguments): rows ``_ROWS_PER_PERIOD`` per cut-off period."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    scale: np.ndarray
    min_len: float
    tol: float
    kernels: SplitKernels
    shared: np.ndarray
    row_dt: float


def _search_rows(res: Identification) -> _Search:
    """Return the split search's rows of ``res``'s filtered regression (with the Coulomb-like columns), the
    shortest segment (``MIN_SEGMENT_S`` or ten cut-off periods) and the tolerance (one independent residual)."""
    data = res.fit_data
    assert data is not None
    every = max(1, int(1.0 / (_ROWS_PER_PERIOD * res.cutoff_hz * res.grid_dt * data["step"])))
    x = _with_coulomb(data["x"])[::every]
    lag = 2.0 / (res.cutoff_hz * res.grid_dt)  # samples per independent residual (the filter's memory)
    return _Search(
        t=data["t"][::every],
        x=x,
        y=data["y"][::every],
        scale=data["scale"],
        min_len=max(MIN_SEGMENT_S, 10.0 / res.cutoff_hz),
        tol=lag / (data["step"] * every),
        kernels=split_kernels(res, data["step"] * every),
        shared=shared_columns(x.shape[-1]),
        row_dt=every * data["step"] * res.grid_dt,
    )


def _split(
    log: CartLog, res, t0: float, t1: float, depth: int, t0_range: tuple[float, float] | None = None
) -> list[dict[str, Any]]:
    """Return the segments of [t0, t1] (whose identification is ``res``), searched ``depth`` more levels.

    A change is kept when the two sides' mass difference (:func:`change_z`), or the joint evidence of their mass and
    yaw inertia (:func:`load_z`), is at least ``CHANGE_Z`` std (or the pose shows a put-in's momentum exchange
    there, :func:`exchange_shown`) and ``MIN_RELATIVE_CHANGE`` of the
    larger mass, each side's mass at least ``IDENTIFIED_Z`` of its std; each
    side is then identified on its own, ``guard`` s (one period of the cut-off) away from the change, and
    those estimates (the ones reported) must differ by ``MIN_RELATIVE_CHANGE`` too, each mass at least
    ``IDENTIFIED_Z`` of its own std (:func:`_weighed`). The split is sought on the
    rows weighted by :func:`robust_weights` first, unweighted when the change found so is not kept.
    """
    from cart.identify import IdentifiabilityError, identify

    here = [_summary(res, t0, t1, t0_range)]
    data = res.fit_data
    if depth <= 0 or data is None:
        return here
    plain = _search_rows(res)
    for s in (reweighted(plain), plain):
        split = _kept_split(log, res, s)
        if split is not None:
            break
    else:
        return here
    tc, lo, hi = split
    guard = 1.0 / res.cutoff_hz
    lo_i, hi_i = information_stretch(s.t, s.x, s.y, s.scale, s.min_len, s.tol, s.kernels, tc, s.shared)
    lo_c, hi_c = confidence_set(s.t, s.x, s.y, s.scale, s.min_len, s.tol, s.kernels, s.shared)
    lo, hi = min(lo, lo_i, lo_c), max(hi, hi_i, hi_c)
    try:
        casters = res.casters if res.casters is not None and res.casters.kept else None  # the same cart's casters
        left = identify(slice_log(log, t0, tc - guard), casters=casters)
        right = identify(slice_log(log, tc + guard, t1), casters=casters)
    except (IdentifiabilityError, np.linalg.LinAlgError):
        return here
    if _alike(left.params.m, right.params.m) or not (_weighed(left) and _weighed(right)):
        return here  # the sides' own estimates, which are reported, must show the change and weigh each side
    segs_l = _split(log, left, t0, tc, depth - 1, t0_range)
    segs_r = _split(log, right, tc, t1, depth - 1, (lo, hi))
    return _joined(log, segs_l, segs_r, guard, casters)


def _kept_split(log: CartLog, res, s: _Search) -> tuple[float, float, float] | None:
    """Return :func:`best_split`'s (time, earliest, latest) on the search ``s`` when the change there is kept (the
    sides' masses, or their masses and yaw inertias jointly, differ by ``CHANGE_Z`` std, or the pose shows a
    put-in's exchange, :func:`_split`), else None."""
    split = best_split(s.t, s.x, s.y, s.scale, s.min_len, s.tol, s.kernels, shared=s.shared)
    if split is None:
        return None
    z, z_load, ml, mr, identified = change_stats(res, split[0], 1.0 / res.cutoff_hz)
    if not (identified >= IDENTIFIED_Z and abs(ml - mr) >= MIN_RELATIVE_CHANGE * max(ml, mr)):
        return None
    if z_load < CHANGE_Z and not exchange_shown(log, res.params.m, split[0], (ml, mr, z), s.row_dt):
        return None
    return split


def robust_weights(s: _Search) -> np.ndarray:
    """Return each row's weight (k, 2) of the search ``s``: at most one, less where the whole log's single fit (no
    change) misfits more than ``ROBUST_MISFIT`` times its typical misfit over ``ROBUST_WINDOW_S`` either side.

    The typical misfit is the median of the windows' mean square, per row of the wrench (force, torque).
    """
    sw = 1.0 / s.scale
    xs, ys = s.x * sw[None, :, None], s.y * sw[None, :]
    p = np.linalg.lstsq(xs.reshape(-1, xs.shape[-1]), ys.reshape(-1), rcond=None)[0]
    r2 = (ys - np.einsum("krp,p->kr", xs, p)) ** 2
    n = max(1, int(round(ROBUST_WINDOW_S / s.row_dt)))
    box = np.ones(2 * n + 1) / (2 * n + 1)
    local = np.stack([np.convolve(r2[:, j], box)[n : n + len(r2)] for j in range(2)], axis=1)  # centred windows
    typical = median_columns(local)
    return np.minimum(1.0, ROBUST_MISFIT * np.sqrt(typical[None, :] / np.maximum(local, 1e-300)))


def reweighted(s: _Search) -> _Search:
    """Return the search ``s`` with its rows weighted by :func:`robust_weights` (the same tolerance).

    The weights vary over a window of ``2 ROBUST_WINDOW_S``, longer than the filter's reach, so the momentum
    exchange's rows (:func:`exchange_corrections`, weighted at the candidate's row) share their window's weight.
    """
    w = robust_weights(s)
    return s._replace(x=s.x * w[:, :, None], y=s.y * w)


def _weighed(res) -> bool:
    """Return whether an identification's mass is at least ``IDENTIFIED_Z`` of its own std (a segment whose mass the
    log does not hold is no side of a change: a split that leaves one is not kept)."""
    return bool(res.params.m >= IDENTIFIED_Z * res.std["mass"])


def _alike(m_a: float, m_b: float) -> bool:
    """Return whether two masses differ by less than ``MIN_RELATIVE_CHANGE`` of the larger."""
    return abs(m_a - m_b) < MIN_RELATIVE_CHANGE * max(m_a, m_b)


def _joined(
    log: CartLog, segs_l: list[dict[str, Any]], segs_r: list[dict[str, Any]], guard: float, casters
) -> list[dict[str, Any]]:
    """Return the segments of both sides of a change, the two next to it joined when a side's own search split
    it further and they no longer differ (binary segmentation re-checks its split: a whole log's best split can
    fall between two segments of the same load when the change lies elsewhere in that side).

    The joined segment is identified again, on its rows ``guard`` s after its start (a change's filter reach).
    """
    from cart.identify import IdentifiabilityError, identify

    a, b = segs_l[-1], segs_r[0]
    if len(segs_l) + len(segs_r) == 2 or not _alike(a["params"].m, b["params"].m):
        return segs_l + segs_r
    start = a["t0"] + (0.0 if a["t0_range"] is None else guard)
    try:
        res = identify(slice_log(log, start, b["t1"]), casters=casters)
    except (IdentifiabilityError, np.linalg.LinAlgError):
        return segs_l + segs_r
    return segs_l[:-1] + [_summary(res, a["t0"], b["t1"], a["t0_range"])] + segs_r[1:]


#: Half-width (s) of the pose fits either side of a put-in's momentum exchange (:func:`exchange_jump`): short
#: against the pushed cart's motion (and the force the handle gives it is taken out), tens of pose samples.
EXCHANGE_WINDOW_S = 0.3


def exchange_jump(log: CartLog, m: float, tc: float, reach: float) -> tuple[float, float, float, float]:
    """Return (forward velocity before, its jump, the jump's std, the largest jump over its std elsewhere) at the
    sample within ``reach`` s of ``tc`` where the jump the handle's force does not explain is most significant.

    The forward displacement along the heading minus the double integral of the forward force over ``m`` (what
    the handle's force explains), fitted by a quadratic on ``EXCHANGE_WINDOW_S`` either side of a sample: the
    jump is the difference of the two fits' slopes there, its std from their residuals; the velocity before from
    the same fit of the displacement alone. A load at rest put on the cart shares its forward momentum
    ``m_L v = m_R (v + jump)`` at once, with no force at the handle. Elsewhere: the same jump's significance at
    samples ``EXCHANGE_WINDOW_S`` apart, farther than twice that from ``tc`` (what the log's other events, a
    caster's swing or a bump, give without a change).
    """
    ok = np.isfinite(log.t) & np.all(np.isfinite(log.q), axis=1) & np.all(np.isfinite(log.gamma), axis=1)
    t, q, gam = log.t[ok], log.q[ok], log.gamma[ok]
    th = q[:, 2]
    d = np.diff(q[:, :2], axis=0)
    s = np.r_[0.0, np.cumsum(np.cos(th[:-1]) * d[:, 0] + np.sin(th[:-1]) * d[:, 1])]
    f = np.cos(th) * gam[:, 0] + np.sin(th) * gam[:, 1]
    vf = np.r_[0.0, np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t))] / m
    e = s - np.r_[0.0, np.cumsum(0.5 * (vf[1:] + vf[:-1]) * np.diff(t))]
    best = (0.0, 0.0, math.inf)
    for i in range(int(np.searchsorted(t, tc - reach)), min(int(np.searchsorted(t, tc + reach)) + 1, len(t))):
        got = _jump(t, e, i)
        if got is not None and abs(got[0]) * math.sqrt(best[2]) >= abs(best[1]) * math.sqrt(got[1]):
            best = (_slope(t[got[2]] - t[i], s[got[2]])[0], got[0], got[1])
    elsewhere = 0.0
    for i in np.searchsorted(t, np.arange(t[0], t[-1], EXCHANGE_WINDOW_S)):
        got = _jump(t, e, int(i)) if abs(t[int(i)] - tc) > 2 * EXCHANGE_WINDOW_S else None
        elsewhere = max(elsewhere, 0.0 if got is None else abs(got[0]) / math.sqrt(got[1]))
    return best[0], best[1], math.sqrt(best[2]), elsewhere


def _jump(t: np.ndarray, e: np.ndarray, i: int) -> tuple[float, float, slice] | None:
    """Return (slope after - slope before, its variance, the rows before) of ``e`` at sample ``i`` (None near an end)."""
    lo = int(np.searchsorted(t, t[i] - EXCHANGE_WINDOW_S))
    hi = int(np.searchsorted(t, t[i] + EXCHANGE_WINDOW_S, side="right"))
    if min(i - lo, hi - i) < 6:
        return None
    (a, va), (b, vb) = (_slope(t[side] - t[i], e[side]) for side in (slice(lo, i), slice(i, hi)))
    return b - a, va + vb, slice(lo, i)


def _slope(t: np.ndarray, s: np.ndarray) -> tuple[float, float]:
    """Return (slope at t = 0, its variance) of the least-squares quadratic through ``s(t)``."""
    a = np.stack([np.ones_like(t), t, t * t], axis=1)
    ata = np.linalg.inv(a.T @ a)
    c = ata @ (a.T @ s)
    r = s - a @ c
    return float(c[1]), float(ata[1, 1] * (r @ r) / max(len(t) - 3, 1))


def exchange_shown(log: CartLog, m: float, tc: float, sides: tuple[float, float, float], reach: float) -> bool:
    """Return whether the pose shows the momentum exchange of a load put in at ``tc`` (:func:`exchange_jump`).

    ``sides``: the two sides' masses and their difference over its std (:func:`change_z`). A put-in (the mass
    grows) while the cart moves drops its speed at once by ``v (1 - m_L / m_R)`` with no force at the handle:
    the jump must be a drop of speed more significant, by ``CHANGE_Z`` of its std, than any the log shows
    elsewhere (unexplained jumps without a change, a caster's swing or a bump, reach 5-20 std on the MuJoCo
    cart's logs), and agree with the one the sides' masses predict within ``IDENTIFIED_Z`` combined std (the prediction's relative std that of the mass
    difference, one over its z). The sides' masses alone can then fall short of ``CHANGE_Z`` (their std
    inflated by misfit along the log, which a jump within a fraction of a second does not see).
    """
    ml, mr, z = sides
    if not (mr > ml and z > 0.0):
        return False
    v0, jump, sd, elsewhere = exchange_jump(log, m, tc, reach)
    pred = v0 * (ml / mr - 1.0)
    return bool(
        jump * v0 < 0.0
        and abs(jump) >= (CHANGE_Z + elsewhere) * sd
        and abs(jump - pred) <= IDENTIFIED_Z * math.hypot(sd, pred / z)
    )


def find_segments(log: CartLog, streams, res) -> tuple[list[dict[str, Any]], list[str]]:
    """Return (segments of constant load, notes) of a log whose whole-log identification is ``res``.

    Each segment: ``t0``, ``t0_range`` (None for the first; else [earliest, latest] start the data allow: a
    change while the cart cruises or stands still shows only at the next acceleration), ``t1``, ``params``,
    ``std``, ``model_fits``, ``residual_ratio``. A log without a load change gives one segment with the
    whole-log numbers.
    """
    t0, t1 = float(log.t[0]), float(log.t[-1])
    segs = _split(log, res, t0, t1, MAX_DEPTH)
    if len(segs) == 1:
        return segs, []

    def when(seg: dict[str, Any]) -> str:
        lo, hi = seg["t0_range"]
        wide = (
            f" (the time is not identified: the change lies between {lo:.1f} and {hi:.1f} s, where the motion does "
            "not excite the load's inertia)"
            if hi - lo > 1
            else ""
        )
        return f"t = {seg['t0']:.2f} s{wide}"

    changes = ", ".join(f"{when(b)} ({a['params'].m:.4g} -> {b['params'].m:.4g} kg)" for a, b in zip(segs, segs[1:]))
    return segs, [
        f"the load changes at {changes}: the log is reported in {len(segs)} segments; the parameters shown "
        "are the last segment's (the cart as it is at the end of the log)"
    ]

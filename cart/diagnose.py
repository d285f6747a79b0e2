"""Model-discrepancy workflow: fit the nominal cart model, find where it fails, name and add missing effects.

``diagnose(log) -> DiagnosisReport``:

a. Nominal fit. The paper's model (eq. 4 projected on the forward and yaw
   directions, eq. 5-7) is linear in x = [m, m dx, m dy, J, sigma, sigma_yaw] given the
   motion. Velocities/accelerations come from local quadratic fits of the
   pose; every row is integrated over consecutive windows of ~0.3 s (so the
   accelerations enter as velocity differences and the residuals are close to
   independent), and solved by weighted least squares with one noise variance
   per row (forward force, yaw torque, lateral displacement of {b}).
b. Replay. The fitted model is integrated over 1 s horizons from the smoothed
   measured state with the measured wrench; the end errors, normalised by the
   noise-predicted std, give chi-square statistics; significant starts
   (Benjamini-Hochberg FDR 1 %) are merged into windows labelled with what the
   cart was doing.
c. Selection. Every candidate effect (``cart.effects``) is refitted with the
   model (nonlinear parameters by grid + 1-D refinement; set-valued terms such
   as friction holding the cart at rest by fixed-point iteration) and scored by
   Delta BIC = -2 Delta log-likelihood - k log(n) (profiled Gaussian
   likelihood, n = number of window rows); the best one with Delta BIC >
   ``threshold`` whose fit is physical (effect and cart: m > 0.5 kg, positive
   inertia about the CoM) and whose replay stays finite is added -- a further
   one only if it does not widen the gap -- and the search repeats.
d. Report: gap before/after (same replay metric), named effects with
   parameters, stds (Gauss-Newton covariance / profile curvature), evidence,
   windows.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field, replace
from collections.abc import Sequence

import numpy as np

from cart.effects import (
    N_NOMINAL,
    Effect,
    FloorSlope,
    WrenchBias,
    measured_rows,
    nominal_columns,
    nominal_loadings,
    registered_effects,
)
from cart.errors import DiagnoseError
from cart.log_signals import (
    Signals,
    cache_bounded,
    lateral_displacements,
    signals_from_log,
    velocity_change_noise,
    window_edges,
    window_integrals,
    window_keep,
)
from cart.logs import CartLog
from cart.standing import pose_stands
from cart.diagnose_checks import (
    MASS_MIN,
    SLIP_RATIO,
    WrenchFrameError,
    cart_is_physical,
    constrained_fit,
    lateral_slip_ratio,
    unexplained_slip,
)
from cart.diagnose_prep import prepare_log
from cart.coloured_evidence import NOISE_KEY, evidence_inflation, fit_wrench_noise
from cart.diagnose_replay import Replay, flag_starts, merge_windows, replay
from cart.diagnose_report import (  # noqa: F401  (re-exported: the report is part of this module's API)
    PARAMETER_UNITS,
    DiagnosisReport,
    DiscrepancyWindow,
    NamedEffect,
    Verdict,
    _format_parameter,
    _mm,
    _physical,
    diagnosis_figures,
    effect_comment,
    plot_diagnosis,
)


GAP_METRIC = (
    "RMS excess position error (m) of the {b} origin over the noise floor: sqrt(max(mean(e^2 - f^2), 0)), "
    "e = RMS error between the model and the measured pose over a 1.0 s replay (started every 0.25 s from "
    "the smoothed measured state with the measured wrench), f = the RMS error the estimated pose, force "
    "and torque noise alone predict for that replay; mean over the starts the nominal replay flags as "
    "significant (all starts when none). 0 = the replay error is at the noise level"
)
NOMINAL_NAMES = ("m", "m_dx", "m_dy", "J", "sigma", "sigma_yaw")
ROW_NAMES = ("forward force", "yaw torque", "lateral displacement")


#: ``Signals.extras`` key of the mask of the windows that lie within one contiguous segment
KEEP_KEY = ("motion", "keep_windows")

#: grid points of a candidate fitted as one batch (bounds the working memory of long logs) ...
QUICK_BATCH = 16
#: ... and at most this many grid points x samples per batch (a transformed candidate, such as a
#: time_delay, keeps its own copy of the signals per grid point)
QUICK_BATCH_SAMPLES = 100_000

#: runners-up of a grid-only nonlinear parameter fitted in full and replayed before an effect is named
GRID_ALTERNATIVES = 3


@dataclass
class Fit:
    """One least-squares fit of the nominal model plus effects (internal)."""

    effects: list[tuple[Effect, tuple[float, ...]]]
    x: np.ndarray
    thetas: list[np.ndarray]
    rss: np.ndarray
    n_win: int
    cov: np.ndarray
    m2ll: float
    #: the fit's (transformed) signals; None for a grid fit, which is scored but never replayed
    sig: Signals | None
    design: np.ndarray | None = field(repr=False, default=None)
    #: fits at the next-best grid points of a grid-only nonlinear parameter (replay-checked by ``diagnose``)
    alternatives: list[Fit] = field(repr=False, default_factory=list)
    #: True for a fit whose cart was bounded to a physical one (:func:`constrained_fit`)
    constrained: bool = False

    def signals(self) -> Signals:
        """Return the fit's signals; raise DiagnoseError for a grid fit, which keeps none."""
        if self.sig is None:
            raise DiagnoseError("a grid fit keeps no signals to replay")
        return self.sig

    @property
    def phi(self) -> np.ndarray:
        """Return the fitted phi = [m, m dx, m dy, J]."""
        return self.x[:4]

    @property
    def n_params(self) -> int:
        """Return the number of fitted parameters (6 nominal + effects)."""
        return N_NOMINAL + sum(e.n_params for e, _ in self.effects)


def _gram(a: np.ndarray) -> np.ndarray:
    """Return a^T a for a stack of matrices a (g, k, p) -> (g, p, p)."""
    return np.matmul(a.transpose(0, 2, 1), a)


def _solve(
    d: np.ndarray, y: np.ndarray, lv: np.ndarray, lw: np.ndarray, s2v: float, s2w: float, n_iter: int = 5
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (x, equation-noise variance per row, covariance, -2 log-likelihood) of y ~ d x with noisy regressors.

    Batched over the leading axis (one independent problem per entry): y (g, n, 3), d (g, n, 3, p).
    The regressors carry the noise of the differentiated pose: column noise = lv * e_v + lw * e_w with
    var(e_v) = s2v, var(e_w) = s2w (velocity changes over a window). The fit is the bias-corrected
    (errors-in-variables) weighted least squares: minimise sum w (r^2 - x' S x) with
    w = 1 / (V_r + x' S_k x); the likelihood uses the variance V_r + x' S_k x of each window row.
    """
    g, n, r, p = d.shape
    d2 = d.reshape(g, n * r, p)
    y2 = y.reshape(g, n * r)
    # the loadings are sparse (a few columns carry pose noise): only those columns enter
    cv = np.flatnonzero(np.any(lv != 0.0, axis=(0, 1, 2)))
    cw = np.flatnonzero(np.any(lw != 0.0, axis=(0, 1, 2)))
    lv2, lw2 = lv.reshape(g, n * r, p)[:, :, cv], lw.reshape(g, n * r, p)[:, :, cw]
    var_eq = np.maximum(np.var(y, axis=1), 1e-24)  # (g, r)
    s_k = np.zeros((g, n, r))
    ridge = 1e-10 * np.eye(p)
    for _ in range(n_iter):
        sw = np.sqrt(1.0 / (var_eq[:, None, :] + s_k)).reshape(g, n * r, 1)
        a2 = d2 * sw
        normal = _gram(a2)
        corr = np.zeros((g, p, p))
        corr[:, cv[:, None], cv[None, :]] = s2v * _gram(lv2 * sw)
        corr[:, cw[:, None], cw[None, :]] += s2w * _gram(lw2 * sw)
        rhs = np.matmul(a2.transpose(0, 2, 1), (y2 * sw[:, :, 0])[:, :, None])[:, :, 0]
        col = np.sqrt(np.maximum(np.diagonal(normal, axis1=1, axis2=2), 1e-300))
        outer = col[:, :, None] * col[:, None, :]
        chol = np.linalg.cholesky(normal / outer + ridge)
        linv = np.linalg.inv(chol)
        mu, u = np.linalg.eigh(linv @ (corr / outer) @ linv.transpose(0, 2, 1))
        # bounded bias correction: remove at most 70 % of the normal matrix in any direction
        mat = chol @ (u * np.maximum(1.0 - mu, 0.3)[:, None, :]) @ u.transpose(0, 2, 1) @ chol.transpose(0, 2, 1)
        x = np.linalg.solve(mat, (rhs / col)[:, :, None])[:, :, 0] / col
        res = y - np.matmul(d2, x[:, :, None]).reshape(g, n, r)
        s_k = (s2v * np.matmul(lv2, x[:, cv, None]) ** 2 + s2w * np.matmul(lw2, x[:, cw, None]) ** 2).reshape(g, n, r)
        var_eq = np.maximum(np.mean(res * res - s_k, axis=1), 0.05 * np.mean(res * res, axis=1) + 1e-24)
    var = var_eq[:, None, :] + s_k
    cov = np.linalg.pinv(_gram((d / np.sqrt(var)[..., None]).reshape(g, n * r, p)))
    m2ll = np.sum(np.log(var) + res * res / var, axis=(1, 2))
    return x, var_eq, cov, m2ll


def _solve_many(problems: Sequence[tuple[np.ndarray, ...]], s2v: float, s2w: float) -> list[tuple]:
    """Return :func:`_solve` of each (d, y, lv, lw) in ``problems``, same-shaped ones solved as one batch."""
    out: dict[int, tuple] = {}
    groups: dict[tuple, list[int]] = {}
    for i, (d, _, _, _) in enumerate(problems):
        groups.setdefault(d.shape, []).append(i)
    for idx in groups.values():
        d_s, y_s, lv_s, lw_s = (np.stack([problems[i][k] for i in idx]) for k in range(4))
        x, var_eq, cov, m2ll = _solve(d_s, y_s, lv_s, lw_s, s2v, s2w)
        for j, i in enumerate(idx):
            out[i] = (x[j], var_eq[j], cov[j], float(m2ll[j]))
    return [out[i] for i in range(len(problems))]


@dataclass
class _FitState:
    """One fit of :func:`fit_models` in progress: its signals, effects and the fixed-point iterate."""

    sig: Signals
    effects: list[tuple[Effect, tuple[float, ...]]]
    base: tuple[np.ndarray, np.ndarray, np.ndarray]
    phi: np.ndarray | None
    thetas_prev: list[np.ndarray | None]
    iterate: bool
    n_iter: int
    solution: tuple | None = None
    thetas: list[np.ndarray] = field(default_factory=list)
    finished: bool = False
    #: True when the current solution is the bounded fit (:func:`cart.diagnose_checks.constrained_fit`)
    bounded: bool = False


def _start_fit(
    sig0: Signals,
    edges: np.ndarray,
    effects: Sequence[tuple[Effect, tuple[float, ...]]],
    phi_ref: np.ndarray | None,
    theta_ref: Sequence[np.ndarray | None] | None,
    max_iter: int,
) -> _FitState:
    """Return the start of one fit: the effects' transformed signals, their window rows (cached), the start iterate."""
    sig = sig0
    for e, nl in effects:
        sig = e.transform(sig, nl)
    base = sig.extras.get("base")
    if base is None:
        a_s = nominal_columns(sig)
        y_w = window_integrals(sig.t, measured_rows(sig), edges)
        y_w[:, 2] = lateral_displacements(sig, edges)
        base = (a_s, window_integrals(sig.t, a_s, edges), y_w)
        sig.extras["base"] = base
        sig.extras["base_edges"] = edges  # the windows of base's integrals (a payload's step reuses them)
    thetas_prev: list[np.ndarray | None] = list(theta_ref) if theta_ref is not None else []
    thetas_prev = (thetas_prev + [None] * len(effects))[: len(effects)]
    iterate = any(e.uses_phi or e.set_valued for e, _ in effects)
    phi = np.asarray(phi_ref, float) if phi_ref is not None else None
    return _FitState(
        sig=sig,
        effects=list(effects),
        base=base,
        phi=phi,
        thetas_prev=thetas_prev,
        iterate=iterate,
        n_iter=max_iter if iterate else 1,
    )


def _phi_over_time(
    sig: Signals, effects: Sequence[tuple[Effect, tuple[float, ...]]], thetas: Sequence[np.ndarray | None], phi
) -> np.ndarray | None:
    """Return phi per sample (N, 4) with the steps of the effects that change it (None: phi is constant)."""
    if phi is None:
        return None
    out = None
    for (e, nl), th in zip(effects, thetas):
        ch = e.replay_phi_change(sig, nl, th, phi) if (e.steps_phi and th is not None) else None
        if ch is not None:
            out = (np.tile(np.asarray(phi[:4], float), (sig.n, 1)) if out is None else out) + ch
    return out


def _bilinear(st: _FitState, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Return the nominal rows (a_s, a_w, y_w) linearised about the iterate for the ``bilinear`` effects, and phi(t).

    An effect whose force is S(theta) phi(t) (a floor slope: m g, with the mass of each sample) is
    bilinear in its parameters and phi. The Gauss-Newton step about (phi0(t), theta0): rows
    y + S(theta0) phi0(t) = (A + S(theta0)) phi(t) + G(phi0(t)) theta, so the phi columns (the nominal
    ones and a payload's step of them) carry S(theta0), the effect's columns phi0(t). A fixed point on
    phi alone does not converge when phi steps (the slope's force on the payload).
    """
    sig, (a_s, a_w, y_w) = st.sig, st.base
    phi_t = _phi_over_time(sig, st.effects, st.thetas_prev, st.phi)
    s0 = None
    for (e, _), th in zip(st.effects, st.thetas_prev):
        s_e = e.phi_force(sig, th) if (e.bilinear and th is not None) else None
        if s_e is not None:
            s0 = s_e if s0 is None else s0 + s_e
    if s0 is None or st.phi is None:
        return a_s, a_w, y_w, phi_t
    phi0 = phi_t if phi_t is not None else np.asarray(st.phi[:4], float)[None, :]
    a_s = a_s.copy()
    a_s[:, :, :4] += s0
    a_w = a_w.copy()
    a_w[:, :, :4] += window_integrals(sig.t, s0, edges)
    y_w = y_w + window_integrals(sig.t, np.einsum("nrk,nk->nr", s0, np.broadcast_to(phi0, (sig.n, 4))), edges)
    return a_s, a_w, y_w, phi_t


def _design(st: _FitState, edges: np.ndarray) -> tuple[np.ndarray, ...]:
    """Return (d, y, lv, lw) of the window rows for the current iterate of ``st`` (set-valued terms first)."""
    sig, a_hold = st.sig, st.base[0]
    a_s, a_w, y_w, phi_t = _bilinear(st, edges)
    lv_b, lw_b = nominal_loadings(a_w.shape[0])
    g_w, lv, lw = [a_w], [lv_b], [lw_b]
    y_fit = y_w
    for (e, nl), th_prev in zip(st.effects, st.thetas_prev):
        # the set-valued term first: it may update state the columns use (active set, swing choice)
        off = e.offset(sig, nl, st.phi, a_hold, th_prev) if e.set_valued else None
        if off is not None:
            y_fit = y_fit - window_integrals(sig.t, off, edges)
        ck = e.column_key(sig, nl) if (a_s is a_hold or not e.steps_phi) else None
        ck = ("cols", ck, len(edges), int(edges[-1])) if ck is not None else None
        g = sig.extras.get(ck) if ck is not None else None
        if g is None:
            phi_e = phi_t if (e.bilinear and phi_t is not None) else st.phi
            g = e.window_columns(sig, nl, phi_e, a_s if e.steps_phi else a_hold, edges)
            if ck is not None:
                cache_bounded(sig, "cols", ck, g, COLUMN_CACHE_BYTES)
        g_w.append(g)
        lo = e.noise_loadings(sig, nl, edges, lv_b, lw_b)
        lv.append(lo[0] if lo is not None else np.zeros_like(g))
        lw.append(lo[1] if lo is not None else np.zeros_like(g))
    return _kept(sig, (np.concatenate(g_w, axis=2), y_fit, np.concatenate(lv, axis=2), np.concatenate(lw, axis=2)))


#: bytes of window columns the fits keep (oldest dropped first): bounded however long the log
COLUMN_CACHE_BYTES = 64 * 2**20


def _kept(sig: Signals, rows: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """Return the window rows without the windows across a logging gap (``sig.extras`` ``keep`` mask)."""
    keep = sig.extras.get(KEEP_KEY)
    if keep is None or bool(np.all(keep)):
        return rows
    return tuple(r[keep] for r in rows)


def _converged(st: _FitState, x: np.ndarray, thetas: list[np.ndarray], freeze: int) -> bool:
    """Return True when phi and the free set-valued effects' parameters stopped moving."""
    if st.phi is None or not np.all(np.abs(x[:4] - st.phi) <= 1e-4 * (np.abs(st.phi) + 1e-3)):
        return False
    gauss_newton = any(e.bilinear for e, _ in st.effects)  # the linearisation point holds every parameter
    return all(
        tp is not None and np.all(np.abs(th - tp) <= 1e-3 * (np.abs(tp) + 1e-3))
        for i, ((e, _), th, tp) in enumerate(zip(st.effects, thetas, st.thetas_prev))
        if (e.set_valued or gauss_newton) and i >= freeze
    )


def _advance(st: _FitState, solution: tuple, it: int, freeze: int) -> None:
    """Take one solved iterate into ``st``: parameters, convergence, the next phi and set-valued parameters."""
    x = solution[0]
    thetas, k = [], N_NOMINAL
    for e, _ in st.effects:
        thetas.append(x[k : k + len(e.param_names)])
        k += len(e.param_names)
    done = _converged(st, x, thetas, freeze)
    st.solution, st.thetas = solution, thetas
    st.phi = x[:4]
    st.thetas_prev = [tp if i < freeze else th for i, (tp, th) in enumerate(zip(st.thetas_prev, thetas))]
    st.finished = bool(done or (it == 0 and not st.iterate) or it + 1 >= st.n_iter)


#: bytes of bounded fits kept per log (:func:`_bounded_fit`, oldest dropped first)
BOUNDED_FIT_CACHE_BYTES = 8 * 2**20


def _bounded_fit(sig0: Signals, rows: tuple[np.ndarray, ...], noise: tuple[float, float], sol: tuple) -> tuple:
    """Return :func:`cart.diagnose_checks.constrained_fit` of the window ``rows`` (d, y, lv, lw) from ``sol``.

    The result is a function of its inputs alone, and the same rows recur (a grid point refitted, the same
    candidate on the same fit): it is kept in ``sig0.extras`` under a digest of every input (a bounded cache).
    """
    h = hashlib.blake2b(digest_size=20)
    for a in (*rows, np.asarray(sol[0], float), np.asarray(sol[1], float), np.asarray(noise, float)):
        h.update(repr(a.shape).encode())
        h.update(np.ascontiguousarray(a).tobytes())
    key = ("bounded_fit", h.digest())
    packed = sig0.extras.get(key)
    if packed is None:
        d, y, lv, lw = rows
        x, var_e, cov, m2ll = constrained_fit(d, y, lv, lw, noise[0], noise[1], sol[0], sol[1])
        packed = np.concatenate([x, var_e, cov.ravel(), [m2ll]])
        cache_bounded(sig0, "bounded_fit", key, packed, BOUNDED_FIT_CACHE_BYTES)
    n_p, n_r = len(sol[0]), len(sol[1])
    x, var_e = packed[:n_p].copy(), packed[n_p : n_p + n_r].copy()
    return x, var_e, packed[n_p + n_r : -1].reshape(n_p, n_p).copy(), float(packed[-1])


def fit_models(
    sig0: Signals,
    edges: np.ndarray,
    effect_lists: Sequence[Sequence[tuple[Effect, tuple[float, ...]]]],
    phi_ref: np.ndarray | None = None,
    max_iter: int = 12,
    theta_refs: Sequence[Sequence[np.ndarray | None] | None] | None = None,
    freeze: int = 0,
    bounded: bool = False,
) -> list[Fit]:
    """Return :func:`fit_model` of every effect list, the least-squares solves of each iteration as one batch.

    The fits are independent (each has its own iterate; ``theta_refs``: one ``theta_ref`` per list);
    each fit's own sequence of designs is the one :func:`fit_model` builds. ``bounded``: a solution
    that is not a cart is replaced by the same weighted fit with the cart bounded to a physical one
    (:func:`cart.diagnose_checks.constrained_fit`; the effects' parameters free), at every iterate.
    """
    refs = list(theta_refs) if theta_refs is not None else [None] * len(effect_lists)
    states = [_start_fit(sig0, edges, eff, phi_ref, ref, max_iter) for eff, ref in zip(effect_lists, refs)]
    s2v, s2w = sig0.extras["noise_dv"]
    cold = [st for st in states if st.phi is None and st.n_iter > 1]
    if cold:  # the nominal fit starts the fixed-point iteration
        lv_b, lw_b = nominal_loadings(cold[0].base[1].shape[0])
        sols = _solve_many([_kept(st.sig, (st.base[1], st.base[2], lv_b, lw_b)) for st in cold], s2v, s2w)
        for st, sol in zip(cold, sols):
            st.phi = sol[0][:4]
    for it in range(max(st.n_iter for st in states) if states else 0):
        active = [st for st in states if not st.finished]
        if not active:
            break
        designs = [_design(st, edges) for st in active]
        sols = _solve_many(designs, s2v, s2w)
        for st, sol, rows in zip(active, sols, designs):
            st.bounded = bounded and not (cart_is_physical(sol[0]) and np.all(sol[0][4:N_NOMINAL] >= 0.0))
            if st.bounded:
                sol = _bounded_fit(sig0, rows, (s2v, s2w), sol)
            _advance(st, sol, it, freeze)
    out = []
    for st in states:
        if st.solution is None:
            raise DiagnoseError("a fit ended without a solution")
        x, rss, cov, m2ll = st.solution
        out.append(
            Fit(
                effects=st.effects,
                x=x[:N_NOMINAL],
                thetas=st.thetas,
                rss=rss,
                n_win=_n_windows(st.sig, st.base[2].shape[0]),
                cov=cov,
                m2ll=m2ll,
                sig=st.sig,
                constrained=st.bounded,
            )
        )
    return out


def fit_model(
    sig0: Signals,
    edges: np.ndarray,
    effects: Sequence[tuple[Effect, tuple[float, ...]]],
    phi_ref: np.ndarray | None = None,
    max_iter: int = 12,
    theta_ref: Sequence[np.ndarray | None] | None = None,
    freeze: int = 0,
) -> Fit:
    """Return the weighted least-squares fit of the nominal model plus ``effects`` (with their nl parameters).

    Effects whose columns use phi, or that add a set-valued term
    (``Effect.offset``), are fitted by fixed-point iteration from ``phi_ref``
    and ``theta_ref`` (previous estimates, one per effect; None: start afresh).
    The set-valued terms of the first ``freeze`` effects stay at ``theta_ref``
    (a quick refit of one more candidate on top of named effects).
    """
    return fit_models(sig0, edges, [effects], phi_ref, max_iter, [theta_ref], freeze)[0]


def _n_windows(sig: Signals, n_all: int) -> int:
    """Return the number of fitted windows (those across a logging gap left out)."""
    keep = sig.extras.get(KEEP_KEY)
    return n_all if keep is None else int(np.sum(keep))


def _cart_ok(x: np.ndarray) -> bool:
    """Return True for a possible cart: finite, m > 0.5 kg, J - ((m dx)^2 + (m dy)^2) / m > 0."""
    return cart_is_physical(x)


#: a fitted viscous coefficient this many stds below 0 is a cart that gains energy from its motion: no cart
DAMPING_Z = 3.0


def _damping_ok(fit: Fit) -> bool:
    """Return True when neither viscous coefficient (sigma, sigma_yaw) is significantly negative (DAMPING_Z stds).

    A negative damping drives the cart: no passive cart has one. An effect whose fit needs one trades its
    columns against the damping's (Coulomb friction and a wrench bias, made larger, against an anti-damping
    that takes the friction off again at speed) and is not named with it.
    """
    var = np.diag(fit.cov)[4:N_NOMINAL] if fit.cov.shape[0] >= N_NOMINAL else np.zeros(2)
    sd = np.sqrt(np.maximum(var, 0.0))
    return bool(np.all(np.asarray(fit.x[4:N_NOMINAL], float) >= -DAMPING_Z * sd))


def _valid(effect: Effect, fit: Fit, check_cart: bool = True) -> bool:
    """Return True when the fit is physical: the effect's parameters (``Effect.is_physical``) and the cart's.

    With ``check_cart`` the cart needs m > 0.5 kg, a positive inertia about
    its CoM and no significantly negative damping (:func:`_damping_ok`): an
    effect whose columns trade off against the nominal ones must not buy its
    fit with an impossible cart. (A missing effect can distort the
    nominal fit itself; when the current cart is impossible and no fit of a
    candidate repairs it, the candidate is judged without this check.)
    """
    if check_cart and not (_cart_ok(fit.x) and _damping_ok(fit)):
        return False
    if not np.all(np.isfinite(fit.x)):
        return False
    return bool(effect.is_physical(fit.thetas[-1], fit.effects[-1][1], fit.x))


@dataclass(frozen=True)
class _Search:
    """The fits of one candidate effect on top of the current fit (internal to :func:`_fit_candidate`)."""

    sig: Signals
    edges: np.ndarray
    current: Fit
    effect: Effect
    #: fit with the cart bounded to a physical one (:func:`fit_models` ``bounded``)
    bounded: bool = False

    @property
    def named(self) -> int:
        """Return the number of effects already named (their set-valued terms stay frozen in quick fits)."""
        return len(self.current.effects)

    def quick(self, nls: Sequence[tuple[float, ...]], theta_tail: Sequence[np.ndarray | None]) -> list[Fit]:
        """Return the grid-style fits at ``nls``: the named effects' set-valued terms at their current estimate.

        They iterate only for a candidate that needs it (3 iterations); ``theta_tail``: the candidate's
        start (None: afresh).
        """
        it_grid = 3 if (self.effect.uses_phi or self.effect.set_valued) else 1
        ref = list(self.current.thetas) + list(theta_tail)
        out: list[Fit] = []
        batch = max(1, min(QUICK_BATCH, QUICK_BATCH_SAMPLES // self.sig.n))
        for c0 in range(0, len(nls), batch):  # bounded memory: a batch of grid points at a time
            part = fit_models(
                self.sig,
                self.edges,
                [self.current.effects + [(self.effect, nl)] for nl in nls[c0 : c0 + batch]],
                self.current.phi,
                max_iter=it_grid,
                theta_refs=[ref] * len(nls[c0 : c0 + batch]),
                freeze=self.named,
                bounded=self.bounded,
            )
            for f in part:  # grid fits are scored, never replayed: drop their (possibly shifted) signals
                f.sig, f.design = None, None
            out.extend(part)
        return out

    def full(self, nls: Sequence[tuple[float, ...]], theta_refs: Sequence[Sequence[np.ndarray]]) -> list[Fit]:
        """Return the full fits at ``nls`` (every set-valued term iterates), started from ``theta_refs``."""
        return fit_models(
            self.sig,
            self.edges,
            [self.current.effects + [(self.effect, nl)] for nl in nls],
            self.current.phi,
            theta_refs=theta_refs,
            bounded=self.bounded,
        )

    def score(self, fit: Fit, check: bool) -> float:
        """Return -2 log-likelihood of a physically valid fit, inf otherwise."""
        return fit.m2ll if _valid(self.effect, fit, check) else np.inf


def _grid_alternatives(search: _Search, grid: list, fits: list[Fit], scores: np.ndarray, check: bool) -> list[Fit]:
    """Return the full fits at the next-best grid points of a grid-only parameter that are physical."""
    picks = [int(k) for k in np.argsort(scores)[1 : 1 + GRID_ALTERNATIVES] if np.isfinite(scores[k])]
    alts = search.full([grid[k] for k in picks], [fits[k].thetas for k in picks]) if picks else []
    return [alt for alt in alts if _valid(search.effect, alt, check)]


def _profile_std(effect: Effect, grid: list, scores: np.ndarray, i: int) -> float:
    """Return the std of a grid-only parameter from the parabola through the profile at the best point i (-1: none)."""
    tr = np.log if effect.log_scale else (lambda z: z)
    j = min(max(i, 1), len(grid) - 2)
    u = np.array([float(tr(grid[k][0])) for k in (j - 1, j, j + 1)])
    f = scores[j - 1 : j + 2]
    if not np.all(np.isfinite(f)):
        return -1.0
    c2 = np.polyfit(u - u[1], f, 2)[0]
    if c2 <= 0:
        return -1.0
    s_u = math.sqrt(1.0 / c2)  # m2ll = -2 log L: curvature 2 c2 = 2 / var
    return s_u * float(np.exp(u[1])) if effect.log_scale else s_u


def _refine_bracket(search: _Search, grid: list, i: int) -> tuple[float, float]:
    """Return the bracket (lo, hi) of the 1-D refinement around grid point i (extended past the grid's ends)."""
    lo_b, hi_b = search.effect.nl_bounds(search.sig)[0]
    log_scale = search.effect.log_scale
    vals = np.array([g[0] for g in grid])
    lo = vals[max(i - 1, 0)]
    hi = vals[min(i + 1, len(vals) - 1)]
    if i == 0:
        lo = max(lo_b, vals[0] - (vals[1] - vals[0])) if not log_scale else max(lo_b, vals[0] ** 2 / vals[1])
    if i == len(vals) - 1:
        hi = min(hi_b, vals[-1] + (vals[-1] - vals[-2])) if not log_scale else min(hi_b, vals[-1] ** 2 / vals[-2])
    return float(lo), float(hi)


def _refine(search: _Search, grid: list, i: int, best: Fit, check: bool) -> tuple[Fit, float]:
    """Return the best fit after a bounded 1-D refinement of the nonlinear parameter, and its std (profile curvature)."""
    from scipy import optimize  # lazy: scipy.optimize costs start-up time

    log_scale = search.effect.log_scale
    tr = np.log if log_scale else (lambda z: z)
    itr = np.exp if log_scale else (lambda z: z)
    lo, hi = _refine_bracket(search, grid, i)
    span = abs(float(tr(hi)) - float(tr(lo)))

    def objs(us: Sequence[float]) -> list[float]:
        fits = search.quick([(float(itr(u)),) for u in us], best.thetas[search.named :])
        return [f.m2ll if _valid(search.effect, f, check) else 1e300 for f in fits]

    if hi > lo:
        res = optimize.minimize_scalar(
            lambda u: objs([u])[0],
            bounds=(float(tr(lo)), float(tr(hi))),
            method="bounded",
            options={"xatol": 1e-3 * max(span, 1e-6)},
        )
        if res.fun < best.m2ll:
            cand = search.full([(float(itr(res.x)),)], [best.thetas])[0]
            if _valid(search.effect, cand, check):
                best = cand
    u0 = float(tr(best.effects[-1][1][0]))
    du = 0.02 * max(span, 1e-3)
    fp, fm = objs([u0 + du, u0 - du])
    curv = (fp + fm - 2.0 * best.m2ll) / du**2
    s_u = math.sqrt(2.0 / curv) if curv > 0 else float("inf")
    s = s_u * float(itr(u0)) if log_scale else s_u
    return best, float(s) if math.isfinite(s) else -1.0


#: grid points (the best unbounded ones) refitted with the cart bounded when no grid fit is a cart
BOUNDED_GRID = 3


def _bounded_grid(search: _Search, grid: list, fits: list[Fit]) -> tuple[_Search, list[Fit], np.ndarray]:
    """Return the search with the cart bounded, the grid's fits and scores (inf where not refitted).

    When no fit of a candidate is a cart (its columns trade off against the nominal ones: Coulomb
    friction or a floor slope alone on a log that holds both put the CoM so far forward that the
    inertia about it is negative), the candidate is fitted with the cart bounded to a physical one
    (m >= MASS_MIN, I about the CoM > 0, dampings >= 0; :func:`cart.diagnose_checks.constrained_fit`),
    as the nominal fit is, at the BOUNDED_GRID grid points whose unbounded fits fit best: an impossible
    single fit does not block the search for the pair it belongs to.
    """
    raw = np.array([f.m2ll if np.isfinite(f.m2ll) else np.inf for f in fits])
    picks = [int(k) for k in np.argsort(raw)[:BOUNDED_GRID] if np.isfinite(raw[k])]
    bounded = replace(search, bounded=True)
    out, scores = list(fits), np.full(len(grid), np.inf)
    for k, f in zip(picks, bounded.quick([grid[k] for k in picks], [None])):
        out[k], scores[k] = f, bounded.score(f, True)
    return bounded, out, scores


def _fit_candidate(sig: Signals, edges: np.ndarray, current: Fit, effect: Effect) -> tuple[Fit, list[float]]:
    """Return the best fit of current effects + ``effect`` (nl parameters searched) and the nl stds.

    Grid fits first (quick: the named effects' set-valued terms stay at their current estimate), then a
    full fit at the best grid point; a grid-only parameter carries its runners-up along
    (``Fit.alternatives``, replay-checked by :func:`diagnose`), a refinable one is refined in 1-D.
    """
    search = _Search(sig, edges, current, effect)
    grid = effect.nl_grid(sig)
    fits = search.quick(grid, [None])
    check = True
    scores = np.array([search.score(f, check) for f in fits])
    if not np.any(np.isfinite(scores)) and (current.constrained or not _cart_ok(current.x)):
        check = False  # the current cart is impossible (or only bounded into a cart): judge the effect alone
        scores = np.array([search.score(f, check) for f in fits])
    if not np.any(np.isfinite(scores)):  # no fit is a cart: the same fits with the cart bounded to one
        b_search, b_fits, b_scores = _bounded_grid(search, grid, fits)
        if np.any(np.isfinite(b_scores)):
            search, fits, scores, check = b_search, b_fits, b_scores, True
    i = int(np.argmin(scores))
    best = search.full([grid[i]], [fits[i].thetas])[0]
    if not np.isfinite(scores[i]) or not _valid(effect, best, check):
        best.m2ll = float("inf")  # no physically valid fit: a failed candidate
        return best, [-1.0] * len(effect.nl_names)
    if not effect.refine and len(grid) > 1:
        best.alternatives.extend(_grid_alternatives(search, grid, fits, scores, check))
    if len(effect.nl_names) != 1 or len(grid) < 2:
        return best, []
    if not effect.refine:
        return best, [_profile_std(effect, grid, scores, i)]
    best, s = _refine(search, grid, i, best, check)
    return best, [s]


def _replay_terms(fit: Fit) -> tuple[np.ndarray, np.ndarray | None]:
    """Return the effects' (forward force, yaw torque, lateral speed) (N, 3) and phi change (N, 4) for replay."""
    sig = fit.signals()
    extra = np.zeros((sig.n, 3))
    dphi = None
    a_s = sig.extras["base"][0]
    phi_t = _phi_over_time(sig, fit.effects, fit.thetas, fit.phi)
    for (e, nl), th in zip(fit.effects, fit.thetas):
        ch = e.replay_phi_change(sig, nl, th, fit.phi)
        if ch is not None:
            dphi = ch if dphi is None else dphi + ch
            continue
        off = e.offset(sig, nl, fit.phi, a_s, th) if e.set_valued else None
        if off is not None:
            extra[:, 0] -= off[:, 0]
            extra[:, 1] -= off[:, 1]
            extra[:, 2] += off[:, 2]
        if len(th) == 0:
            continue
        phi_e = phi_t if (e.bilinear and phi_t is not None) else fit.phi
        g = e.columns(sig, nl, phi_e, a_s) @ th
        extra[:, 0] -= g[:, 0]
        extra[:, 1] -= g[:, 1]
        extra[:, 2] += g[:, 2]
    return extra, dphi


def _activity(sig: Signals, t0: float, t1: float) -> str:
    """Return what the cart was doing in [t0, t1]: reversing, turning, accelerating, cruising, stationary."""
    sel = (sig.t >= t0) & (sig.t <= t1)
    if not np.any(sel):
        return "unknown"
    v, om, vd = sig.v[sel], sig.omega[sel], sig.vdot[sel]
    v_th = max(0.03, 3.0 * sig.sigma_v)
    labels = []
    if np.any(v > v_th) and np.any(v < -v_th):
        labels.append("reversing")
    if np.mean(np.abs(om)) > 0.15:
        labels.append("turning")
    if np.mean(np.abs(vd)) > 0.15 and "reversing" not in labels:
        labels.append("accelerating" if np.mean(vd * np.sign(v)) >= 0 else "braking")
    if not labels:
        labels.append("stationary" if np.max(np.abs(v)) < v_th and np.max(np.abs(om)) < 0.05 else "cruising")
    return "+".join(labels)


@dataclass(frozen=True)
class _Trial:
    """One fitted variant of a candidate effect: its Delta BIC, the variant, its fit and nl stds."""

    dbic: float
    effect: Effect
    fit: Fit
    nl_std: list[float]


@dataclass(frozen=True)
class _Ranked:
    """The fitted variants of one candidate effect, best Delta BIC first."""

    trials: list[_Trial]

    @property
    def best(self) -> _Trial:
        """Return the variant with the best Delta BIC."""
        return self.trials[0]


#: the candidates ranked on one fit (:func:`_rank_candidates`), with that fit
_RankMemo = tuple[Fit, list[_Ranked]]


@dataclass(frozen=True)
class _Named:
    """An effect named in one round of the search: its variant's trial and the replay of the model with it."""

    trial: _Trial
    replay: Replay
    #: which effect of ``trial.fit`` this is (-1: the last; a pair's first effect is reported from the joint fit)
    slot: int = -1


def _checked_signals(
    log: CartLog, horizon: float | None, window: float | None, wrench_holes: Sequence[tuple[float, float]] = ()
) -> tuple[Signals, float, np.ndarray]:
    """Return (signals, replay horizon, window edges) of ``log``; raise DiagnoseError when it cannot be diagnosed.

    The windows that reach a pose hole or one of ``wrench_holes`` (:func:`clear_of`) are left out of the fits.
    """
    if not np.any(log.gamma):
        raise DiagnoseError(f"{log.source}: the wrench is zero throughout; nothing to diagnose")
    sig = signals_from_log(log, filled=wrench_holes)
    if _stands(sig) or (
        np.max(np.abs(sig.v)) < 5.0 * sig.sigma_v and np.max(np.abs(sig.omega)) < 5.0 * sig.sigma_omega
    ):
        raise DiagnoseError(
            f"{log.source}: the cart does not move beyond the noise of its pose "
            f"(speed noise {sig.sigma_v:.2g} m/s); nothing to diagnose"
        )
    if horizon is None:  # 1 s replays for a cart log, shorter for a short log
        horizon = min(1.0, (sig.t[-1] - sig.t[0]) / 6.0)
    med_dt = float(np.median(np.diff(sig.t)))
    if horizon < 3.0 * med_dt:
        raise DiagnoseError(
            f"{log.source}: samples are {med_dt:.3g} s apart, too far apart to replay the model over "
            f"{horizon:.3g} s (need at least 3 samples per replay); if t is in milliseconds, "
            "convert it to seconds"
        )
    edges = window_edges(sig.t, window if window is not None else 2.0 * sig.half_window, sig.breaks)
    keep = window_keep(edges, sig.breaks) & clear_of_holes(sig, edges)
    sig.extras[KEEP_KEY] = keep & clear_of(sig, edges, np.asarray(wrench_holes, float))
    sig.extras["noise_dv"] = velocity_change_noise(sig, edges)
    n_win = int(np.sum(sig.extras[KEEP_KEY]))
    if n_win < 11:
        raise DiagnoseError(f"{log.source}: too short for a fit ({n_win} window{'s' if n_win != 1 else ''})")
    return sig, horizon, edges


def _stands(sig: Signals) -> bool:
    """Return whether the cart stands (:func:`cart.standing.pose_stands`, the estimate's rule, with the heading).

    The extreme speeds of thousands of differentiated noise samples reach past 5 of their std (the test on
    ``v`` and ``omega``); a standing cart's pose does not wander beyond a few of its noise stds.
    """
    return pose_stands(sig.q_raw, sig.sigma_pos, sig.sigma_theta)


def clear_of_holes(sig: Signals, edges: np.ndarray) -> np.ndarray:
    """Return the mask of the windows clear of pose holes: no sample within the fits' half-window of a hole.

    A hole is an interval between pose samples longer than the local fits' half-window (a motion-capture
    dropout): a sample next to it is differentiated from one side only, its velocity and acceleration
    extrapolated with several times the noise :func:`cart.log_signals.velocity_change_noise` predicts,
    so a window that holds such a sample is left out of the fits (as the window across a logging gap).
    Read as data, those windows' rows made a mass step: a held-pose table with three dropouts named a
    9 kg ``payload_change`` (``tests/cart/test_redteam_diagnose.py``).
    """
    holes = np.flatnonzero(np.diff(sig.t) > float(sig.half_window))
    return clear_of(sig, edges, np.column_stack([sig.t[holes], sig.t[holes + 1]]))


def clear_of(sig: Signals, edges: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """Return the mask of the windows that hold no sample within the fits' half-window of any of ``spans``.

    ``spans``: (k, 2) intervals (t0, t1) of ``sig``'s time: pose holes (:func:`clear_of_holes`) or the
    stretches where the wrench was filled, not measured (``Prepared.wrench_holes``: a clipped axis or a stuck
    sensor whose samples the streams excluded; the fill across a clipped peak reads the clip level, and
    read as data the windows there made a ``payload_change``).
    """
    hw = float(sig.half_window)
    keep = np.ones(max(len(edges) - 1, 0), bool)
    spans = np.asarray(spans, float).reshape(-1, 2)
    if len(spans) == 0 or len(keep) == 0:
        return keep
    lo, hi = spans[:, 0] - hw, spans[:, 1] + hw  # the samples whose fits reach the span
    t0, t1 = sig.t[edges[:-1]], sig.t[edges[1:]]
    first = np.searchsorted(t1, lo, side="right")  # first window that ends after lo
    last = np.searchsorted(t0, hi, side="left")  # first window that starts at or after hi
    hit = np.zeros(len(keep) + 1, int)
    np.add.at(hit, first, 1)
    np.add.at(hit, last, -1)
    return keep & (np.cumsum(hit)[:-1] == 0)


def _residual_rows(fit: Fit) -> np.ndarray:
    """Return the fit's residual (N, 3) along the log: forward force, yaw torque, lateral speed of {b}."""
    sig = fit.signals()
    extra, dphi = _replay_terms(fit)
    a_s = sig.extras["base"][0]
    pred = a_s @ fit.x
    if dphi is not None:
        pred += np.einsum("nrk,nk->nr", a_s[:, :, :4], dphi)
    meas = measured_rows(sig)
    return np.column_stack([meas[:, 0] + extra[:, 0], meas[:, 1] + extra[:, 1], meas[:, 2] - extra[:, 2]]) - pred


def _coloured_gain(sig: Signals, edges: np.ndarray, current: Fit, fit: Fit, base_rows: np.ndarray) -> float:
    """Return -2 Delta log L of ``fit`` over ``current``, divided by the inflation coloured F/T noise gives it.

    :func:`cart.coloured_evidence.evidence_inflation` of the change the fit makes to the residual rows
    (``base_rows``: ``current``'s); 1 on a log whose wrench noise is white.
    """
    gain = current.m2ll - fit.m2ll
    if not gain > 0.0 or fit.sig is None or not np.all(np.isfinite(fit.x)):
        return gain
    change = base_rows - _residual_rows(fit)
    return gain / evidence_inflation(sig, edges, change, current.rss)


def _rank_candidates(
    sig: Signals, edges: np.ndarray, current: Fit, cands: Sequence[Effect], named: Sequence[str]
) -> list[_Ranked]:
    """Return every candidate not yet named with its variants ranked by Delta BIC, best candidate first."""
    n_obs = 3 * _n_windows(sig, len(edges) - 1)
    results = []
    base_rows = _residual_rows(current)
    for e in cands:
        if e.name in named:
            continue
        tried = []
        for ev in e.variants():  # nested parameterisations of one effect: ranked by their best Delta BIC
            fit, nl_std = _fit_candidate(sig, edges, current, ev)
            for f in [fit] + fit.alternatives:
                gain = _coloured_gain(sig, edges, current, f, base_rows)
                tried.append(_Trial(gain - ev.n_params * math.log(n_obs), ev, f, nl_std))
        tried.sort(key=lambda r: -r.dbic if np.isfinite(r.dbic) else np.inf)
        results.append(_Ranked(tried))
    results.sort(key=lambda r: -r.best.dbic)
    return results


def _best_replaying_variant(trials: Sequence[_Trial], threshold: float, horizon: float) -> tuple[_Named | None, str]:
    """Return, among an effect's significant variants, the one whose replay follows the whole log best, and why not.

    (None, reason) when no significant variant has a physical fit whose replay stays finite.
    """
    best, why = None, "no significant form of it has a physical fit"
    for tr in trials:
        if tr.dbic <= threshold or not np.isfinite(tr.dbic):
            break
        if tr.fit.x[0] <= 0 or not np.all(np.isfinite(tr.fit.x)):
            why = "its fits give a non-positive or non-finite mass"
            continue
        extra, dphi = _replay_terms(tr.fit)
        rep = replay(tr.fit.signals(), tr.fit.x, extra, dphi, horizon=horizon).without_paths()
        if not rep.finite:  # a blown-up replay = a failed candidate (infinite error)
            why = "the replay of its fit blows up (the fitted cart is not physical)"
            continue
        if best is None or rep.rms_error() < best.replay.rms_error():
            best = _Named(tr, rep)
    return best, why


#: a named effect must close at least this share of the gap the nominal model (or the named effects) leave
MIN_SHRINK = 0.1
#: A wrench_bias (floor_slope force) smaller than this share of the RMS applied forward force and torque, and
#: within the tare limits below, is a sensor's offset.
OFFSET_SHARE = 0.2
#: The largest forward force (N) and yaw torque (N m) an F/T sensor keeps after taring (a few tenths of a newton,
#: fitted up to about twice that under coloured noise): a constant beyond either is a bias of the set-up whatever
#: its share of the push.
TARE_FORCE = 1.5
TARE_TORQUE = 0.4


@dataclass(frozen=True)
class _Round:
    """The outcome of one round of the search: the named effect (or None), why, and why the others were not."""

    chosen: _Named | None
    reason: str
    verdicts: list[Verdict]


def _gap_objection(first: bool, slip_now: bool, last_gap: float, gap: float) -> str:
    """Return why a candidate's replay gap (after) does not justify naming it ('' when it does)."""
    if slip_now:
        if gap > 1.02 * last_gap:
            return f"its replay widens the gap ({_mm(last_gap)} -> {_mm(gap)}) although {{b}} slides sideways"
        return ""
    if last_gap <= 0:
        if first:
            return "the nominal model replays the log at the noise level (gap 0 mm): nothing to explain"
        return "the named effects already replay the log at the noise level (gap 0 mm)"
    if not gap <= (1.0 - MIN_SHRINK) * last_gap:
        left = "the nominal model leaves" if first else "the named effects leave"
        return (
            f"its replay closes too little of the gap {left} ({_mm(last_gap)} -> {_mm(gap)}; "
            f"an effect must close at least {MIN_SHRINK:.0%} of it)"
        )
    return ""


def _chosen_reason(
    name: str,
    dbic: float,
    named: Sequence[str],
    gaps: tuple[float, float],
    slip: float,
    passed: Sequence[Verdict],
    deferred: Sequence[tuple[str, float]] = (),
) -> str:
    """Return why the round's effect was named: the slip rule, its evidence and gap, the stronger ones passed over."""
    base = "the model with " + ", ".join(named) if named else "the nominal model"
    parts = []
    if not named and slip > SLIP_RATIO and name == "lateral_slip":
        ahead = ", ".join(f"{n} (Delta BIC {d:.1f})" for n, d in deferred if d > dbic)
        parts.append(
            f"the {{b}} origin slides sideways ({slip:.1f} x the travel the pose noise explains): the "
            "no-slip constraint (eq. 3) does not hold, so lateral_slip is tried first"
            + (f", before {ahead}" if ahead else "")
        )
    parts.append(f"Delta BIC {dbic:.1f} over {base}; replay gap {_mm(gaps[0])} -> {_mm(gaps[1])}")
    stronger = [v for v in passed if v.delta_bic > dbic]
    if stronger:
        parts.append(
            "named although "
            + "; ".join(f"{v.name} had the larger Delta BIC ({v.delta_bic:.1f}) but {v.reason}" for v in stronger)
        )
    return "; ".join(parts)


def _weak(dbic: float, threshold: float) -> str:
    """Return why a Delta BIC does not name an effect ('' when it is significant)."""
    if not np.isfinite(dbic):
        return "no physically possible fit"
    return "" if dbic > threshold else f"evidence too weak: Delta BIC {dbic:.1f} <= {threshold:g}"


def _logging_timing(trial: _Trial, resolution: float, slot: int = -1) -> str:
    """Return why a time_delay within one sample interval of the log is not named ('' when it is beyond).

    A table that averages the F/T over each pose interval (centred half an interval earlier) or holds a
    sample until the next one shifts the wrench by up to one sample interval: the logging's own timing,
    not a delay of the set-up. The delay must exceed the interval by 2 of its stds. ``slot``: which
    effect of ``trial.fit`` the delay is.
    """
    delay = float(trial.fit.effects[slot][1][0])
    std = float(trial.nl_std[0]) if trial.nl_std and np.isfinite(trial.nl_std[0]) else 0.0
    if abs(delay) - 2.0 * std > resolution:
        return ""
    return (
        f"its delay ({1e3 * delay:.1f} +- {1e3 * std:.1f} ms) is within one sample interval of the log "
        f"({1e3 * resolution:.1f} ms): the logging's own timing (a wrench averaged over or held for an "
        "interval), not a delay of the set-up"
    )


def _sensor_offset(trial: _Trial, push: tuple[float, float], slot: int = -1) -> str:
    """Return why a wrench_bias small against the push is not named ('' when it is not small).

    An F/T sensor carries an offset after taring (a few tenths of a newton); effect-free logs have one, and a
    long log makes it significant. A bias is named when its forward force or its torque reaches
    ``OFFSET_SHARE`` of the RMS forward force or torque applied over the log (``push``: N, N m), or exceeds
    what a tared sensor keeps (``TARE_FORCE``, ``TARE_TORQUE``): a 5 N bias is one on a 50 N push too.
    ``slot``: which effect of ``trial.fit`` the bias is.
    """
    fx, tau = (float(v) for v in trial.fit.thetas[slot][:2])
    share = max(abs(fx) / max(push[0], 1e-12), abs(tau) / max(push[1], 1e-12))
    if share >= OFFSET_SHARE or abs(fx) > TARE_FORCE or abs(tau) > TARE_TORQUE:
        return ""
    return (
        f"its size (fx {fx:.3g} N, tau {tau:.3g} N m) is {share:.2f} of the push (RMS {push[0]:.3g} N, "
        f"{push[1]:.3g} N m), below {OFFSET_SHARE:g}, and within a tared F/T sensor's offset ({TARE_FORCE:g} N, "
        f"{TARE_TORQUE:g} N m): an offset after taring, not a bias of the set-up"
    )


def _slope_offset(trial: _Trial, push: tuple[float, float], slot: int = -1) -> str:
    """Return why a floor_slope whose force is small against the push is not named ('' when it is not small).

    A slope's force m g sin(alpha) is a constant force in {s}: the F/T sensor's offset after taring, written
    in {s}, is one too, and where the heading turns little it is also the constant {b} force of a wrench_bias.
    A slope is named when its force reaches ``OFFSET_SHARE`` of the RMS forward force applied over the log
    (``push``: N, N m) or exceeds ``TARE_FORCE``, as a bias must. ``slot``: which effect of ``trial.fit`` the
    slope is.
    """
    gx, gy = (float(v) for v in trial.fit.thetas[slot][:2])
    force = abs(float(trial.fit.x[0])) * math.hypot(gx, gy)
    share = force / max(push[0], 1e-12)
    if share >= OFFSET_SHARE or force > TARE_FORCE:
        return ""
    return (
        f"its force (m g sin(alpha) = {force:.3g} N) is {share:.2f} of the push (RMS {push[0]:.3g} N), below "
        f"{OFFSET_SHARE:g}, and within a tared F/T sensor's offset ({TARE_FORCE:g} N), which is a constant force "
        "too: not a slope of the floor"
    )


def _choose_effect(
    results: Sequence[_Ranked],
    threshold: float,
    horizon: float,
    mask: np.ndarray | None,
    last: Replay,
    named: Sequence[str],
    slip_ratio: float,
    resolution: float = 0.0,
    push: tuple[float, float] = (0.0, 0.0),
) -> _Round:
    """Return the round's choice: the best significant candidate whose replay stays finite and that shrinks the gap.

    Every effect must close at least MIN_SHRINK of the gap the nominal model (or the named
    effects) leave. When the {b} origin slides sideways
    (``slip_ratio`` > SLIP_RATIO) ``lateral_slip`` is tried first (it must then not widen the gap):
    no other term of the model can stand in for a broken no-slip constraint. A time_delay within
    ``resolution`` (the log's median sample interval) is the logging's timing (:func:`_logging_timing`);
    a wrench_bias or a floor_slope below ``OFFSET_SHARE`` of the ``push`` (RMS forward force, torque) is a
    sensor's offset (:func:`_sensor_offset`, :func:`_slope_offset`).
    """
    first = not named
    slip_rule = first and slip_ratio > SLIP_RATIO
    order = sorted(results, key=lambda r: r.best.effect.name != "lateral_slip") if slip_rule else list(results)
    last_gap = last.gap(mask)
    verdicts: list[Verdict] = []
    passed: list[Verdict] = []  # candidates passed over, for the chosen one's reason
    chosen: _Named | None = None
    reason = ""
    for ranked in order:
        name, dbic = ranked.best.effect.name, float(ranked.best.dbic)
        weak = _weak(dbic, threshold)
        if chosen is not None or weak:
            verdicts.append(
                Verdict(
                    name,
                    dbic,
                    weak or f"{chosen.trial.effect.name if chosen else ''} was named before it in this round",
                )
            )
            continue
        cand, why = _best_replaying_variant(ranked.trials, threshold, horizon)
        gap = cand.replay.gap(mask) if cand is not None else float("nan")
        why = why if cand is None else _gap_objection(first, slip_rule and name == "lateral_slip", last_gap, gap)
        if not why and cand is not None and name == "time_delay":
            why = _logging_timing(cand.trial, resolution)
        if not why and cand is not None and name == "wrench_bias":
            why = _sensor_offset(cand.trial, push)
        if not why and cand is not None and name == "floor_slope":
            why = _slope_offset(cand.trial, push)
        if why:
            verdicts.append(Verdict(name, dbic, why))
            passed.append(verdicts[-1])
            continue
        chosen = cand
        deferred = [(r.best.effect.name, float(r.best.dbic)) for r in results if r.best.effect.name != name]
        reason = _chosen_reason(name, dbic, named, (last_gap, gap), slip_ratio if slip_rule else 0.0, passed, deferred)
    return _Round(chosen, reason, verdicts)


def _named_effects(
    named: Sequence[_Named],
    reasons: Sequence[str],
    reps: Sequence[Replay],
    flagged: np.ndarray,
    horizon: float,
    offset: float,
) -> list[NamedEffect]:
    """Return the report entries of the named effects: parameters, stds, evidence, windows they improve, why."""
    out: list[NamedEffect] = []
    for i, (nm, why) in enumerate(zip(named, reasons)):
        e, fit = nm.trial.effect, nm.trial.fit
        slot = nm.slot % len(fit.effects)
        th = fit.thetas[slot]
        k0 = N_NOMINAL + sum(len(ee.param_names) for ee, _ in fit.effects[:slot])
        cov = fit.cov[k0 : k0 + len(th), k0 : k0 + len(th)] if len(th) else np.zeros((0, 0))
        params, std = e.describe(th, fit.effects[slot][1], cov, nm.trial.nl_std, fit.phi)
        if "time" in params and params["time"] is not None:
            params["time"] = float(params["time"]) + offset
        better = flagged & (reps[i + 1].chi2 < 0.5 * reps[i].chi2)
        wins = merge_windows(reps[0].starts, better, horizon)
        comment = effect_comment(e.name, params)
        out.append(
            NamedEffect(
                name=e.name,
                parameters=params,
                uncertainties=std,
                evidence=float(nm.trial.dbic),
                windows=tuple((a + offset, b + offset) for a, b in wins),
                reason=why + (f"; {comment}" if comment else ""),
            )
        )
    return out


def _discrepancy_windows(
    sig: Signals, rep0: Replay, flagged: np.ndarray, horizon: float, offset: float
) -> list[DiscrepancyWindow]:
    """Return the windows where the nominal replay disagrees significantly, with activity and max chi2."""
    windows = []
    for t0, t1 in merge_windows(rep0.starts, flagged, horizon):
        sel = flagged & (rep0.starts >= t0 - 1e-9) & (rep0.starts <= t1)
        windows.append(
            DiscrepancyWindow(
                t0=t0 + offset,
                t1=t1 + offset,
                activity=_activity(sig, t0, t1),
                chi2=float(np.max(rep0.chi2[sel])),
            )
        )
    return windows


#: -2 log L + k ln n margin (BIC) by which a {b} reading must explain the log better to refuse it
FRAME_MARGIN = 20.0
#: a {b} reading better by this much (BIC), short of the refusal, is a warning
FRAME_WARN = 10.0
#: the two readings are told apart when their plain fits' BIC differ by this much ("strong" evidence)
FRAME_TOLD = 6.0
#: how many of its std the frame mixture must lie from 0 ({s}) for the wrench not to read as in {s}
FRAME_MIX_Z = 4.0
#: the frame mixture's std beyond which the log has no power to tell {s} from {b} (the cart turns too
#: little): lam = 1 must lie FRAME_MIX_Z std from 0 with a std to spare
FRAME_MIX_POWER = 1.0 / (FRAME_MIX_Z + 1.0)


class _FrameMix(Effect):
    """The wrench read as a mixture of its two frames: true forward force (1 - lam) f_fwd^s + lam f_fwd^b.

    ``d`` = f_fwd^s - f_fwd^b (the forward force as logged minus read in {b} and rotated by theta), so that
    ``f_fwd^s = A x + lam d``: lam = 0 is the wrench in {s} (LOG_FORMAT), lam = 1 in {b}. Linear, nested
    in both readings; only a heading that varies along the log (paper eq. 3: the forward direction turns)
    separates the column from the push itself.
    """

    name = "frame_mix"
    param_names = ("lam",)

    def __init__(self, d: np.ndarray) -> None:
        self._d = d

    def column_key(self, sig, nl):
        """Return None: the column is data, not cached."""
        return None

    def columns(self, sig, nl, phi, base):
        """Return G: d in the forward row."""
        g = np.zeros((sig.n, 3, 1))
        g[:, 0, 0] = self._d
        return g


@dataclass(frozen=True)
class _FrameMixTest:
    """The frame mixture lam fitted with the named effects, its std inflated for correlated residuals."""

    lam: float
    std: float
    rho: float

    @property
    def has_power(self) -> bool:
        """Return True when the log separates lam = 0 from lam = 1 (std at most FRAME_MIX_POWER)."""
        return self.std <= FRAME_MIX_POWER

    @property
    def not_s(self) -> bool:
        """Return True when lam lies more than FRAME_MIX_Z std from 0: the wrench does not read as in {s}."""
        return self.lam > FRAME_MIX_Z * self.std

    @property
    def may_be_b(self) -> bool:
        """Return True when lam lies far from 0 and within 3 std of 1 (far from both: a misfit, no frame)."""
        return self.not_s and abs(self.lam - 1.0) <= 3.0 * self.std

    @property
    def leans_b(self) -> bool:
        """Return True when lam lies more than 3 std from 0 and within 3 std of 1: {b} fits the log better than
        {s} does, short of the power or the distance from 0 to say so firmly (a warning, never a refusal)."""
        return self.lam > 3.0 * self.std and abs(self.lam - 1.0) <= 3.0 * self.std

    @property
    def is_b(self) -> bool:
        """Return True when the wrench reads as in {b}: lam far from 0, within 3 std of 1, with power."""
        return self.has_power and self.may_be_b

    def text(self) -> str:
        """Return 'lam = 0.97 +- 0.05' for the messages."""
        return f"frame mixture lam = {self.lam:.2f} +- {self.std:.2f} (0: {{s}}, 1: {{b}})"


def _frame_mixture(
    as_logged: Signals, alt: Signals, edges: np.ndarray, effects: list[tuple[Effect, tuple[float, ...]]]
) -> _FrameMixTest:
    """Return the frame mixture test: lam of :class:`_FrameMix` fitted with ``effects`` (the named ones).

    The fit's std assumes independent window residuals; a model that misses something leaves residuals
    correlated from window to window (lag-1 correlation rho > 0), and the std is inflated by
    sqrt((1 + rho) / (1 - rho)) (the AR(1) variance factor), so a misfit that happens to lean on the
    column is not read as a frame; or, when larger, by the square root of the column's inflation under
    the log's measured F/T noise spectrum (:func:`cart.coloured_evidence.evidence_inflation`: flicker noise
    is correlated far beyond one window).
    """
    eff = list(effects) + [(_FrameMix(as_logged.f_fwd - alt.f_fwd), ())]
    fit = fit_model(replace(as_logged, extras=dict(as_logged.extras)), edges, eff)
    st = _start_fit(fit.signals(), edges, eff, fit.phi, fit.thetas, 1)
    st.phi = fit.phi
    d, y, _, _ = _design(st, edges)
    x = np.concatenate([fit.x] + [np.atleast_1d(th) for th in fit.thetas])
    r = (y - d @ x)[:, 0]
    rho = float(np.sum(r[1:] * r[:-1]) / max(float(np.sum(r * r)), 1e-300)) if len(r) > 2 else 0.0
    rho = min(rho, 0.95)
    column = np.zeros((as_logged.n, 3))
    column[:, 0] = as_logged.f_fwd - alt.f_fwd
    coloured = evidence_inflation(as_logged, edges, column, fit.rss)
    inflate = math.sqrt(max(1.0, (1.0 + rho) / (1.0 - rho), coloured))
    return _FrameMixTest(float(fit.thetas[-1][0]), inflate * math.sqrt(max(float(fit.cov[-1, -1]), 0.0)), rho)


def _cart_frame_signals(sig: Signals, keep: dict) -> Signals:
    """Return the signals with (fx, fy) read as expressed in {b} and rotated into {s} by the heading."""
    th = sig.q_raw[:, 2]
    c, s = np.cos(th), np.sin(th)
    g = sig.gamma_raw
    g_alt = np.column_stack([c * g[:, 0] - s * g[:, 1], s * g[:, 0] + c * g[:, 1], g[:, 2]])
    cq, sq = np.cos(sig.q[:, 2]), np.sin(sig.q[:, 2])
    return replace(
        sig,
        gamma_raw=g_alt,
        f_fwd=cq * g_alt[:, 0] + sq * g_alt[:, 1],
        f_lat=-sq * g_alt[:, 0] + cq * g_alt[:, 1],
        extras=dict(keep),
    )


@dataclass(frozen=True)
class _FrameFits:
    """The model fitted to both readings of the wrench: as logged ({s}) and read in {b}, each plain (with a
    slope and a bias) and with the named effects, and the {b} reading without the named effects (``b_bare``:
    plain, less a named slope or bias).

    The readings are different data, so no single likelihood compares them without bias when the cart
    turns little: a reading that turns force into the lateral channel (free: the wheels take any lateral
    force) gets a smaller mass, and the full likelihood, which carries m^2 times the acceleration noise,
    favours it (by 33 for the wrong frame on a log that hardly turns); the likelihood of the equation noise
    alone (what is left beyond the pose noise's predicted share) leans the other way as far as that share
    is mispredicted. :meth:`margin` is the smaller of the two: a reading is preferred only when both agree.
    """

    s_plain: Fit
    b_plain: Fit
    s_named: Fit
    b_named: Fit
    b_bare: Fit
    ln_n: float
    mix: _FrameMixTest

    def bics(self, fit: Fit) -> np.ndarray:
        """Return the fit's BIC (-2 log L + k ln(3 n)) and that of its equation noise, n ln(V_fwd V_yaw) + k ln(3 n)."""
        eq = fit.n_win * float(np.sum(np.log(np.maximum(fit.rss[:2], 1e-300))))
        return np.array([fit.m2ll, eq]) + fit.n_params * self.ln_n

    def margin(self, worse: Fit, better: Fit) -> float:
        """Return by how much ``better`` beats ``worse`` in both BICs (the smaller margin; < 0: not in both)."""
        return float(np.min(self.bics(worse) - self.bics(better)))

    @property
    def b_best(self) -> Fit:
        """Return the {b} reading that beats the {s} reading by more (plain or with the named effects)."""
        return max((self.b_plain, self.b_named), key=lambda f: self.margin(self.s_named, f))


def _frame_fits(sig: Signals, edges: np.ndarray, final: Fit | None) -> _FrameFits:
    """Return the model fitted to the wrench as logged and read in {b}, plain and with ``final``'s effects.

    Every fit carries a constant force in {s} (a floor slope) and a constant wrench in {b} (a bias), so
    that neither reading wins by absorbing one of those.
    """
    # the window mask, the pose noise and what depends on the motion alone (both readings share the motion)
    keep = {
        k: v
        for k, v in sig.extras.items()
        if k in (KEEP_KEY, "noise_dv") or (isinstance(k, tuple) and len(k) > 0 and k[0] == "motion")
    }
    as_logged, alt = replace(sig, extras=dict(keep)), _cart_frame_signals(sig, keep)
    named = list(final.effects) if final is not None else []
    base: list[tuple[Effect, tuple[float, ...]]] = [(e, ()) for e in (FloorSlope(), WrenchBias())]
    rest = [(e, th) for e, th in base if e.name not in {n.name for n, _ in named}]
    s_plain, b_plain = fit_model(as_logged, edges, base), fit_model(alt, edges, base)
    s_named = fit_model(as_logged, edges, named + rest) if named else s_plain
    b_named = fit_model(alt, edges, named + rest) if named else b_plain
    b_bare = fit_model(alt, edges, rest) if len(rest) < len(base) else b_plain
    ln_n = math.log(3 * _n_windows(sig, len(edges) - 1))
    mix = _frame_mixture(as_logged, alt, edges, named + rest)
    return _FrameFits(s_plain, b_plain, s_named, b_named, b_bare, ln_n, mix)


def _frame_check(
    sig: Signals, edges: np.ndarray, final: Fit | None = None, threshold: float = 10.0
) -> tuple[str | None, bool]:
    """Return (a warning or None, whether the named effects are withdrawn); raise WrenchFrameError when the
    log's wrench reads as expressed in {b}, not in {s} (LOG_FORMAT).

    The frame is decided by the frame mixture (:class:`_FrameMix`, fitted with the named effects) and the
    two readings fitted in full (:class:`_FrameFits`): refused when the {b} reading is a cart (m >
    MASS_MIN; a physical one unless the reading as logged is not either) and either lam lies more than
    FRAME_MIX_Z std from 0, within 3 std of 1, with power (std <= FRAME_MIX_POWER), or lam lies far from 0,
    with power, nearer 1 than 0, and the {b} reading beats the one as logged by FRAME_MARGIN in both BICs
    (the mixture and the full readings agree: seed 10007's ``wrench_in_cart_frame07`` has lam = 0.82 +- 0.05
    and the {b} reading better by 99, with 50.2 kg for a 50.9 kg cart against 26.6 kg as logged). Named effects that do not beat the {b} reading without them by the naming
    threshold in either BIC, on a log whose lam may be that of {b} or whose {b} reading wins, stand for
    the frame as well as for themselves: withdrawn, with a warning. Short of a refusal, a log whose lam
    may be {b} or whose {b} reading wins by FRAME_WARN with lam far from 0, or whose lam lies more than 3 std
    from 0 and within 3 std of 1 (:attr:`_FrameMixTest.leans_b`): a warning. lam far from 0 and
    1 with the reading as logged better is a misfit the named effects leave, not a frame: no warning. A
    log without the power to tell the frames whose plain readings give masses 3 std apart: a warning that
    the frame cannot be checked.
    """
    ff = _frame_fits(sig, edges, final)
    mix, best = ff.mix, ff.b_best
    plausible = best.x[0] > MASS_MIN and (cart_is_physical(best.x) or not cart_is_physical(ff.s_named.x))
    b_margin = ff.margin(ff.s_named, best)  # how far the {b} reading beats the one as logged in both BICs
    b_wins = mix.not_s and mix.has_power and b_margin >= FRAME_WARN
    if plausible and (mix.is_b or (b_wins and mix.lam > 0.5 and b_margin >= FRAME_MARGIN)):
        raise WrenchFrameError(
            f"the wrench (fx, fy) looks expressed in the cart frame {{b}}, not in the world frame {{s}} that "
            f"LOG_FORMAT requires: read as a mix of the two, {mix.text()}; read in {{b}} the model fits better "
            f"by BIC {b_margin:.0f} (m = {best.x[0]:.1f} kg read in {{b}}, {ff.s_named.x[0]:.1f} kg as logged); "
            "rotate fx, fy into {s} (fx_s = cos(theta) fx - sin(theta) fy, fy_s = sin(theta) fx + cos(theta) fy)"
        )
    names = ", ".join(e.name for e, _ in (final.effects if final is not None else []))
    effects_vs_b = -ff.margin(ff.s_named, ff.b_bare)  # how far the effects beat the {b} reading in one BIC at least
    if names and (mix.may_be_b or b_wins) and effects_vs_b < threshold and cart_is_physical(ff.b_bare.x):
        return (
            f"nothing named: {names} would explain the log as logged, but read in the cart frame {{b}} the "
            f"nominal model alone explains it about as well (BIC {effects_vs_b:.0f} short of the threshold "
            f"{threshold:g}; {mix.text()}): the effects may stand for a wrench logged in {{b}}; check the "
            "logger's frame"
        ), True
    if mix.may_be_b or b_wins or mix.leans_b:
        why = (
            f"read in {{b}} the model fits better by BIC {b_margin:.0f} (m = {best.x[0]:.1f} kg against "
            f"{ff.s_named.x[0]:.1f} kg as logged)"
            if b_wins
            else f"the cart turns too little to be sure (m = {best.x[0]:.1f} kg read in {{b}}, "
            f"{ff.s_named.x[0]:.1f} kg as logged)"
        )
        return (
            f"the wrench (fx, fy) may be expressed in the cart frame {{b}} instead of {{s}}: {mix.text()}; {why}; "
            "check the logger's frame"
        ), False
    return (None if mix.has_power else _frame_undecided(ff)), False


def _frame_undecided(ff: _FrameFits) -> str | None:
    """Return a warning when neither plain reading beats the other by FRAME_TOLD but their masses are 3 std apart."""
    told = max(ff.margin(ff.s_plain, ff.b_plain), ff.margin(ff.b_plain, ff.s_plain))
    m_s, m_b = float(ff.s_plain.x[0]), float(ff.b_plain.x[0])
    sd = math.sqrt(max(float(ff.s_plain.cov[0, 0]) + float(ff.b_plain.cov[0, 0]), 1e-300))
    if told >= FRAME_TOLD or abs(m_s - m_b) <= 3.0 * sd:
        return None
    return (
        f"the wrench's frame cannot be checked on this log: read as logged ({{s}}) and in the cart frame {{b}} "
        f"the model fits about alike but gives m = {m_s:.1f} and {m_b:.1f} kg (the cart turns too little to "
        "tell them apart); make sure fx, fy are in {s}"
    )


def _push_work(sig: Signals) -> float:
    """Return the work (J) of the push on the cart: the integral of f_fwd v + tau omega (no lateral motion, eq. 3).

    A passive cart takes the work that changes its kinetic energy and what its resistance dissipates: over
    a push that starts and ends near rest it is positive.
    """
    power = sig.f_fwd * sig.v + sig.tau * sig.omega
    return float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(sig.t)))


def _nominal_fit(sig: Signals, edges: np.ndarray, source: str) -> tuple[Fit, list[str]]:
    """Return the nominal fit, bounded to a physical cart when the plain fit is not one, and the warnings."""
    nominal = fit_model(sig, edges, [])
    if cart_is_physical(nominal.x):
        return nominal, []
    work, work_b = _push_work(sig), _push_work(_cart_frame_signals(sig, {}))
    if nominal.x[0] <= 0.0 and work < 0.0 and work_b < -work:  # read in {b} no clearer push: not a frame
        raise DiagnoseError(
            f"{source}: the nominal fit gives no positive mass (m = {nominal.x[0]:.3g} kg) and the logged wrench "
            f"does {work:.4g} J of work on the cart (a passive cart is pushed with positive work): the wrench's "
            "sign looks flipped (the sensor's reading of the force on the robot?); negate fx, fy and tau "
            "(LOG_FORMAT: the wrench applied to the cart)"
        )
    a_s, a_w, y_w = sig.extras["base"]
    lv, lw = nominal_loadings(a_w.shape[0])
    d, y, lv, lw = _kept(sig, (a_w, y_w, lv, lw))
    s2v, s2w = sig.extras["noise_dv"]
    x, var_eq, cov, m2ll = constrained_fit(d, y, lv, lw, s2v, s2w, nominal.x, nominal.rss)
    m, a, b, j = (float(u) for u in nominal.x[:4])
    inertia = j - (a * a + b * b) / m if m != 0 else float("nan")
    warn = (
        f"the unconstrained nominal fit is not a cart (m = {m:.3g} kg, I about the CoM = {inertia:.3g} kg m^2): "
        f"the nominal model is fitted with m >= 0.5 kg, I > 0 and damping >= 0 instead (m = {x[0]:.3g} kg); "
        "the log lacks excitation, or force and motion do not match the model"
    )
    fit = Fit(
        effects=[], x=x, thetas=[], rss=var_eq, n_win=nominal.n_win, cov=cov, m2ll=m2ll, sig=sig, constrained=True
    )
    return fit, [warn]


@dataclass(frozen=True)
class _Pair:
    """Two effects fitted jointly: the first alone, the second given the first (its fit holds both), the evidence.

    ``dbic``: Delta BIC of the pair over the nominal model; ``drops``: the Delta BIC lost by dropping
    the first, the second (each must exceed the threshold: each effect is needed given the other).
    """

    first: _Named
    second: _Named
    dbic: float
    drops: tuple[float, float]

    @property
    def names(self) -> frozenset[str]:
        """Return the names of the two effects."""
        return frozenset((self.first.trial.effect.name, self.second.trial.effect.name))


def _replayed(trial: _Trial, horizon: float, paths: bool = False) -> _Named | None:
    """Return ``trial`` with the replay of its fit, or None when the replay blows up.

    The replay keeps its paths (the report's plots) only with ``paths``: a candidate's replay is judged by its
    scores, and the paths of every candidate kept would grow the memory with the log's length.
    """
    extra, dphi = _replay_terms(trial.fit)
    rep = replay(trial.fit.signals(), trial.fit.x, extra, dphi, horizon=horizon)
    rep = rep if paths else rep.without_paths()
    return _Named(trial, rep) if rep.finite else None


def _own_objection(nm: _Named, resolution: float, push: tuple[float, float], final: Fit | None = None) -> str:
    """Return why an effect's own size rules it out (a delay within the logging's timing, a sensor's offset).

    With ``final`` (the fit of every effect named, ``nm``'s in the same place in it as in the names) the size
    judged is the one ``final`` gives it: an effect named early, large while it stood in for the effects
    named after it, can shrink to a sensor's offset once they are in.
    """
    name = nm.trial.effect.name
    slot = nm.slot
    trial = nm.trial
    if final is not None:
        slot = [e[0].name for e in final.effects].index(name)
        trial = replace(nm.trial, fit=final)
    if name == "time_delay":
        return _logging_timing(trial, resolution, slot)
    if name == "wrench_bias":
        return _sensor_offset(trial, push, slot)
    if name == "floor_slope":
        return _slope_offset(trial, push, slot)
    return ""


def _pairs_from(
    sig: Signals,
    edges: np.ndarray,
    first: _Named,
    alone: dict[str, tuple[float, float]],
    ctx: tuple,
    gap0: float,
    ranked_on: _RankMemo | None = None,
) -> list[_Pair]:
    """Return the pairs of ``first`` with each other candidate that pass the drop-one and replay rules.

    ``alone``: each candidate's Delta BIC over the nominal model and its replay gap alone (inf when it
    does not replay); dropping either effect must lose more than the threshold and widen the replay gap.
    ``ctx``: (candidates, threshold,
    horizon, mask, resolution, push); ``gap0``: the nominal replay's gap, which the pair must shrink by MIN_SHRINK.
    ``ranked_on``: the candidates ranked on the fit of the effect the rounds named first (:func:`_rounds`),
    the same ranking as ``first``'s when ``first`` is that fit.
    """
    cands, threshold, horizon, mask, resolution, push = ctx
    a = first.trial
    out: list[_Pair] = []
    known = ranked_on is not None and ranked_on[0] is a.fit
    ranking = ranked_on[1] if known and ranked_on is not None else None
    for ranked in ranking if ranking is not None else _rank_candidates(sig, edges, a.fit, cands, [a.effect.name]):
        b_name = ranked.best.effect.name
        second, _ = _best_replaying_variant(ranked.trials, threshold, horizon)
        if second is None or _own_objection(second, resolution, push):
            continue
        dbic = float(a.dbic + second.trial.dbic)
        drop_first = dbic - alone.get(b_name, (-math.inf, math.inf))[0]
        gap = second.replay.gap(mask)  # dropping either effect must widen the replay
        wider = gap < min(first.replay.gap(mask), alone.get(b_name, (0.0, math.inf))[1])
        if drop_first > threshold and wider and gap <= (1.0 - MIN_SHRINK) * gap0:
            out.append(_Pair(first, second, dbic, (drop_first, float(second.trial.dbic))))
    return out


def _joint_pairs(
    sig: Signals,
    edges: np.ndarray,
    results: Sequence[_Ranked],
    ctx: tuple,
    rep0: Replay,
    ranked_on: _RankMemo | None = None,
) -> list[_Pair]:
    """Return every pair of candidates fitted jointly in which each is needed given the other, best first.

    Add-one/drop-one over pairs: one at a time, an effect whose force the nominal model absorbs
    (Coulomb friction into the viscous damping; a floor slope on a cart that hardly turns reads as a
    constant force, like a wrench bias) can lose to a stand-in or widen the replay on its own, and only
    the joint fit shows both. The first of each pair is a candidate significant over the nominal model.
    """
    threshold, horizon, mask, resolution, push = ctx[1:]
    alone: dict[str, tuple[float, float]] = {}
    singles: dict[str, _Named | None] = {}
    for r in results:
        if np.isfinite(r.best.dbic):
            singles[r.best.effect.name] = nm = _replayed(r.best, horizon)
            alone[r.best.effect.name] = (float(r.best.dbic), nm.replay.gap(mask) if nm else math.inf)
    pairs: list[_Pair] = []
    for ranked in results:
        if not ranked.best.dbic > threshold:
            continue
        first = singles.get(ranked.best.effect.name)
        if first is None or _own_objection(first, resolution, push):
            continue
        pairs += _pairs_from(sig, edges, first, alone, ctx, rep0.gap(mask), ranked_on)
    return sorted(pairs, key=lambda p: -p.dbic)


def _pair_reasons(
    pair: _Pair, pairs: Sequence[_Pair], greedy: tuple[Sequence[str], float], ctx: tuple, gap0: float
) -> list[str]:
    """Return why each effect of ``pair`` was named, with the pairs the log cannot tell from it (``gap0``: nominal)."""
    threshold = ctx[1]
    g_names, g_dbic = greedy
    one = ", ".join(g_names) if g_names else "no effect"
    close = [p for p in pairs if p.names != pair.names and pair.dbic - p.dbic <= threshold]
    alike = "; ".join(sorted({" + ".join(sorted(p.names)) + f" (Delta BIC {p.dbic:.1f})" for p in close}))
    out = []
    for i, nm in enumerate((pair.first, pair.second)):
        other = (pair.second if i == 0 else pair.first).trial.effect.name
        text = (
            f"fitted jointly with {other}: Delta BIC {pair.dbic:.1f} over the nominal model, against "
            f"{g_dbic:.1f} for {one} named one at a time; dropping it loses Delta BIC {pair.drops[i]:.1f}; "
            f"replay gap {_mm(gap0)} -> {_mm(pair.second.replay.gap(ctx[3]))} with both"
        )
        if alike:
            text += f"; indistinguishable on this log from {alike}"
        out.append(text)
    return out


def _rounds(
    sig: Signals,
    edges: np.ndarray,
    state: tuple[Fit, list[_Named], list[str], list[Replay]],
    cands: Sequence[Effect],
    settings: tuple[float, float, int],
    start: tuple[np.ndarray | None, Replay, float],
    verdicts: dict[str, Verdict],
    ranked_on: list[_RankMemo] | None = None,
) -> list[_Ranked]:
    """Name effects one at a time from ``state`` (updated in place) until none is named; return round 1's ranking.

    ``settings``: (threshold, horizon, max_effects); ``start``: (mask of flagged starts, nominal replay,
    lateral slip ratio); ``verdicts`` collects why the others were not named; ``ranked_on`` (when given)
    receives round 2's ranking on the first named effect's fit (:func:`_pairs_from` ranks the same).
    """
    threshold, horizon, max_effects = settings
    mask, _, slip_ratio = start
    current, named, reasons, reps = state
    first: list[_Ranked] = []
    resolution = float(np.median(np.diff(sig.t)))
    push = (float(np.sqrt(np.mean(sig.f_fwd**2))), float(np.sqrt(np.mean(sig.tau**2))))
    while len(named) < max_effects:
        round_ = len(named)
        names = [nm.trial.effect.name for nm in named]
        results = _rank_candidates(sig, edges, current, cands, names)
        if not results:
            break
        if ranked_on is not None and round_ == 1:
            ranked_on.append((current, results))
        first = first or results
        rnd = _choose_effect(results, threshold, horizon, mask, reps[-1], names, slip_ratio, resolution, push)
        for v in rnd.verdicts:  # the reasons of every round, the first round's Delta BIC
            old = verdicts.get(v.name)
            if old is None:
                verdicts[v.name] = Verdict(v.name, v.delta_bic, f"round {round_ + 1}: {v.reason}")
            elif not old.reason.endswith(v.reason):
                verdicts[v.name] = Verdict(v.name, old.delta_bic, f"{old.reason}; round {round_ + 1}: {v.reason}")
        if rnd.chosen is None:
            break
        named.append(rnd.chosen)
        reasons.append(rnd.reason)
        verdicts.pop(rnd.chosen.trial.effect.name, None)
        reps.append(rnd.chosen.replay)
        current = rnd.chosen.trial.fit
        state = (current, named, reasons, reps)
    return first


def _replaced(
    named: Sequence[_Named],
    p_named: Sequence[_Named],
    scores: tuple[float, float, float],
    gaps: tuple[float, float],
    objections: dict[str, str],
) -> dict[str, Verdict]:
    """Return the verdicts of the effects named one at a time that the pair's search (``p_named``) replaces.

    ``scores``: (the pair search's Delta BIC, the one-at-a-time search's, threshold); ``gaps``: their replay
    gaps; ``objections``: why each effect's size in the one-at-a-time fit rules it out ('' when it does not).
    """
    p_dbic, g_dbic, threshold = scores
    p_set = {nm.trial.effect.name for nm in p_named}
    p_names = " + ".join(nm.trial.effect.name for nm in p_named)
    out: dict[str, Verdict] = {}
    for nm in named:
        name = nm.trial.effect.name
        if name in p_set:
            continue
        why = "explain the log better" if p_dbic > g_dbic + threshold else "explain it about as well without it"
        if objections.get(name) and p_dbic <= g_dbic - threshold:
            why = f"explain it without it, and given the others {objections[name]}"
        out[name] = Verdict(
            name,
            float(nm.trial.dbic),
            f"named one at a time, but {p_names} {why} (Delta BIC {p_dbic:.1f} against "
            f"{g_dbic:.1f}; replay gap {_mm(gaps[0])} against {_mm(gaps[1])})",
        )
    return out


def _search(
    sig: Signals,
    edges: np.ndarray,
    nominal: Fit,
    cands: Sequence[Effect],
    settings: tuple[float, float, int],
    start: tuple[np.ndarray | None, Replay, float],
) -> tuple[Fit, list[_Named], list[str], list[Replay], list[tuple[str, float]], dict[str, Verdict]]:
    """Return the search's outcome: final fit, named effects, their reasons, replays, first-round scores, verdicts.

    ``settings``: (threshold, horizon, max_effects); ``start``: (mask of flagged starts, nominal replay,
    lateral slip ratio). Effects are named one at a time (:func:`_rounds`); then every pair fitted
    jointly (:func:`_joint_pairs`, each effect needed given the other) is compared with them: the best
    pair, with the rounds that go on from it, replaces them when its Delta BIC beats theirs by the
    threshold and its replay gap is at most MIN_SHRINK wider.
    """
    threshold, horizon, max_effects = settings
    mask, rep0, slip_ratio = start
    verdicts: dict[str, Verdict] = {}
    named: list[_Named] = []
    reasons: list[str] = []
    reps = [rep0]  # the nominal replay and one after each named effect
    ranked_on: list[_RankMemo] = []
    results = _rounds(sig, edges, (nominal, named, reasons, reps), cands, settings, start, verdicts, ranked_on)
    first_scores = [(r.best.effect.name, float(r.best.dbic)) for r in results]
    current = named[-1].trial.fit if named else nominal
    slip_first = bool(named) and named[0].trial.effect.name == "lateral_slip" and slip_ratio > SLIP_RATIO
    if max_effects < 2 or slip_first or not results:
        return current, named, reasons, reps, first_scores, verdicts
    resolution = float(np.median(np.diff(sig.t)))
    push = (float(np.sqrt(np.mean(sig.f_fwd**2))), float(np.sqrt(np.mean(sig.tau**2))))
    ctx = (cands, threshold, horizon, mask, resolution, push)
    pairs = _joint_pairs(sig, edges, results, ctx, rep0, ranked_on[0] if ranked_on else None)
    g_names = [nm.trial.effect.name for nm in named]
    g_dbic = float(sum(nm.trial.dbic for nm in named))
    if not pairs or pairs[0].names == set(g_names):
        return current, named, reasons, reps, first_scores, verdicts
    best = pairs[0]
    joint = best.second.trial.fit  # the first effect reported from the joint fit, its evidence what dropping it costs
    first = _Named(replace(best.first.trial, fit=joint, dbic=best.drops[0]), best.first.replay, len(joint.effects) - 2)
    p_named, p_reps = [first, best.second], [rep0, best.first.replay, best.second.replay]
    p_reasons = _pair_reasons(best, pairs, (g_names, g_dbic), ctx, rep0.gap(mask))
    p_verdicts = {k: v for k, v in verdicts.items() if k not in best.names}
    _rounds(sig, edges, (joint, p_named, p_reasons, p_reps), cands, settings, start, p_verdicts)
    p_dbic = best.dbic + sum(float(nm.trial.dbic) for nm in p_named[2:])
    p_set = {nm.trial.effect.name for nm in p_named}
    # the pair's effects are some of those named one at a time, which add less than the threshold to them or
    # shrink, given the others, to a size the search never names (a sensor's offset, the logging's timing)
    why = {nm.trial.effect.name: _own_objection(nm, resolution, push, current) for nm in named}
    fewer = p_set < set(g_names) and (p_dbic > g_dbic - threshold or all(why[n] for n in set(g_names) - p_set))
    if not (p_dbic > g_dbic + threshold or fewer) or p_reps[-1].gap(mask) > (1.0 + MIN_SHRINK) * reps[-1].gap(mask):
        return current, named, reasons, reps, first_scores, verdicts
    gaps = (p_reps[-1].gap(mask), reps[-1].gap(mask))
    p_verdicts.update(_replaced(named, p_named, (p_dbic, g_dbic, threshold), gaps, why))
    return p_named[-1].trial.fit, p_named, p_reasons, p_reps, first_scores, p_verdicts


def _replay_mask(
    rep0: Replay, horizon: float, wrench_holes: Sequence[tuple[float, float]]
) -> tuple[np.ndarray, np.ndarray | None]:
    """Return (flagged starts, the starts the gaps are measured over: None for all) of the nominal replay ``rep0``.

    A replay whose horizon reaches one of ``wrench_holes`` is driven by a filled wrench (across a clipped peak,
    the clip level): its error is the fill's, not the cart's, and it is neither flagged nor counted in the gaps,
    nor counted in the Benjamini-Hochberg ranking of the others (its near-zero p-values flagged windows 10 s
    away from an outside tester's stuck stretch).
    """
    spans = np.asarray(wrench_holes, float).reshape(-1, 2)
    spans = spans[np.argsort(spans[:, 0])]
    reach = np.r_[-np.inf, np.maximum.accumulate(spans[:, 1])]  # latest end among the spans that begin by then
    clear = reach[np.searchsorted(spans[:, 0], rep0.starts + horizon, side="right")] < rep0.starts
    # the false-discovery rate over the clear replays only: the fill's many tiny p-values would relax the threshold
    flagged = np.zeros(len(clear), bool)
    if np.any(clear):
        flagged[clear] = flag_starts(replace(rep0, chi2=rep0.chi2[clear]))
    if np.any(flagged):
        return flagged, flagged
    return flagged, None if np.all(clear) else clear


def diagnose(
    log: CartLog,
    candidates: Sequence[Effect] | None = None,
    threshold: float = 10.0,
    max_effects: int = 3,
    horizon: float | None = None,
    window: float | None = None,
) -> DiagnosisReport:
    """Return the DiagnosisReport of ``log``: nominal fit, discrepancy windows, named effects, gap before/after.

    ``candidates`` defaults to every registered effect; an effect is named when
    its Delta BIC exceeds ``threshold`` (10 = "very strong" evidence), its replay
    shrinks the gap and its fit is physical; every named effect carries its
    ``reason``, every other candidate a :class:`Verdict` (``report.not_named``).
    The log is first prepared (:func:`cart.diagnose_prep.prepare_log`: sensor streams, size, time origin).
    """
    prep = prepare_log(log)
    sig, horizon, edges = _checked_signals(prep.log, horizon, window, prep.wrench_holes)
    cands = list(candidates) if candidates is not None else registered_effects()
    nominal, warnings = _nominal_fit(sig, edges, log.source)
    sig.extras[NOISE_KEY] = fit_wrench_noise(sig)
    rep0 = replay(sig, nominal.x, horizon=horizon)
    flagged, mask = _replay_mask(rep0, horizon, prep.wrench_holes)
    slip_ratio = lateral_slip_ratio(sig, sig.extras["base"][2][:, 2], edges, sig.extras.get(KEEP_KEY))
    current, named, reasons, reps, first_scores, verdicts = _search(
        sig, edges, nominal, cands, (threshold, horizon, max_effects), (mask, rep0, slip_ratio)
    )
    frame_note, withdraw = _frame_check(sig, edges, current, threshold)
    warnings += [frame_note] if frame_note else []
    if withdraw:
        current, named, reasons, reps = nominal, [], [], [rep0]
    lateral = verdicts.get("lateral_slip")
    lateral_dbic = lateral.delta_bic if lateral is not None else None
    slip_note = unexplained_slip(slip_ratio, [n.trial.effect.name for n in named], lateral_dbic)
    warnings += [slip_note] if slip_note else []
    final = _replayed(named[-1].trial, horizon, paths=True) if named else None
    reps = reps[:-1] + [final.replay] if final is not None else reps  # the same replay with its paths
    return DiagnosisReport(
        effects=tuple(_named_effects(named, reasons, reps, flagged, horizon, prep.time_offset)),
        gap_before=rep0.gap(mask),
        gap_after=reps[-1].gap(mask),
        gap_metric=GAP_METRIC,
        windows=tuple(_discrepancy_windows(sig, rep0, flagged, horizon, prep.time_offset)),
        nominal=_physical(nominal.x, nominal.cov),
        final_model=_physical(current.x, current.cov),
        candidates=tuple(first_scores),
        threshold=float(threshold),
        source=log.source,
        rms_before=rep0.rms_error(mask),
        rms_after=reps[-1].rms_error(mask),
        noise_floor=rep0.noise_floor(mask),
        replay_before=rep0,
        replay_after=reps[-1],
        flagged=flagged,
        not_named=tuple(sorted(verdicts.values(), key=lambda v: -v.delta_bic if math.isfinite(v.delta_bic) else 1e300)),
        warnings=tuple(list(prep.notes) + warnings),
        time_offset=prep.time_offset,
        lateral_slip_ratio=slip_ratio,
    )

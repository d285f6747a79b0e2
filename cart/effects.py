"""Candidate physical effects the nominal cart model lacks, each fittable from a log (diagnose workflow).

The nominal model (paper eq. 4, projected on the two allowed directions) is,
per sample, with forward speed v, yaw rate omega, x = [m, m dx, m dy, J, sigma]:

    f_fwd = m vdot - (m dx) omega^2 - (m dy) omegadot + sigma v          (forward row)
    tau   = J omegadot - (m dy) vdot + (m dx) omega v + sigma omega      (yaw row)
    w_lat = 0                                                            (no lateral slip, eq. 3)

An :class:`Effect` adds ``columns`` G (N, 3, k) to these rows so that
``[f_fwd, tau, w_lat] = A x + G theta`` with ``theta`` its ``k`` linear
parameters; a physical generalized force E on the cart enters as ``G theta = -E``.
Parameters that enter nonlinearly (a distance, a time, a delay) are searched
on ``nl_grid`` and refined by a 1-D search. An effect may instead change the
data (``transform``, e.g. a time shift of the wrench).

To add an effect, subclass :class:`Effect`, set ``name`` and ``param_names``,
implement ``columns`` (and optionally ``nl_names``/``nl_grid``/``transform``/
``describe``), and call :func:`register_effect`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from cart.caster_lanes import CasterLanes, caster_lanes
from cart.dynamics import regressor
from cart.log_signals import Signals, cache_bounded, derivative_gain, local_poly, window_integrals
from cart.noise_model import fit_ar1

#: Nominal parameters x = [m, m dx, m dy, J, sigma, sigma_yaw] (two viscous coefficients).
N_NOMINAL = 6

GRAVITY = 9.81

#: Effect names of the project contract (docs/architecture.md), in the order they are tried.
CONTRACT_NAMES = (
    "coulomb_friction",
    "caster_swivel",
    "wrench_bias",
    "payload_change",
    "floor_slope",
    "time_delay",
    "lateral_slip",
)


def nominal_columns(sig: Signals) -> np.ndarray:
    """Return the nominal design A (N, 3, 6) for x = [m, m dx, m dy, J, sigma, sigma_yaw] (paper eq. 4, body rows).

    The forward and yaw rows are :func:`cart.dynamics.regressor`; the lateral row is empty.
    """
    n = sig.n
    a = np.zeros((n, 3, N_NOMINAL))
    a[:, :2, :] = regressor(sig.v, sig.omega, sig.vdot, sig.omegadot)
    return a


def nominal_loadings(n_win: int) -> tuple[np.ndarray, np.ndarray]:
    """Return (Lv, Lw) (n_win, 3, 6): how the noise of the window velocity changes enters the nominal columns.

    The forward row's m column is the change of v, its m dy column minus the
    change of omega; the yaw row's m dy column is minus the change of v and its
    J column the change of omega.
    """
    lv = np.zeros((n_win, 3, N_NOMINAL))
    lw = np.zeros((n_win, 3, N_NOMINAL))
    lv[:, 0, 0] = 1.0
    lw[:, 0, 2] = -1.0
    lv[:, 1, 2] = -1.0
    lw[:, 1, 3] = 1.0
    return lv, lw


def measured_rows(sig: Signals) -> np.ndarray:
    """Return the measured left-hand sides (N, 3): forward force, yaw torque, lateral speed of {b}."""
    return np.column_stack([sig.f_fwd, sig.tau, sig.w_lat])


def speed_scales(sig: Signals) -> tuple[float, float]:
    """Return (v0, omega0): the speeds below which friction signs are smoothed (tanh), above the noise.

    2 cm/s and 0.03 rad/s for a cart, scaled down for slow motions (5 % of the peak speed), never below
    twice the speed noise.
    """
    v_peak = float(np.max(np.abs(sig.v))) if sig.n else 0.0
    om_peak = float(np.max(np.abs(sig.omega))) if sig.n else 0.0
    return (max(min(0.02, 0.05 * v_peak), 2.0 * sig.sigma_v), max(min(0.03, 0.05 * om_peak), 2.0 * sig.sigma_omega))


def stop_threshold(sig: Signals) -> float:
    """Return the forward speed (m/s) below which the cart counts as (nearly) at rest: 3 x its noise, >= 3 cm/s."""
    return max(0.03, 3.0 * sig.sigma_v)


def forward_residual(sig: Signals, phi: np.ndarray, base: np.ndarray) -> np.ndarray:
    """Return r (N,): the forward force the nominal model (phi, its rows ``base``) leaves unexplained."""
    return sig.f_fwd - base[:, 0, :4] @ np.asarray(phi[:4], float)


def static_hold(sig: Signals, r: np.ndarray, cap) -> np.ndarray | None:
    """Return the set-valued hold (N, 3): clip(r, -cap, cap) in the forward row at rest, 0 moving (None: never at rest)."""
    rest = np.abs(sig.v) < stop_threshold(sig)
    if not np.any(rest):
        return None
    out = np.zeros((sig.n, 3))
    out[:, 0] = np.where(rest, np.clip(r, -cap, cap), 0.0)
    return out


#: a forward force at rest counts as a hold only beyond this many stds of the sensor noise's local mean
HOLD_NOISE_Z = 2.0


def mean_noise_std(sig: Signals, r: np.ndarray, half_window: float) -> float:
    """Return the std the forward force's noise gives its mean over +-``half_window`` s (cached per signals).

    The noise is the log's own: the AR(1) model (:func:`cart.noise_model.fit_ar1`) of the unexplained forward
    force ``r`` while the cart moves (at rest ``r`` may hold a real force). A coloured F/T noise keeps its power
    at low frequencies: its local mean over n samples has variance sigma^2 / n^2 sum_(i, j) a^|i - j|, far
    above the white-noise sigma^2 / n.
    """
    key = ("hold_noise", float(half_window))
    cached = sig.extras.get(key)
    if cached is not None:
        return float(cached)
    dt = float(np.median(np.diff(sig.t))) if sig.n > 1 else 1.0
    moving = np.abs(sig.v) >= stop_threshold(sig)
    src = r[moving] if np.sum(moving) > 100 else r
    model = fit_ar1(src - np.median(src), dt)
    n = max(1, int(round(2.0 * half_window / dt)) + 1)
    k = np.arange(1, n)
    var = model.sigma**2 / n**2 * (n + 2.0 * float(np.sum((n - k) * model.a**k)))
    sig.extras[key] = math.sqrt(max(var, 0.0))
    return float(sig.extras[key])


def local_bounds(t: np.ndarray, half_window: float) -> tuple[np.ndarray, np.ndarray]:
    """Return (lo, hi): the samples [lo, hi) within +-``half_window`` s of each sample (irregular times)."""
    return np.searchsorted(t, t - half_window, side="left"), np.searchsorted(t, t + half_window, side="right")


def local_mean(
    t: np.ndarray, y: np.ndarray, half_window: float, bounds: tuple[np.ndarray, np.ndarray] | None = None
) -> np.ndarray:
    """Return the mean of y (N, ...) over the samples within +-``half_window`` s of each sample (irregular times).

    ``bounds``: :func:`local_bounds` of ``t`` and ``half_window`` when the caller keeps them.
    """
    y = np.asarray(y, float)
    cum = np.concatenate([np.zeros((1,) + y.shape[1:]), np.cumsum(y, axis=0)], axis=0)
    lo, hi = bounds if bounds is not None else local_bounds(t, half_window)
    cnt = np.maximum(hi - lo, 1).reshape((-1,) + (1,) * (y.ndim - 1))
    return (cum[hi] - cum[lo]) / cnt


#: holds (smoothed) above this fraction of the breakaway force count as at the limit (see :func:`hold_column`)
HOLD_LIMIT = 0.8
#: half window (s) of the smoothed unexplained force that decides a hold
HOLD_SMOOTH = 0.1


def held_forces(sig: Signals, phi: np.ndarray, base: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Return (r, r smoothed over +-HOLD_SMOOTH s, the least smoothed force that is a hold).

    r: the forward force the nominal model leaves unexplained. A smoothed force within HOLD_NOISE_Z stds
    of what the sensor's (coloured) noise gives it (:func:`mean_noise_std`) is no evidence of a hold: a
    friction is not credited with the noise of a cart at rest.
    """
    r = forward_residual(sig, phi, base)
    key = ("motion", "local_bounds", HOLD_SMOOTH)
    bounds = sig.extras.get(key)
    if bounds is None:
        bounds = sig.extras[key] = local_bounds(sig.t, HOLD_SMOOTH)
    return r, local_mean(sig.t, r, HOLD_SMOOTH, bounds), HOLD_NOISE_Z * mean_noise_std(sig, r, HOLD_SMOOTH)


def hold_column(
    sig: Signals, moving_col: np.ndarray, cap: np.ndarray, phi: np.ndarray | None, base: np.ndarray | None, f_ref: float
) -> np.ndarray:
    """Return the forward column of a friction that holds the cart at rest up to F ``cap`` (N,) (active set).

    ``moving_col``: the column while the cart moves (0 at rest). At rest the force is set-valued
    (:func:`hold_offset` holds the cart up to F cap); where the unexplained force r (smoothed) exceeds
    HOLD_LIMIT times the current estimate ``f_ref`` of the breakaway force F cap (and the noise), the
    hold is at its limit, E_fwd = -F cap sign(r), which is linear in F: so the holds inform F, and the
    largest holds keep pinning F when no motion does.
    """
    rest = (np.abs(sig.v) < stop_threshold(sig)) & (cap > 1e-6)
    if phi is None or base is None or not np.any(rest):
        return moving_col
    _, rs, least = held_forces(sig, phi, base)
    over = rest & (np.abs(rs) > np.maximum(HOLD_LIMIT * f_ref * cap, least))
    return np.where(over, np.sign(rs) * cap, moving_col)


def hold_offset(
    sig: Signals, cap: np.ndarray, phi: np.ndarray | None, base: np.ndarray, f_ref: float
) -> np.ndarray | None:
    """Return the hold at rest (N, 3): r where |r| (smoothed) is within HOLD_LIMIT f_ref ``cap`` and beyond the noise.

    The set-valued part of a friction that holds the cart up to its breakaway force f_ref cap (N,): the
    forward force the nominal model leaves unexplained (r) is the hold; None when nothing is held.
    """
    if f_ref <= 0.0 or phi is None:
        return None
    rest = np.abs(sig.v) < stop_threshold(sig)
    cap = f_ref * cap
    if not np.any(rest & (cap > 0)):
        return None
    r, rs, least = held_forces(sig, phi, base)
    out = np.zeros((sig.n, 3))
    held = rest & (cap > 0) & (np.abs(rs) <= HOLD_LIMIT * cap) & (np.abs(rs) > least)
    out[:, 0] = np.where(held, r, 0.0)
    return out


def forward_displacement(sig: Signals) -> np.ndarray:
    """Return X(t) = integral of the forward speed v dt (m): signed travel along the body x axis."""
    cached = sig.extras.get(("motion", "x_fwd"))
    if cached is None:
        v, t = sig.v, sig.t
        cached = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
        sig.extras[("motion", "x_fwd")] = cached
    return cached


def travel_direction(sig: Signals, min_rest: float = 0.3) -> np.ndarray:
    """Return the direction the cart moves or is pushed to move, per sample: +1, -1 or 0 (undecided).

    Moving (|v| above :func:`stop_threshold`): sign(v). At rest for at least
    ``min_rest`` s: the sign of the mean forward force over the rest when it is
    significant (3 standard errors and 2 N) -- a cart held still against a
    push (stiction, a caster that has not swung round yet) is trying to move
    that way; a cart at rest without a push is undecided (0). Shorter rests: 0.
    """
    v, t = sig.v, sig.t
    v_th = stop_threshold(sig)
    out = np.where(v > v_th, 1, np.where(v < -v_th, -1, 0)).astype(int)
    rest = out == 0
    if not np.any(rest):
        return out
    edges = np.flatnonzero(np.diff(np.concatenate([[0], rest.astype(int), [0]])))
    for i0, i1 in zip(edges[::2], edges[1::2]):  # rest runs [i0, i1)
        if t[i1 - 1] - t[i0] < min_rest:
            continue
        f = sig.f_fwd[i0:i1]
        mean = float(np.mean(f))
        se = sig.sigma_force / math.sqrt(max(i1 - i0, 1))
        if abs(mean) > max(3.0 * se, 2.0):
            out[i0:i1] = 1 if mean > 0 else -1
    return out


def distance_since_reversal(sig: Signals) -> np.ndarray:
    """Return the distance (m) travelled since the travel direction last reversed (inf before the first).

    Directions come from :func:`travel_direction` (a push against a cart held
    at rest counts as an attempted move). A reversal from direction a to b
    starts at the extreme forward displacement X reached in direction a before
    b began (the zero crossing of v for a plain reversal, the stop for a held
    cart); the distance is then b (X - X_origin), clipped at 0. Signed
    displacement rather than path length: noise and creeping back and forth
    do not add up.
    """
    cached = sig.extras.get("dist_rev")
    if cached is not None:
        return cached
    x = forward_displacement(sig)
    d = travel_direction(sig)
    n = sig.n
    out = np.full(n, np.inf)
    nz = np.flatnonzero(d != 0)
    if len(nz) > 1:
        changes = nz[1:][d[nz[1:]] != d[nz[:-1]]]  # first sample of each new direction
        prev_last = nz[:-1][d[nz[1:]] != d[nz[:-1]]]  # last sample of the old direction
        for ia, ib in zip(prev_last, changes):
            a, b = d[ia], d[ib]
            seg = slice(ia, ib + 1)
            origin = ia + int(np.argmax(a * x[seg]))
            # from the origin to the next reversal's origin (overwritten by the next reversal)
            out[origin:n] = np.maximum(b * (x[origin:n] - x[origin]), 0.0)
    sig.extras["dist_rev"] = out
    return out


class Effect:
    """A candidate effect: name, linear parameters, optional nonlinear parameters searched on a grid."""

    name: str = "effect"
    param_names: tuple[str, ...] = ()
    nl_names: tuple[str, ...] = ()
    #: True when the columns use the current estimate of phi (refit iterates).
    uses_phi: bool = False
    #: True when the effect adds a set-valued (parameter-free given the previous estimate) term, see :meth:`offset`.
    set_valued: bool = False
    #: False: the nonlinear parameter is only searched on its grid (no continuous refinement).
    refine: bool = True
    #: True: the nonlinear parameter is searched (and its std computed) on a log scale.
    log_scale: bool = False
    #: True: the effect's force is S(theta) phi(t), bilinear in its parameters and phi (:meth:`phi_force`)
    bilinear: bool = False
    #: True: the effect steps phi over time (:meth:`replay_phi_change`); its columns are the phi columns ``base``
    steps_phi: bool = False

    def nl_grid(self, sig: Signals) -> list[tuple[float, ...]]:
        """Return the grid of nonlinear-parameter tuples to search (one empty tuple when there are none)."""
        return [()]

    def nl_bounds(self, sig: Signals) -> list[tuple[float, float]]:
        """Return (low, high) bounds of each nonlinear parameter for the refinement search."""
        return []

    def transform(self, sig: Signals, nl: tuple[float, ...]) -> Signals:
        """Return the signals corrected for this effect (default: unchanged)."""
        return sig

    def columns(self, sig: Signals, nl: tuple[float, ...], phi: np.ndarray | None, base: np.ndarray) -> np.ndarray:
        """Return G (N, 3, len(param_names)): rows (forward force, yaw torque, lateral speed) per unit parameter."""
        return np.zeros((sig.n, 3, 0))

    def window_columns(
        self, sig: Signals, nl: tuple[float, ...], phi: np.ndarray | None, base: np.ndarray, edges: np.ndarray
    ) -> np.ndarray:
        """Return the window integrals (windows, 3, k) of :meth:`columns` over the windows cut at ``edges``.

        The fits use these; an effect whose columns are cheaper to integrate another way overrides it.
        """
        return window_integrals(sig.t, self.columns(sig, nl, phi, base), edges)

    def offset(
        self, sig: Signals, nl: tuple[float, ...], phi: np.ndarray | None, base: np.ndarray, theta: np.ndarray | None
    ) -> np.ndarray | None:
        """Return a term (N, 3) added to the rows besides ``G theta`` (a set-valued force), or None (default).

        Called with the previous estimate of phi and of this effect's
        ``theta`` (None on the first pass); the fit iterates to a fixed point
        (``set_valued = True``). Like ``G theta``, it is minus the generalized force.
        """
        return None

    def column_key(self, sig: Signals, nl: tuple[float, ...]) -> tuple | None:
        """Return a hashable key that fixes :meth:`columns` for these signals (fits cache them), or None (no cache).

        Default: the class, its attributes and ``nl`` -- valid unless the
        columns use phi (``uses_phi``) or other state.
        """
        if self.uses_phi:
            return None
        return (type(self).__name__, tuple(sorted(vars(self).items())), tuple(float(u) for u in nl))

    def noise_loadings(
        self, sig: Signals, nl: tuple[float, ...], edges: np.ndarray, lv: np.ndarray, lw: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """Return the window noise loadings (like :func:`nominal_loadings`) of the columns, or None (noise-free)."""
        return None

    def phi_force(self, sig: Signals, theta: np.ndarray) -> np.ndarray | None:
        """Return S (N, 3, 4) with the effect's rows = S(theta) phi(t) (``bilinear`` effects), or None.

        The same rows as :meth:`columns` with phi per sample (``columns(sig, nl, phi_t, base) @ theta``):
        the fits linearise the product of the effect's parameters and phi (a Gauss-Newton step).
        """
        return None

    def is_physical(self, theta: np.ndarray, nl: tuple[float, ...], x: np.ndarray) -> bool:
        """Return False when the fitted parameters are physically impossible (the fit is then rejected)."""
        return True

    def replay_phi_change(
        self, sig: Signals, nl: tuple[float, ...], theta: np.ndarray, phi: np.ndarray | None = None
    ) -> np.ndarray | None:
        """Return the change of phi (N, 4) over time the replay must apply, or None (default)."""
        return None

    def variants(self) -> list[Effect]:
        """Return the parameterisations of this effect to try (default: itself); the best Delta BIC is kept.

        An effect may offer a reduced (nested) form with fewer parameters: it
        has more power when the data cannot resolve the full one.
        """
        return [self]

    def describe(
        self, theta: np.ndarray, nl: tuple[float, ...], cov: np.ndarray, nl_std: Sequence[float], phi: np.ndarray
    ) -> tuple[dict[str, float], dict[str, float]]:
        """Return (parameters, standard deviations) as plain dicts for the report."""
        params = {k: float(v) for k, v in zip(self.param_names, theta)}
        std = {k: float(math.sqrt(max(cov[i, i], 0.0))) for i, k in enumerate(self.param_names)}
        for k, v, s in zip(self.nl_names, nl, nl_std):
            params[k] = float(v)
            std[k] = float(s)
        return params, std

    @property
    def n_params(self) -> int:
        """Return the number of fitted parameters (linear + nonlinear)."""
        return len(self.param_names) + len(self.nl_names)


class CoulombFriction(Effect):
    """Constant-magnitude friction opposing the forward speed (force) and the yaw rate (torque).

    Moving: E_fwd = -F tanh(v / v0), E_yaw = -T tanh(omega / omega0). At rest
    (|v| below :func:`stop_threshold`) the forward friction is static: it holds
    the cart against any push up to F (:meth:`offset`), and a push at the limit
    informs F (:meth:`columns`) -- the hold of ``caster_swivel``'s profile form
    with a profile of 1 (friction that does not fade after a reversal), so that
    the two are compared on the same footing.
    """

    name = "coulomb_friction"
    param_names = ("force", "torque")
    set_valued = True
    #: key of the current force estimate in ``sig.extras`` (set by :meth:`offset`, read by :meth:`columns`)
    REF_KEY = ("coulomb_force_ref",)

    def column_key(self, sig, nl):
        """Return None: the columns at rest depend on phi and on the current force estimate (no caching)."""
        return None

    def columns(self, sig, nl, phi, base):
        """Return G: tanh(v/v0) in the forward row while moving, sign(r) at a hold at its limit; tanh(omega/w0) in yaw."""
        v0, w0 = speed_scales(sig)
        moving = np.abs(sig.v) >= stop_threshold(sig)
        g = np.zeros((sig.n, 3, 2))
        f_ref = float(sig.extras.get(self.REF_KEY, 0.0))
        g[:, 0, 0] = hold_column(sig, np.where(moving, np.tanh(sig.v / v0), 0.0), np.ones(sig.n), phi, base, f_ref)
        g[:, 1, 1] = np.tanh(sig.omega / w0)
        return g

    def offset(self, sig, nl, phi, base, theta):
        """Return the static friction at rest: r where the smoothed r is within the hold (r: nominal residual)."""
        f_ref = 0.0 if theta is None or len(theta) == 0 else max(float(theta[0]), 0.0)
        sig.extras[self.REF_KEY] = f_ref
        return hold_offset(sig, np.ones(sig.n), phi, base, f_ref)


class CasterSwivel(Effect):
    """After the travel direction reverses, the casters swing round: a resisting force that can hold the cart.

    While the cart moves (|v| above :func:`stop_threshold`):
    E_fwd = -F tanh(v / v0) g(s / d); s = distance since the last reversal
    (:func:`distance_since_reversal`), shape g(u) = exp(-u^p): p = 1 an
    exponential decay, p = 2, 4 increasingly compact (raised-cosine-like, then
    step-like) resistance over a finite distance. p is chosen on the grid
    {1, 2, 4} through :meth:`variants` and counted as a parameter.

    At rest (stick): the casters hold the cart against any push up to the
    breakaway force F g(s) -- the set-valued force
    E_fwd = -clip(r, -F g(s), F g(s)), r = the forward force the nominal model
    leaves unexplained (:meth:`offset`). A cart that stays put after a
    push-to-pull reversal until the pull exceeds the breakaway force is thus
    explained, and the replay holds it too.
    """

    name = "caster_swivel"
    param_names: tuple[str, ...] = ("force",)
    nl_names = ("distance",)
    set_valued = True
    log_scale = True
    #: shape exponent p of g(u) = exp(-u^p)
    shape: float = 1.0
    SHAPES: tuple[float, ...] = (1.0, 2.0, 4.0)

    def __init__(self, shape: float = 1.0) -> None:
        self.shape = float(shape)

    def variants(self):
        """Return one variant per shape exponent p in {1, 2, 4}, and the swivelling-caster model per axle position."""
        return (
            [self]
            + [CasterSwivel(p) for p in self.SHAPES if p != self.shape]
            + [SwivelCasterModel(x) for x in SwivelCasterModel.AXLES]
        )

    @property
    def n_params(self) -> int:
        """Return 3: force, distance and the grid-chosen shape exponent."""
        return 3

    def is_physical(self, theta, nl, x):
        """Return True when the casters resist (a positive breakaway force): a negative one would push the cart."""
        return bool(np.isfinite(float(theta[0])) and float(theta[0]) > 0.0)

    def nl_grid(self, sig):
        """Return decay distances from 2 cm to 1.5 m (log-spaced)."""
        return [(d,) for d in np.geomspace(0.02, 1.5, 12)]

    def nl_bounds(self, sig):
        """Return the distance bounds in metres."""
        return [(0.01, 3.0)]

    def profile(self, sig: Signals, nl: tuple[float, ...]) -> np.ndarray:
        """Return g(s / d) per sample (0 before the first reversal)."""
        s = distance_since_reversal(sig)
        with np.errstate(over="ignore", invalid="ignore"):
            shape = np.exp(-np.power(s / nl[0], self.shape))
        return np.where(np.isfinite(s), shape, 0.0)

    def column_key(self, sig, nl):
        """Return None: the columns at rest depend on phi and on the current force estimate (no caching)."""
        return None

    def columns(self, sig, nl, phi, base):
        """Return G: tanh(v / v0) g(s / d) while moving; at rest, g sign(r) where the hold is at its limit.

        At rest the force is set-valued (:meth:`offset` holds the cart up to F g); the holds at the limit
        are linear in F (:func:`hold_column`), so the holds inform F.
        """
        v0, _ = speed_scales(sig)
        moving = np.abs(sig.v) >= stop_threshold(sig)
        prof = self.profile(sig, nl)
        g = np.zeros((sig.n, 3, 1))
        f_ref = float(sig.extras.get(("caster_force_ref", self.shape, float(nl[0])), 0.0))
        g[:, 0, 0] = hold_column(sig, np.where(moving, np.tanh(sig.v / v0) * prof, 0.0), prof, phi, base, f_ref)
        return g

    def offset(self, sig, nl, phi, base, theta):
        """Return the hold at rest: r where |r| (smoothed) is within the breakaway force F g(s) (r: nominal residual)."""
        f_ref = 0.0 if theta is None or len(theta) == 0 else max(float(theta[0]), 0.0)
        sig.extras[("caster_force_ref", self.shape, float(nl[0]))] = f_ref
        return hold_offset(sig, self.profile(sig, nl), phi, base, f_ref)

    def describe(self, theta, nl, cov, nl_std, phi):
        """Return force (N), distance d (m) and the shape exponent p (grid-chosen: std reported as 0)."""
        params, std = Effect.describe(self, theta, nl, cov, nl_std, phi)
        params["shape"] = float(self.shape)
        std["shape"] = 0.0
        return params, std


CASTER_HALF_TRACK = 0.25  # m: lateral offset of the two modelled casters (their exact value matters little)
#: swing modes of a caster that reaches its leading (unstable) equilibrium: (side, least misalignment);
#: side 0 = natural (from the motion), +-1 = forced to that side, misalignment = how far from leading it starts
SWING_MODES: tuple[tuple[int, float], ...] = ((0, 1e-5),) + tuple(
    (side, d) for d in (0.1, 0.01, 1e-3, 1e-4, 1e-5) for side in (1, -1)
)


#: bytes of caster swing unit rows kept (:meth:`SwivelCasterModel._units`, oldest dropped first)
UNIT_CACHE_BYTES = 64 * 2**20


def touched_windows(edges: np.ndarray, ranges: Sequence[tuple[int, int]]) -> list[tuple[int, int]]:
    """Return the runs [ka, kb] of consecutive windows whose samples [e_k, e_k+1] meet a sample range [i0, i1)."""
    e = np.asarray(edges)
    hit = np.zeros(max(len(e) - 1, 0), bool)
    for i0, i1 in ranges:
        ka = int(np.searchsorted(e[1:], i0, side="left"))  # first window that ends at or after i0
        kb = int(np.searchsorted(e[:-1], i1 - 1, side="right")) - 1  # last window that starts at or before i1 - 1
        hit[ka : kb + 1] = True
    on = np.flatnonzero(np.diff(np.concatenate([[0], hit.astype(np.int8), [0]])))
    return [(int(a), int(b) - 1) for a, b in zip(on[::2], on[1::2])]


#: stacked swing terms of a caster model: (swing ranges, Q, P, R, c0, b, S, n_ind), see `_swing_arrays`
_SwingArrays = tuple[
    tuple[tuple[int, int], ...], np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray
]
#: half window (s) of the local quadratic that gives the yaw rate driving the caster kinematics
CASTER_OMEGA_WINDOW = 0.25


def kinematic_yaw_rate(sig: Signals) -> np.ndarray:
    """Return the yaw rate for the caster kinematics: the heading differentiated over +-CASTER_OMEGA_WINDOW s.

    The casters amplify yaw-rate noise by (axle x) / trail ~ 20 in their swivel
    rate, so a smoother yaw rate than the fit's (+-0.15 s) pays off (turns last
    seconds, so the longer window costs little), and it is soft-thresholded at
    twice its noise std (a cart at rest does not rock its casters). Cached.
    """
    key = ("motion", "kin_omega", CASTER_OMEGA_WINDOW)
    cached = sig.extras.get(key)
    if cached is None:
        hw = max(CASTER_OMEGA_WINDOW, sig.half_window)
        _, d1, _, _ = local_poly(sig.t, sig.q_raw[:, 2:3], hw, 2, sig.breaks)
        # soft threshold at twice the noise of this derivative: a cart at rest must not rock its casters
        noise = sig.sigma_theta * derivative_gain(sig.t, hw, 2, sig.breaks)[1]
        cached = np.sign(d1[:, 0]) * np.maximum(np.abs(d1[:, 0]) - 2.0 * noise, 0.0)
        sig.extras[key] = cached
    return cached


def caster_kinematics(sig: Signals, axles: Sequence[float], trails: Sequence[float]) -> CasterLanes:
    """Return the swivel angles and rates of the modelled casters for these axle positions x trails (cached).

    Casters at (x, +-CASTER_HALF_TRACK) in {b} with trail e; the wheel rolls
    along alpha and does not slide sideways:
    alpha' = -(R / e) sin(alpha - psi) - omega, with R, psi the speed and
    direction of the swivel axis, (R cos psi, R sin psi) = (v - omega y, omega x).
    Stepped exactly for the rolling part (tan((alpha - psi)/2) decays as
    exp(-R dt / e)), so any sampling rate is stable. The casters start
    trailing (alpha = 0). Which way, and after how much travel, a caster
    leaves its leading equilibrium after a reversal depends on a misalignment
    too small to measure (noise in omega decides it in the data), so each
    :data:`SWING_MODES` lane keeps the caster at least ``misalignment`` away
    from leading, on the natural side (0) or forced to one side (+-1); the
    fit picks a mode per swing (:class:`SwivelCasterModel`). Streamed
    (:func:`cart.caster_lanes.caster_lanes`): the natural lane along the log, every lane on the swings.
    """
    key = ("motion", "caster_kin", tuple(axles), tuple(trails))
    cached = sig.extras.get(key)
    if cached is None:
        cached = caster_lanes(
            sig.t, sig.v, kinematic_yaw_rate(sig), tuple(axles), tuple(trails), SWING_MODES, CASTER_HALF_TRACK
        )
        sig.extras[key] = cached
    return cached


class SwivelCasterModel(CasterSwivel):
    """``caster_swivel`` as two swivelling casters: the force of their swivel friction along the log.

    Casters at (x, +-0.25 m) in {b} with trail e (:func:`caster_kinematics`);
    the swivel bearing resists with
    T = c1 tanh(alpha' / 0.2) + c2 tanh(alpha' / 0.8) + damping alpha'
    (Coulomb friction -- two regularisations, so that their mix fits a sharp or a
    soft one -- and viscous). Torque balance of each (light) fork makes the
    floor push its wheel sideways with T / e, which the cart feels at the
    swivel axis, and the bearing returns T:
    E_fwd = sum (T / e) sin alpha, E_yaw = sum T (1 - (x cos alpha + y sin alpha) / e).
    After a reversal the casters swing round (resisting the cart, with a yaw
    torque whose sign follows the swing); in turns they resist realigning.
    Linear parameters c1, c2 [N m], damping [N m s/rad]; the trail e is searched
    on a grid (log-spaced 1.5-8 cm), the axle position x in {0.5, 0.8, 1.1} m
    through the variants (5 parameters counted). Each swing that starts from
    (nearly) leading gets weights over the swing modes (side of each caster,
    initial misalignment: :data:`SWING_MODES`) by how well each fits,
    re-weighed with every refit (:meth:`offset`) -- a latent choice, not counted
    as a parameter. At rest the casters hold the cart up to
    (c1 + c2) sum |sin alpha| / e (set-valued, as the profile form).
    The fork's own inertia is not modelled: a column in its swivel
    acceleration (the second derivative of a noise-driven angle) traded off
    against the cart's yaw inertia and made the fits worse, not better.
    """

    param_names = ("torque_sharp", "torque_soft", "damping")
    nl_names = ("trail",)
    refine = False
    log_scale = True
    AXLES: tuple[float, ...] = (0.5, 0.8, 1.1)
    TRAILS: tuple[float, ...] = tuple(float(e) for e in np.geomspace(0.015, 0.08, 14))
    EPS = (0.2, 0.8)  # rad/s: regularisations of the two Coulomb swivel-friction columns
    #: swing-mode combinations (caster 1, caster 2) tried per swing: both natural, then sides x misalignments
    COMBOS: tuple[tuple[int, int], ...] = ((0, 0),) + tuple(
        (a, b) for d in range(1, len(SWING_MODES), 2) for a, b in ((d, d), (d + 1, d + 1), (d, d + 1), (d + 1, d))
    )

    #: swing-mode lane of caster 1 and of caster 2 in each combination
    COMBO_LANES: tuple[np.ndarray, np.ndarray] = (np.array([c[0] for c in COMBOS]), np.array([c[1] for c in COMBOS]))

    def __init__(self, axle_x: float = 0.8) -> None:
        super().__init__(1.0)
        self.axle_x = float(axle_x)

    def variants(self):
        """Return itself (the axle positions are variants of :class:`CasterSwivel`)."""
        return [self]

    @property
    def n_params(self) -> int:
        """Return 5: two Coulomb torques, damping, trail and the grid-chosen axle position."""
        return 5

    def nl_grid(self, sig):
        """Return the trails 1.5-8 cm."""
        return [(e,) for e in self.TRAILS]

    def nl_bounds(self, sig):
        """Return the trail bounds in metres."""
        return [(self.TRAILS[0], self.TRAILS[-1])]

    def _lanes(self, sig: Signals, trail: float) -> tuple[CasterLanes, int, int]:
        """Return the caster pass holding this axle and ``trail`` (grid: one shared pass) and its indices in it."""
        if trail in self.TRAILS and self.axle_x in self.AXLES:
            return (
                caster_kinematics(sig, self.AXLES, self.TRAILS),
                self.AXLES.index(self.axle_x),
                self.TRAILS.index(trail),
            )
        return caster_kinematics(sig, (self.axle_x,), (trail,)), 0, 0

    def _swings(self, sig: Signals, trail: float) -> list[tuple[int, int]]:
        """Return sample ranges [i0, i1) where the swing modes disagree (swings from a leading caster)."""
        lanes, i, j = self._lanes(sig, trail)
        return lanes.swings[(i, j)]

    def _unit_rows(self, alpha: np.ndarray, rate: np.ndarray, trail: float) -> np.ndarray:
        """Return -dE/d(c1, c2, damping) (..., 2 rows: forward, yaw; 3 params) summed over the casters (last axis)."""
        ys = np.array([CASTER_HALF_TRACK, -CASTER_HALF_TRACK])
        lever = 1.0 - (self.axle_x * np.cos(alpha) + ys * np.sin(alpha)) / trail
        sa = np.sin(alpha) / trail
        out = np.empty(alpha.shape[:-1] + (2, 3))
        for k, unit in enumerate((np.tanh(rate / self.EPS[0]), np.tanh(rate / self.EPS[1]), rate)):
            out[..., 0, k] = -np.sum(unit * sa, axis=-1)  # torque per unit parameter
            out[..., 1, k] = -np.sum(unit * lever, axis=-1)
        return out

    def _combo_units(self, sig: Signals, trail: float, swing: int) -> np.ndarray:
        """Return the unit rows of every mode combination on one swing, combination-major (combos, L * 2 * 3).

        Kept (they depend on the motion only; a bounded cache, :data:`UNIT_CACHE_BYTES`).
        """
        key = ("motion", "caster_units", self.axle_x, trail, swing)
        cu = sig.extras.get(key)
        if cu is None:
            lanes, i, j = self._lanes(sig, trail)
            alpha, rate = lanes.swing_alpha[(i, j)][swing], lanes.swing_rates(i, j, swing)
            c1, c2 = self.COMBO_LANES
            al = np.stack([alpha[:, 0, c1], alpha[:, 1, c2]], axis=-1)  # (L, combos, 2 casters)
            ra = np.stack([rate[:, 0, c1], rate[:, 1, c2]], axis=-1)
            cu = self._unit_rows(al, ra, trail).transpose(1, 0, 2, 3).reshape(len(c1), -1)
            cache_bounded(sig, "caster_units", key, cu, UNIT_CACHE_BYTES)
        return cu

    def _units(self, sig: Signals, trail: float, swing: int, combos: np.ndarray | None = None) -> np.ndarray:
        """Return the unit rows (L, combos, 2 rows, 3 params) of the mode combinations (all: None) on one swing."""
        cu = self._combo_units(sig, trail, swing)
        cu = cu if combos is None else cu[combos]
        return np.ascontiguousarray(cu.reshape(len(cu), -1, 2, 3).transpose(1, 0, 2, 3))

    def _mixture(self, sig: Signals, trail: float, swing: int, wts: np.ndarray) -> np.ndarray:
        """Return the unit rows (L, 2 rows, 3 params) of one swing as the mixture ``wts`` of its mode combinations.

        The product ``np.tensordot(wts, units, axes=(0, 1))`` forms (the same numbers), on the kept
        combination-major rows; combinations of weight 0 left out.
        """
        used = np.flatnonzero(wts > 0.0)
        cu = self._combo_units(sig, trail, swing)
        cu = cu if len(used) == len(cu) else cu[used]
        return np.dot(wts[used].reshape(1, -1), cu).reshape(-1, 2, 3)

    def _choice(self, sig: Signals, trail: float) -> dict[tuple[int, int], np.ndarray]:
        """Return the current weights of the mode combinations per swing ({(i0, i1): (combos,)}; empty: natural)."""
        return sig.extras.get(("caster_choice", self.axle_x, trail), {})

    def _swing_stats(self, sig: Signals, trail: float, base: np.ndarray) -> list[tuple]:
        """Return per swing ((i0, i1), k, Q, P, R, c0, b, S): its index and the weighted normal equations of the combos.

        U_c (L, combos, 2 rows, 3 params) are the unit rows of combination c (:meth:`_units`, not kept);
        with W = diag(1/sigma_force^2, 1/sigma_torque^2), y the measured forward
        force and torque and B their nominal phi columns: Q_c = sum U_c' W U_c,
        P_c = sum U_c' W y, R_c = sum U_c' W B, c0 = sum y' W y, b = sum B' W y,
        S = sum B' W B, so that the weighted misfit of c for (phi, theta) is
        theta' Q_c theta - 2 theta' (P_c - R_c phi) + c0 - 2 phi' b + phi' S phi.
        The parts without y depend on the motion only and survive a time
        shift of the wrench (``Signals.shifted``).
        """
        key = ("caster_swing_stats", self.axle_x, trail)
        cached = sig.extras.get(key)
        if cached is not None:
            return cached
        w = np.array([1.0 / sig.sigma_force**2, 1.0 / sig.sigma_torque**2])
        mkey = ("motion", "caster_swing_units", self.axle_x, trail)
        motion = sig.extras.get(mkey)
        if motion is None:
            motion = []
            for k, (i0, i1) in enumerate(self._swings(sig, trail)):
                u = self._units(sig, trail, k)  # (L, combos, 2 rows, 3 params), recomputed from the lanes when needed
                n_c = u.shape[1]
                uc = u.transpose(1, 0, 2, 3).reshape(n_c, -1, 3)  # (combos, L * 2, 3): sums over samples and rows
                uwc = (u * w[None, None, :, None]).transpose(1, 0, 2, 3).reshape(n_c, -1, 3)
                bb = base[i0:i1, :2, :4].reshape(-1, 4)  # (L * 2, 4)
                wr = np.tile(w, i1 - i0)[:, None]
                motion.append(((i0, i1), uwc.transpose(0, 2, 1) @ uc, uwc.transpose(0, 2, 1) @ bb, (bb * wr).T @ bb))
            sig.extras[mkey] = motion
        out = []
        for k, ((i0, i1), q, rr, ss) in enumerate(motion):
            y = np.column_stack([sig.f_fwd[i0:i1], sig.tau[i0:i1]])  # (L, 2)
            bw = (base[i0:i1, :2, :4] * w[None, :, None]).reshape(-1, 4)
            out.append(
                (
                    (i0, i1),
                    k,
                    q,
                    np.einsum("lcrk,lr->ck", self._units(sig, trail, k), y * w),
                    rr,
                    float(np.sum(y * y * w)),
                    bw.T @ y.reshape(-1),
                    ss,
                )
            )
        sig.extras[key] = out
        return out

    def _swing_arrays(self, sig: Signals, trail: float, base: np.ndarray) -> _SwingArrays:
        """Return the swings' ranges and their normal-equation terms of :meth:`_swing_stats` stacked over the swings.

        (ranges, Q (S, C, 3, 3), P (S, C, 3), R (S, C, 3, 4), c0 (S,), b (S, 4), S (S, 4, 4), n_ind (S,)):
        ``n_ind`` the number of roughly independent samples of each swing (one per 0.3 s). Cached.
        """
        key = ("caster_swing_arrays", self.axle_x, trail)
        cached = sig.extras.get(key)
        if cached is None:
            stats = self._swing_stats(sig, trail, base)
            dt = float(np.median(np.diff(sig.t)))
            ranges = tuple(st[0] for st in stats)
            n_ind = np.array([max((i1 - i0) * dt / 0.3, 1.0) for i0, i1 in ranges])
            cached = (ranges,) + tuple(np.array([st[k] for st in stats]) for k in range(2, 8)) + (n_ind,)
            sig.extras[key] = cached
        return cached

    def _choose(self, sig: Signals, trail: float, phi: np.ndarray, base: np.ndarray, theta: np.ndarray) -> None:
        """Weigh the mode combinations of every swing by how well their forces explain the residual (given theta).

        A soft choice (posterior weights) rather than the best combination: the
        misfit ratio to the best one, times the number of roughly independent
        samples (one per 0.3 s), is read as a chi-square difference; a swing the
        data cannot decide keeps a mixture (e.g. both swing directions: their
        yaw torques cancel) instead of a confident wrong guess.
        """
        ph = np.asarray(phi[:4], float)
        th = np.asarray(theta[:3], float)
        ranges, q, pp, rr, c0, b, ss, n_ind = self._swing_arrays(sig, trail, base)
        if not ranges:
            sig.extras[("caster_choice", self.axle_x, trail)] = {}
            return
        score = (
            np.einsum("k,sckj,j->sc", th, q, th)
            - 2.0 * ((pp - rr @ ph) @ th)
            + (c0 - 2.0 * (b @ ph) + np.einsum("j,sjk,k->s", ph, ss, ph))[:, None]
        )
        best = np.maximum(np.min(score, axis=1), 1e-12)
        dchi = 2.0 * n_ind[:, None] * (score / best[:, None] - 1.0)
        wts = np.exp(-0.5 * (dchi - np.min(dchi, axis=1)[:, None]))
        wts = wts / np.sum(wts, axis=1)[:, None]
        sig.extras[("caster_choice", self.axle_x, trail)] = dict(zip(ranges, wts))

    def column_key(self, sig, nl):
        """Return the default key plus the current swing-mode weights (the columns depend on them)."""
        choice = self._choice(sig, float(nl[0]))
        key = Effect.column_key(self, sig, nl)
        if key is None:  # columns that use phi are not cached
            return None
        return key + (tuple((k, tuple(np.round(w, 4))) for k, w in sorted(choice.items())),)

    def _natural_windows(self, sig: Signals, trail: float, edges: np.ndarray) -> np.ndarray:
        """Return the window integrals (windows, 3, 3) of the natural lane's columns (every swing natural), kept."""
        key = ("motion", "caster_natural_windows", self.axle_x, trail, np.asarray(edges).tobytes())
        out = sig.extras.get(key)
        if out is None:
            lanes, i, j = self._lanes(sig, trail)
            g = np.zeros((sig.n, 3, 3))
            g[:, :2, :] = self._unit_rows(lanes.alpha0[:, i, j], lanes.natural_rate(i, j), trail)
            out = sig.extras[key] = window_integrals(sig.t, g, edges)
        return out

    def _natural_part(self, sig: Signals, trail: float, s0: int, s1: int) -> np.ndarray:
        """Return the columns (s1 - s0, 3, 3) of the natural lane on samples [s0, s1) (those of :meth:`columns`), a copy.

        Kept (the motion's; a bounded cache, :data:`UNIT_CACHE_BYTES`).
        """
        key = ("motion", "caster_natural_part", self.axle_x, trail, s0, s1)
        g = sig.extras.get(key)
        if g is None:
            lanes, i, j = self._lanes(sig, trail)
            g = np.zeros((s1 - s0, 3, 3))
            g[:, :2, :] = self._unit_rows(lanes.alpha0[s0:s1, i, j], lanes.natural_rate(i, j, s0, s1), trail)
            cache_bounded(sig, "caster_units", key, g, UNIT_CACHE_BYTES)
        return g.copy()

    def window_columns(self, sig, nl, phi, base, edges):
        """Return the window integrals of :meth:`columns`: the natural lane's, the windows a chosen swing touches redone.

        A window's trapezoid integral holds its own samples only: the windows clear of the swings are those of
        the natural lane's columns (:meth:`_natural_windows`, integrated once per lane); the others are
        integrated from the columns of :meth:`columns` on their samples.
        """
        trail = float(nl[0])
        out = self._natural_windows(sig, trail, edges).copy()
        choice = self._choice(sig, trail)
        stats = sig.extras.get(("caster_swing_stats", self.axle_x, trail), []) if choice else []
        swings = [(st[0], st[1], choice[st[0]]) for st in stats if st[0] in choice]
        mixes: dict[int, np.ndarray] = {}
        for ka, kb in touched_windows(edges, [sw[0] for sw in swings]):
            s0, s1 = int(edges[ka]), int(edges[kb + 1]) + 1
            g = self._natural_part(sig, trail, s0, s1)
            for (i0, i1), k, wts in swings:
                lo, hi = max(i0, s0), min(i1, s1)
                if lo < hi:
                    if k not in mixes:
                        mixes[k] = self._mixture(sig, trail, k, wts)
                    g[lo - s0 : hi - s0, :2, :] = mixes[k][lo - i0 : hi - i0]
            out[ka : kb + 1] = window_integrals(sig.t[s0:s1], g, np.asarray(edges[ka : kb + 2]) - s0)
        return out

    def _rows(self, sig: Signals, trail: float) -> np.ndarray:
        """Return the unit rows (N, 2, 3): natural swings, each chosen swing as its weighted mixture of combos."""
        lanes, i, j = self._lanes(sig, trail)
        # not kept: the lanes are, and the fits keep their columns
        rows = self._unit_rows(lanes.alpha0[:, i, j], lanes.natural_rate(i, j), trail)
        choice = self._choice(sig, trail)
        if choice:
            for st in sig.extras.get(("caster_swing_stats", self.axle_x, trail), []):
                wts = choice.get(st[0])
                if wts is not None:
                    rows[st[0][0] : st[0][1]] = self._mixture(sig, trail, st[1], wts)  # (L, rows, params)
        return rows

    def _hold_capacity(self, sig: Signals, trail: float) -> np.ndarray:
        """Return sum |sin alpha| / e (N,) per unit torque: the casters' most likely swing per chosen swing."""
        lanes, i, j = self._lanes(sig, trail)
        alpha, swings, s_alpha = lanes.alpha0[:, i, j], lanes.swings[(i, j)], lanes.swing_alpha[(i, j)]
        nkey = ("motion", "caster_hold_natural", self.axle_x, trail)
        natural = sig.extras.get(nkey)
        if natural is None:
            natural = np.sum(np.abs(np.sin(alpha)), axis=1) / trail
            sig.extras[nkey] = natural
        cap = natural.copy()
        c1, c2 = self.COMBO_LANES
        on_swing = dict(zip(swings, s_alpha))
        for (i0, i1), wts in self._choice(sig, trail).items():
            c = int(np.argmax(wts))
            al = on_swing[(i0, i1)]
            cap[i0:i1] = (np.abs(np.sin(al[:, 0, c1[c]])) + np.abs(np.sin(al[:, 1, c2[c]]))) / trail
        return cap

    def columns(self, sig, nl, phi, base):
        """Return G = -dE/d(torque, damping) in the forward and yaw rows (swings as their chosen mixtures)."""
        g = np.zeros((sig.n, 3, 3))
        g[:, :2, :] = self._rows(sig, float(nl[0]))
        return g

    def offset(self, sig, nl, phi, base, theta):
        """Re-weigh the swing modes for this estimate; return the hold at rest, cap = (c1 + c2) sum |sin alpha| / e."""
        e = float(nl[0])
        if theta is None or phi is None or len(theta) == 0:
            sig.extras[("caster_choice", self.axle_x, e)] = {}  # a fresh fit starts from the natural swings
            return None
        if np.any(np.asarray(theta, float) != 0.0):
            self._choose(sig, e, phi, base, theta)
        coulomb = float(theta[0]) + float(theta[1])
        if coulomb <= 0.0 or not np.any(np.abs(sig.v) < stop_threshold(sig)):
            return None
        return static_hold(sig, forward_residual(sig, phi, base), coulomb * self._hold_capacity(sig, e))

    def is_physical(self, theta, nl, x):
        """Return True when the swivel resists: c1 + c2 > 0 and a non-negative friction slope at rest."""
        c1, c2, damp = (float(u) for u in theta[:3])
        if not np.all(np.isfinite([c1, c2, damp])):
            return False
        return bool(c1 + c2 > 0.0 and c1 / self.EPS[0] + c2 / self.EPS[1] + damp >= 0.0)

    def describe(self, theta, nl, cov, nl_std, phi):
        """Return c1, c2, damping, trail, axle_x, torque = c1 + c2 and force = 2 torque / trail (casters side-on)."""
        params, std = Effect.describe(self, theta, nl, cov, nl_std, phi)
        e = float(nl[0])
        s_t = math.sqrt(max(cov[0, 0] + cov[1, 1] + 2.0 * cov[0, 1], 0.0))
        tq = float(theta[0]) + float(theta[1])
        params.update({"axle_x": self.axle_x, "torque": tq, "force": 2.0 * tq / e})
        std.update({"axle_x": 0.0, "torque": s_t, "force": 2.0 * s_t / e})
        return params, std


class WrenchBias(Effect):
    """A constant offset of the measured wrench fixed in {b}: forward force and torque (lateral is unobservable)."""

    name = "wrench_bias"
    param_names = ("fx", "tau")

    def columns(self, sig, nl, phi, base):
        """Return G: 1 in the forward and yaw rows (measured = true + bias)."""
        g = np.zeros((sig.n, 3, 2))
        g[:, 0, 0] = 1.0
        g[:, 1, 1] = 1.0
        return g


class FloorSlope(Effect):
    """An inclined floor: the constant world force m (gx, gy) at the CoM, gx, gy = g sin(alpha) (cos, sin) beta."""

    name = "floor_slope"
    param_names = ("gx", "gy")
    uses_phi = True
    bilinear = True

    def columns(self, sig, nl, phi, base):
        """Return G = -dE/d(gx, gy) with E the force and its torque about {b} (CoM from phi: (4,) or per sample)."""
        phi = np.asarray(phi, float)
        m, a, b = phi[..., 0], phi[..., 1], phi[..., 2]
        c, s = np.cos(sig.q[:, 2]), np.sin(sig.q[:, 2])
        g = np.zeros((sig.n, 3, 2))
        g[:, 0, 0] = -m * c
        g[:, 0, 1] = -m * s
        g[:, 1, 0] = a * s + b * c
        g[:, 1, 1] = -(a * c - b * s)
        return g

    def phi_force(self, sig, theta):
        """Return S(g) (N, 3, 4): the slope's rows per unit phi, m (gx, gy) at the CoM (the mass of each sample)."""
        gx, gy = float(theta[0]), float(theta[1])
        c, s = np.cos(sig.q[:, 2]), np.sin(sig.q[:, 2])
        out = np.zeros((sig.n, 3, 4))
        out[:, 0, 0] = -(gx * c + gy * s)
        out[:, 1, 1] = gx * s - gy * c
        out[:, 1, 2] = gx * c + gy * s
        return out

    def describe(self, theta, nl, cov, nl_std, phi):
        """Return angle alpha (rad), downhill direction beta in {s} (rad), gx, gy (m/s^2), with stds."""
        gx, gy = float(theta[0]), float(theta[1])
        r = math.hypot(gx, gy)
        alpha = math.asin(min(1.0, r / GRAVITY))
        beta = math.atan2(gy, gx)
        jr = np.array([gx, gy]) / max(r, 1e-12)
        jb = np.array([-gy, gx]) / max(r * r, 1e-12)
        cov2 = cov[:2, :2]
        s_alpha = math.sqrt(max(float(jr @ cov2 @ jr), 0.0)) / GRAVITY / max(math.cos(alpha), 1e-6)
        s_beta = math.sqrt(max(float(jb @ cov2 @ jb), 0.0))
        params = {"angle": alpha, "direction": beta, "gx": gx, "gy": gy}
        std = {
            "angle": s_alpha,
            "direction": s_beta,
            "gx": math.sqrt(max(cov[0, 0], 0)),
            "gy": math.sqrt(max(cov[1, 1], 0)),
        }
        return params, std


def stepped_window_integrals(sig: Signals, base: np.ndarray, edges: np.ndarray, t_change: float) -> np.ndarray | None:
    """Return the window integrals of the phi columns ``base[:, :, :4]`` times the step (t >= ``t_change``), windowed.

    ``base`` must be the nominal rows ``a_s`` whose window integrals on ``edges`` the fits keep
    (``sig.extras["base"]``, ``sig.extras["base_edges"]``); else None. The windows after the change are those
    integrals, the windows before it zero, and only the window that holds the change is integrated again from
    its samples: no per-sample copy of the columns (the same sums as :func:`window_integrals` of the product).
    """
    rows = sig.extras.get("base")
    if rows is None or base is not rows[0] or sig.extras.get("base_edges") is not edges:
        return None
    a_w = rows[1][:, :, :4]
    first = int(np.searchsorted(sig.t, t_change, side="left"))  # the first sample after the change
    after = int(np.searchsorted(edges[:-1], first, side="left"))  # the first window wholly after it
    out = np.zeros_like(a_w)
    out[after:] = a_w[after:]
    if after > 0:  # the window holding the change, from its own samples
        i0, i1 = int(edges[after - 1]), int(edges[after])
        step = (np.arange(i0, i1 + 1) >= first).astype(float)
        part = base[i0 : i1 + 1, :, :4] * step[:, None, None]
        out[after - 1] = window_integrals(sig.t[i0 : i1 + 1], part, np.array([0, i1 - i0]))[0]
    return out


class PayloadChange(Effect):
    """A step of phi = [m, m dx, m dy, J] at an unknown time (a payload put in or taken out)."""

    name = "payload_change"
    param_names: tuple[str, ...] = ("delta_m", "delta_m_dx", "delta_m_dy", "delta_J")
    nl_names = ("time",)
    steps_phi = True

    #: most change times on the grid (a long log gets a coarser grid; the 1-D refinement follows)
    GRID_MAX = 120

    def nl_grid(self, sig):
        """Return change times every 0.25 s within :meth:`nl_bounds` (at most GRID_MAX, evenly spaced)."""
        t0, t1 = self.nl_bounds(sig)[0]
        step = max(0.25, (t1 - t0) / self.GRID_MAX)
        return [(float(x),) for x in np.arange(t0, t1, step)] or [(0.5 * (t0 + t1),)]

    def nl_bounds(self, sig):
        """Return the change-time bounds: at least 1.5 s and 5 % of the acceleration content on each side.

        phi is identifiable on a side only from its excitation; a change time
        with (almost) none on one side would fit noise there.
        """
        e = sig.vdot**2 + (0.3 * sig.omegadot) ** 2
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (e[1:] + e[:-1]) * np.diff(sig.t))])
        cum = cum / max(cum[-1], 1e-12)
        lo = max(sig.t[0] + 1.5, float(np.interp(0.05, cum, sig.t)))
        hi = min(sig.t[-1] - 1.5, float(np.interp(0.95, cum, sig.t)))
        if hi <= lo:
            mid = 0.5 * (sig.t[0] + sig.t[-1])
            return [(mid - 1e-3, mid + 1e-3)]
        return [(lo, hi)]

    def columns(self, sig, nl, phi, base):
        """Return G = the nominal phi columns after the change time (the step of phi)."""
        step = (sig.t >= nl[0]).astype(float)
        return base[:, :, :4] * step[:, None, None]

    def window_columns(self, sig, nl, phi, base, edges):
        """Return the window integrals of :meth:`columns`: the nominal window rows after the change, windowed.

        Of the nominal rows (``base`` is the fit's nominal ``a_s``, on these ``edges``) only the window that holds
        the change is integrated again; the others are the nominal window rows or zero (no per-sample copy).
        """
        stepped = stepped_window_integrals(sig, base, edges, float(nl[0]))
        if stepped is None:  # phi's rows carry a bilinear effect's force: integrated sample by sample
            stepped = window_integrals(sig.t, PayloadChange.columns(self, sig, nl, phi, base), edges)
        return stepped

    def noise_loadings(self, sig, nl, edges, lv, lw):
        """Return the nominal phi loadings in the windows after the change time."""
        step = (sig.t[edges[:-1]] >= nl[0]).astype(float)[:, None, None]
        return lv[:, :, :4] * step, lw[:, :, :4] * step

    def is_physical(self, theta, nl, x):
        """Return True when phi before and after the change both have m > 0.5 kg and I (about the CoM) > 0."""
        if not (np.all(np.isfinite(np.asarray(x[:4], float))) and np.all(np.isfinite(np.asarray(theta[:4], float)))):
            return False
        for ph in (np.asarray(x[:4], float), np.asarray(x[:4], float) + np.asarray(theta[:4], float)):
            if ph[0] <= 0.5 or ph[3] - (ph[1] ** 2 + ph[2] ** 2) / ph[0] <= 0.0:
                return False
        return True

    def replay_phi_change(self, sig, nl, theta, phi=None):
        """Return the step of phi over time."""
        step = (sig.t >= nl[0]).astype(float)
        return step[:, None] * np.asarray(theta, float)[None, :4]

    def variants(self):
        """Return the full step of phi and the reduced step of the mass alone (CoM and radius of gyration kept)."""
        return [self, PayloadMassStep()]

    def describe(self, theta, nl, cov, nl_std, phi):
        """Return time, mass before/after, mass change, CoM after the change (with stds)."""
        params, std = Effect.describe(self, theta, nl, cov, nl_std, phi)
        after = np.asarray(phi[:4], float) + np.asarray(theta[:4], float)
        params.update(
            {
                "mass_before": float(phi[0]),
                "mass_after": float(after[0]),
                "com_x_after": float(after[1] / after[0]) if after[0] > 0 else float("nan"),
                "com_y_after": float(after[2] / after[0]) if after[0] > 0 else float("nan"),
            }
        )
        std.update({"mass_after": std["delta_m"]})
        return params, std


class PayloadMassStep(PayloadChange):
    """Reduced ``payload_change``: phi scales by (1 + delta_m / m) at an unknown time (CoM, gyration radius kept).

    Two parameters (delta_m, time) instead of five: the leading-order effect
    of a payload near the cart's CoM, detectable from less excitation.
    Reported with the same parameter names as the full form.
    """

    param_names = ("delta_m",)
    uses_phi = True

    def variants(self):
        """Return itself."""
        return [self]

    def columns(self, sig, nl, phi, base):
        """Return G = (nominal phi columns . phi / m) after the change time."""
        sig.extras["phi_mass_step"] = np.asarray(phi[:4], float)
        step = (sig.t >= nl[0]).astype(float)
        u = np.asarray(phi[:4], float) / float(phi[0])
        return (base[:, :, :4] @ u)[:, :, None] * step[:, None, None]

    def window_columns(self, sig, nl, phi, base, edges):
        """Return the window integrals of the columns: those of the stepped phi columns along phi / m."""
        sig.extras["phi_mass_step"] = np.asarray(phi[:4], float)
        u = np.asarray(phi[:4], float) / float(phi[0])
        return (PayloadChange.window_columns(self, sig, nl, phi, base, edges) @ u)[:, :, None]

    def noise_loadings(self, sig, nl, edges, lv, lw):
        """Return the nominal phi loadings along phi / m in the windows after the change time."""
        phi = sig.extras.get("phi_mass_step")
        if phi is None:
            return None
        u = np.asarray(phi[:4], float) / float(phi[0])
        step = (sig.t[edges[:-1]] >= nl[0]).astype(float)[:, None, None]
        return (lv[:, :, :4] @ u)[:, :, None] * step, (lw[:, :, :4] @ u)[:, :, None] * step

    def is_physical(self, theta, nl, x):
        """Return True when the mass is above 0.5 kg and the inertia about the CoM positive, before and after."""
        x4 = np.asarray(x[:4], float)
        if not np.all(np.isfinite(x4)) or not np.isfinite(float(theta[0])) or x4[0] <= 0.5:
            return False
        return PayloadChange.is_physical(self, np.asarray(theta[0], float) * x4 / x4[0], nl, x4)

    def replay_phi_change(self, sig, nl, theta, phi=None):
        """Return the step of phi over time (phi scaled by the mass ratio)."""
        step = (sig.t >= nl[0]).astype(float)
        u = np.asarray(phi[:4], float) / float(phi[0])
        return step[:, None] * (float(theta[0]) * u)[None, :]

    def describe(self, theta, nl, cov, nl_std, phi):
        """Return the same parameters as the full form (delta_m_dx, delta_m_dy, delta_J from the scaling)."""
        u = np.asarray(phi[:4], float) / float(phi[0])
        full = float(theta[0]) * u
        s_m = math.sqrt(max(cov[0, 0], 0.0))
        std4 = np.abs(u) * s_m
        params = {k: float(v) for k, v in zip(PayloadChange.param_names, full)}
        std = {k: float(v) for k, v in zip(PayloadChange.param_names, std4)}
        for k, v, sd in zip(self.nl_names, nl, nl_std):
            params[k], std[k] = float(v), float(sd)
        after = np.asarray(phi[:4], float) + full
        params.update(
            {
                "mass_before": float(phi[0]),
                "mass_after": float(after[0]),
                "com_x_after": float(after[1] / after[0]),
                "com_y_after": float(after[2] / after[0]),
            }
        )
        std.update({"mass_after": std["delta_m"]})
        return params, std


class TimeDelay(Effect):
    """The wrench stream lags the motion by a constant delay: gamma_true(t) = gamma_logged(t + delay)."""

    name = "time_delay"
    param_names = ()
    nl_names = ("delay",)

    def nl_grid(self, sig):
        """Return delays from -0.5 s to 0.5 s every 20 ms (0 excluded: that is the nominal model)."""
        return [(float(d),) for d in np.arange(-0.5, 0.5001, 0.02) if abs(d) > 1e-9]

    def nl_bounds(self, sig):
        """Return the delay bounds in seconds."""
        return [(-0.6, 0.6)]

    def transform(self, sig, nl):
        """Return the signals with the wrench shifted by the delay."""
        return sig.shifted(nl[0])


class LateralSlip(Effect):
    """The {b} origin slides sideways at compliance * (lateral force the wheels must hold) (violates eq. 3)."""

    name = "lateral_slip"
    param_names = ("compliance",)
    uses_phi = True

    def variants(self) -> list[Effect]:
        """Return the creep (this form) and the sliding wheels (:class:`cart.diagnose_slide.SlidingWheels`).

        Both are fitted by the same machinery and the better Delta BIC is named; the sliding form is
        imported when asked for, so the registry offers both without importing the diagnosis.
        """
        from cart.diagnose_slide import SlidingWheels

        return [self, SlidingWheels()]

    def columns(self, sig, nl, phi, base):
        """Return G: lateral force the wheels carry, f_lat - (m v omega + m dx omegadot - m dy omega^2)."""
        m, a, b = phi[0], phi[1], phi[2]
        f_need = sig.f_lat - (m * sig.v * sig.omega + a * sig.omegadot - b * sig.omega**2)
        g = np.zeros((sig.n, 3, 1))
        g[:, 2, 0] = f_need
        return g


_REGISTRY: dict[str, type[Effect]] = {}


def register_effect(cls: type[Effect]) -> type[Effect]:
    """Register an Effect subclass under ``cls.name`` (usable as a class decorator); return it."""
    if not (isinstance(cls, type) and issubclass(cls, Effect)):
        raise TypeError("register_effect expects a subclass of cart.effects.Effect")
    _REGISTRY[cls.name] = cls
    return cls


def unregister_effect(name: str) -> None:
    """Remove a registered effect (no error if absent)."""
    _REGISTRY.pop(name, None)


def registered_effects() -> list[Effect]:
    """Return one instance of every registered effect, in registration order."""
    return [cls() for cls in _REGISTRY.values()]


for _cls in (CoulombFriction, CasterSwivel, WrenchBias, PayloadChange, FloorSlope, TimeDelay, LateralSlip):
    register_effect(_cls)

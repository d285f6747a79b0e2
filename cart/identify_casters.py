"""Swivelling casters in the filtered regression of :mod:`cart.identify`: their swivel resistance as columns.

A cart on two fixed wheels and two swivelling casters (the paper's cart, Fig. 1) obeys paper eq. 4 only
while the casters trail their swivel axes. Whenever the direction in which a swivel axis moves changes
(a start, a stop with a turn, a reversal, the start or end of a turn) the casters swing round, and the
swivel bearing's friction and the wheel's scrub on the floor resist the swing. Each caster is a light fork:
its torque balance about the swivel axis makes the floor push the wheel sideways with ``T / e`` (``T`` the
resisting torque, ``e`` the trail), which the cart feels at the swivel axis, plus the bearing's own torque.
These swings happen exactly when the cart accelerates, so the force they need is read as mass: a
physics-engine cart (MuJoCo, ``studies.testbeds.mujoco_cart``) reads 1-11 % heavy without them.

The swivel angles follow from the cart's motion alone (no-slip rolling of each caster wheel,
:func:`cart.caster_lanes.caster_lanes`): ``alpha' = -(R / e) sin(alpha - psi) - omega`` with ``(R cos psi,
R sin psi) = (v - omega y, omega x)`` the velocity of the swivel axis at ``(x, y)`` in {b}. The resisting
torque has three linear parameters: bearing friction ``tanh(alpha' / eps)`` (Coulomb, regularised) and
damping ``alpha'``, and the wheel's scrub ``tanh((alpha' + omega) / eps)`` (torsional friction against
the wheel's yaw rate in the world, felt by the cart only through the sideways force). The geometry (axle
position ``x`` of the swivel axes, trail ``e``) enters nonlinearly and is searched on a grid (least
weighted residual); the casters' half-track matters little and is fixed.

The columns are kept only when the four resistances are jointly significant *as resistances*: each
coefficient (bearing friction, damping, scrub, rolling resistance) opposes the motion it acts on, so it is
non-negative, and the test (:func:`resisting_statistic`) is the likelihood ratio of the sign-constrained fit
against none (a one-sided Wald test, whose chi-bar-squared null distribution lies below the chi-squared one,
so the chi-squared threshold with the grid search's Bonferroni factor stays conservative). On a cart without
casters (or one whose casters hardly swing) the nominal fit is unchanged: there the free coefficients take
either sign and a joint fit of noise with the wrong signs is no caster.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


#: Swivel-axis positions x (m, along {b} x) and trails e (m) searched: carts from a trolley to a hospital bed.
AXLES: tuple[float, ...] = tuple(float(x) for x in np.geomspace(0.35, 1.6, 4))
TRAILS: tuple[float, ...] = tuple(float(e) for e in np.geomspace(0.018, 0.06, 3))
#: Lateral offset (m) of the two modelled casters (their exact value matters little: it enters the yaw lever only).
HALF_TRACK = 0.25
#: Significance of the caster columns (Wald test, three dof, Bonferroni over the grid).
ALPHA = 1e-3
#: Grid samples on which the geometry is searched (the first ones; the chosen geometry then runs on all).
SEARCH_SAMPLES = 12_000
#: Least swivelling (half-turns per caster) along the log for the caster model to be tested: a log that never
#: swings the casters round cannot tell their resistance from any other misfit.
MIN_HALF_TURNS = 1.0
#: Regularisation of the Coulomb columns: this share of the RMS of the rate they act on.
EPS_SHARE = 0.05
N_COLUMNS = 4


@dataclass(frozen=True)
class Casters:
    """The caster model's test in a fit: best geometry, Wald statistic, its threshold (:func:`wald_threshold`), kept,
    and how far the modelled casters swivel along the log (:func:`half_turns`)."""

    axle: float
    trail: float
    wald: float
    threshold: float
    kept: bool
    half_turns: float = 0.0


def wald_threshold() -> float:
    """Return the Wald threshold of the caster columns: N_COLUMNS dof at ALPHA over the number of geometries searched."""
    from cart.ekf import chi2_isf

    return chi2_isf(ALPHA / (len(AXLES) * len(TRAILS)), N_COLUMNS)


def resisting_statistic(coef: np.ndarray, cov: np.ndarray) -> float:
    """Return the one-sided Wald statistic of resistances ``coef`` (k,) with covariance ``cov`` (k, k).

    ``coef' P coef - min_{p >= 0} (coef - p)' P (coef - p)`` with ``P = cov^-1``: the likelihood ratio of the
    best non-negative (resisting) coefficients against zero (Kudo 1963; Silvapulle and Sen, *Constrained
    Statistical Inference*, 2005, ch. 3). Equal to the plain Wald statistic when every coefficient is
    positive; coefficients that assist the motion count for nothing.
    """
    if not np.all(np.isfinite(cov)) or not np.all(np.isfinite(coef)):
        return 0.0
    prec = np.linalg.pinv(cov)
    prec = 0.5 * (prec + prec.T)
    w, vec = np.linalg.eigh(prec)
    root = (vec * np.sqrt(np.clip(w, 0.0, None))) @ vec.T  # root' root = P
    target = root @ coef
    return float(target @ target - _nonnegative_residual(root, target) ** 2)


def _nonnegative_residual(A: np.ndarray, b: np.ndarray) -> float:
    """Return ``min_{p >= 0} |A p - b|`` for the few (<= 8) columns of ``A``: the best of the unconstrained fits on
    each subset of columns whose coefficients are all non-negative (the optimum is one of them: its free set's
    fit; exact, and no scipy.optimize import on the estimate path)."""
    best = float(np.linalg.norm(b))
    k = A.shape[1]
    for mask in range(1, 2**k):
        cols = [j for j in range(k) if mask >> j & 1]
        p, *_ = np.linalg.lstsq(A[:, cols], b, rcond=None)
        if np.all(p >= 0.0):
            best = min(best, float(np.linalg.norm(A[:, cols] @ p - b)))
    return best


def _caster_sum(x: np.ndarray) -> np.ndarray:
    """Return x[:, 0] + x[:, 1]: the two casters' sum (what ``np.sum(x, axis=1)`` gives, without a reduction over
    an axis of two)."""
    return x[:, 0] + x[:, 1]


def unit_rows(
    alpha: np.ndarray, rate: np.ndarray, v: np.ndarray, om: np.ndarray, axle: float, trail: float
) -> np.ndarray:
    """Return the wrench (n, 2 rows: forward, yaw; 4 columns) each unit of resistance needs, summed over the casters.

    ``alpha``, ``rate`` (n, 2): swivel angles and rates of the two casters at ``(axle, +-HALF_TRACK)``; ``v``,
    ``om`` (n,) the cart's forward speed and yaw rate. A resisting torque ``T`` in the bearing needs the
    sideways force ``T / e`` at the swivel axis and the torque ``T`` itself; the wheel's scrub needs the force
    only. The caster wheel's rolling resistance (a force ``f`` against its rolling, along its heading, through
    the swivel axis) needs ``f`` along the heading at the swivel axis.
    """
    ys = np.array([HALF_TRACK, -HALF_TRACK])
    cos_a, sin_a = np.cos(alpha), np.sin(alpha)
    arm = (axle * cos_a + ys * sin_a) / trail
    side = sin_a / trail
    wheel_rate = rate + om[:, None]
    rolling = (v[:, None] - om[:, None] * ys) * cos_a + om[:, None] * axle * sin_a
    eps = [EPS_SHARE * float(np.sqrt(np.mean(r**2))) + 1e-12 for r in (rate, wheel_rate, rolling)]
    out = np.empty((len(om), 2, N_COLUMNS))
    for k, (unit, own) in enumerate(
        ((np.tanh(rate / eps[0]), 1.0), (rate, 1.0), (np.tanh(wheel_rate / eps[1]), 0.0)),
    ):
        out[:, 0, k] = -_caster_sum(unit * side)
        out[:, 1, k] = -_caster_sum(unit * (own - arm))
    roll = np.tanh(rolling / eps[2])
    out[:, 0, 3] = _caster_sum(roll * cos_a)
    out[:, 1, 3] = _caster_sum(roll * (axle * sin_a - ys * cos_a))
    return out


#: samples per block of :func:`_prefix_products` (a doubling scan within blocks, then one across the block totals;
#: short blocks: log2(SCAN_BLOCK) doubling passes over the samples, the recursion on the totals is cheap)
SCAN_BLOCK = 8


def _times(
    a00: np.ndarray, a01: np.ndarray, a10: np.ndarray, a11: np.ndarray, b: tuple[np.ndarray, ...]
) -> list[np.ndarray]:
    """Return the entries [c00, c01, c10, c11] of the 2x2 matrix products A B (entrywise arrays; B's entries ``b``)."""
    b00, b01, b10, b11 = b
    c = [a00 * b00, a00 * b01, a10 * b00, a10 * b01]
    c[0] += a01 * b10
    c[1] += a01 * b11
    c[2] += a11 * b10
    c[3] += a11 * b11
    return c


def _scaled_into(c: list[np.ndarray], out: tuple[np.ndarray, ...]) -> None:
    """Write the entries ``c`` divided by their largest magnitude (+ 1e-300) into ``out`` (projective state)."""
    scale = np.abs(c[0])
    for x in c[1:]:
        np.maximum(scale, np.abs(x), out=scale)
    scale += 1e-300
    for x, o in zip(c, out):
        np.divide(x, scale, out=o)


def _doubling_scan(a: list[np.ndarray]) -> None:
    """Turn the entries a = [m00, m01, m10, m11], each (blocks, n, ...), in place into their prefix products.

    Doubling (Hillis-Steele) scan along axis 1 of arrays shaped (blocks, n, ...): log2(n) vectorised passes.
    Each product is scaled to a largest entry of one: the matrices act on a projective state (only the
    direction of (p, q) matters).
    """
    a00, a01, a10, a11 = a
    d = 1
    while d < a00.shape[1]:
        b00, b01, b10, b11 = a00[:, :-d], a01[:, :-d], a10[:, :-d], a11[:, :-d]
        c = _times(a00[:, d:], a01[:, d:], a10[:, d:], a11[:, d:], (b00, b01, b10, b11))
        _scaled_into(c, (a00[:, d:], a01[:, d:], a10[:, d:], a11[:, d:]))
        d *= 2


def _prefix_products(m: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """Return P_i = m_i m_(i-1) ... m_0 of 2x2 matrices given by their entries (m00, m01, m10, m11), each (n, ...).

    Blocked scan, linear in n: a doubling scan (:func:`_doubling_scan`) within blocks of ``SCAN_BLOCK``
    samples, the prefix products of the blocks' totals (the same function, on n / SCAN_BLOCK of them), and
    each block's prefixes times the product of all blocks before it. Products are scaled (projective state).
    """
    n = len(m[0])
    nb = -(-n // SCAN_BLOCK)
    rest = np.shape(m[0])[1:]
    pad = nb * SCAN_BLOCK - n
    eye = (1.0, 0.0, 0.0, 1.0)
    a = [
        np.concatenate([np.asarray(x, float), np.full((pad, *rest), e)]).reshape(nb, SCAN_BLOCK, *rest)
        for x, e in zip(m, eye)
    ]
    _doubling_scan(a)
    if nb > 1:  # E_b: the product of blocks 0..b; block b + 1's prefixes are multiplied by it on the right
        e00, e01, e10, e11 = _prefix_products(tuple(x[:, -1] for x in a))
        b00, b01, b10, b11 = (x[:-1, None] for x in (e00, e01, e10, e11))
        a00, a01, a10, a11 = (x[1:] for x in a)
        c = _times(a00, a01, a10, a11, (b00, b01, b10, b11))
        _scaled_into(c, tuple(x[1:] for x in a))
    return tuple(x.reshape(nb * SCAN_BLOCK, *rest)[:n] for x in a)


def lanes(
    t: np.ndarray, v: np.ndarray, om: np.ndarray, axles: tuple[float, ...], trails: tuple[float, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """Return the swivel angles and rates (n, axles, trails, 2 casters) of casters at (x, +-HALF_TRACK), trail e.

    The natural lane of :func:`cart.caster_lanes.caster_lanes` (the casters start trailing; no forced swing
    side): per sample, ``tan(b / 2)`` of the misalignment ``b = alpha - psi`` decays exactly by
    ``exp(-R dt / e)`` and turns with the swivel axis's direction. Each step is a linear map of the
    projective pair (p, q), ``tan(b / 2) = p / q``, so the whole lane is a prefix product
    (:func:`_prefix_products`) rather than a loop over samples.
    """
    xs = np.asarray(axles, float)[:, None, None]
    ys = np.array([HALF_TRACK, -HALF_TRACK])[None, None, :]
    es = np.asarray(trails, float)[None, :, None]
    vm = np.concatenate([[v[0]], 0.5 * (v[1:] + v[:-1])])[:, None, None, None]
    omm = np.concatenate([[om[0]], 0.5 * (om[1:] + om[:-1])])[:, None, None, None]
    dt = np.concatenate([[0.0], np.diff(t)])[:, None, None, None]
    px, py = vm - omm * ys, omm * xs
    psi = np.arctan2(py, px)  # (n, axles, 1, 2)
    decay = np.exp(-np.hypot(px, py) * dt / es)  # (n, axles, trails, 2)
    yaw = omm * dt
    half = 0.5 * (psi[:-1] - yaw[:-1] - psi[1:])
    c, s = np.cos(half), np.sin(half)
    # A_0 = D_0 (p *= decay); A_i = D_i R_(i-1), R: (p, q) -> (c p + s q, c q - s p)
    ones = np.ones_like(decay)
    m00 = decay * np.concatenate([ones[:1], np.broadcast_to(c, decay[1:].shape)])
    m01 = decay * np.concatenate([0.0 * ones[:1], np.broadcast_to(s, decay[1:].shape)])
    m10 = np.concatenate([0.0 * ones[:1], -np.broadcast_to(s, decay[1:].shape)])
    m11 = np.concatenate([ones[:1], np.broadcast_to(c, decay[1:].shape)])
    p00, p01, p10, p11 = _prefix_products((m00, m01, m10, m11))
    s0, c0 = np.sin(-0.5 * psi[0]), np.cos(-0.5 * psi[0])  # the casters start trailing: b = -psi
    p, q = p00 * s0 + p01 * c0, p10 * s0 + p11 * c0
    alpha = 2.0 * np.arctan2(p, q) + psi - yaw
    qx, qy = v[:, None, None, None] - om[:, None, None, None] * ys, om[:, None, None, None] * xs
    rate = (-qx * np.sin(alpha) + qy * np.cos(alpha)) / es - om[:, None, None, None]
    return alpha, rate


def columns(t: np.ndarray, v: np.ndarray, om: np.ndarray, axle: float, trail: float) -> tuple[np.ndarray, float]:
    """Return (the caster columns (n, 2, 3) of one geometry along the whole grid (unfiltered), :func:`half_turns`)."""
    alpha, rate = lanes(t, v, om, (axle,), (trail,))
    return unit_rows(alpha[:, 0, 0], rate[:, 0, 0], v, om, axle, trail), half_turns(alpha[:, 0, 0])


def half_turns(alpha: np.ndarray) -> float:
    """Return how far the casters swivel along the log, in half-turns (pi) per caster: sum |d alpha| / (pi casters).

    Each step's change is wrapped to (-pi, pi]: ``alpha`` comes from ``2 atan2(p, q)`` of a projective pair and
    jumps by a whole turn when the pair changes sign, which is no swing.
    """
    step = np.angle(np.exp(1j * np.diff(alpha, axis=0)))
    return float(np.sum(np.abs(step)) / (math.pi * alpha.shape[-1]))

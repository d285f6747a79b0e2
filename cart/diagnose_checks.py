"""Checks of the diagnosis that are not effects: a physically consistent nominal fit, the no-slip test.

- :func:`constrained_fit`: when the nominal least-squares fit is not a cart (mass below
  ``MASS_MIN`` or a non-positive inertia about the CoM), the same weighted fit with the cart's
  parameters bounded (m >= ``MASS_MIN``, I about the CoM >= ``GYRATION_MIN``^2 m, both viscous
  coefficients >= 0). A real recording then gets an answer, with a warning, not a refusal.
- :func:`lateral_slip_ratio`: the sideways travel of the {b} origin per fit window against what
  the pose noise predicts. Well above 1, the no-slip constraint (paper eq. 3) is broken, and the
  model's other terms cannot stand in for that: ``lateral_slip`` is then named first.
- :func:`unexplained_slip`: the warning for a broken no-slip constraint that neither form of ``lateral_slip``
  explains (it was tried first and not named).
"""

from __future__ import annotations

import math

import numpy as np

from cart.effects import N_NOMINAL
from cart.errors import DiagnoseError
from cart.log_signals import Signals

#: Lightest cart the diagnosis accepts (kg); also the bound of the constrained nominal fit.
MASS_MIN = 0.5
#: Smallest radius of gyration about the CoM of the constrained nominal fit (m).
GYRATION_MIN = 0.02
#: Sideways travel of {b} per window this many times what the pose noise predicts (RMS) breaks no-slip.
SLIP_RATIO = 2.0


class WrenchFrameError(DiagnoseError):
    """The log's wrench is in the cart frame {b}, not in the world frame {s} that LOG_FORMAT requires."""


def cart_is_physical(x: np.ndarray) -> bool:
    """Return True for a possible cart: finite, m > MASS_MIN and a positive inertia about the CoM."""
    m, a, b, j = (float(u) for u in x[:4])
    return bool(np.all(np.isfinite(x)) and m > MASS_MIN and j - (a * a + b * b) / m > 0.0)


def _x_of(p: np.ndarray) -> np.ndarray:
    """Return x = [m, m dx, m dy, J, sigma, sigma_yaw, theta...] of p = [m, m dx, m dy, I about the CoM, ...].

    The entries after the first four (the dampings, an effect's parameters) are the same in both.
    """
    m, a, b, inertia = p[0], p[1], p[2], p[3]
    x = np.array(p, float)
    x[3] = inertia + (a * a + b * b) / m
    return x


def _jac_x(p: np.ndarray) -> np.ndarray:
    """Return dx/dp (P, P) of :func:`_x_of`."""
    m, a, b = p[0], p[1], p[2]
    jac = np.eye(len(p))
    jac[3, :4] = [-(a * a + b * b) / (m * m), 2.0 * a / m, 2.0 * b / m, 1.0]
    return jac


def _start(x: np.ndarray) -> np.ndarray:
    """Return a feasible start p for the bounded fit from an unconstrained x (an effect's parameters kept)."""
    m = max(float(x[0]), 2.0 * MASS_MIN)
    a, b = (float(x[1]), float(x[2])) if x[0] > MASS_MIN else (0.0, 0.0)
    inertia = float(x[3]) - (a * a + b * b) / m
    inertia = max(inertia, 4.0 * GYRATION_MIN**2 * m, 0.05 * m)
    p = np.array(x, float)
    p[:N_NOMINAL] = [m, a, b, inertia, max(float(x[4]), 0.0), max(float(x[5]), 0.0)]
    return p


#: how far inside the bounds a start is moved (relative): the barrier needs a strictly feasible one
_INSIDE = 1e-3


def _interior(x: np.ndarray, lo3: float) -> np.ndarray:
    """Return x moved strictly inside the bounds of :func:`bounded_least_squares` (m, I about the CoM, dampings)."""
    x = np.array(x, float)
    m = max(float(x[0]), MASS_MIN * (1.0 + _INSIDE))
    inertia = max(float(x[3]) - (x[1] ** 2 + x[2] ** 2) / m, lo3 * (1.0 + _INSIDE))
    x[0], x[3] = m, inertia + (x[1] ** 2 + x[2] ** 2) / m
    x[4:N_NOMINAL] = np.maximum(x[4:N_NOMINAL], _INSIDE)
    return x


def _slacks(x: np.ndarray, lo3: float) -> tuple[float, float, float, float]:
    """Return the slacks of the bounds: m - MASS_MIN, sigma, sigma_yaw, m (J - lo3) - (m dx)^2 - (m dy)^2."""
    m, a, b, j, s_1, s_2 = x[:6].tolist()
    return m - MASS_MIN, s_1, s_2, m * (j - lo3) - a * a - b * b


def _barrier_value(x: np.ndarray, lo3: float) -> float:
    """Return the log barrier of the bounds at x (inf outside): -sum log(slack) over :func:`_slacks`.

    I about the CoM >= lo3 is the rotated cone m (J - lo3) >= (m dx)^2 + (m dy)^2 (m > 0), whose
    barrier -log(m (J - lo3) - (m dx)^2 - (m dy)^2) is self-concordant (parameter 2); each of
    m >= MASS_MIN, sigma >= 0, sigma_yaw >= 0 adds -log(slack) (parameter 1).
    """
    m, a, b, j, s_1, s_2 = x[:6].tolist()  # the slacks of :func:`_slacks`, inline (the line searches' hot path)
    s_m, q = m - MASS_MIN, m * (j - lo3) - a * a - b * b
    if s_m <= 0.0 or s_1 <= 0.0 or s_2 <= 0.0 or q <= 0.0:
        return math.inf
    return -(math.log(s_m) + math.log(s_1) + math.log(s_2) + math.log(q))


def _barrier_derivatives(x: np.ndarray, lo3: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the gradient and Hessian of :func:`_barrier_value` at a feasible x."""
    n = len(x)
    grad, hess = np.zeros(n), np.zeros((n, n))
    m, a, b, j, s_1, s_2 = x[:6].tolist()  # the slacks of :func:`_slacks`, inline
    s_m, q = m - MASS_MIN, m * (j - lo3) - a * a - b * b
    dq = (j - lo3, -2.0 * a, -2.0 * b, m)
    qq = q * q
    outer = [[0.0 + dq[i] * dq[k] / qq for k in range(4)] for i in range(4)]  # as added to zeros
    outer[0][0] += 1.0 / (s_m * s_m)
    outer[0][3] -= 1.0 / q
    outer[3][0] -= 1.0 / q
    outer[1][1] += 2.0 / q
    outer[2][2] += 2.0 / q
    hess[:4, :4] = outer
    hess[4, 4], hess[5, 5] = 1.0 / (s_1 * s_1), 1.0 / (s_2 * s_2)
    grad[:6] = (-(1.0 / s_m) - dq[0] / q, 0.0 - dq[1] / q, 0.0 - dq[2] / q, 0.0 - dq[3] / q, -(1.0 / s_1), -(1.0 / s_2))
    return grad, hess


#: barrier parameter of :func:`_barrier` (three bounds and a cone of parameter 2)
_NU = 5.0


def _newton_step(
    r: np.ndarray,
    c: np.ndarray,
    x: np.ndarray,
    t: float,
    lo3: float,
    fixed: tuple[np.ndarray, np.ndarray],
    e: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """Return the Newton step of t ||c - r x||^2 + barrier at x and its Newton decrement.

    ``fixed``: (2 t r^T r, the ridge 1e-13 I), the same at every step of one centring; ``e``: c - r x when known.
    """
    from cart.small_linalg import solve_small  # lazy: scipy.linalg costs start-up; np.linalg.solve's numbers

    t_rtr, ridge = fixed
    g_b, h_b = _barrier_derivatives(x, lo3)
    grad = -2.0 * t * (r.T @ (c - r @ x if e is None else e)) + g_b
    hess = t_rtr + h_b
    scale = np.array([1.0 / math.sqrt(d) if d > 0.0 else 1.0 for d in hess.diagonal().tolist()])
    # the equilibrated system, a tiny ridge for columns without weight (an effect's column that is all zero)
    step = -scale * solve_small(hess * np.multiply.outer(scale, scale) + ridge, grad * scale)
    return step, math.sqrt(max(-float(grad @ step), 0.0))


def _damped(phi, x: np.ndarray, step: np.ndarray, lam: float, phi0: float) -> tuple[float, tuple | None]:
    """Return the step size that backtracking on the barrier function ``phi`` accepts, and ``phi`` there (None: not
    reached; ``phi`` returns its value and the residual).

    Halve from 1 while phi does not decrease by 0.25 size lam^2 from ``phi0`` = phi(x) (down to 1e-12).
    """
    size = 1.0
    while size > 1e-12:
        val = phi(x + size * step)
        if not val[0] > phi0 - 0.25 * size * lam * lam:
            return size, val
        size *= 0.5
    return size, None


def _stops(lam: float, lam_prev: float) -> bool:
    """Return True when a centring ends after a step of Newton decrement ``lam``: converged, or stalled at the
    rounding level of t ||c - r x||^2 (the decrement no longer halves)."""
    return lam < 1e-5 or (lam < 1e-2 and lam > 0.5 * lam_prev)


def _periodic_end(xs: list[np.ndarray], lams: list[float], m: int) -> np.ndarray:
    """Return the x a centring ends at once its iterate repeats: x after step i (the last of ``xs``) equals x after
    step m (``xs[m]``; 0: the start).

    Each Newton step is a function of x alone, so from there the iterates and their decrements repeat with period
    p = i - m; the steps left (to a stop by :func:`_stops` or to _MAX_NEWTON) are counted on the kept ones.
    """
    i = len(xs) - 1
    p = i - m
    lam_prev = lams[i]
    for j in range(i + 1, _MAX_NEWTON + 1):
        lam = lams[m + 1 + (j - m - 1) % p]  # the decrement of step j: that of x after step j - 1
        if _stops(lam, lam_prev):
            return xs[m + (j - m) % p]
        lam_prev = lam
    return xs[m + (_MAX_NEWTON - m) % p] if i < _MAX_NEWTON else xs[i]


def _centre(r: np.ndarray, c: np.ndarray, x: np.ndarray, t: float, lo3: float) -> np.ndarray:
    """Return the minimiser of t ||c - r x||^2 + barrier (Newton, backtracking while far, from a feasible x).

    At the rounding level the iterate may come back to a point it held before (often x + step == x): the
    centring then ends where those repeating steps would end it (:func:`_periodic_end`), without taking them.
    """

    def phi(u: np.ndarray) -> tuple[float, np.ndarray]:
        e = c - r @ u
        return t * float(e @ e) + _barrier_value(u, lo3), e

    lam_prev = math.inf
    fixed = (2.0 * t * (r.T @ r), 1e-13 * np.eye(len(x)))
    phi_x = None  # phi and the residual at x, when the backtracking has evaluated them there
    xs, lams, seen = [x], [math.nan], {x.tobytes(): 0}  # x after each step (0: the start), their decrements
    for i in range(1, _MAX_NEWTON + 1):
        step, lam = _newton_step(r, c, x, t, lo3, fixed, phi_x[1] if phi_x is not None else None)
        size, phi_new = 1.0, None
        if lam >= 0.25:  # damped phase: backtrack on the barrier function
            size, phi_new = _damped(phi, x, step, lam, (phi(x) if phi_x is None else phi_x)[0])
        x_new = x + size * step
        if phi_new is None or not math.isfinite(phi_new[0]):  # a finite phi is inside the bounds
            phi_new = None
            while size > 1e-12 and _barrier_value(x_new, lo3) == math.inf:
                size *= 0.5
                x_new = x + size * step
            if _barrier_value(x_new, lo3) == math.inf:
                break
        x, phi_x = x_new, phi_new
        if _stops(lam, lam_prev):
            break
        lam_prev = lam
        xs.append(x)
        lams.append(lam)
        m = seen.setdefault(x.tobytes(), i)
        if m != i:
            return _periodic_end(xs, lams, m)
    return x


#: Newton steps per centring at most (a few are typical; the first centring from a far start takes tens)
_MAX_NEWTON = 200
#: relative accuracy of the bounded fit's cost (the barrier's gap over the cost)
_GAP = 1e-14


def bounded_least_squares(r: np.ndarray, c: np.ndarray, x0: np.ndarray, lo3: float, rss0: float = 0.0) -> np.ndarray:
    """Return argmin ||c - r x||^2 with the cart bounded: m >= MASS_MIN, I about the CoM >= lo3, both dampings >= 0.

    x = [m, m dx, m dy, J, sigma, sigma_yaw, theta...] (J about {b}'s origin: I about the CoM =
    J - ((m dx)^2 + (m dy)^2) / m); theta free. ``r`` (P, P), ``c`` (P,): a least-squares problem
    ||b - A x||^2 reduced by A = Q r (QR), c = Q^T b; ``rss0`` = ||b||^2 - ||c||^2 sets the accuracy
    (the gap relative to the whole cost). The bounded set is convex (the inertia bound is a rotated
    second-order cone in x), so the minimiser is unique: the log-barrier (interior-point) method
    from x0 moved inside the bounds, the barrier's weight raised until its gap, _NU / t, is below
    _GAP of the cost.
    """
    x = _interior(np.asarray(x0, float), lo3)
    e = c - r @ x
    t = _NU / max(float(e @ e), 1e-300)
    for _ in range(40):
        x = _centre(r, c, x, t, lo3)
        e = c - r @ x
        if _NU / t <= _GAP * (float(e @ e) + rss0):
            break
        t *= 100.0
    return x


def constrained_fit(
    d: np.ndarray,
    y: np.ndarray,
    lv: np.ndarray,
    lw: np.ndarray,
    s2v: float,
    s2w: float,
    x0: np.ndarray,
    var_eq: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Return (x, equation variance per row, covariance, -2 log-likelihood) of the bounded fit.

    Rows as :func:`cart.diagnose._solve` (``d`` (n, 3, P) window columns: the nominal six, then any
    effect's, ``y`` (n, 3), noise loadings ``lv``, ``lw``); weights from the unconstrained fit's
    equation variances ``var_eq`` (3,) and the regressor noise at the current estimate, re-weighted
    twice. Bounds on the cart only: m >= MASS_MIN, I about the CoM >= GYRATION_MIN^2 m, sigma and
    sigma_yaw >= 0; an effect's parameters are free. The likelihood is computed as
    :func:`cart.diagnose._solve` computes it, so fits compare against it unchanged.
    """
    n_p = d.shape[-1]
    d2 = d.reshape(-1, n_p)
    y2 = y.reshape(-1)
    p = _start(np.asarray(x0, float))
    x = _x_of(p)
    var_e = np.maximum(np.asarray(var_eq, float), 1e-24)
    for _ in range(3):
        s_k = s2v * np.einsum("nrp,p->nr", lv, x) ** 2 + s2w * np.einsum("nrp,p->nr", lw, x) ** 2
        sw = 1.0 / np.sqrt(var_e[None, :] + s_k).reshape(-1)
        q, r = np.linalg.qr(d2 * sw[:, None])
        b = y2 * sw
        c = q.T @ b
        x = bounded_least_squares(r, c, x, GYRATION_MIN**2 * max(float(x[0]), MASS_MIN), float(b @ b - c @ c))
        r_w = y - np.einsum("nrp,p->nr", d, x)
        var_e = np.maximum(np.mean(r_w * r_w - s_k, axis=0), 0.05 * np.mean(r_w * r_w, axis=0) + 1e-24)
    s_k = s2v * np.einsum("nrp,p->nr", lv, x) ** 2 + s2w * np.einsum("nrp,p->nr", lw, x) ** 2
    r = y - np.einsum("nrp,p->nr", d, x)
    var = var_e[None, :] + s_k
    a = (d / np.sqrt(var)[..., None]).reshape(-1, n_p)
    cov = np.linalg.pinv(a.T @ a)
    m2ll = float(np.sum(np.log(var) + r * r / var))
    return x, var_e, cov, m2ll


def lateral_slip_ratio(sig: Signals, lateral: np.ndarray, edges: np.ndarray, keep: np.ndarray | None) -> float:
    """Return RMS sideways travel of {b} per window over the RMS the pose noise predicts (about 1 when eq. 3 holds).

    ``lateral``: the windows' sideways travel (:func:`cart.log_signals.lateral_displacements`). The
    noise of one window's travel: the lateral position noise at both ends, 2 sigma_pos^2, plus the
    smoothed heading's error times the distance travelled, (g0 sigma_theta L)^2.
    """
    e = np.asarray(edges)
    travel = np.hypot(sig.q_raw[e[1:], 0] - sig.q_raw[e[:-1], 0], sig.q_raw[e[1:], 1] - sig.q_raw[e[:-1], 1])
    var = 2.0 * sig.sigma_pos**2 + (sig.gain_value * sig.sigma_theta * travel) ** 2
    lat = np.asarray(lateral, float)
    if keep is not None:
        lat, var = lat[keep], var[keep]
    if len(lat) == 0:
        return float("nan")
    return math.sqrt(float(np.mean(lat * lat)) / max(float(np.mean(var)), 1e-30))


def unexplained_slip(slip_ratio: float, named: list[str], lateral_dbic: float | None) -> str:
    """Return a warning when {b} slides sideways (ratio above SLIP_RATIO) and ``lateral_slip`` was not named.

    ``lateral_slip`` has two forms: a creep (a sideways speed proportional to the lateral force the wheels
    carry, a compliant tyre) and sliding wheels (a friction-braked sideways speed, :mod:`cart.diagnose_slide`).
    Where neither is named (no significant or physical fit), the log's kinematics still show the broken
    constraint, and the report says so rather than leave the user with "nothing named". Empty when no such
    warning applies.
    """
    if not math.isfinite(slip_ratio) or slip_ratio <= SLIP_RATIO or "lateral_slip" in named:
        return ""
    why = f"Delta BIC {lateral_dbic:.1f}" if lateral_dbic is not None and math.isfinite(lateral_dbic) else "not ranked"
    return (
        f"the {{b}} origin slides sideways ({slip_ratio:.1f} x the travel the pose noise explains): the no-slip "
        f"constraint (eq. 3) does not hold, but neither form of lateral_slip (a creep: sideways speed "
        f"proportional to the wheels' lateral force; sliding wheels: a sideways speed braked by friction) "
        f"explains it ({why}): the sideways motion needs a model the effects do not list"
    )

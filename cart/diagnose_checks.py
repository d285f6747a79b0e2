"""Checks of the diagnosis that are not effects: a physically consistent nominal fit, the no-slip test.

- :func:`constrained_fit`: when the nominal least-squares fit is not a cart (mass below
  ``MASS_MIN`` or a non-positive inertia about the CoM), the same weighted fit with the cart's
  parameters bounded (m >= ``MASS_MIN``, I about the CoM >= ``GYRATION_MIN``^2 m, both viscous
  coefficients >= 0). A real recording then gets an answer, with a warning, not a refusal.
- :func:`lateral_slip_ratio`: the sideways travel of the {b} origin per fit window against what
  the pose noise predicts. Well above 1, the no-slip constraint (paper eq. 3) is broken, and the
  model's other terms cannot stand in for that: ``lateral_slip`` is then named first.
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
    from scipy import optimize  # lazy: scipy.optimize costs start-up time

    n_p = d.shape[-1]
    d2 = d.reshape(-1, n_p)
    y2 = y.reshape(-1)
    p = _start(np.asarray(x0, float))
    lo = np.full(n_p, -np.inf)
    lo[:N_NOMINAL] = [MASS_MIN, -np.inf, -np.inf, 0.0, 0.0, 0.0]
    var_e = np.maximum(np.asarray(var_eq, float), 1e-24)
    for _ in range(3):
        s_k = s2v * np.einsum("nrp,p->nr", lv, _x_of(p)) ** 2 + s2w * np.einsum("nrp,p->nr", lw, _x_of(p)) ** 2
        sw = 1.0 / np.sqrt(var_e[None, :] + s_k).reshape(-1)

        def res(u: np.ndarray, sw: np.ndarray = sw) -> np.ndarray:
            return (y2 - d2 @ _x_of(u)) * sw

        def jac(u: np.ndarray, sw: np.ndarray = sw) -> np.ndarray:
            return -(d2 @ _jac_x(u)) * sw[:, None]

        lo[3] = GYRATION_MIN**2 * max(p[0], MASS_MIN)
        p = np.maximum(p, lo + 1e-12)
        sol = optimize.least_squares(res, p, jac=jac, bounds=(lo, np.full(n_p, np.inf)), method="trf")
        p = sol.x
        r = y - np.einsum("nrp,p->nr", d, _x_of(p))
        var_e = np.maximum(np.mean(r * r - s_k, axis=0), 0.05 * np.mean(r * r, axis=0) + 1e-24)
    x = _x_of(p)
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

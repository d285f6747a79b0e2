"""Physically consistent cart parameters: the least-squares estimate constrained to a physical body.

The regression of paper eq. 4 is linear in ``p = [m, m dx, m dy, J, c_v, c_w]`` with
``J = I + m (dx^2 + dy^2)`` (paper §II.B), and nothing in it stops ``J`` falling below
``m (dx^2 + dy^2)`` (a negative inertia about the CoM) on a weakly excited log. In ``p`` the
physical bodies (``m > 0``, ``I > 0``; dampings ``c_v, c_w >= 0``) form a convex cone:
``m J - (m dx)^2 - (m dy)^2 >= 0`` is a rotated second-order cone, the planar case of the
positive-semidefinite pseudo-inertia of Wensing, Kim & Slotine (2018) that the log-Cholesky
parameterisation of Rucker & Wensing (2022) spans. :func:`constrained_fit` minimises the
least-squares cost ``(p - p_hat)^T W (p - p_hat)`` (``W`` the inverse covariance of the
unconstrained estimate) over that cone, in coordinates whitened by the covariance (an
interior-point trust-region method, ``scipy.optimize.minimize(method="trust-constr")``): the
problem is convex, so the minimum found is the global one however ill-conditioned ``W`` is (a cart
that never turns leaves the CoM and the yaw damping nearly collinear). :func:`p_of_u` maps the
log-Cholesky-style coordinates ``u = [log m, dx, dy, log I, c_v, c_w]`` to ``p``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np


def p_of_u(u: np.ndarray) -> np.ndarray:
    """Return p = [m, m dx, m dy, I + m(dx^2 + dy^2), c_v, c_w] of u = [log m, dx, dy, log I, c_v, c_w]."""
    m, dx, dy, inertia = math.exp(u[0]), u[1], u[2], math.exp(u[3])
    return np.array([m, m * dx, m * dy, inertia + m * (dx * dx + dy * dy), u[4], u[5]])


def _physical_margins(p: np.ndarray) -> np.ndarray:
    """Return [m J - (m dx)^2 - (m dy)^2, m, c_v, c_w]: all >= 0 for a physical body."""
    m, a, b, j, cv, cw = p
    return np.array([m * j - a * a - b * b, m, cv, cw])


def _margin_jacobian(p: np.ndarray) -> np.ndarray:
    """Return d(margins)/dp (4, 6)."""
    m, a, b, j = p[:4]
    jac = np.zeros((4, 6))
    jac[0, :4] = [j, -2.0 * a, -2.0 * b, m]
    jac[1, 0] = jac[2, 4] = jac[3, 5] = 1.0
    return jac


def _made_physical(p: np.ndarray, i_min: float) -> np.ndarray:
    """Return ``p`` with the mass and dampings at least 0 (mass > 0) and the inertia about the CoM at least i_min."""
    p = p.copy()
    p[0] = max(p[0], 1e-9)
    p[4], p[5] = max(p[4], 0.0), max(p[5], 0.0)
    inertia = p[3] - (p[1] ** 2 + p[2] ** 2) / p[0]
    if inertia < i_min:
        p[3] += i_min - inertia
    return p


def _usable_cov(cov: np.ndarray) -> np.ndarray:
    """Return the symmetrised ``cov`` with every parameter whose variance is not a finite number >= 0 (a column
    the log does not excite: a heading that never changes) made free: uncorrelated, with a variance 1e6 times
    the largest usable one (the closest physical point may move it at no cost)."""
    cov = np.asarray(cov, float)
    cov = 0.5 * (cov + cov.T)
    d = np.diag(cov)
    bad = ~np.isfinite(d) | (d < 0.0) | ~np.all(np.isfinite(cov), axis=1)
    if not bad.any():
        return cov
    cov = np.where(np.isfinite(cov), cov, 0.0)
    good = d[~bad]
    free = 1e6 * max(float(good.max()) if good.size else 1.0, 1e-12)
    cov[bad, :] = 0.0
    cov[:, bad] = 0.0
    cov[bad, bad] = free
    return cov


def constrained_fit(p_hat: np.ndarray, cov: np.ndarray, min_inertia_share: float = 1e-3) -> np.ndarray:
    """Return the physical p (m > 0, I about the CoM > 0, c_v, c_w >= 0) closest to ``p_hat`` in the metric of ``cov``.

    ``p_hat`` (6,): the unconstrained estimate with covariance ``cov`` (6, 6). A physical ``p_hat`` is
    returned unchanged. Otherwise ``p = p_hat + L z`` with ``L L^T = cov`` and ``|z|^2`` is minimised
    subject to the margins of :func:`_physical_margins`; the inertia about the CoM is then raised to at
    least ``min_inertia_share`` of the std of J (a boundary point, not exactly 0).
    """
    from scipy import optimize  # lazy: scipy.optimize costs start-up time

    p_hat = np.asarray(p_hat, float)
    margins = _physical_margins(p_hat)
    if margins[0] > 0 and margins[1] > 0 and min(margins[2:]) >= 0:
        return p_hat.copy()
    cov = _usable_cov(cov)
    lam, vec = np.linalg.eigh(cov)
    whiten = vec * np.sqrt(np.maximum(lam, max(float(lam.max()), 1e-300) * 1e-16))
    cons = optimize.NonlinearConstraint(
        lambda z: _physical_margins(p_hat + whiten @ z),
        0.0,
        np.inf,
        jac=lambda z: _margin_jacobian(p_hat + whiten @ z) @ whiten,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # trust-constr notes its own internal choices
        res = optimize.minimize(
            lambda z: float(z @ z),
            np.zeros(6),
            jac=lambda z: 2.0 * z,
            hess=lambda z: 2.0 * np.eye(6),
            method="trust-constr",
            constraints=[cons],
            options={"maxiter": 3000, "gtol": 1e-12, "xtol": 1e-14},
        )
    i_min = min_inertia_share * max(math.sqrt(max(cov[3, 3], 0.0)), 1e-9)
    return _made_physical(p_hat + whiten @ res.x, i_min)

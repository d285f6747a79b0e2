"""Physically consistent cart parameters: the least-squares estimate constrained to m > 0 and I > 0.

The regression of paper eq. 4 is linear in ``p = [m, m dx, m dy, J, c_v, c_w]`` with
``J = I + m (dx^2 + dy^2)`` (paper §II.B), and nothing in it stops ``J`` falling below
``m (dx^2 + dy^2)`` (a negative inertia about the CoM) on a weakly excited log. Like the
log-Cholesky parameterisation of rigid-body inertia (Rucker & Wensing 2022), the parameters are
written ``m = exp(u0)``, ``I = exp(u3)``, ``dx``, ``dy``, ``c_v``, ``c_w`` free, so every ``u`` is a
physical body; :func:`constrained_fit` minimises the least-squares cost ``(p(u) - p_hat)^T W
(p(u) - p_hat)`` (``W`` the inverse covariance of the unconstrained estimate) over ``u`` by
Levenberg-Marquardt. On a log whose estimate is already physical it returns it unchanged.
"""

from __future__ import annotations

import math

import numpy as np


def p_of_u(u: np.ndarray) -> np.ndarray:
    """Return p = [m, m dx, m dy, I + m(dx^2 + dy^2), c_v, c_w] of u = [log m, dx, dy, log I, c_v, c_w]."""
    m, dx, dy, inertia = math.exp(u[0]), u[1], u[2], math.exp(u[3])
    return np.array([m, m * dx, m * dy, inertia + m * (dx * dx + dy * dy), u[4], u[5]])


def _jacobian(u: np.ndarray) -> np.ndarray:
    """Return dp/du (6, 6)."""
    m, dx, dy, inertia = math.exp(u[0]), u[1], u[2], math.exp(u[3])
    jac = np.zeros((6, 6))
    jac[:, 0] = [m, m * dx, m * dy, m * (dx * dx + dy * dy), 0.0, 0.0]
    jac[1, 1], jac[3, 1] = m, 2.0 * m * dx
    jac[2, 2], jac[3, 2] = m, 2.0 * m * dy
    jac[3, 3] = inertia
    jac[4, 4] = jac[5, 5] = 1.0
    return jac


def constrained_fit(p_hat: np.ndarray, cov: np.ndarray, min_inertia_share: float = 1e-3) -> np.ndarray:
    """Return the physical p (m > 0, I about the CoM > 0) closest to ``p_hat`` in the metric of ``cov``.

    ``p_hat`` (6,): the unconstrained estimate with covariance ``cov`` (6, 6). Starts from p_hat with the
    mass and the CoM inertia raised to positive values (``min_inertia_share`` of J, at least).
    """
    p_hat = np.asarray(p_hat, float)
    w = np.linalg.pinv(cov)
    m0 = max(p_hat[0], 1e-3 * abs(p_hat[0]) + 1e-9)
    dx, dy = p_hat[1] / m0, p_hat[2] / m0
    i0 = max(p_hat[3] - m0 * (dx * dx + dy * dy), min_inertia_share * max(abs(p_hat[3]), 1e-9))
    u = np.array([math.log(m0), dx, dy, math.log(i0), p_hat[4], p_hat[5]])

    def cost(v: np.ndarray) -> float:
        d = p_of_u(v) - p_hat
        return float(d @ w @ d)

    lam, f = 1e-3, cost(u)
    for _ in range(100):
        jac = _jacobian(u)
        d = p_of_u(u) - p_hat
        h = jac.T @ w @ jac
        g = jac.T @ w @ d
        step = np.linalg.solve(h + lam * np.diag(np.diag(h) + 1e-12), -g)
        trial = u + step
        if np.all(np.abs(trial[[0, 3]]) < 700) and (f_new := cost(trial)) < f:
            u, f, lam = trial, f_new, lam * 0.3
            if np.max(np.abs(step)) < 1e-10:
                break
        else:
            lam *= 10.0
            if lam > 1e12:
                break
    return p_of_u(u)

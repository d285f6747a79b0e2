"""Constrained planar dynamics of a nonholonomic cart (paper §II.A, eq. 1-7).

Generalized coordinates ``q = (x, y, theta)`` of the {b} origin (fixed-axle
midpoint) in {s}; ``qd`` their rates; ``gamma = (fx, fy, tau)`` the generalized
force of the manipulator, force in {s}, torque about the {b} origin.

Every function taking ``params`` accepts a :class:`~cart.params.CartParams` or a
``phi`` array ``[m, m dx, m dy, J]`` (``J`` about the {b} origin; ``sigma`` is
then passed separately where it matters: a scalar for both viscous coefficients,
or the pair ``(sigma, sigma_yaw)``).

The fast body-frame form lives in :mod:`cart.dynamics` (the one cart-dynamics
core); the matrix form here is its cross-check and the paper's notation.

``forward_dynamics(..., exact=True)`` solves eq. (4) with the constraint kept at
acceleration level, ``Lambda qdd + Lambdadot qd = 0``; ``exact=False`` is the
paper's projected system (eq. 5-7), which leaves the ``Lambdadot qd`` term out
and lets the lateral speed of the {b} origin drift while the cart turns.

``extra_force`` (an additive generalized force, same convention as ``gamma``)
is the hook for effects the nominal model lacks (friction, slope, ...).
"""

from __future__ import annotations

import math

import numpy as np

from cart import dynamics
from cart.params import CartParams
from cart.small_linalg import solve_small

ParamsLike = CartParams | np.ndarray


def _phi(params: ParamsLike) -> np.ndarray:
    if isinstance(params, CartParams):
        return params.phi
    return np.asarray(params, dtype=float).reshape(4)


SigmaLike = float | tuple[float, float] | None


def damping_pair(params: ParamsLike, sigma: SigmaLike = None) -> tuple[float, float]:
    """Return (sigma, sigma_yaw): from ``sigma`` (scalar or pair) if given, else from ``params``."""
    if sigma is not None:
        if isinstance(sigma, (tuple, list, np.ndarray)):
            return float(sigma[0]), float(sigma[1])
        return float(sigma), float(sigma)
    return params.damping if isinstance(params, CartParams) else (0.0, 0.0)


def mass_matrix(q: np.ndarray, params: ParamsLike) -> np.ndarray:
    """Return the 3x3 mass matrix M(q) of paper eq. (4)."""
    m, a, b, j = _phi(params).tolist()  # floats: the same IEEE arithmetic as numpy scalars, faster
    s, c = math.sin(q[2]), math.cos(q[2])
    m13 = -(a * s + b * c)
    m23 = a * c - b * s
    return np.array([[m, 0.0, m13], [0.0, m, m23], [m13, m23, j]])


def coriolis_matrix(q: np.ndarray, qd: np.ndarray, params: ParamsLike) -> np.ndarray:
    """Return the 3x3 Coriolis matrix C(q, qd) of paper eq. (4)."""
    _, a, b, _ = _phi(params).tolist()
    s, c = math.sin(q[2]), math.cos(q[2])
    w = float(qd[2])
    return np.array([[0.0, 0.0, w * (b * s - a * c)], [0.0, 0.0, -w * (b * c + a * s)], [0.0, 0.0, 0.0]])


def damping_force(qd: np.ndarray, sigma: SigmaLike) -> np.ndarray:
    """Return the viscous generalized force N = diag(sigma, sigma, sigma_yaw) qd of paper eq. (4)."""
    sv, sw = damping_pair(np.zeros(4), sigma if sigma is not None else 0.0)
    qd = np.asarray(qd, dtype=float)
    return np.array([sv * qd[0], sv * qd[1], sw * qd[2]])


def constraint_matrix(q: np.ndarray) -> np.ndarray:
    """Return Lambda(q) = [-sin(theta), cos(theta), 0] (1x3), the no-lateral-slip constraint, paper eq. (3)."""
    return np.array([[-math.sin(q[2]), math.cos(q[2]), 0.0]])


def constraint_matrix_dot(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """Return d/dt Lambda(q) = theta_dot * [-cos(theta), -sin(theta), 0] (1x3)."""
    w = qd[2]
    return np.array([[-w * math.cos(q[2]), -w * math.sin(q[2]), 0.0]])


def lateral_speed(q: np.ndarray, qd: np.ndarray) -> float:
    """Return Lambda(q) qd, the lateral speed of the {b} origin (zero when the constraint holds)."""
    return -math.sin(q[2]) * qd[0] + math.cos(q[2]) * qd[1]


def projection(q: np.ndarray, params: ParamsLike) -> np.ndarray:
    """Return P_Lambda = I - Lambda^T (Lambda M^-1 Lambda^T)^-1 Lambda M^-1, paper eq. (5)."""
    mm = mass_matrix(q, params)
    lam = constraint_matrix(q)
    minv_lt = np.linalg.solve(mm, lam.T)
    return np.eye(3) - lam.T @ (lam @ np.linalg.solve(mm, np.eye(3))) / (lam @ minv_lt).item()


def contact_wrench_to_generalized(
    q: np.ndarray, point_b: np.ndarray, force_b: np.ndarray, torque: float = 0.0
) -> np.ndarray:
    """Return gamma = (fx, fy, tau) in {s} of a planar wrench applied at ``point_b`` (in {b}).

    ``force_b`` is the force in {b} axes, ``torque`` the moment about z at the
    contact point. The torque about the {b} origin adds ``p x f`` (paper eq. 23-24
    restricted to the plane).
    """
    s, c = math.sin(q[2]), math.cos(q[2])
    fx_b, fy_b = float(force_b[0]), float(force_b[1])
    px, py = float(point_b[0]), float(point_b[1])
    return np.array([c * fx_b - s * fy_b, s * fx_b + c * fy_b, torque + px * fy_b - py * fx_b])


def generalized_to_body(q: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Return (f_forward, f_lateral, tau) of gamma: its force in {b} axes and the torque about the {b} origin."""
    s, c = math.sin(q[2]), math.cos(q[2])
    return np.array([c * gamma[0] + s * gamma[1], -s * gamma[0] + c * gamma[1], gamma[2]])


def _free_rhs(
    q: np.ndarray,
    qd: np.ndarray,
    gamma: np.ndarray,
    params: ParamsLike,
    sigma: SigmaLike,
    extra_force: np.ndarray | None,
) -> np.ndarray:
    """Return gamma + extra_force - C qd - N: eq. (4)'s right-hand side without the constraint force."""
    rhs = (
        np.asarray(gamma, float) - coriolis_matrix(q, qd, params) @ qd - damping_force(qd, damping_pair(params, sigma))
    )
    return rhs if extra_force is None else rhs + np.asarray(extra_force, float)


def constraint_force(
    q: np.ndarray,
    qd: np.ndarray,
    gamma: np.ndarray,
    params: ParamsLike,
    sigma: SigmaLike = None,
    exact: bool = True,
    extra_force: np.ndarray | None = None,
) -> float:
    """Return the Lagrange multiplier lambda of eq. (4); the constraint force is -Lambda^T lambda.

    exact=True solves Lambda qdd + Lambdadot qd = 0; exact=False Lambda qdd = 0 (paper eq. 5-7).
    """
    return _multiplier(q, qd, mass_matrix(q, params), _free_rhs(q, qd, gamma, params, sigma, extra_force), exact)


def _multiplier(q: np.ndarray, qd: np.ndarray, mm: np.ndarray, rhs: np.ndarray, exact: bool) -> float:
    """Return `constraint_force`'s lambda from the mass matrix M(q) and the free right-hand side (`_free_rhs`)."""
    lam = constraint_matrix(q)
    minv_rhs = solve_small(mm, rhs)  # np.linalg.solve's LAPACK gesv: the same numbers
    minv_lt = solve_small(mm, lam.T)
    drift = (constraint_matrix_dot(q, qd) @ qd).item() if exact else 0.0
    return ((lam @ minv_rhs).item() + drift) / (lam @ minv_lt).item()


def forward_dynamics(
    q: np.ndarray,
    qd: np.ndarray,
    gamma: np.ndarray,
    params: ParamsLike,
    sigma: SigmaLike = None,
    exact: bool = True,
    extra_force: np.ndarray | None = None,
) -> np.ndarray:
    """Return qdd of the constrained cart, paper eq. (4) (exact) or eq. (5-7) (exact=False).

    M qdd + C qd = gamma + extra_force - N - Lambda^T lambda with lambda from
    :func:`constraint_force`.
    """
    q = np.asarray(q, float)
    qd = np.asarray(qd, float)
    mm = mass_matrix(q, params)
    rhs = _free_rhs(q, qd, gamma, params, sigma, extra_force)
    if not exact:
        return np.linalg.solve(mm, projection(q, params) @ rhs)  # paper eq. (7): M qdd = P (gamma - C qd - N)
    lam = _multiplier(q, qd, mm, rhs, True)  # constraint_force's, from the same M and right-hand side
    return solve_small(mm, rhs - constraint_matrix(q)[0] * lam)


def forward_dynamics_fast(
    theta: float,
    vx: float,
    vy: float,
    omega: float,
    fx: float,
    fy: float,
    tau: float,
    m: float,
    a: float,
    b: float,
    j: float,
    sigma: float,
    sigma_yaw: float | None = None,
) -> tuple[float, float, float]:
    """Return (xdd, ydd, thetadd) of the exact constrained dynamics, in plain floats.

    Same result as ``forward_dynamics(..., exact=True)``; :func:`cart.dynamics.forward_dynamics`
    with ``sigma_yaw = sigma`` unless given.
    """
    return dynamics.forward_dynamics(
        theta, vx, vy, omega, fx, fy, tau, m, a, b, j, sigma, sigma if sigma_yaw is None else sigma_yaw
    )

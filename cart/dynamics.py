"""The one cart-dynamics core: forward dynamics, inverse dynamics (the regressor) and their Jacobians.

Every part of the project that needs the cart's equations of motion imports
them from here (simulation, the EKF, the batch estimator, the controller).

Body-frame form of paper eq. (4) with the no-slip constraint (eq. 3) kept at
acceleration level. With ``v`` the forward and ``w`` the lateral speed of the
{b} origin, ``omega`` the yaw rate, ``a = m dx``, ``b = m dy``,
``J = I + m (dx^2 + dy^2)`` (the paper's ``phi = [m, a, b, J]``) and the
viscous coefficients ``c_v`` (forward/lateral, N s/m) and ``c_w`` (yaw,
N m s/rad; the paper's scalar sigma is ``c_v = c_w``)::

    [ m  -b ] [ vdot     ]   [ F_u - c_v v + a omega^2 + m omega w ]
    [ -b  J ] [ omegadot ] = [ tau - c_w omega - a omega v - b omega w ]

and ``wdot = 0`` (the wheels absorb the lateral force). ``F_u`` is the
forward force in {b}, ``tau`` the torque about the {b} origin.

On the constraint manifold (``w = 0``) the model is linear in the
parameter vector ``p = [m, a, b, J, c_v, c_w]``::

    Y(v, omega, vdot, omegadot) p = [F_u, tau],
    Y = [[vdot, -omega^2, -omegadot, 0,        v, 0    ],
         [0,     omega v, -vdot,      omegadot, 0, omega]]

which :func:`regressor` returns (the basis of least-squares identification).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

#: Names of the entries of the extended parameter vector p of :func:`regressor`.
PARAMETER_NAMES = ("m", "m_dx", "m_dy", "J", "c_v", "c_w")


def body_accelerations(v, omega, f_forward, tau, m, a, b, j, c_v, c_w, w_lat=0.0, min_det: float = 0.0):
    """Return (vdot, omegadot) of the body-frame form of paper eq. (4) (floats or numpy arrays, broadcast).

    ``f_forward`` and ``tau`` include every applied force (wrench, effects); ``w_lat`` is the
    lateral speed of the {b} origin (zero on the constraint). ``min_det > 0`` replaces a
    determinant m J - b^2 smaller in magnitude by ``min_det`` (for arrays of non-physical models).
    """
    r1 = f_forward - c_v * v + a * omega * omega + m * omega * w_lat
    r2 = tau - c_w * omega - a * omega * v - b * omega * w_lat
    det = m * j - b * b
    if min_det > 0.0:
        det = np.where(np.abs(det) < min_det, min_det, det)
    return (j * r1 + b * r2) / det, (b * r1 + m * r2) / det


def forward_dynamics(
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
    c_v: float,
    c_w: float,
) -> tuple[float, float, float]:
    """Return (xdd, ydd, thetadd) of the exact constrained dynamics (paper eq. 4), in plain floats.

    Velocities in {s}; (fx, fy) in {s}, tau about the {b} origin.
    """
    c, s = math.cos(theta), math.sin(theta)
    v = c * vx + s * vy
    w = -s * vx + c * vy
    vdot, odot = body_accelerations(v, omega, c * fx + s * fy, tau, m, a, b, j, c_v, c_w, w)
    u1 = vdot - omega * w
    u2 = omega * v
    return c * u1 - s * u2, s * u1 + c * u2, odot


def inverse_dynamics(
    v: float,
    omega: float,
    vdot: float,
    omegadot: float,
    m: float,
    a: float,
    b: float,
    j: float,
    c_v: float,
    c_w: float,
    w_lat: float = 0.0,
) -> tuple[float, float]:
    """Return (F_u, tau): the forward force in {b} and torque about {b} that produce (vdot, omegadot).

    The first two rows of the body-frame form of paper eq. (4), solved for the
    wrench; ``w_lat`` the lateral speed of the {b} origin (zero on the constraint).
    """
    fu = m * vdot - b * omegadot + c_v * v - a * omega * omega - m * omega * w_lat
    tau = -b * vdot + j * omegadot + c_w * omega + a * omega * v + b * omega * w_lat
    return fu, tau


def lateral_inertial_force(v, omega, omegadot, m, a, b):
    """Return m v omega + a omegadot - b omega^2: the lateral force (in {b}) the cart's motion needs on the constraint.

    The third row of the body-frame form of paper eq. (4); the wheels supply what the applied
    lateral force does not (the constraint force, -Lambda^T lambda).
    """
    return m * v * omega + a * omegadot - b * omega * omega


def regressor(v: np.ndarray, omega: np.ndarray, vdot: np.ndarray, omegadot: np.ndarray) -> np.ndarray:
    """Return Y (..., 2, 6) with Y p = [F_u, tau] for p = [m, m dx, m dy, J, c_v, c_w] (constraint w = 0)."""
    v, omega, vdot, omegadot = (np.asarray(u, dtype=float) for u in (v, omega, vdot, omegadot))
    z = np.zeros(np.broadcast(v, omega, vdot, omegadot).shape)
    y = np.zeros(z.shape + (2, 6))  # written in place: one pass over the rows, no stacked copies
    entries = {
        (0, 0): vdot, (0, 1): -omega * omega, (0, 2): -omegadot, (0, 4): v,
        (1, 1): omega * v, (1, 2): -vdot, (1, 3): omegadot, (1, 5): omega,
    }  # fmt: skip
    for (row, col), value in entries.items():
        np.add(value, z, out=y[..., row, col])  # + z: broadcast to the rows' shape
    return y


def wrench_input_matrix(theta: float, m: float, b: float, j: float) -> np.ndarray:
    """Return B = d(xdd, ydd, thetadd) / d(fx, fy, tau) (3 x 3) of :func:`forward_dynamics`.

    vdot = (J r1 + b r2) / D and omegadot = (b r1 + m r2) / D with D = m J - b^2,
    r1 = c fx + s fy + ..., r2 = tau + ...; the lateral force is absorbed by the wheels.
    """
    c, s = math.cos(theta), math.sin(theta)
    i_d = 1.0 / (m * j - b * b)
    dv = np.array([j * c, j * s, b]) * i_d
    do = np.array([b * c, b * s, m]) * i_d
    return np.array([c * dv, s * dv, do])


def dynamics_jacobian_rows(
    x: np.ndarray | list,
    gamma: Sequence[float] | np.ndarray,
    c_v: float,
    c_w: float,
    with_damping: bool,
    scale: float = 1.0,
    add_eye: bool = False,
) -> tuple[float, float, float, list[float]]:
    """Return (xdd, ydd, thetadd, rows): rows 3..5 of ``scale * F (+ I)`` as one flat list of floats.

    ``x = [x, y, theta, vx, vy, omega, m, a, b, J]`` (+ ``[c_v, c_w]`` when
    ``with_damping``, which then override the arguments); F = d f / d x is the
    analytic Jacobian of :func:`forward_dynamics` (paper eq. 11). With
    ``scale = dt`` and ``add_eye`` the rows are those of Phi = I + F dt (eq. 13).
    Straight-line formula code (one block per state column).
    """
    xs = x if isinstance(x, list) else x.tolist()
    th, vx, vy, om, m, a, b, j = xs[2:10]
    if with_damping:
        c_v, c_w = xs[10], xs[11]
    fx, fy, tau = (gamma.tolist() if isinstance(gamma, np.ndarray) else gamma)[:3]
    c, s = math.cos(th), math.sin(th)
    v = c * vx + s * vy
    w = -s * vx + c * vy
    fu = c * fx + s * fy
    fl = -s * fx + c * fy
    r1 = fu - c_v * v + a * om * om + m * om * w
    r2 = tau - c_w * om - a * om * v - b * om * w
    i_d = 1.0 / (m * j - b * b)
    vd = (j * r1 + b * r2) * i_d
    od = (b * r1 + m * r2) * i_d
    u1 = vd - om * w
    u2 = om * v
    xdd = c * u1 - s * u2
    ydd = s * u1 + c * u2
    cs, ss, i_s = c * scale, s * scale, i_d * scale
    xdd_s, ydd_s = xdd * scale, ydd * scale
    # theta
    dr1 = fl - c_v * w - m * om * v
    dr2 = -a * om * w + b * om * v
    dvd = (j * dr1 + b * dr2) * i_d
    d1 = dvd + om * v
    d2 = om * w
    f3_2 = cs * d1 - ss * d2 - ydd_s
    f4_2 = ss * d1 + cs * d2 + xdd_s
    f5_2 = (b * dr1 + m * dr2) * i_s
    # vx
    dr1 = -c_v * c - m * om * s
    dr2 = -a * om * c + b * om * s
    dvd = (j * dr1 + b * dr2) * i_d
    d1 = dvd + om * s
    d2 = om * c
    f3_3 = cs * d1 - ss * d2
    f4_3 = ss * d1 + cs * d2
    f5_3 = (b * dr1 + m * dr2) * i_s
    # vy
    dr1 = -c_v * s + m * om * c
    dr2 = -a * om * s - b * om * c
    dvd = (j * dr1 + b * dr2) * i_d
    d1 = dvd - om * c
    d2 = om * s
    f3_4 = cs * d1 - ss * d2
    f4_4 = ss * d1 + cs * d2
    f5_4 = (b * dr1 + m * dr2) * i_s
    # omega
    dr1 = 2.0 * a * om + m * w
    dr2 = -c_w - a * v - b * w
    dvd = (j * dr1 + b * dr2) * i_d
    d1 = dvd - w
    d2 = v
    f3_5 = cs * d1 - ss * d2
    f4_5 = ss * d1 + cs * d2
    f5_5 = (b * dr1 + m * dr2) * i_s
    # m
    dr1 = om * w
    dvd = (j * dr1 - vd * j) * i_d
    f3_6 = cs * dvd
    f4_6 = ss * dvd
    f5_6 = (b * dr1 + r2 - od * j) * i_s
    # a = m dx
    dr1 = om * om
    dr2 = -om * v
    dvd = (j * dr1 + b * dr2) * i_d
    f3_7 = cs * dvd
    f4_7 = ss * dvd
    f5_7 = (b * dr1 + m * dr2) * i_s
    # b = m dy
    dr2 = -om * w
    dvd = (r2 + b * dr2 + 2.0 * b * vd) * i_d
    f3_8 = cs * dvd
    f4_8 = ss * dvd
    f5_8 = (r1 + m * dr2 + 2.0 * b * od) * i_s
    # J
    dvd = (r1 - vd * m) * i_d
    f3_9 = cs * dvd
    f4_9 = ss * dvd
    f5_9 = -od * m * i_s
    if add_eye:  # Phi = I + F dt
        f3_3 += 1.0
        f4_4 += 1.0
        f5_5 += 1.0
    if with_damping:
        # c_v: dr1 = -v, dr2 = 0; c_w: dr1 = 0, dr2 = -omega
        dvd = -j * v * i_d
        f3_10, f4_10, f5_10 = cs * dvd, ss * dvd, -b * v * i_s
        dvd = -b * om * i_d
        f3_11, f4_11, f5_11 = cs * dvd, ss * dvd, -m * om * i_s
        return (
            xdd,
            ydd,
            od,
            [
                0.0,
                0.0,
                f3_2,
                f3_3,
                f3_4,
                f3_5,
                f3_6,
                f3_7,
                f3_8,
                f3_9,
                f3_10,
                f3_11,
                0.0,
                0.0,
                f4_2,
                f4_3,
                f4_4,
                f4_5,
                f4_6,
                f4_7,
                f4_8,
                f4_9,
                f4_10,
                f4_11,
                0.0,
                0.0,
                f5_2,
                f5_3,
                f5_4,
                f5_5,
                f5_6,
                f5_7,
                f5_8,
                f5_9,
                f5_10,
                f5_11,
            ],
        )
    return (
        xdd,
        ydd,
        od,
        [
            0.0,
            0.0,
            f3_2,
            f3_3,
            f3_4,
            f3_5,
            f3_6,
            f3_7,
            f3_8,
            f3_9,
            0.0,
            0.0,
            f4_2,
            f4_3,
            f4_4,
            f4_5,
            f4_6,
            f4_7,
            f4_8,
            f4_9,
            0.0,
            0.0,
            f5_2,
            f5_3,
            f5_4,
            f5_5,
            f5_6,
            f5_7,
            f5_8,
            f5_9,
        ],
    )

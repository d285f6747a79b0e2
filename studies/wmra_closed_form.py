"""The WMRA paper's closed forms written out with numpy only (WMRA paper eq. 1-21, docs/papers.md).

Independent of Pinocchio and of `wholebody.motion.kinematics`: used by the tests as the
reference, and as readable documentation of the paper's model. Units: metres, radians.
Coordinates: base pose ``(Px, Py, phi)`` of the wheelchair frame W (axle centre,
L5 above the floor), arm angles ``q`` (theta_i = q_i), wheels (left, right).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: D-H twists alpha_{i-1} of Table I (rad); all a_{i-1} = 0.
ALPHA = np.radians([-90, 90, -90, 90, -90, 90, -90])


def dh_transform(alpha: float, a: float, d: float, theta: float) -> np.ndarray:
    """Return the 4x4 modified D-H transform ^{i-1}_i T of paper eq. (1)."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -sa * d],
            [st * sa, ct * sa, ca, ca * d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def arm_frames(q: Sequence[float], d: Sequence[float]) -> list[np.ndarray]:
    """Return [^A_1 T, ^A_2 T, ..., ^A_7 T]: the running products of paper eq. (2)."""
    T = np.eye(4)
    out = []
    for i in range(7):
        T = T @ dh_transform(ALPHA[i], 0.0, d[i], q[i])
        out.append(T.copy())
    return out


def arm_fk(q: Sequence[float], d: Sequence[float]) -> np.ndarray:
    """Return ^A_E T = ^0_1 T ... ^6_7 T, paper eq. (2)."""
    return arm_frames(q, d)[-1]


def arm_jacobian(q: Sequence[float], d: Sequence[float]) -> np.ndarray:
    """Return J_E (6x7) of paper eq. (3): joint rates -> (v, omega) of the EE origin in frame A.

    Column i = [z_i x (p_E - p_i); z_i] (revolute joints about each D-H frame's z).
    """
    frames = arm_frames(q, d)
    pE = frames[-1][:3, 3]
    J = np.zeros((6, 7))
    for i, T in enumerate(frames):
        z, p = T[:3, 2], T[:3, 3]
        J[:3, i] = np.cross(z, pE - p)
        J[3:, i] = z
    return J


def odometry_step(dtheta_l: float, dtheta_r: float, L1: float, L5: float) -> np.ndarray:
    """Return ^{W0}_{W1} T of paper eq. (4)-(7) (straight-line limit R*sin -> arc when dphi = 0)."""
    arc = L5 * (dtheta_l + dtheta_r) / 2.0  # eq. (4)
    dphi = L5 * (dtheta_r - dtheta_l) / L1  # eq. (5)
    if dphi == 0.0:
        dx, dy = arc, 0.0
    else:
        R = arc / dphi  # eq. (6)
        dx, dy = R * np.sin(dphi), R - R * np.cos(dphi)
    c, s = np.cos(dphi), np.sin(dphi)
    return np.array([[c, -s, 0, dx], [s, c, 0, dy], [0, 0, 1, 0], [0, 0, 0, 1.0]])  # eq. (7)


def mount_transform(L2: float, L3: float, L4: float) -> np.ndarray:
    """Return ^W_A T, paper eq. (8)."""
    T = np.eye(4)
    T[:3, 3] = (L2, L3, L4)
    return T


def ground_to_wheelchair(Px: float, Py: float, phi: float, L5: float) -> np.ndarray:
    """Return ^G_W T, paper eq. (9)."""
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s, 0, Px], [s, c, 0, Py], [0, 0, 1, L5], [0, 0, 0, 1.0]])


def ground_to_ee(
    pose: Sequence[float], q: Sequence[float], d: Sequence[float], mount: Sequence[float], L5: float
) -> np.ndarray:
    """Return ^G_E T = ^G_W T ^W_A T ^A_E T, paper eq. (10) and (13)."""
    return ground_to_wheelchair(*pose, L5) @ mount_transform(*mount) @ arm_fk(q, d)


def J_whA(phi: float, L1: float, L2: float, L3: float, L5: float) -> np.ndarray:
    """Return the 3x2 J_whA of paper eq. (12): (theta_l_dot, theta_r_dot) -> (xA_dot, yA_dot, phiA_dot)."""
    c, s = np.cos(phi), np.sin(phi)
    k = 2.0 / L1
    return (
        L5
        / 2.0
        * np.array(
            [
                [c + k * (L2 * s + L3 * c), c - k * (L2 * s + L3 * c)],
                [s - k * (L2 * c - L3 * s), s + k * (L2 * c - L3 * s)],
                [-k, k],
            ]
        )
    )


def J_whA_6d(phi: float, L1: float, L2: float, L3: float, L5: float) -> np.ndarray:
    """Return the 6x2 J_whA^6D of paper eq. (15) (rows x, y, z, wx, wy, wz)."""
    J3 = J_whA(phi, L1, L2, L3, L5)
    J = np.zeros((6, 2))
    J[0:2] = J3[0:2]
    J[5] = J3[2]
    return J


def J_A_E(phi: float, PEx: float, PEy: float) -> np.ndarray:
    """Return the 6x6 J_A^E of paper eq. (16): twist at A -> twist at E for a base rotation about z."""
    c, s = np.cos(phi), np.sin(phi)
    J = np.eye(6)
    J[0, 5] = -(PEx * s + PEy * c)
    J[1, 5] = PEx * c - PEy * s
    return J


def J_E_G(phi: float, q: Sequence[float], d: Sequence[float]) -> np.ndarray:
    """Return J_E^G = diag(^G_A R, ^G_A R) J_E, paper eq. (17)-(18); ^G_A R = Rz(phi) (eq. 8-9)."""
    c, s = np.cos(phi), np.sin(phi)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    R6 = np.zeros((6, 6))
    R6[:3, :3] = R
    R6[3:, 3:] = R
    return R6 @ arm_jacobian(q, d)


def combined_jacobian(
    pose: Sequence[float], q: Sequence[float], d: Sequence[float], L1: float, mount: Sequence[float], L5: float
) -> np.ndarray:
    """Return J_G^E = [J_E^G, J_A^E J_whA^6D] (6x9), paper eq. (19)-(21); u = [q_dot (7), theta_l_dot, theta_r_dot]."""
    phi = pose[2]
    L2, L3, _ = mount
    PE = arm_fk(q, d)[:3, 3]  # P_Ex, P_Ey: EE position in frame A (eq. 16)
    return np.hstack([J_E_G(phi, q, d), J_A_E(phi, PE[0], PE[1]) @ J_whA_6d(phi, L1, L2, L3, L5)])

"""Wheeled mobile bases: wheel rates -> planar twist, nonholonomic constraints, exact odometry.

Planar pose ``(x, y, theta)`` in the world; body twist ``(vx, vy, wz)`` in the
base frame (x forward, z up). Wheel rates are in rad/s, wheel increments in rad.
Paper: the WMRA paper (docs/papers.md), eq. (4)-(12), (15).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from numba import njit

from wholebody.errors import WholeBodyError


def _rot2(theta: float) -> np.ndarray:
    """Return the 3x3 map from body twist (vx, vy, wz) to world rates (xdot, ydot, thetadot)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def planar_pose_matrix(x: float, y: float, theta: float) -> np.ndarray:
    """Return the 4x4 homogeneous transform of a planar pose (x, y, theta) on the floor (rotation about z)."""
    c, s = np.cos(theta), np.sin(theta)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = x, y
    return T


@njit(cache=True)
def se2_exp_factors(dphi: float) -> tuple[float, float]:
    """Return (sin(dphi)/dphi, (1 - cos(dphi))/dphi), continuous through dphi = 0 (series). Compiled (numba),
    so that `wholebody.motion.kernels` calls it from the state integration."""
    if abs(dphi) < 1e-4:
        d2 = dphi * dphi
        return 1.0 - d2 / 6.0 + d2 * d2 / 120.0, dphi / 2.0 - dphi * d2 / 24.0
    return math.sin(dphi) / dphi, (1.0 - math.cos(dphi)) / dphi


def integrate_body_displacement(
    pose: Sequence[float] | np.ndarray, body_step: Sequence[float] | np.ndarray
) -> np.ndarray:
    """Return the pose reached by moving with a constant body twist whose integral is `body_step`.

    Exact SE(2) exponential: paper eq. (7) for vy = 0 (R = arc/dphi, sin/cos terms),
    composed with the current pose, paper eq. (9)-(10).
    """
    x, y, th = (float(v) for v in pose)
    dx, dy, dphi = (float(v) for v in body_step)
    return np.array(displaced_pose(x, y, th, dx, dy, dphi))


@njit(cache=True)
def displaced_pose(x: float, y: float, th: float, dx: float, dy: float, dphi: float) -> tuple[float, float, float]:
    """`integrate_body_displacement` on floats: the pose (x, y, th) moved by the body step (dx, dy, dphi).
    Compiled (numba), callable from Python and from `wholebody.motion.kernels`."""
    a, b = se2_exp_factors(dphi)
    # displacement in the start frame W0 (paper eq. 7: R sin(dphi), R (1 - cos(dphi)) with R = arc / dphi)
    px = a * dx - b * dy
    py = b * dx + a * dy
    c, s = math.cos(th), math.sin(th)
    return x + c * px - s * py, y + s * px + c * py, th + dphi


class MobileBase:
    """Common interface of wheeled bases: wheel map, constraints, odometry."""

    wheel_radius: float
    holonomic: bool = False

    @property
    def n_wheels(self) -> int:
        """Return the number of driven wheels."""
        return self.wheel_to_body_twist().shape[1]

    def wheel_to_body_twist(self) -> np.ndarray:
        """Return the 3 x n_wheels map from wheel rates to the body twist (vx, vy, wz)."""
        raise NotImplementedError

    def twist_to_wheels(self) -> np.ndarray:
        """Return the n_wheels x 3 map from a body twist (vx, vy, wz) to wheel rates: pinv of `wheel_to_body_twist`."""
        return np.linalg.pinv(self.wheel_to_body_twist())

    def body_twist_to_wheels(self, twist: npt.ArrayLike) -> np.ndarray:
        """Return the wheel rates that produce a body twist (least squares for a nonholonomic base)."""
        return np.linalg.pinv(self.wheel_to_body_twist()) @ np.asarray(twist, dtype=float)

    def wheel_to_world_twist(self, theta: float) -> np.ndarray:
        """Return the 3 x n_wheels map from wheel rates to world rates (xdot, ydot, thetadot)."""
        return _rot2(theta) @ self.wheel_to_body_twist()

    def constraint_matrix(self, theta: float) -> np.ndarray:
        """Return A (k x 3) with A @ (xdot, ydot, thetadot) = 0 for every feasible base motion."""
        raise NotImplementedError

    def point_velocity_jacobian(self, theta: float, offset: Sequence[float] | np.ndarray) -> np.ndarray:
        """Return J (3 x n_wheels): wheel rates -> world (xdot, ydot, phidot) of a point at body `offset` (x, y).

        For the WMRA's arm mount A at (L2, L3) this is J_whA of paper eq. (12).
        """
        ox, oy = float(offset[0]), float(offset[1])
        c, s = np.cos(theta), np.sin(theta)
        shift = np.array([[1.0, 0.0, -(ox * s + oy * c)], [0.0, 1.0, ox * c - oy * s], [0.0, 0.0, 1.0]])
        return shift @ self.wheel_to_world_twist(theta)

    def point_velocity_jacobian_6d(self, theta: float, offset: Sequence[float] | np.ndarray) -> np.ndarray:
        """Return the 6 x n_wheels map wheel rates -> (v, omega) of a body point, paper eq. (15)."""
        j3 = self.point_velocity_jacobian(theta, offset)
        out = np.zeros((6, j3.shape[1]))
        out[0:2] = j3[0:2]
        out[5] = j3[2]
        return out

    def integrate(self, pose: Sequence[float] | np.ndarray, wheel_increments: npt.ArrayLike) -> np.ndarray:
        """Return the pose after wheel angle increments (rad), exact for constant rates (paper eq. 4-10)."""
        dq = np.asarray(wheel_increments, dtype=float)
        if dq.shape != (self.n_wheels,):
            raise WholeBodyError(f"expected {self.n_wheels} wheel increments, got shape {dq.shape}")
        return integrate_body_displacement(pose, self.wheel_to_body_twist() @ dq)

    def integrate_twist(self, pose: Sequence[float] | np.ndarray, body_twist: npt.ArrayLike, dt: float) -> np.ndarray:
        """Return the pose after applying a constant body twist for dt seconds (exact)."""
        return integrate_body_displacement(pose, np.asarray(body_twist, dtype=float) * dt)


@dataclass(frozen=True)
class DifferentialDrive(MobileBase):
    """Two driven wheels on one axle, wheel order (left, right); paper §II-B.

    Attributes:
        track: distance L1 between the wheel centres (m).
        wheel_radius: L5 (m).
    """

    track: float
    wheel_radius: float
    holonomic: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        if not (self.track > 0 and self.wheel_radius > 0):
            raise WholeBodyError(f"track ({self.track}) and wheel_radius ({self.wheel_radius}) must be positive (m)")

    def wheel_to_body_twist(self) -> np.ndarray:
        """Return the 3x2 map (theta_l_dot, theta_r_dot) -> (vx, 0, wz); paper eq. (4)-(5) per unit time."""
        r, L = self.wheel_radius, self.track
        return np.array([[r / 2, r / 2], [0.0, 0.0], [-r / L, r / L]])

    def constraint_matrix(self, theta: float) -> np.ndarray:
        """Return the 1x3 no-lateral-slip constraint (-sin th, cos th, 0)."""
        return np.array([[-np.sin(theta), np.cos(theta), 0.0]])


@dataclass(frozen=True)
class Omnidirectional(MobileBase):
    """Mecanum base (rollers at 45 deg), e.g. the Ridgeback; holonomic.

    Wheel i at body position (x_i, y_i) turns at
    ``w_i = (vx - y_i wz + s_i (vy + x_i wz)) / r`` with roller sign
    ``s_i = -sign(x_i y_i)`` (the usual X arrangement) unless given.

    Attributes:
        wheel_radius: r (m).
        wheel_positions: ((x_i, y_i), ...) in the base frame (m).
        roller_signs: s_i per wheel, or None for -sign(x_i y_i).
    """

    wheel_radius: float
    wheel_positions: tuple[tuple[float, float], ...]
    roller_signs: tuple[float, ...] | None = None
    holonomic: bool = field(default=True, init=False)

    def __post_init__(self) -> None:
        if not self.wheel_radius > 0:
            raise WholeBodyError(f"wheel_radius must be positive (m), got {self.wheel_radius}")
        if len(self.wheel_positions) < 3:
            raise WholeBodyError("an omnidirectional base needs at least 3 wheels")
        if np.linalg.matrix_rank(self.twist_to_wheels()) < 3:
            raise WholeBodyError("wheel layout does not span the planar twists (rank < 3)")

    def signs(self) -> np.ndarray:
        """Return the roller sign s_i of every wheel."""
        if self.roller_signs is not None:
            return np.asarray(self.roller_signs, dtype=float)
        return np.array([-np.sign(x * y) or 1.0 for x, y in self.wheel_positions])

    def twist_to_wheels(self) -> np.ndarray:
        """Return H (n x 3): body twist (vx, vy, wz) -> wheel rates (mecanum inverse kinematics)."""
        s = self.signs()
        rows = [[1.0, si, -y + si * x] for (x, y), si in zip(self.wheel_positions, s)]
        return np.asarray(rows) / self.wheel_radius

    def wheel_to_body_twist(self) -> np.ndarray:
        """Return pinv(H) (3 x n): wheel rates -> body twist (least squares over roller slip)."""
        return np.linalg.pinv(self.twist_to_wheels())

    def body_twist_to_wheels(self, twist: npt.ArrayLike) -> np.ndarray:
        """Return the wheel rates of a body twist (exact for a mecanum base)."""
        return self.twist_to_wheels() @ np.asarray(twist, dtype=float)

    def constraint_matrix(self, theta: float) -> np.ndarray:
        """Return an empty 0x3 matrix: an omnidirectional base has no velocity constraint."""
        return np.zeros((0, 3))

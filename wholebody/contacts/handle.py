"""Contact frames on the cart handle and the grasp map (paper §II.C, eqs. 21–25).

Frames (see docs/log_format.md): {b} is the cart frame (origin at the
fixed-axle midpoint, x forward, z up); a contact frame {a} has the orientation
of {b} and its origin at the contact point ``p`` (coordinates in {b}).

An end-effector wrench is the 6-vector ``[f; tau]`` (eq. 21) the hand applies
to the cart at the contact point, expressed in {a}. The cart wrench
``Gamma_MM = (fx, fy, tau)`` is planar, in {b}, with the torque about the {b}
origin. The paper's grasp map ``G = Ad_{g_ab}^T B_a`` (eq. 23) is 6x3: it maps
the planar part of an end-effector wrench to a spatial wrench at {b}. The
allocation works with the transposed view, the 3x6 *planar grasp map*
``B_a^T Ad_{g_ab}^T`` that takes a full end-effector wrench to
``Gamma_MM`` (eq. 24): the out-of-plane rows (fz, tau_x, tau_y) are carried by
the floor because the cart neither lifts nor tilts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from wholebody.errors import WholeBodyError

#: Default handle of the shopping cart, in {b} (the lead's URDF agrees with these).
HANDLE_X_B = -0.15  # m, behind the fixed axle
HANDLE_Z_B = 0.9365  # m, 1.0 m above the floor; {b} sits at the rear axle height 0.0635 m
HANDLE_WIDTH = 0.50  # m, centred on y = 0


def skew(p: Sequence[float] | np.ndarray) -> np.ndarray:
    """Return the 3x3 skew-symmetric matrix [p]_x with [p]_x v = p x v."""
    x, y, z = (float(v) for v in p)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def wrench_basis() -> np.ndarray:
    """Return the paper's wrench basis B_a (6x3): selects (fx, fy, tau_z) of [f; tau]."""
    basis = np.zeros((6, 3))  # paper eq. (22)
    basis[0, 0] = basis[1, 1] = basis[5, 2] = 1.0
    return basis


def adjoint(rotation: npt.ArrayLike, translation: Sequence[float] | np.ndarray) -> np.ndarray:
    """Return Ad_g = [[R, [p]x R], [0, R]] (6x6) of g = (p, R) (paper eq. 23)."""
    R = np.asarray(rotation, dtype=float)
    out = np.zeros((6, 6))
    out[:3, :3] = R
    out[:3, 3:] = skew(translation) @ R
    out[3:, 3:] = R
    return out


def wrench_to_b(point_b: npt.ArrayLike) -> np.ndarray:
    """Return Ad_{g_ab}^T (6x6): maps a wrench [f; tau] at {a} to the same wrench at {b}.

    ``g_ab`` is the pose of {b} seen from {a}: R = I, p = -point_b, so the
    result is [[I, 0], [[point_b]x, I]], i.e. tau_b = tau_a + point_b x f.
    """
    return adjoint(np.eye(3), -np.asarray(point_b, dtype=float)).T  # paper eq. (23)


def grasp_map_paper(point_b: npt.ArrayLike) -> np.ndarray:
    """Return the paper's grasp map G = Ad_{g_ab}^T B_a (6x3, eq. 23) for a contact at point_b."""
    return wrench_to_b(point_b) @ wrench_basis()


def grasp_matrices(points_b: np.ndarray) -> np.ndarray:
    """Return [G_1 ... G_N] (..., 3, 6N) for contact points (..., N, 3): a batch of eq. 25 grasp matrices.

    Rows are (fx_b, fy_b, tau_b about the {b} origin); each 3x6 block equals B_a^T Ad_{g_ab}^T (eqs. 23–24).
    """
    p = np.asarray(points_b, dtype=float)
    n = p.shape[-2]
    G = np.zeros(p.shape[:-2] + (3, 6 * n))
    G[..., 0, 0::6] = 1.0
    G[..., 1, 1::6] = 1.0
    G[..., 2, 0::6] = -p[..., 1]  # (p x f)_z = px fy - py fx
    G[..., 2, 1::6] = p[..., 0]
    G[..., 2, 5::6] = 1.0
    return G


def grasp_map(point_b: npt.ArrayLike) -> np.ndarray:
    """Return the planar grasp map (3x6): Gamma_MM = G @ [f; tau]_a (paper eqs. 23–24).

    Rows are (fx_b, fy_b, tau_b about the {b} origin); equals B_a^T Ad_{g_ab}^T.
    """
    return grasp_matrices(np.reshape(np.asarray(point_b, dtype=float), (1, 3)))


def grasp_matrix(points_b: Sequence[Sequence[float]] | np.ndarray) -> np.ndarray:
    """Return [G_1 ... G_N] (3 x 6N): Gamma_MM = sum_i G_i Gamma_ee,i (paper eq. 25)."""
    return grasp_matrices(np.reshape(np.asarray(points_b, dtype=float), (-1, 3))) if len(points_b) else np.zeros((3, 0))


def cart_wrench(points_b: Sequence[Sequence[float]] | np.ndarray, wrenches_ee: npt.ArrayLike) -> np.ndarray:
    """Return Gamma_MM (3,) produced by end-effector wrenches (N x 6) at points_b (eq. 25)."""
    w = np.asarray(wrenches_ee, dtype=float).reshape(len(points_b), 6)
    return grasp_matrix(points_b) @ w.reshape(-1)


@dataclass(frozen=True)
class ContactSpec:
    """One end effector's contact: point in {b} (frame {a} is oriented like {b})."""

    point_b: tuple[float, float, float]
    name: str = ""

    def __post_init__(self) -> None:
        p = tuple(float(v) for v in self.point_b)
        if len(p) != 3 or not all(np.isfinite(p)):
            raise WholeBodyError(f"contact point must be 3 finite numbers, got {self.point_b!r}")
        object.__setattr__(self, "point_b", p)


@dataclass(frozen=True)
class HandleSegment:
    """A straight handle between two points of {b}; contacts are points on it.

    The curvilinear coordinate ``s`` runs from 0 at ``start_b`` to ``length``
    at ``end_b``. ``HandleSegment.default()`` is the shopping cart's handle.
    """

    start_b: tuple[float, float, float]
    end_b: tuple[float, float, float]
    _dir: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        a = np.asarray(self.start_b, dtype=float)
        b = np.asarray(self.end_b, dtype=float)
        if a.shape != (3,) or b.shape != (3,) or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            raise WholeBodyError("handle end points must be 3 finite numbers each")
        if np.linalg.norm(b - a) <= 0.0:
            raise WholeBodyError("handle segment has zero length")
        object.__setattr__(self, "start_b", tuple(a))
        object.__setattr__(self, "end_b", tuple(b))
        object.__setattr__(self, "_dir", (b - a) / np.linalg.norm(b - a))

    @classmethod
    def default(cls, width: float = HANDLE_WIDTH, x_b: float = HANDLE_X_B, z_b: float = HANDLE_Z_B) -> HandleSegment:
        """Return the shopping-cart handle: a bar along y_b of `width`, centred on y = 0."""
        if not (np.isfinite(width) and width > 0.0):
            raise WholeBodyError(f"handle width must be positive, got {width}")
        return cls((x_b, -width / 2.0, z_b), (x_b, width / 2.0, z_b))

    @property
    def length(self) -> float:
        """Return the segment length in metres."""
        return float(np.linalg.norm(np.subtract(self.end_b, self.start_b)))

    @property
    def direction(self) -> np.ndarray:
        """Return the unit vector from start_b to end_b."""
        return self._dir.copy()

    def point(self, s: float) -> np.ndarray:
        """Return the point of {b} at curvilinear coordinate s (0 <= s <= length)."""
        if not (-1e-12 <= s <= self.length + 1e-12):
            raise WholeBodyError(f"s = {s} is outside the handle [0, {self.length}]")
        return np.asarray(self.start_b) + float(s) * self._dir

    def coordinate(self, point_b: npt.ArrayLike) -> float:
        """Return s of the projection of point_b onto the segment's line."""
        return float(np.dot(np.asarray(point_b, dtype=float) - np.asarray(self.start_b), self._dir))


#: spacing (m) of the contact candidates along the handle when one arm pushes (two arms: twice as coarse)
CONTACT_GRID_STEP = 0.025


def contact_grid(step: float = CONTACT_GRID_STEP, width: float = HANDLE_WIDTH) -> np.ndarray:
    """Return the contact candidates y (m, in {b}) along the default handle, from -width/2 to +width/2 by `step`."""
    if not (step > 0.0 and width > 0.0):
        raise WholeBodyError(f"contact grid step and handle width must be positive, got {step}, {width}")
    half = width / 2.0
    return np.round(np.arange(-half, half + 1e-4, step), 6)

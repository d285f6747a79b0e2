"""Tracking controllers for the cart, using the (estimated) model parameters.

- :class:`FeedbackLinearizationLQR`: the paper's feedback linearization with an
  LQR on the error system (paper eq. 26-28). It treats the three coordinates as
  actuated; the lateral part of its gamma is absorbed by the wheels, so it
  cannot remove a lateral error directly.
- :class:`KanayamaTracker`: the kinematic tracking law of Kanayama, Kimura,
  Miyazaki and Noguchi, "A stable tracking control method for an autonomous
  mobile robot", ICRA 1990 (lateral error corrected through the heading),
  extended to forces by computed torque on the cart's reduced dynamics
  (backstepping as in Fierro and Lewis, "Control of a nonholonomic mobile
  robot: backstepping kinematics into dynamics", J. Robotic Systems 1997).

Both implement ``gamma(t, q, qd, params) -> (fx, fy, tau)`` and are selected by
name with :func:`make_controller` (``"fl_lqr"`` or ``"kanayama"``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.linalg

from cart import model
from cart.dynamics import inverse_dynamics
from cart.errors import CartError
from cart.params import CartParams
from cart.trajectories import CartTrajectory

#: Names of the cart tracking laws of :func:`make_controller`.
ControllerName = Literal["fl_lqr", "kanayama"]
CONTROLLERS: tuple[ControllerName, ...] = ("fl_lqr", "kanayama")


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def care_hamiltonian(a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Return the stabilising solution X of A^T X + X A - X B R^-1 B^T X + Q = 0.

    Eigenvector method (MacFarlane 1963, Potter 1966): with the Hamiltonian
    Z = [[A, -B R^-1 B^T], [-Q, -A^T]] and U = [U1; U2] spanning its stable
    eigenspace, X = U2 U1^-1. Only numpy calls on a 2n x 2n matrix: for the
    6-state error system this is ~20x faster than scipy's Schur/QZ-based
    solve_continuous_are (whose small LAPACK calls are slow on a loaded
    multi-threaded BLAS) and agrees with it to ~1e-12. Falls back to scipy when
    the stable eigenspace is not found cleanly (eigenvalues near the imaginary
    axis, complex or inaccurate X: the Riccati residual is checked).
    """
    n = a.shape[0]
    g = b @ np.linalg.solve(r, b.T)
    z = np.block([[a, -g], [-q, -a.T]])
    w, v = np.linalg.eig(z)
    stable = w.real < 0.0
    margin = 1e-6 * max(1.0, float(np.abs(w).max()))
    if int(stable.sum()) == n and float(np.abs(w.real).min()) > margin:  # none near the imaginary axis
        u = v[:, stable]
        try:
            x = np.linalg.solve(u[:n].T, u[n:].T).T
        except np.linalg.LinAlgError:
            x = None
        if x is not None and np.abs(x.imag).max() <= 1e-8 * max(1.0, np.abs(x.real).max()):
            x = x.real
            x = 0.5 * (x + x.T)
            residual = a.T @ x + x @ a - x @ g @ x + q
            scale = np.abs(q).max() + 2.0 * np.abs(a).max() * np.abs(x).max() + np.abs(x @ g @ x).max()
            if np.abs(residual).max() <= 1e-9 * scale:
                return x
    return scipy.linalg.solve_continuous_are(a, b, q, r)


def lqr_gain(
    mass: np.ndarray, coriolis: np.ndarray, alpha: np.ndarray, q_weight: np.ndarray, r_weight: np.ndarray
) -> np.ndarray:
    """Return K (3x6) of the LQR on the error system z = [e, r] of paper eq. (28), u = -K z."""
    minv = np.linalg.inv(mass)
    a = np.zeros((6, 6))
    a[:3, :3] = -alpha
    a[:3, 3:] = np.eye(3)
    a[3:, 3:] = -minv @ coriolis
    b = np.zeros((6, 3))
    b[3:, :] = minv
    p = care_hamiltonian(a, b, q_weight, r_weight)
    return np.linalg.solve(r_weight, b.T @ p)


@dataclass
class FeedbackLinearizationLQR:
    """Paper eq. (26-28): gamma = M(qdd_d + alpha edot) + C(qd_d + alpha e) + N - u, u = -K [e; r].

    K is recomputed every ``gain_period`` seconds from the current M, C (estimated parameters).
    """

    trajectory: CartTrajectory
    alpha: float = 2.0
    q_e: float = 400.0
    q_r: float = 20.0
    r_u: float = 0.01
    gain_period: float = 0.5

    def __post_init__(self) -> None:
        self._k: np.ndarray | None = None
        self._k_time = -math.inf

    def gamma(self, t: float, q: np.ndarray, qd: np.ndarray, params: CartParams) -> np.ndarray:
        """Return the generalized force (fx, fy, tau) of paper eq. (26)."""
        q_d, qd_d, qdd_d = self.trajectory.sample(t)
        e = q_d - q
        e[2] = _wrap(e[2])
        edot = qd_d - qd
        r = edot + self.alpha * e
        phi = params.phi  # once per step (mass and Coriolis matrices)
        mm = model.mass_matrix(q, phi)
        cc = model.coriolis_matrix(q, qd, phi)
        if self._k is None or t - self._k_time >= self.gain_period - 1e-9:
            eye = np.eye(3)
            qw = np.diag([self.q_e] * 3 + [self.q_r] * 3)
            self._k = lqr_gain(mm, cc, self.alpha * eye, qw, self.r_u * eye)
            self._k_time = t
        u = -self._k @ np.concatenate([e, r])
        return (
            mm @ (qdd_d + self.alpha * edot)
            + cc @ (qd_d + self.alpha * e)
            + model.damping_force(qd, params.damping)
            - u
        )  # paper eq. (26)


@dataclass
class KanayamaTracker:
    """Kanayama et al. (1990) velocity law + computed-torque dynamic extension (Fierro & Lewis 1997).

    v_c = v_r cos e_th + k_x e_x, w_c = w_r + v_r (k_y e_y + k_th sin e_th) with
    the errors in the cart frame; forces from the reduced dynamics so that
    vdot = vdot_r + k_v (v_c - v), wdot = wdot_r + k_w (w_c - w).
    """

    trajectory: CartTrajectory
    k_x: float = 3.0
    k_y: float = 12.0
    k_th: float = 5.0
    k_v: float = 6.0
    k_w: float = 10.0

    def gamma(self, t: float, q: np.ndarray, qd: np.ndarray, params: CartParams) -> np.ndarray:
        """Return the generalized force (fx, fy, tau) realising the commanded accelerations."""
        q_d, qd_d, qdd_d = self.trajectory.sample(t)
        th = q[2]
        c, s = math.cos(th), math.sin(th)
        dxw, dyw = q_d[0] - q[0], q_d[1] - q[1]
        e_x = c * dxw + s * dyw
        e_y = -s * dxw + c * dyw
        e_th = _wrap(q_d[2] - th)
        cd, sd = math.cos(q_d[2]), math.sin(q_d[2])
        v_r = cd * qd_d[0] + sd * qd_d[1]
        w_r = qd_d[2]
        vdot_r = cd * qdd_d[0] + sd * qdd_d[1]
        wdot_r = qdd_d[2]
        v_c = v_r * math.cos(e_th) + self.k_x * e_x
        w_c = w_r + v_r * (self.k_y * e_y + self.k_th * math.sin(e_th))
        v = c * qd[0] + s * qd[1]
        w_lat = -s * qd[0] + c * qd[1]
        om = qd[2]
        vdot = vdot_r + self.k_v * (v_c - v)
        odot = wdot_r + self.k_w * (w_c - om)
        m, a, b, j = params.phi
        c_v, c_w = params.damping
        fu, tau = inverse_dynamics(v, om, vdot, odot, m, a, b, j, c_v, c_w, w_lat=w_lat)
        return np.array([c * fu, s * fu, tau])


def make_controller(
    name: ControllerName, trajectory: CartTrajectory, **gains
) -> FeedbackLinearizationLQR | KanayamaTracker:
    """Return the controller called ``name`` ("fl_lqr" or "kanayama") for ``trajectory``."""
    if name == "fl_lqr":
        return FeedbackLinearizationLQR(trajectory, **gains)
    if name == "kanayama":
        return KanayamaTracker(trajectory, **gains)
    raise CartError(f"unknown controller {name!r}; choose one of {', '.join(CONTROLLERS)}")

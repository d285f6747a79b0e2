"""Compiled inner loops of the resolved-rate QP (numba, cached on disk).

Each function is the one implementation of its formula: the built-in `Task`s and `Limit`s
(`wholebody.motion.tasks`, `wholebody.motion.limits`) and `solve_step` call them on the step's small
arrays (n_u <= ~20), where one compiled loop replaces several numpy calls. The first step of a process
loads the machine code from numba's cache (`cache=True`, 0.2 s), or compiles it when there is none (about 3 s,
once per installation; `benchmarks/bench_wholebody.py` times both). The callers check the arrays' shapes and
the kernels are compiled with bounds checking: an index out of range raises `IndexError`, never reads past an
array.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from wholebody.motion.bases import displaced_pose


@njit(cache=True, boundscheck=True)
def add_weighted_gram(J: np.ndarray, w: np.ndarray, v: np.ndarray, H: np.ndarray, c: np.ndarray) -> None:
    """H += J^T W J and c -= J^T W v in place, W = diag(w): the cost w||J u - v||^2 (factor 1/2 of the QP)."""
    m, n = J.shape
    for i in range(n):
        s = 0.0
        for k in range(m):
            s += J[k, i] * w[k] * v[k]
        c[i] -= s
        for j in range(i, n):
            s = 0.0
            for k in range(m):
                s += J[k, i] * w[k] * J[k, j]
            H[i, j] += s
            if j != i:
                H[j, i] += s


@njit(cache=True, boundscheck=True)
def add_scaled_difference(c: np.ndarray, scale: float, target: np.ndarray, x: np.ndarray, offset: int) -> None:
    """c[i] += scale (target[i] - x[offset + i]) for i < len(target), in place."""
    for i in range(target.shape[0]):
        c[i] += scale * (target[i] - x[offset + i])


@njit(cache=True, boundscheck=True)
def intersect_position_box(
    lower: np.ndarray, upper: np.ndarray, x: np.ndarray, offset: int, dt: float, lb: np.ndarray, ub: np.ndarray
) -> None:
    """Intersect lb[:n], ub[:n] in place with the rates reaching [lower, upper] from x[offset:] in dt,
    each widened to contain 0."""
    for i in range(lower.shape[0]):
        lo = (lower[i] - x[offset + i]) / dt
        if not lo < 0.0:
            lo = 0.0
        if lo > lb[i]:
            lb[i] = lo
        hi = (upper[i] - x[offset + i]) / dt
        if not hi > 0.0:
            hi = 0.0
        if hi < ub[i]:
            ub[i] = hi


@njit(cache=True, boundscheck=True)
def clip_to_box(u: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> None:
    """u = min(max(u, lb), ub) in place."""
    for i in range(u.shape[0]):
        if u[i] < lb[i]:
            u[i] = lb[i]
        if u[i] > ub[i]:
            u[i] = ub[i]


@njit(cache=True, boundscheck=True)
def residual_norm(J: np.ndarray, u: np.ndarray, v: np.ndarray) -> float:
    """Return ||J u - v||."""
    m, n = J.shape
    r = 0.0
    for k in range(m):
        s = 0.0
        for i in range(n):
            s += J[k, i] * u[i]
        r += (s - v[k]) ** 2
    return math.sqrt(r)


@njit(cache=True, boundscheck=True)
def reference_twist(
    e: np.ndarray, gain: float, v_des: np.ndarray, linear: float, angular: float
) -> tuple[np.ndarray, float, float]:
    """Return (v_ref, |e[:3]|, |e[3:]|): v_ref = gain e + v_des (6,) with its linear and angular halves scaled
    down to norms <= the limits, and the norms of the pose error's halves."""
    v = np.empty(6)
    for i in range(6):
        v[i] = gain * e[i] + v_des[i]
    for start, limit in ((0, linear), (3, angular)):
        norm = math.sqrt(v[start] * v[start] + v[start + 1] * v[start + 1] + v[start + 2] * v[start + 2])
        if norm > limit:
            for i in range(start, start + 3):
                v[i] *= limit / norm
    e_lin = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
    e_ang = math.sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5])
    return v, e_lin, e_ang


@njit(cache=True, boundscheck=True)
def cholesky_solve(S: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, bool]:
    """Return (x, True) with S x = b for a symmetric positive definite S (its lower triangle is read), or
    (x, False) if S is not positive definite (or holds NaN).

    A Cholesky factorisation S = L L^T written out as loops: at the sizes solved here (n <= ~20) it costs less than
    a LAPACK call from Python, and compiles in a fraction of the time numba takes for `np.linalg.solve`.
    """
    n = b.shape[0]
    L = np.zeros((n, n))
    x = np.empty(n)
    for j in range(n):
        d = S[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            return x, False
        L[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            s = S[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    for i in range(n):  # L y = b
        s = b[i]
        for k in range(i):
            s -= L[i, k] * x[k]
        x[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):  # L^T x = y
        s = x[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x, True


@njit(cache=True, boundscheck=True)
def unconstrained_if_feasible(
    H: np.ndarray, c: np.ndarray, G: np.ndarray, h: np.ndarray, lb: np.ndarray, ub: np.ndarray
) -> tuple[np.ndarray, bool]:
    """Return (u, True) if H is positive definite and the minimiser u = -H^-1 c of 1/2 u^T H u + c^T u satisfies
    lb <= u <= ub and G u <= h exactly (then u solves the QP), else (u, False)."""
    u, ok = cholesky_solve(H, -c)
    if not ok:  # not positive definite (or NaN): leave it to the active-set solver
        return u, False
    n = u.shape[0]
    for i in range(n):
        if not (lb[i] <= u[i] <= ub[i]):
            return u, False
    for k in range(G.shape[0]):
        s = 0.0
        for i in range(n):
            s += G[k, i] * u[i]
        if not s <= h[k]:
            return u, False
    return u, True


@njit(cache=True, boundscheck=True)
def write_configuration(q: np.ndarray, x: np.ndarray, root_q: int, arm_idx_q: np.ndarray) -> None:
    """Write reduced coordinates x = [x, y, theta, arm...] into a Pinocchio configuration q in place: the planar
    root joint's (x, y, cos theta, sin theta) at root_q, the arm joints at arm_idx_q."""
    q[root_q] = x[0]
    q[root_q + 1] = x[1]
    q[root_q + 2] = math.cos(x[2])
    q[root_q + 3] = math.sin(x[2])
    for k in range(arm_idx_q.shape[0]):
        q[arm_idx_q[k]] = x[3 + k]


@njit(cache=True, boundscheck=True)
def pose_difference(T: np.ndarray, T_des: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (e, R_des R^T) of two 4 x 4 placements: e (6,) holds p_des - p in e[:3] (e[3:] left to fill)."""
    e = np.empty(6)
    R = np.empty((3, 3))
    for i in range(3):
        e[i] = T_des[i, 3] - T[i, 3]
        for j in range(3):
            R[i, j] = T_des[i, 0] * T[j, 0] + T_des[i, 1] * T[j, 1] + T_des[i, 2] * T[j, 2]
    return e, R


@njit(cache=True, boundscheck=True)
def integrate_state(x: np.ndarray, u: np.ndarray, dt: float, wheel_map: np.ndarray, n_arm: int) -> np.ndarray:
    """Return x = [x, y, theta, arm...] after input u = [arm rates, base input] for dt: the arm joints linearly, the
    base by the exact odometry of its body step wheel_map u_base dt (`bases.displaced_pose`, paper eq. 4-10)."""
    step = np.zeros(3)
    for i in range(3):
        for j in range(wheel_map.shape[1]):
            step[i] += wheel_map[i, j] * u[n_arm + j]
        step[i] *= dt
    out = np.empty(x.shape[0])
    out[0], out[1], out[2] = displaced_pose(x[0], x[1], x[2], step[0], step[1], step[2])
    for i in range(n_arm):
        out[3 + i] = x[3 + i] + dt * u[i]
    return out

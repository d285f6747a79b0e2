"""``lateral_slip``'s sliding form: wheels that carry at most a friction force sideways (Coulomb), then slide.

``lateral_slip`` (:class:`cart.effects.LateralSlip`) is a *creep*: the {b} origin moves sideways at a speed
proportional to the lateral force the wheels carry. A cart on a slippery floor (or on four casters) does
not creep: its wheels hold it sideways up to a friction force F; beyond it the cart slides, its sideways
speed w a state of its own that the wheels' friction brakes,

    m w' = f_need - F tanh(w / w0)        sliding (|w| above its noise, or a push beyond F)
    w = 0, the wheels carry f_need        held (at rest sideways and |f_need| <= F)

with f_need = f_lat - (m v omega + m dx omegadot - m dy omega^2) the lateral force the wheels must carry to
keep eq. 3 (:class:`cart.effects.LateralSlip`'s column) and w0 the speed over which the friction builds up
(a regularised Coulomb friction, as in a physics engine's soft contact). The fit window rows hold the
sideways travel of {b} over each window k, D_k; the model predicts it from the sideways speed at the
window's start, w(t_k), and the acceleration a = (f_need - friction) / m over the window. w(t_k) comes
from the previous window's travel (exact kinematics: D_(k-1) = T_(k-1) w(t_k) - int (s - t_(k-1)) a ds),
or is 0 where the wheels hold the cart at t_k, so that a held cart is predicted to stay put. Where {b}
slides, the forward and yaw rows of eq. 4 gain the CoM's acceleration due to the measured sideways motion
(forward -m omega w, yaw m dx w' + m dy omega w; the nominal rows drop them under eq. 3). The model is
linear in F given the active set (the held samples, decided with the previous estimate of F: a set-valued
term iterated like ``coulomb_friction``'s hold) and uses phi (``uses_phi``).

:class:`cart.effects.LateralSlip` offers both forms as its ``Effect.variants()``: each is fitted by the same
machinery and the better one is named (:func:`cart.diagnose._rank_candidates`).
"""

from __future__ import annotations

import numpy as np

from cart.effects import Effect, LateralSlip
from cart.log_signals import Signals, lateral_displacements

#: a sideways speed within this many speed-noise stds of 0 is at rest sideways (the wheels may hold it)
REST_Z = 3.0
#: the lateral force is smoothed over +-this (s) before it is compared with the friction (hold or breakaway)
HOLD_HALF_WINDOW = 0.1


def _lateral_need(sig: Signals, phi: np.ndarray) -> np.ndarray:
    """Return f_need (N,): the lateral force the wheels carry under eq. 3 (LateralSlip's column)."""
    return LateralSlip().columns(sig, (), phi, np.zeros((sig.n, 3, 0)))[:, 2, 0]


def _smoothed(t: np.ndarray, y: np.ndarray, half: float) -> np.ndarray:
    """Return the moving mean of y over +-``half`` s (cumulative trapezoid; irregular sampling allowed)."""
    c = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))])
    lo = np.clip(t - half, t[0], t[-1])
    hi = np.clip(t + half, t[0], t[-1])
    width = np.maximum(hi - lo, 1e-12)
    return (np.interp(hi, t, c) - np.interp(lo, t, c)) / width


def _window_starts(sig: Signals, edges: np.ndarray) -> np.ndarray:
    """Return, per sample, the index of the window it lies in (edge samples open the next window)."""
    idx = np.searchsorted(edges, np.arange(sig.n), side="right") - 1
    return np.clip(idx, 0, len(edges) - 2)


def slide_speed(
    sig: Signals, edges: np.ndarray, accel: np.ndarray, held: np.ndarray, travel: np.ndarray | None
) -> np.ndarray:
    """Return the model's sideways speed w (N,) of {b} for the acceleration ``accel`` (N,), window by window.

    In window k (samples edges[k] .. edges[k+1]): w(t) = w(t_k) + int_(t_k)^t accel. w(t_k) = 0 where the
    wheels hold the cart (``held`` at edges[k]), at the first window of a segment and when ``travel`` is
    None (the parts of w linear in a parameter); otherwise (D_(k-1) + int (s - t_(k-1)) accel ds) / T_(k-1)
    with D_(k-1) = ``travel[k-1]``, the measured sideways travel over the previous window.
    """
    t = sig.t
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (accel[1:] + accel[:-1]) * np.diff(t))])  # int accel
    cum_t = np.concatenate([[0.0], np.cumsum(0.5 * (accel[1:] * t[1:] + accel[:-1] * t[:-1]) * np.diff(t))])
    e0, e1 = edges[:-1], edges[1:]
    t0, t1 = t[e0], t[e1]
    start = np.zeros(len(e0))
    if travel is not None and len(e0) > 1:
        # int_(t_(k-1))^(t_k) (s - t_(k-1)) accel ds of the previous window, then w at its end
        moment = (cum_t[e1] - cum_t[e0]) - t0 * (cum[e1] - cum[e0])
        start[1:] = (travel[:-1] + moment[:-1]) / np.maximum(t1[:-1] - t0[:-1], 1e-12)
    breaks = set(int(b) for b in sig.breaks)
    first = np.array([int(e) in breaks for e in e0], dtype=bool)
    first[0] = True
    start[first | held[e0]] = 0.0
    k = _window_starts(sig, edges)
    return start[k] + cum - cum[e0[k]]


def _sliding_rows(sig: Signals, w: np.ndarray, phi: np.ndarray | None = None) -> np.ndarray:
    """Return the rows (N, 3) of the model's sideways speed ``w``, with what eq. 4 gains where {b} slides.

    The lateral row is the sideways speed. With ``phi``, the forward and yaw rows get the CoM's acceleration
    due to the *measured* sideways motion of {b} (w_lat and its rate, like the nominal rows' measured
    accelerations): forward -m omega w_lat, yaw (about {b}) m dx w_lat' + m dy omega w_lat.
    """
    out = np.zeros((sig.n, 3))
    out[:, 2] = w
    if phi is not None:
        w_m = sig.w_lat
        out[:, 0] = -float(phi[0]) * sig.omega * w_m
        out[:, 1] = float(phi[1]) * np.gradient(w_m, sig.t) + float(phi[2]) * sig.omega * w_m
    return out


class SlidingWheels(LateralSlip):
    """``lateral_slip``'s sliding form: Coulomb lateral friction ``friction`` (N) over a speed ``slide_speed``."""

    name = "lateral_slip"
    param_names = ("friction",)
    nl_names = ("slide_speed",)
    uses_phi = True
    set_valued = True
    log_scale = True
    #: key of the current friction estimate in ``sig.extras`` (set by :meth:`offset`, read by :meth:`columns`)
    REF_KEY = ("slide_friction_ref",)

    def nl_grid(self, sig):
        """Return slide speeds w0 from 5 mm/s to 0.2 m/s (never below twice the speed noise)."""
        floor = 2.0 * sig.sigma_v
        return [(max(float(w), floor),) for w in (0.005, 0.01, 0.02, 0.05, 0.1, 0.2)]

    def nl_bounds(self, sig):
        """Return the slide-speed bounds (m/s)."""
        return [(max(0.002, 2.0 * sig.sigma_v), 0.5)]

    def _state(self, sig: Signals, nl, phi, f_ref: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (f_need, friction direction s (N,), held (N,)) for the friction estimate ``f_ref``."""
        f_need = _lateral_need(sig, phi)
        f_s = _smoothed(sig.t, f_need, HOLD_HALF_WINDOW)
        rest = np.abs(sig.w_lat) < REST_Z * sig.sigma_v
        held = rest & (np.abs(f_s) <= f_ref)
        direction = np.where(rest, np.sign(f_s), np.tanh(sig.w_lat / float(nl[0])))
        direction[held] = 0.0
        return f_need, direction, held

    def _edges(self, sig: Signals) -> np.ndarray:
        edges = sig.extras.get("base_edges")
        if edges is None:
            raise ValueError("lateral_slip's sliding form needs the fit's windows (sig.extras['base_edges'])")
        return np.asarray(edges)

    def columns(self, sig, nl, phi, base):
        """Return G: the sideways speed per newton of friction, -(1/m) int (friction direction) over each window."""
        f_ref = float(sig.extras.get(self.REF_KEY, 0.0))
        _, direction, held = self._state(sig, nl, phi, f_ref)
        g = np.zeros((sig.n, 3, 1))
        m = max(float(phi[0]), 1e-6)
        edges = self._edges(sig)
        accel = -direction / m
        # the previous window's friction enters w(t_k) through its travel's kinematics (zero travel: that part)
        w = slide_speed(sig, edges, accel, held, np.zeros(len(edges) - 1))
        g[:, :, 0] = _sliding_rows(sig, w)
        return g

    def offset(self, sig, nl, phi, base, theta):
        """Return the sideways speed without friction: the previous window's travel carried on, plus f_need / m."""
        f_ref = 0.0 if theta is None or len(theta) == 0 else max(float(theta[0]), 0.0)
        sig.extras[self.REF_KEY] = f_ref
        f_need, direction, held = self._state(sig, nl, phi, f_ref)
        edges = self._edges(sig)
        m = max(float(phi[0]), 1e-6)
        travel = lateral_displacements(sig, edges)
        accel = np.where(held, 0.0, f_need / m)
        return _sliding_rows(sig, slide_speed(sig, edges, accel, held, travel), phi)

    def variants(self) -> list[Effect]:
        """Return itself (the creep and this form are the variants of :class:`cart.effects.LateralSlip`)."""
        return [self]

    def is_physical(self, theta, nl, x):
        """Return False for a negative friction (it would push the sliding cart)."""
        return bool(len(theta) == 0 or float(theta[0]) >= 0.0)

    def describe(self, theta, nl, cov, nl_std, phi):
        """Return the friction, the slide speed and the friction coefficient it means on the whole weight."""
        params, std = super().describe(theta, nl, cov, nl_std, phi)
        m = float(phi[0])
        if m > 0.0:
            params["friction_coefficient"] = float(theta[0]) / (m * 9.81)
            std["friction_coefficient"] = std["friction"] / (m * 9.81)
        return params, std

"""Load changes during a push: a mass put into the cart or taken out of it at a given time.

A :class:`LoadChange` is a point mass (kg; negative: removed) at a place ``(x, y)`` on the deck in {b}. The cart's
parameters after it compose in the paper's parameter vector, which is linear in the masses (paper §II.B):
``phi_new = phi + m_l [1, x, y, x^2 + y^2]`` (:func:`params_after`). A load put in at rest takes the cart's momentum
in a perfectly inelastic impulse that the wheels' no-slip constraint also acts in (:func:`velocity_after`):
``M(phi_new) qd+ = M(phi_old) qd- + Lambda^T lambda`` with ``Lambda qd+ = 0`` (paper eq. 3-4); a load lifted out
leaves with its own momentum, so the cart's velocity is unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cart import model
from cart.errors import ParameterError
from cart.params import CartParams
from wholebody.errors import WholeBodyError


@dataclass(frozen=True)
class LoadChange:
    """A load put in (``mass`` > 0, kg) or taken out (< 0) at time ``t`` (s), at ``xy`` (m) in {b} on the deck.

    ``xy`` None: at the cart's centre of mass at that time (the CoM does not move)."""

    t: float
    mass: float
    xy: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        values = [self.t, self.mass, *(self.xy or ())]
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            raise WholeBodyError(f"a load change needs finite numbers, got {self}")
        if self.t < 0.0:
            raise WholeBodyError(f"a load change's time must be t >= 0 s, got {self.t:g} s (for {self.mass:+g} kg)")
        if self.mass == 0.0:
            raise WholeBodyError(
                f"a load change needs a nonzero mass (kg put in, or taken out if negative), got 0 at {self.t:g} s"
            )
        if self.xy is not None and len(self.xy) != 2:
            raise WholeBodyError(f"a load change's place is (x, y) in {{b}}, got {self.xy}")

    def place(self, params: CartParams) -> tuple[float, float]:
        """Return where the load is put or taken: ``xy``, or the CoM of the cart `params`."""
        return (params.dx, params.dy) if self.xy is None else (float(self.xy[0]), float(self.xy[1]))

    def as_dict(self) -> dict:
        """Return the change as a JSON-ready dict (``x``/``y`` None: at the CoM)."""
        x, y = (None, None) if self.xy is None else (float(self.xy[0]), float(self.xy[1]))
        return {"t": float(self.t), "mass_kg": float(self.mass), "x": x, "y": y}


def params_after(params: CartParams, change: LoadChange) -> CartParams:
    """Return the cart parameters once `change` is put in or taken out: phi + m_l [1, x, y, x^2 + y^2].

    Raises WholeBodyError when the cart left has no mass or no yaw inertia about its CoM (more taken out than is
    there, or from where it is not)."""
    x, y = change.place(params)
    phi = params.phi + change.mass * np.array([1.0, x, y, x * x + y * y])
    try:
        return CartParams.from_phi(phi, params.sigma, params.sigma_yaw)
    except ParameterError:
        raise WholeBodyError(
            f"the load change at t = {change.t:g} s takes out {-change.mass:g} kg at ({x:g}, {y:g}) m: more than the "
            f"{params.m:g} kg cart holds there"
        ) from None


def truth_schedule(params: CartParams, changes: Sequence[LoadChange]) -> list[tuple[float, CartParams]]:
    """Return [(t, parameters from t on)], the first at t = 0, one more per change in time order."""
    out = [(0.0, params)]
    for c in sorted(changes, key=lambda c: c.t):
        out.append((float(c.t), params_after(out[-1][1], c)))
    return out


def check_changes(params: CartParams | None, changes: Sequence[LoadChange], duration: float) -> None:
    """Raise WholeBodyError when a change falls outside (0, duration) or takes out more than the cart `params`
    holds (None: the times only)."""
    for c in changes:
        if not 0.0 < c.t < duration:
            raise WholeBodyError(f"a load change at t = {c.t:g} s is outside the run (0, {duration:g}) s")
    if params is not None:
        truth_schedule(params, changes)


def velocity_after(q: np.ndarray, qd: np.ndarray, old: CartParams, new: CartParams) -> np.ndarray:
    """Return the cart's velocity just after a load change from `old` to `new` parameters.

    A load put in at rest (``new.m > old.m``): the inelastic impulse with the no-slip constraint, the KKT system
    ``[[M_new, Lambda^T], [Lambda, 0]] [qd+, lambda] = [M_old qd-, 0]`` (paper eq. 3-4). A load taken out leaves
    with its own velocity: ``qd`` unchanged."""
    qd = np.asarray(qd, dtype=float)
    if new.m <= old.m:
        return qd.copy()
    lam = model.constraint_matrix(q)
    kkt = np.block([[model.mass_matrix(q, new), lam.T], [lam, np.zeros((1, 1))]])
    rhs = np.r_[model.mass_matrix(q, old) @ qd, 0.0]
    return np.linalg.solve(kkt, rhs)[:3]


def params_series(schedule: Sequence[tuple[float, CartParams]], t: np.ndarray) -> np.ndarray:
    """Return (N, 5) m, dx, dy, I, sigma in force at each time of `t` (a change counts from its time on)."""
    rows = np.array([(p.m, p.dx, p.dy, p.I, p.sigma) for _, p in schedule])
    starts = np.array([s for s, _ in schedule])
    idx = np.searchsorted(starts, np.asarray(t, dtype=float) + 1e-9, side="right") - 1
    return rows[np.clip(idx, 0, len(rows) - 1)]

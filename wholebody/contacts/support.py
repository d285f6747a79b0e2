"""The cart's support polygon and the tip-over bound on the hand wrenches.

A cart stands on its wheels' floor contacts; each contact can only push up. The hands' wrenches, gravity and the
cart's own inertia (d'Alembert) must leave every contact a normal load >= 0. For a rigid body on a convex support
polygon that is the zero-moment-point condition: for each edge of the polygon (floor contacts ``P1 -> P2``,
counter-clockwise, unit direction ``e``, inward normal ``n = z x e``) the moment about the edge line of

* gravity, ``-m g d`` with ``d = (c - P1) . n`` the CoM's distance inside the edge,
* the d'Alembert force ``-m a`` of the CoM's acceleration, at the CoM's height ``h``: ``h (-m a) . (-n)``,
* each hand's wrench ``[f; tau]`` at its contact ``p``: ``f . (e x (p - P1)) + tau . e``,

is <= 0 (at 0 the inside contacts' normal loads are 0 and the cart starts to roll over the edge). The floor's
friction forces act in the floor plane, on the edge's line's plane: they have no moment about it. The rows are
linear in the stacked hand wrenches, so `wholebody.contacts.allocation.WrenchAllocator.set_tip_bound` adds them
to the allocation QP (paper eq. 25): the allocation then pushes sideways only as hard as the cart stands, and
presses down on the handle (a downward force inside an edge holds the cart on it) where it must push harder.

The cart's mass and CoM are the estimator's; `CartLoad` shrinks the holding moment by their uncertainty on each edge
the hands are inside of: there a downward push on the handle holds the cart on the edge, so the allocation can keep
the margin at the cost of a press. On an edge the hands are outside of (the rear axle, for a handle behind it)
pressing down tips the cart further and a margin would forbid the motion itself (braking): there the bound takes the
estimate as it is. The CoM's height is
not estimated (the planar model has none): `SupportPolygon.com_height` is an upper bound, counted only where the
inertia tips the cart (a lower CoM tips it less). A swivelling caster's contact moves on a circle about its swivel
axis (its trail): `SupportPolygon.radius` moves each edge inward by it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import numpy.typing as npt

from wholebody.errors import WholeBodyError

#: standard gravity (m/s^2)
GRAVITY = 9.81


@dataclass(frozen=True)
class SupportPolygon:
    """Floor contacts of a cart in {b}: (x, y) of each wheel's contact, the floor's height, caster trails, CoM bound.

    ``points``: (K, 2), K >= 3, any order (their convex hull is the polygon); ``floor_z``: the floor's z in {b}
    (minus the height of {b}); ``radius``: how far (m) each contact may move from its point (a caster's trail;
    one value or one per point); ``com_height``: the highest the CoM may sit above the floor (m).
    """

    points: tuple[tuple[float, float], ...]
    floor_z: float
    com_height: float
    radius: float | tuple[float, ...] = 0.0

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3 or not np.isfinite(pts).all():
            raise WholeBodyError("a support polygon needs at least 3 finite floor points (x, y)")
        r = np.broadcast_to(np.asarray(self.radius, dtype=float), (len(pts),))
        if np.any(r < 0) or not np.isfinite(r).all():
            raise WholeBodyError("support contact radii must be finite and >= 0")
        if not (np.isfinite(self.floor_z) and self.com_height > 0.0):
            raise WholeBodyError("a support polygon needs a finite floor height and a positive CoM height bound")
        if len(hull_ccw(pts)) < 3:
            raise WholeBodyError("the support points are collinear: no polygon")

    def edges(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Return (start points (E, 2), unit directions e (E, 2), inward normals n (E, 2), inward shifts (E,)).

        The edges of the convex hull, counter-clockwise; the shift is the larger radius of the edge's two ends.
        """
        return self._edges

    @cached_property
    def _edges(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        pts = np.asarray(self.points, dtype=float)
        r = np.broadcast_to(np.asarray(self.radius, dtype=float), (len(pts),))
        idx = hull_ccw(pts)
        p1, p2 = pts[idx], pts[np.roll(idx, -1)]
        d = p2 - p1
        e = d / np.linalg.norm(d, axis=1)[:, None]
        n = np.stack([-e[:, 1], e[:, 0]], axis=1)  # z x e: inside of a counter-clockwise edge
        return p1, e, n, np.maximum(r[idx], r[np.roll(idx, -1)])

    def com_margin(self, com_b: npt.ArrayLike) -> np.ndarray:
        """Return each edge's distance (m) inside it of the point com_b (x, y), less its shift (< 0: outside)."""
        p1, _, n, shift = self.edges()
        return np.einsum("ij,ij->i", np.asarray(com_b, dtype=float)[:2] - p1, n) - shift


def hull_ccw(pts: np.ndarray) -> np.ndarray:
    """Return the indices of the convex hull of planar points, counter-clockwise (monotone chain)."""
    order = sorted(range(len(pts)), key=lambda i: (pts[i, 0], pts[i, 1]))

    def half(seq: list[int]) -> list[int]:
        out: list[int] = []
        for i in seq:
            while len(out) >= 2:
                a, b = pts[out[-2]], pts[out[-1]]
                if (b[0] - a[0]) * (pts[i, 1] - a[1]) - (b[1] - a[1]) * (pts[i, 0] - a[0]) > 1e-12:
                    break
                out.pop()
            out.append(i)
        return out

    lower, upper = half(order), half(order[::-1])
    return np.array(lower[:-1] + upper[:-1], dtype=int)


@dataclass(frozen=True)
class CartLoad:
    """What the cart itself puts on its support: mass (kg), CoM (x, y) in {b}, the CoM's acceleration in {b}.

    ``mass_std`` (kg) and ``com_std`` (m, along x and y of {b}) shrink the gravity's holding moment by
    ``std_factor`` of them: the CoM's distance inside each edge less ``std_factor`` times its 1-sigma along the
    edge's normal.
    """

    mass: float
    com: tuple[float, float]
    acceleration: tuple[float, float] = (0.0, 0.0)
    mass_std: float = 0.0
    com_std: tuple[float, float] = (0.0, 0.0)
    std_factor: float = 1.0

    def __post_init__(self) -> None:
        vals = (self.mass, *self.com, *self.acceleration, self.mass_std, *self.com_std, self.std_factor)
        if not (np.isfinite(vals).all() and self.mass > 0 and min(self.mass_std, *self.com_std, self.std_factor) >= 0):
            raise WholeBodyError("a cart load needs a positive mass, finite CoM and acceleration, stds >= 0")


def tip_rows(
    support: SupportPolygon, load: CartLoad, points_b: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Return (rows C (E + 1, 6N), right-hand sides h, labels): ``C w <= h`` keeps every support contact loaded.

    ``w`` stacks the hands' wrenches [f; tau] (in {a}, the orientation of {b}) at ``points_b`` (N, 3, in {b}).
    One row per edge (module docstring): hand moments about the edge <= what gravity holds less what the
    inertia tips, with the load's margins on the edges every hand is inside of (`holding_moment`); the last row keeps the hands from lifting the cart (sum fz <= m g).
    A right-hand side below 0 (the cart tips with no hand on it) is held at 0 so that w = 0 stays allowed.
    The rows and labels depend on the support and the hands' points only (`tip_geometry`), the right-hand sides
    on the load (`tip_rhs`).
    """
    rows, labels, inside = tip_geometry(support, points_b)
    return rows, tip_rhs(support, load, inside), labels


def tip_geometry(support: SupportPolygon, points_b: npt.ArrayLike) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Return `tip_rows`' rows and labels, and per edge whether every hand is inside it (`hands_inside`)."""
    pts = np.asarray(points_b, dtype=float).reshape(-1, 3)
    p1, e, _, _ = support.edges()
    rows = np.zeros((len(e) + 1, 6 * len(pts)))
    for i, p in enumerate(pts):
        rx, ry, rz = p[0] - p1[:, 0], p[1] - p1[:, 1], p[2] - support.floor_z
        # f . (e x r) = (r x f) . e, with e = (ex, ey, 0)
        rows[:-1, 6 * i] = e[:, 1] * rz
        rows[:-1, 6 * i + 1] = -e[:, 0] * rz
        rows[:-1, 6 * i + 2] = e[:, 0] * ry - e[:, 1] * rx
        rows[:-1, 6 * i + 3 : 6 * i + 5] = e
        rows[-1, 6 * i + 2] = 1.0
    labels = [
        f"cart tip-over bound (edge from {np.round(p1[k], 3).tolist()} along {np.round(e[k], 3).tolist()})"
        for k in range(len(e))
    ]
    return rows, labels + ["cart tip-over bound (hands lift the cart)"], hands_inside(support, pts)


def tip_rhs(support: SupportPolygon, load: CartLoad, inside: np.ndarray) -> np.ndarray:
    """Return `tip_rows`' right-hand sides under `load`, with `inside` of `tip_geometry`: per edge the holding
    moment less the inertia's tipping moment (at least 0), then the lifting bound m g."""
    _, _, n, _ = support.edges()
    m_low = max(load.mass - load.std_factor * load.mass_std, 0.0)
    hold = holding_moment(support, load, inside)
    a_in = np.asarray(load.acceleration, dtype=float) @ n.T  # toward the inside: the d'Alembert -m a points out
    tipping = load.mass * support.com_height * np.maximum(a_in, 0.0)
    return np.append(np.maximum(hold - tipping, 0.0), m_low * GRAVITY)


def hands_inside(support: SupportPolygon, points_b: npt.ArrayLike) -> np.ndarray:
    """Return, per edge of `support`, whether every hand point (x, y of `points_b`, (N, 3) in {b}) is inside it.

    Inside an edge (beyond its shift) a hand's downward force holds the cart on that edge.
    """
    xy = np.asarray(points_b, dtype=float).reshape(-1, 3)[:, :2]
    return np.asarray(np.all([support.com_margin(p) > 0.0 for p in xy], axis=0))


def holding_moment(support: SupportPolygon, load: CartLoad, margined: np.ndarray) -> np.ndarray:
    """Return per edge the moment m g d (N m) by which the cart's weight holds it on the edge.

    On the edges where `margined` is True the mass and the CoM's distance inside the edge are the estimate's less
    ``std_factor`` of their 1-sigma (the CoM's along the edge's normal); elsewhere they are the estimate's.
    """
    _, _, n, _ = support.edges()
    d = support.com_margin(load.com)
    com_std_n = np.sqrt((n**2) @ np.square(load.com_std))  # the CoM's 1-sigma along each edge's normal
    m_low = max(load.mass - load.std_factor * load.mass_std, 0.0)
    robust = m_low * GRAVITY * (d - load.std_factor * com_std_n)
    return np.where(np.asarray(margined, dtype=bool), robust, load.mass * GRAVITY * d)

"""The cart geometry a push controller needs: where the handle is and how high the cart frame {b} sits.

Nothing inertial: the controller estimates mass, CoM and inertia (cart paper eq. 8-20); it is told only where
its hands may hold. The default is the shopping cart of `robots` (a 0.5 m bar 0.15 m behind the fixed axle);
a MuJoCo cart file gives its own (`geometry_from_cart_file`, the contract of docs/mujoco.md).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from robots.shopping_cart import CART_WHEEL_RADIUS
from wholebody.contacts.handle import CONTACT_GRID_STEP, HandleSegment
from wholebody.errors import WholeBodyError


@dataclass(frozen=True)
class CartGeometry:
    """The handle in {b} (a bar along y_b), the height of {b} above the floor, and the point grips if any.

    ``grips``: the lateral coordinates y (m) of point grips (a wheelchair's two push handles); None when a
    hand may hold anywhere along the bar. ``grip_points``: each grip's point in {b} (x, y, z), when the grips are
    not all on the handle's line (handles at different heights or depths); None: on the line.
    """

    handle: HandleSegment = field(default_factory=HandleSegment.default)
    frame_height: float = CART_WHEEL_RADIUS
    grips: tuple[float, ...] | None = None
    grip_points: tuple[tuple[float, float, float], ...] | None = None

    def __post_init__(self) -> None:
        if not np.isfinite(self.frame_height):
            raise WholeBodyError(f"cart frame height must be finite, got {self.frame_height}")
        if self.grips is not None and (len(self.grips) == 0 or not np.all(np.isfinite(self.grips))):
            raise WholeBodyError("point grips need at least one finite lateral coordinate")
        if self.grip_points is not None:
            pts = np.asarray(self.grip_points, dtype=float)
            if self.grips is None or pts.shape != (len(self.grips), 3) or not np.all(np.isfinite(pts)):
                raise WholeBodyError("grip_points need one finite (x, y, z) per grip")
            if not np.allclose(pts[:, 1], self.grips):
                raise WholeBodyError("grip_points' y must be the grips' lateral coordinates, in the same order")

    @property
    def y_range(self) -> tuple[float, float]:
        """Return the lateral span (m) a hand may hold."""
        ys = [self.handle.start_b[1], self.handle.end_b[1]] if self.grips is None else list(self.grips)
        return float(min(ys)), float(max(ys))

    def point(self, y: float) -> np.ndarray:
        """Return the handle point with lateral coordinate y, in {b} (along the bar's line; a grip's own point when
        ``grip_points`` are given: the grip nearest y)."""
        if self.grip_points is not None:
            return np.array(min(self.grip_points, key=lambda p: abs(p[1] - y)), dtype=float)
        a, b = np.asarray(self.handle.start_b), np.asarray(self.handle.end_b)
        d = b - a
        if abs(d[1]) < 1e-12:  # a point grip's degenerate bar: the point itself
            return np.array([a[0], y, a[2]])
        return a + (float(y) - a[1]) / d[1] * d

    def grid(self, step: float = CONTACT_GRID_STEP) -> np.ndarray:
        """Return the contact candidates y (m): the grips, or the bar sampled every `step` (its ends included)."""
        if self.grips is not None:
            return np.array(sorted(self.grips), dtype=float)
        lo, hi = self.y_range
        n = max(1, int(round((hi - lo) / step)))
        return np.round(np.linspace(lo, hi, n + 1), 6)

    def nearest(self, y: float) -> float:
        """Return the holdable y nearest to `y`."""
        if self.grips is not None:
            return float(min(self.grips, key=lambda g: abs(g - y)))
        lo, hi = self.y_range
        return float(np.clip(y, lo, hi))


DEFAULT_GEOMETRY = CartGeometry()


def geometry_from_cart_file(path: str | os.PathLike) -> CartGeometry:
    """Return the geometry of an MJCF cart file: its `handle*` sites (docs/mujoco.md) and the height of {b}.

    The sites a robot pushing from behind holds (`cart_file.rear_handles`): a bar across the cart is held
    anywhere along it; other sites (points, bars along x or z) are point grips, each held at its own point (a bar's
    middle); the handle line runs through their mean x and z. Raises `wholebody.push.cart_file.CartFileError` for a broken file.
    """
    from wholebody.push.cart_file import load_cart_file, rear_handles

    source = load_cart_file(path)
    sites = list(rear_handles(source.handles))
    if len(sites) == 1 and abs(float(sites[0].end_b[1] - sites[0].start_b[1])) >= 0.05:
        a, b = np.asarray(sites[0].start_b, dtype=float), np.asarray(sites[0].end_b, dtype=float)
        return CartGeometry(HandleSegment(tuple(a), tuple(b)), float(source.z))
    pts = np.array([0.5 * (np.asarray(s.start_b) + np.asarray(s.end_b)) for s in sites], dtype=float)
    x, z = float(pts[:, 0].mean()), float(pts[:, 2].mean())
    ys = tuple(float(v) for v in pts[:, 1])
    lo, hi = min(ys), max(ys)
    if hi - lo < 1e-3:
        lo, hi = lo - 1e-3, hi + 1e-3
    on_line = np.allclose(pts[:, 0], x, atol=1e-6) and np.allclose(pts[:, 2], z, atol=1e-6)
    own = None if on_line else tuple((float(p[0]), float(p[1]), float(p[2])) for p in pts)
    return CartGeometry(HandleSegment((x, lo, z), (x, hi, z)), float(source.z), ys, own)

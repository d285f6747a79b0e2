"""Cart inertial parameters and the one conversion between physical values and phi.

The paper estimates ``phi = [m, m*dx, m*dy, I + m*(dx^2 + dy^2)]`` (paper §II.B),
i.e. the mass, the first mass moments and the inertia about the {b} origin.
:class:`CartParams` stores the physical values ``(m, dx, dy, I)`` with ``I``
about the centre of mass, plus the viscous coefficients of
``N = diag(sigma, sigma, sigma_yaw) qdot``: ``sigma`` forward/lateral (N s/m) and
``sigma_yaw`` (N m s/rad; ``None`` means equal to ``sigma``, the paper's scalar case).
:meth:`CartParams.phi` and :meth:`CartParams.from_phi`
are the only place in the project where the two are converted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from cart.errors import ParameterError

#: Smallest mass (kg) and CoM inertia (kg m^2) accepted as physical.
MIN_MASS = 1e-6
MIN_INERTIA = 1e-9


@dataclass(frozen=True, init=False)
class CartParams:
    """Physical cart parameters: mass, CoM (dx, dy) in {b}, inertia about the CoM, viscous coefficients.

    ``sigma`` damps the velocity of the {b} origin (N s/m), ``sigma_yaw`` the yaw
    rate (N m s/rad); ``sigma_yaw=None`` takes the paper's scalar sigma for both.
    """

    m: float
    dx: float
    dy: float
    I: float
    sigma: float
    sigma_yaw: float

    def __init__(
        self, m: float, dx: float, dy: float, I: float, sigma: float = 0.0, sigma_yaw: float | None = None
    ) -> None:
        """Set the fields (``sigma_yaw=None``: equal to ``sigma``); raise ParameterError for unphysical values."""
        for name, value in (("m", m), ("dx", dx), ("dy", dy), ("I", I), ("sigma", sigma)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "sigma_yaw", sigma if sigma_yaw is None else sigma_yaw)
        self.__post_init__()

    def __post_init__(self) -> None:
        for name in ("m", "dx", "dy", "I", "sigma", "sigma_yaw"):
            value = getattr(self, name)
            if not isinstance(value, (int, float, np.floating, np.integer)) or not math.isfinite(float(value)):
                raise ParameterError(f"cart parameter {name} must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.m <= MIN_MASS:
            raise ParameterError(f"cart mass must be positive, got m={self.m}")
        if self.I <= MIN_INERTIA:
            raise ParameterError(f"cart inertia about the CoM must be positive, got I={self.I}")
        if self.sigma < 0.0 or self.sigma_yaw < 0.0:
            raise ParameterError(
                f"viscous coefficients must be >= 0, got sigma={self.sigma}, sigma_yaw={self.sigma_yaw}"
            )

    @property
    def com(self) -> np.ndarray:
        """Return the centre of mass (dx, dy) in {b}."""
        return np.array([self.dx, self.dy])

    @property
    def inertia_b(self) -> float:
        """Return the inertia about the {b} origin, I + m (dx^2 + dy^2) (parallel axis)."""
        return self.I + self.m * (self.dx * self.dx + self.dy * self.dy)

    @property
    def phi(self) -> np.ndarray:
        """Return the paper's parameter vector [m, m dx, m dy, I + m(dx^2+dy^2)] (paper §II.B)."""
        return np.array([self.m, self.m * self.dx, self.m * self.dy, self.inertia_b])

    @property
    def damping(self) -> tuple[float, float]:
        """Return the viscous coefficients (forward/lateral N s/m, yaw N m s/rad)."""
        return self.sigma, self.sigma_yaw

    @classmethod
    def from_phi(cls, phi: np.ndarray, sigma: float = 0.0, sigma_yaw: float | None = None) -> CartParams:
        """Return the physical parameters of a phi vector; raise ParameterError if m <= 0 or I <= 0."""
        phi = np.asarray(phi, dtype=float).reshape(-1)
        if phi.shape != (4,) or not np.all(np.isfinite(phi)):
            raise ParameterError(f"phi must be 4 finite numbers [m, m dx, m dy, J], got {phi!r}")
        m, a, b, j = (float(v) for v in phi)
        if m <= MIN_MASS:
            raise ParameterError(f"phi has non-positive mass m={m}")
        dx, dy = a / m, b / m
        inertia = j - (a * a + b * b) / m
        return cls(m=m, dx=dx, dy=dy, I=inertia, sigma=sigma, sigma_yaw=sigma_yaw)

    def with_mass(self, m: float, keep_com: bool = True) -> CartParams:
        """Return a copy with another mass; the CoM and the radius of gyration are kept."""
        return replace(self, m=m, I=self.I * m / self.m if keep_com else self.I)


def project_phi(phi: np.ndarray, min_mass: float = 0.1, min_inertia: float = 1e-3) -> np.ndarray:
    """Return phi clipped to a physically consistent set: m >= min_mass and I_com >= min_inertia.

    The first moments (m dx, m dy) are kept; J = I + m(dx^2+dy^2) is raised if needed.
    """
    out = np.array(phi, dtype=float, copy=True)
    if out[0] < min_mass:
        out[0] = min_mass
    j_min = min_inertia + (out[1] * out[1] + out[2] * out[2]) / out[0]
    if out[3] < j_min:
        out[3] = j_min
    return out

"""Exceptions of the `wholebody` package."""

from __future__ import annotations

from cart.errors import CartpushError


class WholeBodyError(CartpushError):
    """Base class of the wholebody package's errors for bad input."""


class InfeasibleWrenchError(WholeBodyError):
    """A requested cart wrench cannot be produced within the arms' limits.

    Attributes:
        binding: name of the limit that binds (e.g. ``"arm0 force bound"``).
        closest: the closest achievable cart wrench ``(fx, fy, tau)``.
    """

    def __init__(self, message: str, binding: str = "", closest=None) -> None:
        super().__init__(message)
        self.binding = binding
        self.closest = closest


class TrajectoryInfeasibleError(WholeBodyError):
    """Time parameterization found no feasible trajectory (toppra returned None)."""


class SingularConfigurationError(WholeBodyError):
    """A configuration where the requested quantity is undefined (singular pose)."""


class SceneError(WholeBodyError):
    """Bad input to a Meshcat scene (`wholebody.viz.Scene`): unknown robot name, malformed pose or points."""

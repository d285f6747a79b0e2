"""Exceptions of the `cart` package, and the project's root exception `CartpushError`.

Every error the project raises for bad input derives from :class:`CartpushError`
(a ``ValueError``): `cart` is the dependency root, so `robots` and `wholebody`
import it from here. The CLI maps it to one line on stderr and exit code 2.
"""

from __future__ import annotations


class CartpushError(ValueError):
    """Root of every cartpush error for bad input (one line a user can act on)."""


class CartError(CartpushError):
    """Base class of every error the cart package raises for bad input."""


class LogFormatError(CartError):
    """A cart log violates docs/log_format.md (names the file, the line and the problem)."""


class ParameterError(CartError):
    """Physically inconsistent cart parameters (non-positive mass or inertia, ...)."""


class NumericalError(CartError):
    """A computation broke down numerically on the given data (e.g. a covariance no longer positive definite)."""


class DiagnoseError(CartError):
    """The log cannot be diagnosed (too short, no motion, degenerate fit); also importable from cart.diagnose."""

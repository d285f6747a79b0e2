"""Exceptions of the `cart` package; every one carries a message a user can act on."""
from __future__ import annotations


class CartError(ValueError):
    """Base class of every error the cart package raises for bad input."""


class LogFormatError(CartError):
    """A cart log violates LOG_FORMAT.md (names the file, the line and the problem)."""


class ParameterError(CartError):
    """Physically inconsistent cart parameters (non-positive mass or inertia, ...)."""

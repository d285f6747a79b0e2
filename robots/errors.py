"""Exceptions of the `robots` package."""

from __future__ import annotations

from cart.errors import CartpushError


class RobotError(CartpushError):
    """Base class of the robots package's errors for bad input."""


class UnknownRobotError(RobotError, KeyError):
    """A robot name that `robots.available()` does not list."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""

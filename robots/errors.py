"""Exceptions of the `robots` package."""

from __future__ import annotations

from cart.errors import CartpushError


class RobotError(CartpushError):
    """Base class of the robots package's errors for bad input."""


class UnknownRobotError(RobotError, KeyError):
    """A robot name that `robots.available()` does not list."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class ProfileError(RobotError):
    """A robot profile (TOML) that cannot describe its robot: the message names the key and the fix."""

    def __init__(self, source: object, key: str, problem: str) -> None:
        self.source = str(source)
        self.key = key
        super().__init__(f"robot profile {self.source}: {key}: {problem}")

"""Errors of the product layer (command-line options, batch runs), under the project's root exception."""

from __future__ import annotations

from cart.errors import CartpushError


class OptionError(CartpushError):
    """A command-line option has a value the command cannot use (the CLI prints one line and exits 2)."""


class BatchError(CartpushError):
    """Bad batch input: no logs, an unusable output file, an unknown job, Ray missing or unreachable."""

"""Exceptions of `cartpush.ros`: bad bags and bad import options (one line, exit code 2 in the CLI)."""

from __future__ import annotations

from wholebody.errors import WholeBodyError


class BagImportError(WholeBodyError):
    """A bag cannot be turned into a cart log: missing topic, unsupported type, empty window, unreadable bag."""


class TransformLookupError(BagImportError):
    """Two TF frames cannot be connected (separate trees, a frame absent, or no transform at the times asked).

    Attributes:
        source: the frame the transform was asked from.
        target: the frame it was asked into.
    """

    def __init__(self, message: str, source: str = "", target: str = "") -> None:
        super().__init__(message)
        self.source = source
        self.target = target

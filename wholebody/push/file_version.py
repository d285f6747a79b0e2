"""A file's version for a cache key: an edited robot URDF or cart file (a notebook's next cell) is read again."""

from __future__ import annotations

import os


def file_version(path: str | os.PathLike) -> tuple[int, int] | None:
    """Return (modification time in ns, size in bytes) of `path`, or None when it cannot be read (the reader then
    says why)."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_mtime_ns, st.st_size

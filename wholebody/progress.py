"""One progress bar for the long commands and studies: tqdm on stderr, only on a terminal and never with --json.

>>> from wholebody.progress import progress_bar, show_progress
>>> for k in progress_bar(range(3), desc="push", enabled=False):  # a plain iterator when disabled
...     pass
"""

from __future__ import annotations

import sys
from typing import TypeVar
from collections.abc import Iterable, Iterator

T = TypeVar("T")


def show_progress(json_output: bool = False) -> bool:
    """Return True when a bar should show: stderr is a terminal and the output is not JSON."""
    isatty = getattr(sys.stderr, "isatty", None)
    return bool(not json_output and isatty is not None and isatty())


def progress_bar(
    iterable: Iterable[T], desc: str = "", total: int | None = None, unit: str = "it", enabled: bool | None = None
) -> Iterator[T]:
    """Return `iterable`, wrapped in a tqdm bar on stderr when `enabled` (None: `show_progress()`)."""
    if not (show_progress() if enabled is None else enabled):
        return iter(iterable)
    from tqdm import tqdm

    return iter(tqdm(iterable, desc=desc, total=total, unit=unit, file=sys.stderr, leave=False, dynamic_ncols=True))

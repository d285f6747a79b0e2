"""Optional test dependencies: skip with one line saying what to install, or fail where they are required.

`.ci/run` sets ``CARTPUSH_REQUIRE_EXTRAS=1``: there the dev extras are installed by `make test`, so a missing
one is a broken install, not a reason to skip.
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType

import pytest

REQUIRED = os.environ.get("CARTPUSH_REQUIRE_EXTRAS") == "1"


def missing(what: str, install: str) -> None:
    """Skip the caller (module or test) because `what` is missing, or fail under CARTPUSH_REQUIRE_EXTRAS=1."""
    message = f"{what} is not installed ({install})"
    if REQUIRED:
        pytest.fail(message + " [CARTPUSH_REQUIRE_EXTRAS=1]", pytrace=False)
    pytest.skip(message, allow_module_level=True)


def require_module(name: str, install: str = "pip install -e '.[dev]'") -> ModuleType:
    """Return the imported module `name`; `missing` when it cannot be imported."""
    try:
        return importlib.import_module(name)
    except ImportError:
        missing(name, install)
        raise  # not reached: missing() skips or fails

"""The library type-checks: `mypy cart robots wholebody cartpush` reports no error (config: pyproject's [tool.mypy])."""

from __future__ import annotations

import pathlib
import subprocess
import sys

from tests.optional import require_module

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGES = ("cart", "robots", "wholebody", "cartpush")


def test_mypy_reports_no_error() -> None:
    require_module("mypy")
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", *PACKAGES],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, f"mypy {' '.join(PACKAGES)} failed:\n{proc.stdout}{proc.stderr}"

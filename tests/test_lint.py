"""`ruff check` and `ruff format --check` (the rules in pyproject.toml's [tool.ruff]) pass on the whole repository."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tests.optional import require_module

ROOT = Path(__file__).resolve().parents[1]


def _ruff(*args: str) -> subprocess.CompletedProcess:
    require_module("ruff")
    return subprocess.run([sys.executable, "-m", "ruff", *args], cwd=ROOT, capture_output=True, text=True, timeout=120)


def test_ruff_check_passes() -> None:
    proc = _ruff("check", "--no-cache", "--output-format", "concise", ".")
    assert proc.returncode == 0, (
        f"ruff check found problems (fix them or `ruff check --fix`):\n{proc.stdout}{proc.stderr}"
    )


def test_ruff_format_is_applied() -> None:
    proc = _ruff("format", "--check", "--no-cache", ".")
    assert proc.returncode == 0, f"files not formatted (run `ruff format .`):\n{proc.stdout}{proc.stderr}"

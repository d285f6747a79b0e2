"""`import cartpush`: the curated API resolves every name it lists, lazily."""

from __future__ import annotations

import subprocess
import sys

import pytest

import cartpush


def test_every_listed_name_resolves():
    for name in cartpush.__all__:
        assert getattr(cartpush, name) is not None, name
    assert cartpush.load_robot("wmra").model.nq > 0
    with pytest.raises(AttributeError):
        cartpush.not_a_name  # noqa: B018


def test_importing_cartpush_loads_no_robot_stack():
    """The names load on first use: `import cartpush` alone imports neither Pinocchio nor the push loop."""
    code = "import sys, cartpush; print('pinocchio' in sys.modules, 'wholebody.push' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "False"]

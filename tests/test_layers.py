"""Layers point down: cartpush -> wholebody -> robots, cart; nothing installed imports studies."""

from __future__ import annotations

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: package -> the project packages it may import (itself included)
ALLOWED = {
    "cart": {"cart"},
    "robots": {"robots", "cart"},
    "wholebody": {"wholebody", "robots", "cart"},
    "cartpush": {"cartpush", "wholebody", "robots", "cart"},
}
PROJECT = set(ALLOWED) | {"studies", "tests", "benchmarks", "notebooks"}


def imported_packages(path: pathlib.Path) -> set[str]:
    """Return the top-level project packages a module imports (absolute imports, anywhere in the file)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        found |= {n.split(".")[0] for n in names} & PROJECT
    return found


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_no_module_imports_a_higher_layer(package):
    bad = {
        str(f.relative_to(ROOT)): sorted(imported_packages(f) - ALLOWED[package])
        for f in sorted((ROOT / package).rglob("*.py"))
    }
    assert not {k: v for k, v in bad.items() if v}


def test_the_distribution_installs_no_studies():
    import tomllib

    find = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]["find"]
    assert not any(p.startswith("studies") for p in find["include"])
    assert "cartpush.cli:main" in (ROOT / "pyproject.toml").read_text()


def test_the_walker_sees_an_upward_import(tmp_path):
    """The check can fail: a module importing `cartpush` from `cart` is found."""
    f = tmp_path / "m.py"
    f.write_text("def f():\n    from cartpush.cli import main\n    import studies.testbeds\n")
    assert imported_packages(f) == {"cartpush", "studies"}

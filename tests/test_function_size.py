"""No library function is longer than 60 lines (issue 17), except the named straight-line formula code."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAX_LINES = 60
#: straight-line formula code, written out term by term (docs/architecture.md, "Function size")
EXEMPT = {("cart/dynamics.py", "dynamics_jacobian_rows")}


def long_functions() -> list[tuple[int, str, str]]:
    out = []
    for pkg in ("cart", "wholebody", "robots"):
        for path in sorted((ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    n = node.end_lineno - node.lineno + 1
                    if n > MAX_LINES and (rel, node.name) not in EXEMPT:
                        out.append((n, rel, node.name))
    return out


def test_no_library_function_longer_than_60_lines() -> None:
    assert long_functions() == [], "split these into named helpers:\n" + "\n".join(map(str, long_functions()))


def test_the_exemption_is_still_needed() -> None:
    path = ROOT / "cart/dynamics.py"
    sizes = {
        n.name: n.end_lineno - n.lineno + 1
        for n in ast.walk(ast.parse(path.read_text()))
        if isinstance(n, ast.FunctionDef)
    }
    assert sizes["dynamics_jacobian_rows"] > MAX_LINES

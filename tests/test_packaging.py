"""The distribution installs and runs its main job without extras.

Slow (a fresh venv, `pip install .` of Pinocchio, ProxSuite, ... : a few minutes, then
`cartpush demo`), so it runs only with CARTPUSH_FRESH_VENV_TEST=1: `.ci/run` sets it in a
separate step after `make test`. Locally: `CARTPUSH_FRESH_VENV_TEST=1 .venv/bin/python -m
pytest tests/test_packaging.py`. Needs the package index (or a local wheel cache) pip uses.
"""

from __future__ import annotations

import os
import shutil
import json
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ENABLED = os.environ.get("CARTPUSH_FRESH_VENV_TEST") == "1"

pytestmark = pytest.mark.skipif(
    not ENABLED, reason="fresh-venv install test: set CARTPUSH_FRESH_VENV_TEST=1 (.ci/run does)"
)


def run(cmd: list[str], cwd: Path, timeout: float) -> subprocess.CompletedProcess:
    """Run a command with a clean environment; fail with its output tail on a non-zero exit."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, (
        f"{' '.join(cmd)} exited {proc.returncode}\nstdout:\n{proc.stdout[-3000:]}\nstderr:\n{proc.stderr[-3000:]}"
    )
    return proc


def test_install_without_extras_runs_the_demo(tmp_path):
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True, clear=True).create(env_dir)
    bin_dir = env_dir / ("Scripts" if sys.platform == "win32" else "bin")
    python = bin_dir / "python"
    # A copy of the source tree (pip builds in place; keep build/ out of the checkout), installed
    # like a wheel (not editable): package data must ship.
    src = tmp_path / "src"
    shutil.copytree(
        ROOT,
        src,
        ignore=shutil.ignore_patterns(
            ".git", ".venv", "build", "*.egg-info", "__pycache__", ".pytest_cache", ".hypothesis", "cartpush_report"
        ),
    )
    run([str(python), "-m", "pip", "install", "--quiet", str(src)], cwd=tmp_path, timeout=1500)
    # Nothing from the source tree on sys.path: run from tmp_path.
    probe = run(
        [
            str(python),
            "-c",
            "import cart, wholebody, robots, sys; print(wholebody.__file__); print(robots.load('wmra').urdf.is_file())",
        ],
        cwd=tmp_path,
        timeout=120,
    )
    assert str(ROOT) not in probe.stdout.splitlines()[0] and str(src) not in probe.stdout, probe.stdout
    assert probe.stdout.splitlines()[1] == "True"
    # `studies` stays in the repository: nothing named so is installed, and the installed commands that
    # reproduce the papers work without it
    site = run(
        [str(python), "-c", "import importlib.util as u; print(u.find_spec('studies'))"], cwd=tmp_path, timeout=60
    )
    assert site.stdout.strip() == "None", site.stdout
    table = run([str(bin_dir / "cartpush"), "reproduce", "--tests", "1", "--json"], cwd=tmp_path, timeout=600)
    rows = json.loads(table.stdout)
    assert [r["test"] for r in rows] == [1] and rows[0]["mass_error_final_kg"] < 1.0, table.stdout
    for package in ("cart", "wholebody", "robots", "cartpush"):
        typed = run(
            [
                str(python),
                "-c",
                f"import {package}, pathlib; print((pathlib.Path({package}.__file__).parent / 'py.typed').is_file())",
            ],
            cwd=tmp_path,
            timeout=60,
        )
        assert typed.stdout.strip() == "True", f"{package}/py.typed is not installed"
    out = tmp_path / "demo"
    run([str(bin_dir / "cartpush"), "demo", "--out", str(out)], cwd=tmp_path, timeout=900)
    assert out.is_dir() and any(out.iterdir()), "cartpush demo wrote nothing"
    assert (out / "scene.html").is_file(), sorted(p.name for p in out.iterdir())

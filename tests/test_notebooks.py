"""Every notebook in notebooks/ runs top to bottom from the repository root (outputs are not committed).

Executing a notebook leaves the checkout as it was (`git status --porcelain`
unchanged: notebooks write only to temporary folders), every code cell that
plots has an image output (Matplotlib's inline backend, the kernel's default:
no `matplotlib.use` in library code may turn it off), and the contact-planning,
allocation and push notebooks (the Ridgeback's and the WMRA's) show the Meshcat scene inline.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
#: A code cell "plots" when it calls pyplot or a plotting function of the project.
PLOTS = re.compile(r"\bplt\.|\bplot_\w*\(|\w+_figures\(|\.plot\(")
#: Notebooks that show a Meshcat scene inline.
WITH_SCENE = {
    "01_contact_planning",
    "05_multi_arm_allocation",
    "06_push_cart",
    "07_wmra_push",
    "08_bring_your_own_robot",
}


def test_there_are_notebooks():
    names = {p.stem for p in NOTEBOOKS}
    assert {
        "01_contact_planning",
        "02_cart_ekf",
        "03_wmra_tracking",
        "04_diagnose_model",
        "05_multi_arm_allocation",
        "06_push_cart",
        "07_wmra_push",
        "08_bring_your_own_robot",
    } <= names


def git_status() -> set[str] | None:
    """Return the lines of `git status --porcelain` (untracked files listed one by one), or None outside git.

    Edits to tracked files (`` M file``) and new source files (``*.py``, ``*.md``)
    outside notebooks/ are left out: a notebook writes data, figures and pages,
    not sources, and edits made while the notebooks run (an editor, another
    session) would make the comparison flaky. Any other new file, any deleted
    file and any change under notebooks/ count.
    """
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        return None
    out = subprocess.run(
        ["git", "status", "--porcelain", "--untracked-files=all"], cwd=ROOT, capture_output=True, text=True, check=True
    )

    def counts(line: str) -> bool:
        code, path = line[:2], line[3:]
        if path.startswith("notebooks/"):
            return True
        if code.strip() == "M":
            return False
        return not (code == "??" and path.endswith((".py", ".md")))

    return {line for line in out.stdout.splitlines() if counts(line)}


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path: Path, monkeypatch):
    nb = nbformat.read(path, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert not cell.get("outputs"), f"{path.name} is committed with outputs; strip them"
    monkeypatch.delenv("MPLBACKEND", raising=False)  # the kernel's default: inline figures
    before = git_status()
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(ROOT)}}).execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors
    if before is not None:
        new = sorted(git_status() - before)
        assert not new, f"{path.name} changed the checkout (run from the repository root): {new}"
    for i, cell in enumerate(nb.cells):
        if cell.cell_type != "code" or not PLOTS.search(cell.source):
            continue
        images = [
            o
            for o in cell.outputs
            if o.output_type in ("display_data", "execute_result") and "image/png" in o.get("data", {})
        ]
        assert images, f"{path.name} cell {i} plots but shows no figure:\n{cell.source[:300]}"
    if path.stem in WITH_SCENE:
        html = [
            o["data"]["text/html"]
            for c in nb.cells
            if c.cell_type == "code"
            for o in c.outputs
            if o.output_type in ("display_data", "execute_result") and "text/html" in o.get("data", {})
        ]
        assert any("<iframe srcdoc=" in h and "MeshCat.Viewer" in h for h in html), (
            f"{path.name} shows no Meshcat scene inline"
        )

"""Write docs/img/scene.png, the README's screenshot: the static page of a scene rendered by headless Chromium.

The page's legend (bottom left) names every overlay and the arrows' scale.

Run from the repository root: .venv/bin/python docs/img/make_scene.py
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from robots.shopping_cart import CART_HANDLE_X
from wholebody.viz import Camera, pushing_scene
from wholebody.viz.browser import find_chromium, screenshot

OUT = Path(__file__).resolve().parent


def main() -> int:
    """Build the scene, save the page and the screenshot; return the exit code."""
    tmp = Path(tempfile.mkdtemp())
    with pushing_scene((0.9, 0.0, 0.0)) as scene:
        scene.set_camera(Camera(target=(0.55, 0.0, 0.55), eye=(2.3, -2.4, 1.9), fov_deg=50.0))
        scene.show_contact("arm0", [(CART_HANDLE_X, 0.0)], frame="b")
        # a typical push (the demo's median hand force is 3.5 N, its cruise 10 N): 3 cm per N, drawn on top
        scene.show_wrench("arm0", [(CART_HANDLE_X, 0.0)], (12.0, 2.0), torque=4.0, frame="b")
        scene.show_wrench("arm0", [(CART_HANDLE_X, 0.0)], (10.0, -3.0), kind="desired", frame="b")
        scene.show_com((0.35, 0.12), (0.30, 0.0))
        s = np.linspace(0.0, 1.0, 60)
        scene.show_trace(
            "plan", np.column_stack((0.9 + 4.0 * s, 0.8 * np.sin(np.pi * s) ** 2)), label="cyan line: a planned path"
        )
        html = scene.save_html(tmp / "scene.html", controls=False)
    browser = find_chromium()
    if browser is None:
        print("chromium not found; wrote only", html, file=sys.stderr)
        return 1
    screenshot(browser, html, OUT / "scene.png")
    shutil.rmtree(tmp)
    print("wrote", OUT / "scene.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())

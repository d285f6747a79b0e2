"""Browser test of a physics run's page: headless Chromium shows both hand-force arrows of a MuJoCo run.

The page of a short MuJoCo push (`wholebody.push.report.build_scene`) is rendered paused at the frame of its
largest allocated hand force, once whole and once each with one of the two arrows hidden: the allocated force
(green) and the F/T-measured force (blue) must each be a visible arrow of its own colour. Needs the Debian
package `chromium` (skipped with one line otherwise, unless CARTPUSH_REQUIRE_BROWSER=1).
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from PIL import Image

from wholebody.viz.browser import find_chromium, screenshot

WIDTH, HEIGHT = 1024, 768
CHROMIUM = find_chromium()
if CHROMIUM is None:
    if os.environ.get("CARTPUSH_REQUIRE_BROWSER") == "1":
        raise RuntimeError("browser tests need headless Chromium [CARTPUSH_REQUIRE_BROWSER=1]")
    pytest.skip("browser tests need headless Chromium: apt-get install chromium", allow_module_level=True)


def render(html, png, profile, fragment: str) -> np.ndarray:
    """Return the RGB screenshot (H, W, 3) of a local page at the URL fragment."""
    assert CHROMIUM is not None
    screenshot(CHROMIUM, html, png, size=(WIDTH, HEIGHT), fragment=fragment, profile=profile, budget_ms=4000)
    return np.asarray(Image.open(png).convert("RGB"), dtype=float).reshape(-1, 3)


def is_blue(p):
    """The measured arrow's blue (0x1565C0 under the scene's lights), not the sky."""
    return (p[:, 2] > 110) & (p[:, 0] < 70) & (p[:, 1] > 50) & (p[:, 1] < 150) & (p[:, 2] - p[:, 1] > 60)


def is_green(p):
    """The allocated arrow's green (0x2E7D32 under the scene's lights)."""
    return (p[:, 1] > 70) & (p[:, 1] - p[:, 0] > 40) & (p[:, 1] - p[:, 2] > 40)


@pytest.fixture(scope="module")
def shots(tmp_path_factory):
    from wholebody.push import PushConfig, build_scene, run_push

    tmp = tmp_path_factory.mktemp("physics_page")
    result = run_push(PushConfig(trajectory=1, duration=8.0, plant="mujoco", contact="fixed"))
    frames = np.arange(0, len(result.t), 10)  # build_scene animates at 10 frames per second
    t = float(result.t[frames[np.argmax(np.linalg.norm(result.wrenches[frames, 0, :2], axis=1))]])
    with build_scene(result) as scene:
        pages = {"page": None, "no_measured": "measured", "no_allocated": "allocated"}
        for name, hide in pages.items():
            if hide is not None:
                scene.viewer["wrenches"][hide].set_property("visible", False)
            scene.save_html(tmp / f"{name}.html", controls=False)
            if hide is not None:
                scene.viewer["wrenches"][hide].set_property("visible", True)
    return {name: render(tmp / f"{name}.html", tmp / f"{name}.png", tmp / "profile", f"#t={t:.2f}") for name in pages}


def test_the_measured_force_is_a_blue_arrow(shots):
    own = is_blue(shots["page"]) & ~is_blue(shots["no_measured"])
    assert own.sum() > 150, f"only {own.sum()} pixels of the measured arrow"


def test_the_allocated_force_is_a_green_arrow(shots):
    own = is_green(shots["page"]) & ~is_green(shots["no_allocated"])
    assert own.sum() > 150, f"only {own.sum()} pixels of the allocated arrow"

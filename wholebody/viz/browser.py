"""Screenshots of offline Meshcat pages with headless Chromium (the docs' figures and the browser tests).

>>> from wholebody.viz.browser import find_chromium, screenshot   # doctest: +SKIP
>>> screenshot(find_chromium(), Path("scene.html"), Path("scene.png"))   # doctest: +SKIP
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from wholebody.errors import SceneError

#: Flags for a reproducible headless render: software WebGL, no network or profile side effects.
HEADLESS_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--enable-unsafe-swiftshader",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--hide-scrollbars",
)


#: Executable names tried, in order.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")


def find_chromium() -> str | None:
    """Return the path of the first Chromium executable on PATH (`CHROMIUM_NAMES`), or None."""
    return next((path for path in map(shutil.which, CHROMIUM_NAMES) if path), None)


def screenshot(
    browser: str,
    html: Path,
    png: Path,
    size: tuple[int, int] = (1024, 640),
    fragment: str = "",
    budget_ms: int = 4000,
    profile: Path | None = None,
    timeout: float = 120.0,
) -> subprocess.CompletedProcess:
    """Render the local page `html` (URL fragment `fragment`) to `png` at `size` pixels after `budget_ms` of virtual time.

    A fresh browser profile is used unless `profile` is given. Raises `SceneError` when no screenshot was written.
    """
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [
            browser,
            *HEADLESS_FLAGS,
            f"--user-data-dir={profile if profile is not None else tmp}",
            f"--window-size={size[0]},{size[1]}",
            f"--virtual-time-budget={budget_ms}",
            f"--screenshot={png}",
            Path(html).resolve().as_uri() + fragment,
        ]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if not Path(png).is_file():
        raise SceneError(f"chromium wrote no screenshot (exit {proc.returncode}): {proc.stderr[-2000:]}")
    return proc


def dump_dom(browser: str, html: Path, fragment: str = "", budget_ms: int = 4000, timeout: float = 120.0) -> str:
    """Return the DOM (HTML text) of the local page `html` after `budget_ms` of virtual time (scripts have run).

    Raises `SceneError` when Chromium printed nothing.
    """
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [
            browser,
            *HEADLESS_FLAGS,
            f"--user-data-dir={tmp}",
            f"--virtual-time-budget={budget_ms}",
            "--dump-dom",
            Path(html).resolve().as_uri() + fragment,
        ]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if not proc.stdout.strip():
        raise SceneError(f"chromium printed no DOM (exit {proc.returncode}): {proc.stderr[-2000:]}")
    return proc.stdout

"""Screenshots of offline Meshcat pages with headless Chromium (the docs' figures and the browser tests).

>>> from wholebody.viz.browser import find_chromium, screenshot   # doctest: +SKIP
>>> screenshot(find_chromium(), Path("scene.html"), Path("scene.png"))   # doctest: +SKIP
"""

from __future__ import annotations

import os
import re
import shutil
import signal
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


#: Flags that make Chromium write the page's console messages to its stderr (`console_messages`).
CONSOLE_FLAGS = ("--enable-logging=stderr", "--v=0")
#: A console line of Chromium's log: ``[...:INFO:CONSOLE:12] "message", source: URL (12)`` (older: ``CONSOLE(12)``).
_CONSOLE_LINE = re.compile(r':CONSOLE(?::\d+|\(\d+\))?\] "(.*)", source: ')


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
    console: bool = False,
) -> subprocess.CompletedProcess:
    """Render the local page `html` (URL fragment `fragment`) to `png` at `size` pixels after `budget_ms` of virtual time.

    A fresh browser profile is used unless `profile` is given. With `console` the page's console messages go
    to the returned process's stderr (`console_messages` reads them). Raises `SceneError` when no screenshot
    was written.
    """
    with tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as tmp:  # a profile Chromium may still write
        cmd = [
            browser,
            *HEADLESS_FLAGS,
            *(CONSOLE_FLAGS if console else ()),
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


def console_messages(stderr: str) -> list[str]:
    """Return the page's console messages (text only) from the stderr of Chromium run with `CONSOLE_FLAGS`."""
    return [m.group(1) for m in map(_CONSOLE_LINE.search, stderr.splitlines()) if m]


def dump_dom(browser: str, html: Path, fragment: str = "", budget_ms: int = 4000, timeout: float = 120.0) -> str:
    """Return the DOM (HTML text) of the local page `html` after `budget_ms` of virtual time (scripts have run).

    Raises `SceneError` when Chromium printed nothing.
    """
    with tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as tmp:  # a profile Chromium may still write
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


class DevToolsPage:
    """A local page open in headless Chromium, driven as a user drives it (mouse clicks, key presses) over DevTools.

    The browser runs in real time (no virtual-time budget). Use it as a context
    manager; `evaluate` reads the page (JavaScript expression -> JSON value),
    `click` presses and releases the mouse at the centre of an element, `press`
    types a key. Raises `SceneError` when the browser does not come up.

    >>> with DevToolsPage(find_chromium(), Path("scene.html")) as page:   # doctest: +SKIP
    ...     page.click("cartpush-play")
    """

    def __init__(self, browser: str, html: Path, size: tuple[int, int] = (1024, 768), timeout: float = 60.0) -> None:
        import asyncio

        self._tmp = tempfile.TemporaryDirectory(ignore_cleanup_errors=True)
        self._timeout = timeout
        self._ids = 0
        cmd = [
            browser,
            *HEADLESS_FLAGS,
            f"--user-data-dir={self._tmp.name}",
            f"--window-size={size[0]},{size[1]}",
            "--remote-debugging-port=0",
            Path(html).resolve().as_uri(),
        ]
        self._proc = subprocess.Popen(
            cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
        )  # its own process group: close() stops Chromium's helper processes with it
        self._loop = asyncio.new_event_loop()
        try:
            self._ws = self._loop.run_until_complete(self._connect())
        except BaseException:
            self.close()
            raise

    async def _connect(self):
        """Return the websocket of the page's DevTools target (polls DevToolsActivePort, then /json/list)."""
        import asyncio
        import json
        import time
        import urllib.request

        from tornado.websocket import websocket_connect

        port_file = Path(self._tmp.name) / "DevToolsActivePort"
        deadline = time.monotonic() + self._timeout
        while time.monotonic() < deadline:
            if self._proc.poll() is not None:
                raise SceneError(f"chromium exited with {self._proc.returncode} before DevTools came up")
            if port_file.is_file() and port_file.read_text().strip():
                port = int(port_file.read_text().split()[0])
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as resp:
                    pages = [t for t in json.loads(resp.read()) if t.get("type") == "page"]
                if pages:
                    return await websocket_connect(pages[0]["webSocketDebuggerUrl"], max_message_size=1 << 26)
            await asyncio.sleep(0.2)
        raise SceneError(f"chromium's DevTools did not come up within {self._timeout:g} s")

    def send(self, method: str, **params: object) -> dict:
        """Send one DevTools command and return its result (raises `SceneError` on a protocol error)."""
        import json

        self._ids += 1
        ident = self._ids

        async def call() -> dict:
            await self._ws.write_message(json.dumps({"id": ident, "method": method, "params": params}))
            while True:
                raw = await self._ws.read_message()
                if raw is None:
                    raise SceneError(f"DevTools closed the connection during {method}")
                msg = json.loads(raw)
                if msg.get("id") == ident:
                    if "error" in msg:
                        raise SceneError(f"DevTools {method}: {msg['error']}")
                    return msg.get("result", {})

        return self._loop.run_until_complete(call())

    def evaluate(self, expression: str) -> object:
        """Return the JSON value of a JavaScript expression evaluated in the page."""
        result = self.send("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in result:
            raise SceneError(f"the page raised evaluating {expression!r}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def click(self, element_id: str) -> None:
        """Press and release the left mouse button at the centre of the element `element_id`, as a user clicks."""
        box = self.evaluate(
            f"(function () {{ const r = document.getElementById({element_id!r}).getBoundingClientRect();"
            " return [r.left + r.width / 2, r.top + r.height / 2]; })()"
        )
        if not isinstance(box, list) or len(box) != 2:
            raise SceneError(f"the page gave no position for the element {element_id!r}, got {box!r}")
        x, y = (float(v) for v in box)
        for kind in ("mousePressed", "mouseReleased"):
            self.send("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", clickCount=1)

    def screenshot(self) -> bytes:
        """Return a PNG screenshot of the page as it is now."""
        import base64

        return base64.b64decode(self.send("Page.captureScreenshot", format="png")["data"])

    def press(self, key: str = " ", code: str = "Space") -> None:
        """Press and release a key (default the space bar) on the page."""
        for kind in ("keyDown", "keyUp"):
            self.send("Input.dispatchKeyEvent", type=kind, key=key, code=code, text=key if kind == "keyDown" else "")

    def close(self) -> None:
        """Close the connection, stop the browser and remove its profile."""
        ws = getattr(self, "_ws", None)
        if ws is not None:
            ws.close()
        if self._proc.poll() is None:
            try:  # the browser and its renderer/GPU helpers, which may still write into the profile
                os.killpg(self._proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                self._proc.kill()
        self._proc.wait()
        self._loop.close()
        self._tmp.cleanup()

    def __enter__(self) -> DevToolsPage:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

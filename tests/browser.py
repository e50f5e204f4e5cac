"""Headless Chromium driven over its DevTools protocol on a pipe (--remote-debugging-pipe: JSON messages ended by
NUL on file descriptors 3 and 4), for tests that open pages as a person would: no websocket or browser-driver
package needed.

    with Browser() as b:
        page = b.open(Path("report/index.html"))   # waits for the load event
        page.errors          # console errors, uncaught exceptions and failed loads, as text
        page.evaluate("document.title")
        page.screenshot()    # PNG bytes
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

CHROMIUM = ("chromium", "chromium-browser", "google-chrome")


def _above_4(fd: int) -> int:
    """`fd` moved to a number above 4, so that setting fds 3 and 4 in the child cannot overwrite it."""
    moved = fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10)
    os.close(fd)
    return moved


def find_chromium() -> str | None:
    return next((p for p in map(shutil.which, CHROMIUM) if p), None)


class Browser:
    def __init__(self, timeout: float = 30.0):
        self.timeout = timeout
        self._id = 0
        self._buffer = b""

    def __enter__(self) -> Browser:
        exe = find_chromium()
        if exe is None:
            raise RuntimeError("no chromium")
        self._profile = tempfile.mkdtemp(prefix="sagebench-chromium-")
        to_chrome_r, self._to_chrome = os.pipe()
        self._from_chrome, from_chrome_w = os.pipe()
        to_chrome_r, from_chrome_w = (_above_4(fd) for fd in (to_chrome_r, from_chrome_w))
        args = ["--headless", "--remote-debugging-pipe", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--no-first-run", "--no-default-browser-check", "--disable-extensions", "--mute-audio",
                f"--user-data-dir={self._profile}", "about:blank"]
        # bash moves Chromium's ends of the pipes to fds 3 and 4 as it becomes Chromium (no Python between fork
        # and exec)
        self._proc = subprocess.Popen(
            ["bash", "-c", f'exec "$0" "$@" 3<&{to_chrome_r} 4>&{from_chrome_w}', exe, *args],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            pass_fds=(to_chrome_r, from_chrome_w))
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        return self

    def __exit__(self, *exc: object) -> None:
        try:
            self.send("Browser.close")
        except (OSError, RuntimeError, TimeoutError):
            pass
        try:
            self._proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        os.close(self._to_chrome)
        os.close(self._from_chrome)
        shutil.rmtree(self._profile, ignore_errors=True)

    # ------------------------------------------------------------ the protocol

    def send(self, method: str, params: dict | None = None, session: str | None = None,
             events: list | None = None) -> dict:
        """Send one command and wait for its answer; the events that arrive meanwhile go to `events`."""
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self._to_chrome, json.dumps(msg).encode() + b"\0")
        while True:
            reply = self._next()
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            if events is not None and "method" in reply:
                events.append(reply)

    def _next(self) -> dict:
        deadline = time.monotonic() + self.timeout
        while b"\0" not in self._buffer:
            if time.monotonic() > deadline:
                raise TimeoutError("chromium did not answer")
            chunk = os.read(self._from_chrome, 1 << 16)
            if not chunk:
                raise RuntimeError("chromium closed its pipe")
            self._buffer += chunk
        line, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(line)

    def open(self, path: Path, width: int = 1200, height: int = 900) -> Page:
        """Open a local file in a new tab and wait for its load event (and a moment for its scripts)."""
        target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        page = Page(self, session, target)
        for method in ("Runtime.enable", "Log.enable", "Page.enable"):
            self.send(method, session=session, events=page.events)
        self.send("Emulation.setDeviceMetricsOverride", {"width": width, "height": height, "deviceScaleFactor": 1,
                                                         "mobile": False}, session=session, events=page.events)
        self.send("Page.navigate", {"url": Path(path).resolve().as_uri()}, session=session, events=page.events)
        deadline = time.monotonic() + self.timeout
        while not any(e["method"] == "Page.loadEventFired" and e.get("sessionId") == session for e in page.events):
            if time.monotonic() > deadline:
                raise TimeoutError(f"{path} did not load")
            reply = self._next()
            if "method" in reply:
                page.events.append(reply)
        page.evaluate("new Promise((done) => requestAnimationFrame(() => setTimeout(done, 50)))")
        return page


@dataclass
class Page:
    browser: Browser
    session: str
    target: str
    events: list = field(default_factory=list)

    def evaluate(self, expression: str):  # noqa: ANN201 - whatever the page returns
        """The value of a JavaScript expression in the page (promises awaited)."""
        result = self.browser.send("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                                        "awaitPromise": True}, self.session, self.events)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def screenshot(self) -> bytes:
        data = self.browser.send("Page.captureScreenshot", {"format": "png"}, self.session, self.events)["data"]
        return base64.b64decode(data)

    @property
    def errors(self) -> list[str]:
        """Console errors, uncaught exceptions and resources that failed to load, one line each."""
        out = []
        for e in self.events:
            if e.get("sessionId") != self.session:
                continue
            p = e.get("params", {})
            if e["method"] == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
                out.append("console: " + " ".join(str(a.get("value", a.get("description"))) for a in p["args"]))
            elif e["method"] == "Runtime.exceptionThrown":
                out.append("exception: " + p["exceptionDetails"].get("text", "") + " " + str(
                    p["exceptionDetails"].get("exception", {}).get("description", "")))
            elif e["method"] == "Log.entryAdded" and p["entry"]["level"] == "error":
                out.append(f"log: {p['entry']['text']} {p['entry'].get('url', '')}")
        return out

    def close(self) -> None:
        self.browser.send("Target.closeTarget", {"targetId": self.target}, events=self.events)

"""A headless Chromium driven over the DevTools protocol on a pipe (--remote-debugging-pipe: no
port, no network, no Python dependency): open a page, wait for a condition, read JSON, take a
screenshot, and record every request the page makes. For the HTML viewer's tests."""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

#: Where Debian installs it (`apt-get install chromium`).
CANDIDATES = ("chromium", "chromium-browser", "google-chrome")
#: Software WebGL in headless mode (SwiftShader through ANGLE); --use-gl=swiftshader alone gives
#: no WebGL context in Chromium 150.
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
         "--no-default-browser-check", "--disable-extensions", "--mute-audio", "--hide-scrollbars",
         "--remote-debugging-pipe")


def find_chromium() -> str | None:
    for name in CANDIDATES:
        exe = shutil.which(name)
        if exe:
            return exe
    return None


class Browser:
    """One headless Chromium with one page; ``requests`` collects the URLs the page asked for."""

    def __init__(self, exe: str, width: int, height: int) -> None:
        self.profile = tempfile.mkdtemp(prefix="vebuild-chromium-")
        r_in, self._w = os.pipe()  # we write commands → chromium's fd 3
        self._r, w_out = os.pipe()  # chromium writes replies on its fd 4 → we read
        args = [exe, *FLAGS, f"--user-data-dir={self.profile}", f"--window-size={width},{height}", "about:blank"]

        def fds() -> None:  # chromium reads commands on fd 3 and answers on fd 4
            a, b = os.dup(r_in), os.dup(w_out)  # above 4, so that the two dup2 cannot clobber each other
            os.dup2(a, 3)
            os.dup2(b, 4)

        self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL, pass_fds=(3, 4), preexec_fn=fds)
        os.close(r_in)
        os.close(w_out)
        self._buf = b""
        self._id = 0
        self.events: list[dict[str, Any]] = []
        self.requests: list[str] = []
        target = None
        deadline = time.time() + 30
        while target is None and time.time() < deadline:
            for t in self.call("Target.getTargets")["targetInfos"]:
                if t["type"] == "page":
                    target = t["targetId"]
            time.sleep(0.05)
        assert target is not None, "chromium opened no page"
        self.session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        self.page("Page.enable")
        self.page("Runtime.enable")
        self.page("Network.enable")
        self.page("Emulation.setDeviceMetricsOverride", {"width": width, "height": height, "deviceScaleFactor": 1,
                                                         "mobile": False})

    def _send(self, method: str, params: dict[str, Any] | None, session: str | None) -> int:
        self._id += 1
        msg: dict[str, Any] = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self._w, json.dumps(msg).encode() + b"\0")
        return self._id

    def _read(self, timeout: float) -> dict[str, Any]:
        import select

        end = time.time() + timeout
        while b"\0" not in self._buf:
            left = end - time.time()
            if left <= 0 or not select.select([self._r], [], [], left)[0]:
                raise TimeoutError("chromium did not answer")
            chunk = os.read(self._r, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed its DevTools pipe")
            self._buf += chunk
        raw, self._buf = self._buf.split(b"\0", 1)
        msg: dict[str, Any] = json.loads(raw)
        if msg.get("method") == "Network.requestWillBeSent":
            self.requests.append(msg["params"]["request"]["url"])
        elif "method" in msg:
            self.events.append(msg)
        return msg

    def call(self, method: str, params: dict[str, Any] | None = None, session: str | None = None,
             timeout: float = 60) -> dict[str, Any]:
        want = self._send(method, params, session)
        while True:
            msg = self._read(timeout)
            if msg.get("id") == want:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                result: dict[str, Any] = msg.get("result", {})
                return result

    def page(self, method: str, params: dict[str, Any] | None = None, timeout: float = 60) -> dict[str, Any]:
        return self.call(method, params, self.session, timeout)

    def evaluate(self, expression: str) -> Any:
        r = self.page("Runtime.evaluate", {"expression": expression, "returnByValue": True, "awaitPromise": True})
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def open(self, url: str) -> None:
        self.page("Page.navigate", {"url": url})

    def wait_for(self, expression: str, timeout: float = 30) -> Any:
        end = time.time() + timeout
        while time.time() < end:
            try:
                value = self.evaluate(expression)
            except RuntimeError:
                value = None
            if value:
                return value
            time.sleep(0.1)
        raise TimeoutError(f"timed out waiting for {expression}")

    def wait_event(self, method: str, timeout: float = 10) -> list[dict[str, Any]]:
        """The parameters of every ``method`` event received so far, waiting up to ``timeout``
        seconds for a first one."""
        end = time.time() + timeout
        while True:
            found = [e["params"] for e in self.events if e.get("method") == method]
            if found or time.time() > end:
                return found
            self.evaluate("0")  # reads what chromium sent meanwhile
            time.sleep(0.05)

    def screenshot(self, path: Path) -> Path:
        data = self.page("Page.captureScreenshot", {"format": "png"})["data"]
        path.write_bytes(base64.b64decode(data))
        return path

    def dom(self) -> str:
        return str(self.evaluate("document.documentElement.outerHTML"))

    def close(self) -> None:
        try:
            self.call("Browser.close", timeout=5)
        except Exception:
            pass
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(10)
        for fd in (self._r, self._w):
            try:
                os.close(fd)
            except OSError:
                pass
        shutil.rmtree(self.profile, ignore_errors=True)

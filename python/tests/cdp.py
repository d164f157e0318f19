"""A minimal Chrome DevTools Protocol client over ``--remote-debugging-pipe`` (standard library
and numpy only): headless Chromium for the viewer's browser test and ``bench/viewer_timing.py``.

Chromium reads commands from file descriptor 3 and writes replies and events to 4, each message a
JSON object followed by a NUL byte. No port is opened and no websocket library is needed.

Every request the page makes is intercepted (``Fetch``) and failed unless it is the page itself
(``allowed``); ``requests`` lists every URL the page asked for (``Network``), ``blocked`` those
that were failed.
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import shutil
import struct
import subprocess
import tempfile
import threading
import time
import zlib
from typing import Any, Callable, Dict, List, Optional

import numpy as np


def find_chromium() -> Optional[str]:
    """``$FUNCORR_CHROMIUM``, else ``chromium`` / ``chromium-browser`` / ``google-chrome`` on PATH."""
    env = os.environ.get("FUNCORR_CHROMIUM")
    if env:
        return env
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


class CdpError(RuntimeError):
    pass


class Browser:
    """Headless Chromium driven over the DevTools pipe; one page (``session``) attached."""

    def __init__(self, binary: str, width: int = 1200, height: int = 700, timeout: float = 30.0):
        self.timeout = timeout
        self.profile = tempfile.mkdtemp(prefix="funcorr-chromium-")
        to_child_r, to_child_w = os.pipe()
        from_child_r, from_child_w = os.pipe()
        # Copies at free descriptors ≥ 100, so that dup2 onto 3 and 4 in the child cannot clobber
        # one of them.
        hi_r = fcntl.fcntl(to_child_r, fcntl.F_DUPFD, 100)
        hi_w = fcntl.fcntl(from_child_w, fcntl.F_DUPFD, 100)

        def child():
            os.dup2(hi_r, 3)
            os.dup2(hi_w, 4)

        args = [
            binary,
            "--headless=new",
            "--remote-debugging-pipe",
            "--no-sandbox",
            "--no-first-run",
            "--no-default-browser-check",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-extensions",
            "--disable-default-apps",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--hide-scrollbars",
            "--mute-audio",
            f"--user-data-dir={self.profile}",
            f"--window-size={width},{height}",
            "about:blank",
        ]
        self.proc = subprocess.Popen(
            args,
            pass_fds=(3, 4),
            preexec_fn=child,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for fd in (to_child_r, from_child_w, hi_r, hi_w):
            os.close(fd)
        self._out = os.fdopen(to_child_w, "wb", buffering=0)
        self._in = os.fdopen(from_child_r, "rb", buffering=0)
        self._lock = threading.Lock()
        self._cond = threading.Condition()
        self._next = 0
        self._replies: Dict[int, dict] = {}
        self.events: List[dict] = []
        self.requests: List[str] = []
        self.blocked: List[str] = []
        self.allowed: Callable[[str], bool] = lambda url: url.startswith("about:")
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.session = None
        targets = self.send("Target.getTargets")["targetInfos"]
        page = next(t for t in targets if t["type"] == "page")
        self.session = self.send("Target.attachToTarget", {"targetId": page["targetId"], "flatten": True})["sessionId"]
        self.send("Runtime.enable")
        self.send("Page.enable")
        self.send("Network.enable")
        self.send("Fetch.enable", {"patterns": [{"urlPattern": "*", "requestStage": "Request"}]})
        self.send("Emulation.setDeviceMetricsOverride", {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})

    # ---- transport -----------------------------------------------------------------------
    def _read(self):
        buf = b""
        while True:
            try:
                chunk = self._in.read(1 << 20)
            except OSError:
                chunk = b""
            if not chunk:
                with self._cond:
                    self._cond.notify_all()
                return
            buf += chunk
            while b"\0" in buf:
                raw, buf = buf.split(b"\0", 1)
                msg = json.loads(raw)
                if "id" in msg:
                    with self._cond:
                        self._replies[msg["id"]] = msg
                        self._cond.notify_all()
                else:
                    self._event(msg)

    def _event(self, msg: dict):
        method, params = msg.get("method"), msg.get("params", {})
        if method == "Fetch.requestPaused":
            url = params["request"]["url"]
            if self.allowed(url):
                self._post("Fetch.continueRequest", {"requestId": params["requestId"]}, msg.get("sessionId"))
            else:
                self.blocked.append(url)
                self._post("Fetch.failRequest", {"requestId": params["requestId"], "errorReason": "BlockedByClient"}, msg.get("sessionId"))
        elif method == "Network.requestWillBeSent":
            self.requests.append(params["request"]["url"])
        with self._cond:
            self.events.append(msg)
            self._cond.notify_all()

    def _post(self, method: str, params: Optional[dict], session: Optional[str]) -> int:
        with self._lock:
            self._next += 1
            mid = self._next
            msg: Dict[str, Any] = {"id": mid, "method": method, "params": params or {}}
            if session:
                msg["sessionId"] = session
            self._out.write(json.dumps(msg).encode() + b"\0")
        return mid

    def send(self, method: str, params: Optional[dict] = None, timeout: Optional[float] = None) -> dict:
        """Sends a command (to the attached page once there is one) and returns its result."""
        mid = self._post(method, params, self.session)
        deadline = time.monotonic() + (timeout or self.timeout)
        with self._cond:
            while mid not in self._replies:
                left = deadline - time.monotonic()
                if left <= 0 or self.proc.poll() is not None:
                    raise CdpError(f"{method}: no reply within {timeout or self.timeout} s (chromium exit code {self.proc.poll()})")
                self._cond.wait(min(left, 0.5))
            reply = self._replies.pop(mid)
        if "error" in reply:
            raise CdpError(f"{method}: {reply['error']}")
        return reply.get("result", {})

    # ---- page helpers ------------------------------------------------------------------------
    def navigate(self, url: str, timeout: Optional[float] = None):
        """Opens ``url`` and waits for its load event."""
        with self._cond:
            seen = len(self.events)
        self.send("Page.navigate", {"url": url})
        self.wait_event("Page.loadEventFired", seen, timeout)

    def wait_event(self, method: str, after: int = 0, timeout: Optional[float] = None) -> dict:
        """The first event ``method`` among the events from index ``after`` on (waits for it)."""
        deadline = time.monotonic() + (timeout or self.timeout)
        with self._cond:
            while True:
                for e in self.events[after:]:
                    if e.get("method") == method:
                        return e
                left = deadline - time.monotonic()
                if left <= 0 or self.proc.poll() is not None:
                    raise CdpError(f"no {method} within {timeout or self.timeout} s")
                self._cond.wait(min(left, 0.5))

    def eval(self, expression: str, timeout: Optional[float] = None) -> Any:
        """Evaluates JavaScript in the page (promises awaited) and returns its value (JSON)."""
        r = self.send(
            "Runtime.evaluate",
            {"expression": expression, "awaitPromise": True, "returnByValue": True},
            timeout,
        )
        if "exceptionDetails" in r:
            d = r["exceptionDetails"]
            raise CdpError(f"{expression[:80]}: {d.get('exception', {}).get('description') or d.get('text')}")
        return r["result"].get("value")

    def exceptions(self) -> List[str]:
        """Uncaught exceptions and console errors of the page so far."""
        out = []
        for e in self.events:
            if e.get("method") == "Runtime.exceptionThrown":
                d = e["params"]["exceptionDetails"]
                out.append(d.get("exception", {}).get("description") or d.get("text", ""))
            elif e.get("method") == "Runtime.consoleAPICalled" and e["params"]["type"] == "error":
                out.append(" ".join(str(a.get("value", a.get("description", ""))) for a in e["params"]["args"]))
        return out

    def screenshot(self) -> np.ndarray:
        """The page as an (h, w, 3) uint8 array."""
        data = base64.b64decode(self.send("Page.captureScreenshot", {"format": "png"})["data"])
        return decode_png(data)

    def click(self, x: float, y: float):
        for kind in ("mouseMoved", "mousePressed", "mouseReleased"):
            self.send("Input.dispatchMouseEvent", {"type": kind, "x": x, "y": y, "button": "left", "buttons": 1 if kind == "mousePressed" else 0, "clickCount": 1})

    def close(self):
        try:
            self._post("Browser.close", None, None)
            self.proc.wait(timeout=10)
        except Exception:
            self.proc.kill()
            self.proc.wait()
        for f in (self._out, self._in):
            try:
                f.close()
            except OSError:
                pass
        shutil.rmtree(self.profile, ignore_errors=True)


def decode_png(data: bytes) -> np.ndarray:
    """Decodes an 8-bit RGB or RGBA, non-interlaced PNG (what Chromium's screenshots are) to an
    (h, w, 3) uint8 array."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat = 8, []
    width = height = bpp = 0
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            width, height, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or ctype not in (2, 6) or interlace:
                raise ValueError(f"unsupported PNG: depth {depth}, colour type {ctype}, interlace {interlace}")
            bpp = 3 if ctype == 2 else 4
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
    raw = zlib.decompress(b"".join(idat))
    stride = width * bpp
    rows = np.zeros((height, stride), np.uint8)
    prev = bytearray(stride)
    for y in range(height):
        start = y * (stride + 1)
        f = raw[start]
        line = raw[start + 1 : start + 1 + stride]
        if f == 0:
            cur = bytearray(line)
        elif f == 2:
            cur = bytearray(((np.frombuffer(line, np.uint8).astype(np.uint16) + np.frombuffer(bytes(prev), np.uint8)) & 255).astype(np.uint8).tobytes())
        elif f == 1:
            a = np.frombuffer(line, np.uint8).reshape(width, bpp).astype(np.uint32)
            cur = bytearray((np.cumsum(a, axis=0) & 255).astype(np.uint8).tobytes())
        else:
            cur = bytearray(line)
            for i in range(stride):
                left = cur[i - bpp] if i >= bpp else 0
                up = prev[i]
                if f == 3:
                    cur[i] = (cur[i] + ((left + up) >> 1)) & 255
                else:
                    ul = prev[i - bpp] if i >= bpp else 0
                    p = left + up - ul
                    pa, pb, pc = abs(p - left), abs(p - up), abs(p - ul)
                    pred = left if pa <= pb and pa <= pc else up if pb <= pc else ul
                    cur[i] = (cur[i] + pred) & 255
        rows[y] = np.frombuffer(bytes(cur), np.uint8)
        prev = cur
    return rows.reshape(height, width, bpp)[:, :, :3].copy()

"""Real studios for the tests: `drivestudio studio` started as a process (its URL read from what it prints), a
WebSocket client that speaks the page's protocol, and Debian's Chromium driven by Selenium."""
from __future__ import annotations

import asyncio
import json
import os
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from drivestudio.studio.protocol import unpack_frame

REPO = Path(__file__).resolve().parents[2]
CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
FLAGS = ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--window-size=1500,1000")


class Studio:
    """A `drivestudio VERB ... --port 0` process and the URL it printed."""

    def __init__(self, args: list[str], out: Path, marker: str = "open ", timeout: float = 90.0):
        self.out = out
        env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               "PYTHONUNBUFFERED": "1"}
        self.proc = subprocess.Popen([sys.executable, "-m", "drivestudio", *args], cwd=REPO, env=env,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        self._pending = ""      # printed, not yet a whole line
        self.url = self._wait_for(marker, timeout).split(marker, 1)[1].strip()

    def _wait_for(self, marker: str, timeout: float) -> str:
        """The first printed line holding `marker`. The pipe is read in chunks straight from its descriptor, so
        that lines already printed are never left in a reader's buffer that select() cannot see."""
        out = self.proc.stdout
        assert out is not None   # started with stdout=PIPE
        fd = out.fileno()
        end = time.monotonic() + timeout
        while True:
            while "\n" in self._pending:
                line, self._pending = self._pending.split("\n", 1)
                self.lines.append(line + "\n")
                if marker in line:
                    return line + "\n"
            if time.monotonic() >= end:
                break
            ready, _, _ = select.select([fd], [], [], 0.5)
            if not ready:
                if self.proc.poll() is not None:
                    break
                continue
            chunk = os.read(fd, 65536)
            if not chunk:
                break
            self._pending += chunk.decode(errors="replace")
        self.stop()
        raise AssertionError(f"no '{marker}' from {self.proc.args!r}: {''.join(self.lines)[-2000:]}")

    @property
    def base(self) -> str:
        return self.url.split("?", 1)[0].rstrip("/")

    @property
    def ws_url(self) -> str:
        return self.base.replace("http://", "ws://") + "/ws"

    @property
    def token(self) -> str | None:
        return self.url.split("token=", 1)[1] if "token=" in self.url else None

    def stop(self, sig: int = signal.SIGINT) -> str:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        chunks = []
        while self.proc.stdout is not None and (chunk := os.read(self.proc.stdout.fileno(), 65536)):
            chunks.append(chunk)
        self.lines.append(self._pending + b"".join(chunks).decode(errors="replace"))
        self._pending = ""
        return "".join(self.lines)


# --- a page without a browser: the protocol over aiohttp's client ------------------------------------------------
class Client:
    """A WebSocket client that acknowledges frames as the page does."""

    def __init__(self, ws):
        self.ws = ws
        self.hello: dict | None = None
        self.texts: list[dict] = []
        self.states: list[dict] = []

    async def receive(self, until, timeout: float = 30.0) -> None:
        """Take messages until until(self) is true."""
        end = time.monotonic() + timeout
        while not until(self):
            left = end - time.monotonic()
            if left <= 0:
                raise AssertionError(f"timed out; texts {self.texts[-5:]}, {len(self.states)} frames")
            msg = await self.ws.receive(timeout=left)
            if msg.type.name == "TEXT":
                obj = json.loads(msg.data)
                self.texts.append(obj)
                if obj["type"] == "hello":
                    self.hello = obj
            elif msg.type.name == "BINARY":
                state, _ = unpack_frame(msg.data)
                self.states.append(state)
                await self.ws.send_str(json.dumps({"type": "ack", "seq": state["seq"]}))
            else:
                raise AssertionError(f"the socket closed: {msg}")

    async def send(self, obj) -> None:
        await self.ws.send_str(obj if isinstance(obj, str) else json.dumps(obj))

    def errors(self) -> list[str]:
        return [t["message"] for t in self.texts if t["type"] == "error"]

    def infos(self) -> list[str]:
        return [t["message"] for t in self.texts if t["type"] == "info"]


async def connect(session, studio: Studio, headers: dict | None = None) -> Client:
    url = studio.ws_url + (f"?token={studio.token}" if studio.token else "")
    return Client(await session.ws_connect(url, headers=headers or {}, max_msg_size=0))


def run(coro):
    return asyncio.run(coro)


# --- a real browser --------------------------------------------------------------------------------------------
def browser():
    """Headless Chromium under Selenium (skips the test where Debian's chromium is not installed)."""
    if not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()):
        pytest.skip("needs Debian's chromium and chromium-driver (apt-get install -y chromium chromium-driver)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in FLAGS:
        opts.add_argument(flag)
    profile = tempfile.mkdtemp(prefix="studio-chromium-")
    opts.add_argument(f"--user-data-dir={profile}")
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    driver.profile_dir = profile  # type: ignore[attr-defined]   # removed with the driver (quit_chromium)
    return driver


def close_browser(driver) -> None:
    driver.quit()
    shutil.rmtree(driver.profile_dir, ignore_errors=True)


def page_state(driver, expr: str = "window.studio"):
    return driver.execute_script(f"return {expr};")


def wait_page(driver, expr: str, timeout: float = 30.0):
    """Wait until the JavaScript expression is truthy; returns its value."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = driver.execute_script(f"return {expr};")
        if value:
            return value
        time.sleep(0.1)
    seen = driver.execute_script("return [window.studio && window.studio.errors, "
                                 "document.body.innerText.slice(0, 300)]")
    raise AssertionError(f"the page never had {expr}: {seen}")

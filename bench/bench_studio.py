"""The studio's targets (issue 22), measured in the page of a real browser (Debian's Chromium, headless, under
Selenium) on this machine: the browser, the studio and its world share its cores.

    python bench/bench_studio.py [--seconds 10] [--presses 20] [--windows 12] [--window 5] [--json F]

1. Frames to the page: `drivestudio studio` with the world's own driver; frames drawn in the page per second
   over --seconds (after 3 s of warm-up), the 280x210 camera (highway, as fast as it can: its real time is 10 Hz)
   and the stereo pair (sidewalk, real time at 30 Hz, and as fast as it can). Targets: >= 30 and >= 20 frames/s.
2. Key to command: the person drives in real time; the page notes performance.now() at a key press and again when
   the first step whose command differs reaches it (window.studio.latencies); --presses presses, each from a
   steady command. Target: within 100 ms.
3. --view's cost: one long `drivestudio drive --model oracle --view` (highway, two processes over shared memory,
   lock-step), watched and not watched in alternating windows of --window seconds (--windows of each), probed
   from outside: the steps published (the bridge segment's frame_seq) give the loop rate of each window (target:
   at most 10 % slower while watched), and /proc gives the CPU time a step of the loop's thread, of the process's
   other threads (the server's) and of the driver process. Alternating windows of one run let the machine's other
   work drift alike over both kinds. Once with a page in Chromium on the same two cores, once with a protocol
   client that takes and acknowledges every frame and draws nothing (the publishing alone).
"""
from __future__ import annotations

import argparse
import asyncio
import json
import mmap
import os
import random
import statistics
import struct
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import aiohttp  # noqa: E402
from selenium.webdriver.common.action_chains import ActionChains  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402

from shm_bridge.layout import OFFSET  # noqa: E402
from tests.studio.helpers import Studio, browser, close_browser, connect, wait_page  # noqa: E402

WARMUP = 3.0     # [s] before counting frames


def frames_to_page(page, args: list[str], seconds: float, tmp: Path) -> dict:
    s = Studio(["studio", "--port", "0", "--out", str(tmp), *args], tmp)
    try:
        page.get(s.url)
        wait_page(page, "window.studio.drawn >= 3")
        time.sleep(WARMUP)
        n0, t0 = page.execute_script("return window.studio.drawn"), time.perf_counter()
        loop = []
        while time.perf_counter() - t0 < seconds:
            time.sleep(0.5)
            loop.append(page.execute_script("return window.studio.state.loop_hz"))
        n1, t1 = page.execute_script("return window.studio.drawn"), time.perf_counter()
        kb = page.execute_script("return window.studio.bytes / window.studio.frames / 1024")
    finally:
        s.stop()
    return {"args": args, "frames_per_s": round((n1 - n0) / (t1 - t0), 1),
            "loop_hz": round(statistics.median(loop), 1), "kb_per_frame": round(kb, 1)}


def key_latency(page, world: str, presses: int, tmp: Path) -> dict:
    s = Studio(["studio", "--world", world, "--port", "0", "--out", str(tmp)], tmp)
    try:
        page.get(s.url)
        wait_page(page, "window.studio.drawn >= 5")
        page.execute_script("window.studio.latencies = []")
        rng = random.Random(0)
        for k in range(presses):
            key = Keys.ARROW_LEFT if k % 2 else Keys.ARROW_RIGHT
            time.sleep(rng.uniform(0.6, 0.7))     # the steering is back in the centre; a press lands anywhere in a step
            ActionChains(page).key_down(key).perform()
            time.sleep(0.25)
            ActionChains(page).key_up(key).perform()
        time.sleep(0.5)
        lat = page.execute_script("return window.studio.latencies")
    finally:
        s.stop()
    lat = sorted(lat)
    return {"world": world, "presses": presses, "measured": len(lat), "median_ms": round(statistics.median(lat), 1),
            "p95_ms": round(lat[min(len(lat) - 1, int(0.95 * len(lat)))], 1), "max_ms": round(lat[-1], 1)}


def browser_cpu() -> float:
    """CPU seconds Chromium's processes have used so far."""
    total = 0
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            if b"chromium" not in Path(f"/proc/{pid}/cmdline").read_bytes():
                continue
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            total += int(fields[11]) + int(fields[12])
        except OSError:
            continue
    return total / os.sysconf("SC_CLK_TCK")


class ProtocolClient:
    """A page without a browser: it takes and acknowledges every frame as the page does, and draws nothing; `t` is
    the simulated time of the newest frame."""

    def __init__(self, studio: Studio):
        self.studio = studio
        self.t: float | None = None
        self._stop = threading.Event()
        self.thread = threading.Thread(target=asyncio.run, args=(self._watch(),), daemon=True)
        self.thread.start()

    async def _watch(self) -> None:
        async with aiohttp.ClientSession() as http:
            c = await connect(http, self.studio)

            def until(c) -> bool:
                if c.states:
                    self.t = c.states[-1]["t"]
                return self._stop.is_set()
            try:
                await c.receive(until, timeout=3600)
            finally:
                await c.ws.close()

    def close(self) -> None:
        self._stop.set()
        self.thread.join(timeout=10)


TICK = os.sysconf("SC_CLK_TCK")


def _cpu(stat: Path) -> float:
    """CPU seconds (user + system) of a /proc stat file."""
    fields = stat.read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


class RunProbe:
    """What a `drive` run does, read from outside it: the steps it has published (the bridge segment's frame_seq,
    docs/shm-protocol.md) and the CPU time of its loop's thread, of its other threads (the server's) and of its
    driver process."""

    def __init__(self, pid: int):
        self.pid = pid
        end = time.monotonic() + 30
        path = Path(f"/dev/shm/drivestudio-{pid}")
        while not path.exists() and time.monotonic() < end:
            time.sleep(0.1)
        self._file = open(path, "rb")
        self._map = mmap.mmap(self._file.fileno(), 0, access=mmap.ACCESS_READ)
        children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
        self.driver = int(children[0])

    def read(self) -> tuple[float, int, float, float, float]:
        """(wall seconds, steps, loop thread CPU, other threads' CPU, driver CPU)."""
        steps = struct.unpack_from("<Q", self._map, OFFSET["frame_seq"])[0]
        loop = _cpu(Path(f"/proc/{self.pid}/task/{self.pid}/stat"))
        others = sum(_cpu(t / "stat") for t in Path(f"/proc/{self.pid}/task").iterdir() if t.name != str(self.pid))
        return time.perf_counter(), steps, loop, others, _cpu(Path(f"/proc/{self.driver}/stat"))

    def close(self) -> None:
        self._map.close()
        self._file.close()


def _window(probe: RunProbe, seconds: float) -> dict:
    a = probe.read()
    time.sleep(seconds)
    b = probe.read()
    n = max(1, b[1] - a[1])
    return {"hz": n / (b[0] - a[0]), "loop_ms": (b[2] - a[2]) / n * 1e3, "server_ms": (b[3] - a[3]) / n * 1e3,
            "driver_ms": (b[4] - a[4]) / n * 1e3}


def view_cost(page, how: str, windows: int, window: float, tmp: Path) -> dict:
    """One long `drive --view` run (highway oracle, lock-step over shared memory), watched (by a page in Chromium,
    or a protocol client) and not watched in alternating windows of `window` seconds, probed from outside."""
    out = Path(tempfile.mkdtemp(dir=tmp))
    s = Studio(["drive", "--model", "oracle", "--seconds", "800000", "--view", "0", "--out", str(out)],
               out, marker="watch the run at ")
    probe = RunProbe(s.proc.pid)
    watched, unwatched = [], []
    browser0, t0 = browser_cpu(), time.perf_counter()
    try:
        for _ in range(windows):
            client = None
            if how == "browser":
                page.get(s.url)
                wait_page(page, "window.studio.drawn >= 1")
            else:
                client = ProtocolClient(s)
                end = time.monotonic() + 30
                while client.t is None and time.monotonic() < end:
                    time.sleep(0.05)
            watched.append(_window(probe, window))
            if client is not None:
                client.close()
            else:
                page.get("about:blank")
            time.sleep(0.3)      # the page is gone
            unwatched.append(_window(probe, window))
    finally:
        probe.close()
        s.stop()
    browser_share = (browser_cpu() - browser0) / (time.perf_counter() - t0)
    ratios = [1 - w["hz"] / u["hz"] for w, u in zip(watched, unwatched)]

    def med(rows: list[dict], key: str) -> float:
        return round(statistics.median(r[key] for r in rows), 3)
    return {"how": how, "windows": windows, "window_s": window,
            "watched_hz": med(watched, "hz"), "unwatched_hz": med(unwatched, "hz"),
            "median_slowdown": round(statistics.median(ratios), 4),
            "quartiles": [round(q, 4) for q in statistics.quantiles(ratios, n=4)],
            "loop_thread_ms": [med(watched, "loop_ms"), med(unwatched, "loop_ms")],
            "server_threads_ms": [med(watched, "server_ms"), med(unwatched, "server_ms")],
            "driver_ms": [med(watched, "driver_ms"), med(unwatched, "driver_ms")],
            "browser_cpu_share": round(browser_share, 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=10.0, help="wall-clock seconds of frame counting per run")
    ap.add_argument("--presses", type=int, default=20, help="key presses per world")
    ap.add_argument("--windows", type=int, default=12, help="watched (and as many unwatched) windows of the --view run")
    ap.add_argument("--window", type=float, default=5.0, help="wall-clock seconds of a window")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    out: dict = {"load_average_start": round(os.getloadavg()[0], 2)}
    page = browser()
    try:
        with tempfile.TemporaryDirectory() as tmp_:
            tmp = Path(tmp_)
            runs = {"highway camera, as fast as it can": ["--model", "oracle", "--fast"],
                    "highway camera, real time (10 Hz)": ["--model", "oracle"],
                    "sidewalk stereo pair, real time (30 Hz)": ["--world", "sidewalk", "--model", "expert"],
                    "sidewalk stereo pair, as fast as it can": ["--world", "sidewalk", "--model", "expert", "--fast"]}
            out["frames"] = {}
            print("| run | frames/s in the page | loop Hz | kB a frame |\n|---|---|---|---|")
            for name, a in runs.items():
                r = frames_to_page(page, a, args.seconds, tmp)
                out["frames"][name] = r
                print(f"| {name} | {r['frames_per_s']} | {r['loop_hz']} | {r['kb_per_frame']} |", flush=True)
            out["latency"] = {}
            print("\n| world (real time) | key presses | median ms | p95 ms | max ms |\n|---|---|---|---|---|")
            for world in ("sidewalk", "highway"):
                r = key_latency(page, world, args.presses, tmp)
                out["latency"][world] = r
                print(f"| {world} | {r['measured']}/{r['presses']} | {r['median_ms']} | {r['p95_ms']} | "
                      f"{r['max_ms']} |", flush=True)
            out["view"] = {}
            print("\n| watched by | windows | loop Hz watched, not | slowdown (median; quartiles) | CPU ms a step "
                  "watched, not: loop thread; server threads; driver | browser CPU |\n|---|---|---|---|---|---|")
            for how in ("browser", "client"):
                r = view_cost(page, how, args.windows, args.window, tmp)
                out["view"][how] = r
                print(f"| {'a page in Chromium' if how == 'browser' else 'a protocol client'} | {r['windows']} x "
                      f"{r['window_s']:g} s | {r['watched_hz']:.0f}, {r['unwatched_hz']:.0f} | "
                      f"{r['median_slowdown']:.1%} ({', '.join(f'{q:.1%}' for q in r['quartiles'])}) | "
                      f"{r['loop_thread_ms'][0]:.2f}, {r['loop_thread_ms'][1]:.2f}; {r['server_threads_ms'][0]:.2f}, "
                      f"{r['server_threads_ms'][1]:.2f}; {r['driver_ms'][0]:.2f}, {r['driver_ms'][1]:.2f} | "
                      f"{r['browser_cpu_share']:.0%} of a core |", flush=True)
    finally:
        close_browser(page)
    out["load_average_end"] = round(os.getloadavg()[0], 2)
    if args.json:
        args.json.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()

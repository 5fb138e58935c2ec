"""The studio's targets (issue 22), measured in the page of a real browser (Debian's Chromium, headless, under
Selenium) on this machine: the browser, the studio and its world share its cores.

    python bench/bench_studio.py [--seconds 10] [--presses 20] [--view-seconds 600] [--rounds 3] [--json F]

1. Frames to the page: `drivestudio studio` with the world's own driver; frames drawn in the page per second
   over --seconds (after 3 s of warm-up), the 280x210 camera (highway, as fast as it can: its real time is 10 Hz)
   and the stereo pair (sidewalk, real time at 30 Hz, and as fast as it can). Targets: >= 30 and >= 20 frames/s.
2. Key to command: the person drives in real time; the page notes performance.now() at a key press and again when
   the first step whose command differs reaches it (window.studio.latencies); --presses presses, each from a
   steady command. Target: within 100 ms.
3. --view's cost: `drivestudio drive --model oracle` (highway, two processes over shared memory, lock-step) for
   --view-seconds simulated seconds, without and with `--view` and a page watching, alternated --rounds times;
   the loop rate of each run's metrics.json (target: at most 10 % slower), and, less sensitive to other work on
   the machine, the CPU time the run's two processes spent a step and the browser's share of a core.
"""
from __future__ import annotations

import argparse
import json
import os
import random
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from selenium.webdriver.common.action_chains import ActionChains  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402

from tests.studio.helpers import Studio, browser, close_browser, wait_page  # noqa: E402

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


def drive_rate(page, view: bool, seconds: float, tmp: Path) -> dict:
    """One `drive` run: its loop rate, the CPU its two processes spent a step, and the browser's CPU share."""
    out = Path(tempfile.mkdtemp(dir=tmp))
    args = ["drive", "--model", "oracle", "--seconds", str(seconds), "--out", str(out)]
    cpu0, browser0, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), browser_cpu(), time.perf_counter()
    if view:
        s = Studio(args + ["--view", "--view-port", "0"], out, marker="watch the run at ")
        page.get(s.url)
        wait_page(page, "window.studio.drawn >= 1")
    else:
        s = Studio(args, out, marker="waiting for a driver")
    s.proc.wait(timeout=3600)
    s.stop()
    cpu1, browser1, t1 = resource.getrusage(resource.RUSAGE_CHILDREN), browser_cpu(), time.perf_counter()
    m = json.loads((out / "metrics.json").read_text())
    steps = m["simulated_time_s"] / 0.1
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    return {"loop_hz": m["loop_rate_hz"], "cpu_ms_per_step": round(cpu / steps * 1e3, 3),
            "browser_cpu_share": round((browser1 - browser0) / (t1 - t0), 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=10.0, help="wall-clock seconds of frame counting per run")
    ap.add_argument("--presses", type=int, default=20, help="key presses per world")
    ap.add_argument("--view-seconds", type=float, default=600.0, help="simulated seconds of each --view run")
    ap.add_argument("--rounds", type=int, default=3, help="pairs of runs without and with --view")
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
            pairs = []
            print("\n| round | drive Hz | drive --view Hz (a page watching) | slowdown | CPU ms a step (drive, --view) "
                  "| browser CPU |\n|---|---|---|---|---|---|")
            for k in range(args.rounds):
                plain = drive_rate(page, False, args.view_seconds, tmp)
                viewed = drive_rate(page, True, args.view_seconds, tmp)
                slow = round(1 - viewed["loop_hz"] / plain["loop_hz"], 4)
                pairs.append({"plain": plain, "view": viewed, "slowdown": slow})
                print(f"| {k + 1} | {plain['loop_hz']} | {viewed['loop_hz']} | {slow:.1%} | "
                      f"{plain['cpu_ms_per_step']}, {viewed['cpu_ms_per_step']} | "
                      f"{viewed['browser_cpu_share']:.0%} of a core |", flush=True)
            slows = [p["slowdown"] for p in pairs]
            extra = [p["view"]["cpu_ms_per_step"] - p["plain"]["cpu_ms_per_step"] for p in pairs]
            out["view"] = {"seconds": args.view_seconds, "pairs": pairs, "median_slowdown": statistics.median(slows),
                           "range": [min(slows), max(slows)],
                           "median_extra_cpu_ms_per_step": round(statistics.median(extra), 3),
                           "median_plain_cpu_ms_per_step": statistics.median(p["plain"]["cpu_ms_per_step"]
                                                                             for p in pairs),
                           "median_browser_cpu_share": statistics.median(p["view"]["browser_cpu_share"]
                                                                         for p in pairs)}
            print(f"\n--view slows the lock-step loop by {statistics.median(slows):.1%} (median of {len(slows)} "
                  f"pairs; {min(slows):.1%} to {max(slows):.1%}); it adds "
                  f"{out['view']['median_extra_cpu_ms_per_step']:.3f} ms of CPU a step to the run's processes")
    finally:
        close_browser(page)
    out["load_average_end"] = round(os.getloadavg()[0], 2)
    if args.json:
        args.json.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()

"""The pictures and the worked example of docs/studio.md, made with the real studio in a real browser (Debian's
Chromium, headless, under Selenium): `python docs/figures/studio_figures.py --out /tmp/studio-figures`.

    studio-highway.png    the page on the highway: a GIST regressor drives, its estimate beside the truth
    studio-sidewalk.png   the page on the sidewalk while a person drives and records

and the human-driven set, end to end: a person at the keyboard (here a small script standing in for one: it reads
the labels panel, where the expert's steering and motor for the frame are shown, and holds the arrow keys toward
them, as a person learning from a co-pilot would) drives the sidewalk in real time through the page and records a
dataset with the Record button; `stats` reads it, `train` fits a Z2Color on it, `evaluate` measures it
on its test episode and `drive` lets it drive under the expert's correction (percentage autonomy). Every step is
skipped when its output exists, so an interrupted run continues.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from selenium.webdriver.common.action_chains import ActionChains  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402

from tests.studio.helpers import Studio, browser, close_browser, wait_page  # noqa: E402

IMG = ROOT / "docs" / "img"
ARROWS = {"left": Keys.ARROW_LEFT, "right": Keys.ARROW_RIGHT, "up": Keys.ARROW_UP, "down": Keys.ARROW_DOWN}


def cli(*args, log=None) -> str:
    cmd = [sys.executable, "-m", "drivestudio", *map(str, args)]
    print("$ drivestudio " + " ".join(map(str, args)), flush=True)
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"failed ({r.returncode}): {r.stderr.strip()[-500:]}")
    if log is not None:
        Path(log).write_text(r.stdout)
    return r.stdout


def highway_shot(page, out: Path) -> None:
    """A small GIST regressor of the highway drives, so that its estimate boxes and error bars show."""
    data, model = out / "highway-data", out / "highway-gist.pt"
    if not (data / "manifest.json").exists():
        cli("generate", "--out", data, "--frames", 2000)
    if not model.exists():
        cli("train", "--data", data, "--model", "gist", "--out", model)
    s = Studio(["studio", "--port", "0", "--model", model, "--out", out / "studio-highway"], out)
    try:
        page.get(s.url)
        wait_page(page, "window.studio.drawn >= 5")
        # a moment with an estimated car ahead (purple) beside the truth
        wait_page(page, "window.studio.state.t > 4 && window.studio.state.labels.find(l => l.name === 'dist_MM')"
                        ".estimate < 50", timeout=120)
        page.save_screenshot(str(IMG / "studio-highway.png"))
        print("wrote", IMG / "studio-highway.png")
    finally:
        s.stop()


def drive_like_a_person(page, seconds: float, shot: Path | None = None) -> None:
    """Hold the arrows toward the expert's command shown in the labels panel, about 25 times a second."""
    held: set[str] = set()

    def press(want: set[str]) -> None:
        chain = ActionChains(page)
        for k in held - want:
            chain.key_up(ARROWS[k])
        for k in want - held:
            chain.key_down(ARROWS[k])
        chain.perform()
        held.clear()
        held.update(want)

    end = time.monotonic() + seconds
    shot_at = time.monotonic() + seconds / 2
    while time.monotonic() < end:
        s = page.execute_script("const s = window.studio.state; return s && [s.labels.map(l => l.truth), s.command];")
        if s:
            (steer, motor), (cmd_steer, cmd_motor) = s
            want = set()
            if steer > cmd_steer + 0.02:
                want.add("right")
            elif steer < cmd_steer - 0.02:
                want.add("left")
            if motor > cmd_motor + 0.01:
                want.add("up")
            elif motor < cmd_motor - 0.08:
                want.add("down")
            press(want)
        if shot is not None and time.monotonic() > shot_at:
            page.save_screenshot(str(shot))
            print("wrote", shot)
            shot = None
        time.sleep(0.04)
    press(set())


def sidewalk_set(page, out: Path, seconds: float) -> Path:
    root = out / "studio-sidewalk" / "recordings" / "person"
    if (root / "manifest.json").exists() and json.loads((root / "manifest.json").read_text())["complete"]:
        return root
    s = Studio(["studio", "--world", "sidewalk", "--port", "0", "--out", out / "studio-sidewalk"], out)
    try:
        page.get(s.url)
        wait_page(page, "window.studio.drawn >= 5")
        page.find_element(By.ID, "rec-name").send_keys("person")
        page.find_element(By.ID, "record").click()
        page.find_element(By.TAG_NAME, "body").click()
        wait_page(page, "window.studio.state.recording")
        drive_like_a_person(page, seconds, shot=IMG / "studio-sidewalk.png")
        page.find_element(By.ID, "record").click()
        print(wait_page(page, "window.studio.infos.find(m => m.startsWith('recorded'))", timeout=60))
    finally:
        s.stop()
    return root


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("/tmp/studio-figures"))
    ap.add_argument("--seconds", type=float, default=150.0, help="wall-clock seconds the person drives")
    ap.add_argument("--epochs", type=int, default=6)
    args = ap.parse_args()
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    page = browser()
    try:
        if not (IMG / "studio-highway.png").exists():
            highway_shot(page, out)
        data = sidewalk_set(page, out, args.seconds)
    finally:
        close_browser(page)
    cli("stats", data, log=out / "stats.txt")
    model = out / "person-z2color.pt"     # the set holds direct mode only: Z2Color without the modal input (MTL)
    if not model.exists():
        cli("train", "--data", data, "--model", "z2color", "--set", "mtl=direct", "--out", model, "--epochs",
            args.epochs, "--device", "cpu", log=out / "train.txt")
    cli("evaluate", "--data", data, "--model", model, "--out", out / "evaluate", log=out / "evaluate.txt")
    cli("drive", "--world", "sidewalk", "--model", model, "--seconds", 60, "--out", out / "drive",
        log=out / "drive.txt")
    print((out / "drive.txt").read_text())


if __name__ == "__main__":
    main()

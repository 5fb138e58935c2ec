"""The studio in a real browser: Debian's Chromium, headless, driven by Selenium, against real studios. The page
loads, frames advance, a key press steers the car, a take-over is counted, a recording becomes a dataset that `stats`
reads, a wrong token is refused, and a watched run (drive --view) shows read-only."""
from __future__ import annotations

import subprocess
import sys
import time

import pytest
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys

from perception.shards import Dataset
from tests.studio.helpers import REPO, Studio, page_state, wait_page


@pytest.fixture(scope="module")
def highway(tmp_path_factory):
    """The highway in real time, the person at the wheel, a token in the URL (--host)."""
    out = tmp_path_factory.mktemp("highway")
    s = Studio(["studio", "--host", "127.0.0.1", "--port", "0", "--cars", "4", "--out", str(out)], out)
    yield s
    s.stop()


@pytest.fixture(scope="module")
def sidewalk(tmp_path_factory):
    """The sidewalk in real time, the poor driver (a network's stand-in) driving autonomously."""
    out = tmp_path_factory.mktemp("sidewalk")
    s = Studio(["studio", "--world", "sidewalk", "--port", "0", "--model", "poor", "--operation", "autonomous",
                "--obstacles", "none", "--out", str(out)], out)
    yield s
    s.stop()


def label(driver, name: str) -> float:
    return driver.execute_script(f"return window.studio.state.labels.find(l => l.name === '{name}').truth;")


def sim_wait(driver, seconds: float) -> None:
    """Until the world has run `seconds` of simulated time (a loaded machine steps it slower than the wall clock)."""
    t0 = page_state(driver, "window.studio.state.t")
    wait_page(driver, f"window.studio.state.t >= {t0 + seconds}")


def hold(driver, key, seconds: float) -> None:
    """Hold a key for `seconds` of simulated time."""
    ActionChains(driver).key_down(key).perform()
    sim_wait(driver, seconds)
    ActionChains(driver).key_up(key).perform()


def test_the_page_loads_and_frames_advance(page, highway):
    page.get(highway.url)
    hello = wait_page(page, "window.studio.hello")
    assert hello["world"] == "highway" and hello["role"] == "driver"
    assert "highway" in page.find_element(By.ID, "world").text
    wait_page(page, "window.studio.drawn >= 5")
    t0 = page_state(page, "window.studio.state.t")
    wait_page(page, "window.studio.drawn >= 15")
    assert page_state(page, "window.studio.state.t") > t0
    sizes = page_state(page, "[...document.querySelectorAll('canvas')].map(c => [c.id, c.width, c.height])")
    assert ["cam-front", 280, 210] in sizes and ["topdown", 320, 660] in sizes
    assert page_state(page, "window.studio.errors") == []


def test_a_key_press_steers_the_car(page, highway):
    page.get(highway.url)
    wait_page(page, "window.studio.drawn >= 5 && window.studio.state.driver === 'human'")
    before_marking, before_angle = label(page, "toMarking_ML"), label(page, "angle")
    before_lane = label(page, "lanes_left")
    hold(page, Keys.ARROW_LEFT, 1.2)
    steered = page_state(page, "window.studio.state.command[0]")
    sim_wait(page, 0.3)
    after_marking, after_angle = label(page, "toMarking_ML"), label(page, "angle")
    assert steered >= 0.0
    # turned left: the car's nose points left of the road (angle < 0) and it moved toward its left marking
    assert after_angle < before_angle - 0.02
    # toward its left marking, onto it (the in-lane system then inactive: toMarking_ML at its floor, -5.5 m), or,
    # where a loaded machine stepped on while the key was still down, over it into the lane on the left (whose
    # left marking toMarking_ML then measures)
    assert after_marking > before_marking + 0.3 or after_marking <= -5.5 + 1e-6 or \
        label(page, "lanes_left") < before_lane
    assert page_state(page, "window.studio.latencies.length") >= 1


def test_a_wrong_token_is_refused(page, highway):
    page.get(highway.base + "/?token=not-the-token")        # even beside the right cookie of the visits before
    assert "wrong or missing token" in page.find_element(By.TAG_NAME, "body").text
    page.delete_all_cookies()
    page.get(highway.base + "/")
    assert "wrong or missing token" in page.find_element(By.TAG_NAME, "body").text
    page.get(highway.url)
    assert wait_page(page, "window.studio.hello")["world"] == "highway"


def test_a_take_over_is_counted(page, sidewalk):
    page.get(sidewalk.url)
    wait_page(page, "window.studio.drawn >= 5 && window.studio.state.metrics.corrections !== undefined")
    assert page_state(page, "window.studio.state.metrics.corrections") == 0
    ActionChains(page).key_down(Keys.ARROW_UP).perform()
    # the record of a step carries the operation of the command before it: from the take-over's second step on
    taken = wait_page(page, "window.studio.state.takeover && window.studio.state.controller.operation === "
                            "'correctional' && window.studio.state.controller", timeout=10)
    ActionChains(page).key_up(Keys.ARROW_UP).perform()
    assert taken["correcting"] is True
    wait_page(page, "!window.studio.state.takeover", timeout=10)
    time.sleep(0.5)     # the metrics are refreshed four times a second
    metrics = page_state(page, "window.studio.state.metrics")
    assert metrics["corrections"] == 1 and metrics["autonomy_percent"] < 100


def test_a_recording_in_the_page_becomes_a_dataset_that_stats_reads(page, sidewalk):
    page.get(sidewalk.url)
    wait_page(page, "window.studio.drawn >= 3")
    page.find_element(By.ID, "rec-name").send_keys("from-the-page")
    page.find_element(By.ID, "record").click()
    wait_page(page, "window.studio.state.recording && window.studio.state.recording.steps > 0")
    page.find_element(By.TAG_NAME, "body").click()            # the keys go to the page, not the name field
    hold(page, Keys.ARROW_UP, 1.0)
    page.find_element(By.ID, "record").click()
    done = wait_page(page, "window.studio.infos.find(m => m.startsWith('recorded'))")
    root = sidewalk.out / "recordings" / "from-the-page"
    assert str(root) in done
    data = Dataset(root)
    assert data.frames() >= 30 and data.manifest["complete"]
    assert sum(s.params["human_steps"] for s in data.shards) > 0
    r = subprocess.run([sys.executable, "-m", "drivestudio", "stats", str(root)], cwd=REPO, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert f"{data.frames()}" in r.stdout


@pytest.mark.long
def test_a_watched_run_shows_read_only(page, tmp_path):
    s = Studio(["drive", "--in-process", "--model", "oracle", "--cars", "4", "--seconds", "8", "--realtime",
                "--view", "0", "--out", str(tmp_path)], tmp_path, marker="watch the run at ")
    try:
        page.get(s.url)
        hello = wait_page(page, "window.studio.hello")
        assert hello["studio"] is False and hello["role"] == "watcher"
        wait_page(page, "window.studio.drawn >= 5")
        assert page_state(page, "document.getElementById('run-controls').hidden")
        assert page_state(page, "document.getElementById('driver').offsetParent === null")   # not shown
        assert page_state(page, "window.studio.state.driver") == "oracle"
        s.proc.wait(timeout=60)         # the run ends as it would unwatched
    finally:
        out = s.stop()
    assert "metrics saved" in out
    assert (tmp_path / "metrics.json").exists()


PAD = """
const buttons = Array.from({length: 17}, (_, i) => ({value: i === 7 ? arguments[1] : 0, pressed: false}));
const pad = arguments[0] === null ? [] : [{id: "stand-in pad", mapping: "standard", axes: [arguments[0], 0, 0, 0],
                                           buttons: buttons}];
Object.defineProperty(navigator, "getGamepads", {value: () => pad, configurable: true});
"""


def test_a_gamepad_drives_through_the_gamepad_api(page, sidewalk):
    """Headless Chromium has no pad: a stand-in object answers navigator.getGamepads() as a pad in the standard
    mapping would, and the page's own polling reads it (left stick X steers, right trigger is the throttle)."""
    page.get(sidewalk.url)
    wait_page(page, "window.studio.drawn >= 3")
    page.execute_script(PAD, 0.6, 0.8)
    state = wait_page(page, "window.studio.state.takeover && window.studio.state.input[0] > 0.5 && "
                            "window.studio.state", timeout=10)
    assert state["input"][:2] == [0.6, 0.8]
    steer, motor = state["command"]
    assert steer > 0.5 and motor > 0.5            # right, and forward
    page.execute_script(PAD, None, 0)
    wait_page(page, "!window.studio.state.takeover", timeout=10)

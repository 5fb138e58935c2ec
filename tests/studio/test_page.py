"""The studio's page in a real browser (Debian's Chromium, headless, under Selenium), against real studios: the
driver menu after a refused checkpoint, the live speed and the Run panel, a key that changes nothing left untimed,
a loop that falls behind real time, off the road, a watched run that ends, and a studio that stops."""
from __future__ import annotations

import os
import signal
import time

import pytest
import torch
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys
from selenium.webdriver.support.ui import Select

from core.worlds.sidewalk import SIDEWALK
from perception.checkpoint import save_checkpoint
from perception.models import Regressor, make_spec
from tests.studio.helpers import Studio, page_state, wait_page


@pytest.fixture(scope="module")
def highway(tmp_path_factory):
    """The highway in real time, nobody else on it, the person at the wheel, a sidewalk checkpoint on offer."""
    out = tmp_path_factory.mktemp("page")
    torch.manual_seed(0)
    model = Regressor(make_spec("z2color", SIDEWALK))
    save_checkpoint(out / "sidewalk.pt", {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    s = Studio(["studio", "--port", "0", "--cars", "0", "--checkpoint", str(out / "sidewalk.pt"), "--out",
                str(out)], out)
    yield s
    s.stop()


def opened(driver, studio: Studio) -> None:
    driver.get(studio.url)
    wait_page(driver, "window.studio.drawn >= 3 && window.studio.state.driver === 'human'")


def sim_wait(driver, seconds: float) -> None:
    """Until the world has run `seconds` of simulated time."""
    t0 = page_state(driver, "window.studio.state.t")
    wait_page(driver, f"window.studio.state.t >= {t0 + seconds}")


def shown(driver, element: str) -> bool:
    return page_state(driver, f"document.getElementById('{element}').offsetParent !== null")


def test_a_refused_checkpoint_leaves_the_menu_naming_who_drives(page, highway):
    opened(page, highway)
    Select(page.find_element(By.ID, "driver")).select_by_value("sidewalk.pt")
    refused = wait_page(page, "window.studio.errors.find(m => m.includes('sidewalk.pt cannot drive'))")
    assert "sidewalk" in refused
    ActionChains(page).key_down(Keys.ARROW_UP).perform()          # the person drives on
    sim_wait(page, 0.5)
    ActionChains(page).key_up(Keys.ARROW_UP).perform()
    assert page_state(page, "window.studio.state.driver") == "human"
    assert page_state(page, "document.getElementById('driver').value") == "human"


def test_the_page_shows_the_live_speed_and_one_simulated_time(page, highway):
    opened(page, highway)
    wait_page(page, "window.studio.state.metrics.distance_m !== undefined")
    speed, text = page_state(page, "[window.studio.state.speed, document.getElementById('speed').textContent]")
    assert speed > 5.0 and shown(page, "speed")                     # started at 15 m/s, coasting
    shown_speed = float(text.split(" m/s")[0])
    assert abs(shown_speed - speed) < 0.5 and "km/h" in text
    rows = page_state(page, "[...document.getElementById('metrics').rows].map(r => r.cells[0].textContent)")
    assert "speed [m/s]" in rows and "mean_speed_mps" in rows
    assert [r for r in rows if "time" in r or r.startswith("t ")] == ["t [s]"]     # one simulated time


def test_a_key_that_changes_no_command_is_not_timed(page, highway):
    """Up pressed again while the throttle is full changes nothing: it is no key press to time (it would be
    timed until the next change of the command, seconds later)."""
    opened(page, highway)
    ActionChains(page).key_down(Keys.ARROW_UP).perform()
    wait_page(page, "window.studio.state.input[1] === 1")           # the throttle full
    ActionChains(page).key_up(Keys.ARROW_UP).key_down(Keys.ARROW_UP).perform()   # again, within one step
    n = page_state(page, "window.studio.latencies.length")
    sim_wait(page, 2.0)
    ActionChains(page).key_down(Keys.ARROW_LEFT).perform()         # a key that changes the command
    wait_page(page, f"window.studio.latencies.length > {n}")
    ActionChains(page).key_up(Keys.ARROW_LEFT).key_up(Keys.ARROW_UP).perform()
    latencies = page_state(page, "window.studio.latencies")
    assert max(latencies) < 1000, latencies


def test_off_the_road_is_said_on_the_page(page, highway):
    opened(page, highway)
    assert not shown(page, "offroad")
    ActionChains(page).key_down(Keys.ARROW_LEFT).perform()
    try:
        wait_page(page, "window.studio.state.off_road && document.getElementById('offroad').offsetParent !== null",
                  timeout=60)
    finally:
        ActionChains(page).key_up(Keys.ARROW_LEFT).perform()
    assert page_state(page, "document.getElementById('offroad').textContent") == "off road"


def test_a_loop_behind_real_time_is_said_and_only_then(page, highway):
    """The studio's process is stopped for 1.5 s, as a busy CPU would starve it: the loop falls behind real time,
    and the page says how far; then it keeps up again and the note goes."""
    opened(page, highway)
    assert not shown(page, "behind")
    os.kill(highway.proc.pid, signal.SIGSTOP)
    try:
        time.sleep(1.5)        # the starvation itself: nothing to wait for
    finally:
        os.kill(highway.proc.pid, signal.SIGCONT)
    text = wait_page(page, "document.getElementById('behind').offsetParent !== null && "
                           "document.getElementById('behind').textContent")
    assert text.startswith("behind real time: ") and "take-over lasts" in text
    assert min(page_state(page, "window.studio.behindSeen")) < 0.5
    wait_page(page, "document.getElementById('behind').offsetParent === null", timeout=30)


def test_a_watched_run_that_ends_says_so_and_shows_no_rates(page, tmp_path):
    s = Studio(["drive", "--in-process", "--model", "oracle", "--cars", "0", "--seconds", "5", "--realtime",
                "--view", "0", "--out", str(tmp_path)], tmp_path, marker="watch the run at ")
    try:
        page.get(s.url)
        wait_page(page, "window.studio.drawn >= 3")
        assert not shown(page, "help-drive") and shown(page, "help-watch")     # nothing here drives
        assert "frames/s" in wait_page(page, "document.getElementById('status').textContent")
        s.proc.wait(timeout=60)
        wait_page(page, "window.studio.closed !== null")
    finally:
        s.stop()
    world, status = page_state(page, "[document.getElementById('world').textContent, "
                                     "document.getElementById('status').textContent]")
    assert "the run ended" in world and "refused" not in world, world
    assert "frames/s" not in status and "Hz" not in status, status


def test_a_stopped_studio_says_so_and_shows_no_rates(page, highway):
    """The last of this module's tests: it stops the module's studio."""
    opened(page, highway)
    assert shown(page, "help-drive")
    wait_page(page, "document.getElementById('status').textContent.includes('frames/s')")
    highway.stop()
    wait_page(page, "window.studio.closed !== null")
    world = page_state(page, "document.getElementById('world').textContent")
    assert "the studio stopped" in world, world
    wait_page(page, "document.getElementById('status').textContent === 'disconnected'")

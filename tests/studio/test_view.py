"""drive --view and serve --view (docs/studio.md): a running job published to the studio's page, read-only unless
--view ...,control; tested on real runs (serve with a driver over shared memory, drive in one process) with a real
WebSocket client."""
from __future__ import annotations

import os
import subprocess
import sys

import aiohttp
import pytest

from tests.studio.helpers import REPO, Studio, connect, run


def test_serve_view_publishes_the_world_side_read_only(tmp_path):
    name = f"studio-view-{os.getpid()}"
    s = Studio(["serve", "--shm", name, "--cars", "0", "--seconds", "6", "--realtime", "--view", "0",
                "--out", str(tmp_path)], tmp_path, marker="watch the run at ")
    driver = None
    try:
        async def go():
            nonlocal driver
            async with aiohttp.ClientSession() as http:
                c = await connect(http, s)                          # the page is there before the driver
                await c.receive(lambda c: c.hello is not None)
                assert c.hello["studio"] is False and c.hello["role"] == "watcher"
                assert c.hello["drivers"] == ["driver"] and c.hello["controls"] is False
                driver = subprocess.Popen([sys.executable, "-m", "drivestudio", "drive", "--shm", name, "--model",
                                           "oracle"], cwd=REPO, stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL)
                await c.receive(lambda c: len(c.states) >= 10)
                assert c.states[-1]["t"] > c.states[0]["t"]
                assert {i["name"] for i in c.states[-1]["images"]} == {"front", "topdown"}
                for msg in ({"type": "pause"}, {"type": "claim"}, {"type": "driver", "name": "oracle"}):
                    await c.send(msg)
                await c.receive(lambda c: len(c.errors()) >= 3)
                assert "--view PORT,control" in c.errors()[0]
                assert "only watched here" in c.errors()[1]
                n = len(c.states)
                await c.receive(lambda c: len(c.states) >= n + 5)     # and it goes on
                await c.ws.close()
        run(go())
        s.proc.wait(timeout=60)
    finally:
        out = s.stop()
        if driver is not None:
            driver.wait(timeout=30)
    assert s.proc.returncode == 0, out
    assert (tmp_path / "metrics.json").exists()


@pytest.mark.long
def test_view_control_pauses_steps_and_resumes_a_drive(tmp_path):
    s = Studio(["drive", "--in-process", "--model", "oracle", "--cars", "0", "--seconds", "8", "--realtime",
                "--view", "0,control", "--out", str(tmp_path)], tmp_path,
               marker="watch the run at ")
    try:
        async def go():
            async with aiohttp.ClientSession() as http:
                c = await connect(http, s)
                await c.receive(lambda c: c.hello is not None and len(c.states) >= 3)
                assert c.hello["role"] == "driver" and c.hello["controls"] is True
                await c.send({"type": "pause"})
                await c.receive(lambda c: c.states[-1]["paused"])
                t = c.states[-1]["t"]
                await c.send({"type": "step"})
                await c.receive(lambda c: c.states[-1]["t"] > t)
                assert abs(c.states[-1]["t"] - t - 0.1) < 1e-6           # exactly one step of 0.1 s
                await c.send({"type": "driver", "name": "oracle"})
                await c.receive(lambda c: c.errors())
                assert "the studio's" in c.errors()[0]
                await c.ws.close()                                       # nobody left to resume: it resumes
        run(go())
        s.proc.wait(timeout=60)
    finally:
        out = s.stop()
    assert s.proc.returncode == 0, out
    assert "metrics saved" in out


def test_the_view_option_reads_address_control_and_rate_in_one_value():

    from drivestudio.commands.studio import DEFAULT_PORT, VIEW_FPS, view_address
    from drivestudio.errors import UsageError
    assert view_address(str(DEFAULT_PORT)) == (None, DEFAULT_PORT, False, VIEW_FPS)
    assert view_address("0") == (None, 0, False, VIEW_FPS)
    assert view_address("0.0.0.0:9000,control,fps=5") == ("0.0.0.0", 9000, True, 5.0)
    assert view_address("[::1]:9000".replace("[", "").replace("]", ""))[:2] == ("::1", 9000)
    for bad, why in (("70000", "port must be an integer from 0 to 65535"), ("x", "port must be an integer"),
                     ("0,ctl", "after the address come 'control' and 'fps=F'"), ("0,fps=0", "fps must be in"),
                     ("0,fps=nan", "fps must be")):
        with pytest.raises(UsageError, match=why):
            view_address(bad)

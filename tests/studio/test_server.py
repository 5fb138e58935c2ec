"""The studio's server, safe by default (docs/studio.md), tested against a real `drivestudio studio` process with a
real WebSocket client: tokens, origins, host names, static files, malformed messages, one page at a time at the
wheel, a port in use, and recordings that survive a kill or a closed page."""
from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request

import aiohttp
import pytest

from drivestudio.commands.studio import STUDIO_FPS
from perception.shards import Dataset, read_manifest
from tests.studio.helpers import REPO, Studio, connect, run


@pytest.fixture(scope="module")
def token_studio(tmp_path_factory):
    """A highway studio on 127.0.0.1 asked for with --host: the page needs the printed URL's token."""
    s = Studio(["studio", "--host", "127.0.0.1", "--port", "0", "--model", "oracle", "--fast", "--cars", "4",
                "--out", str(tmp_path_factory.mktemp("token"))], tmp_path_factory.mktemp("unused"))
    yield s
    s.stop()


@pytest.fixture(scope="module")
def sidewalk(tmp_path_factory):
    """A sidewalk studio on 127.0.0.1 (no token), the expert driving as fast as it can, 30-step episodes."""
    out = tmp_path_factory.mktemp("sidewalk")
    s = Studio(["studio", "--world", "sidewalk", "--port", "0", "--model", "expert", "--fast", "--shard-steps", "30",
                "--out", str(out)], out)
    yield s
    s.stop()


def get(url: str, headers: dict | None = None) -> tuple[int, str, dict]:
    req = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, r.read().decode(), dict(r.headers)
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode(), dict(e.headers)


def test_the_url_carries_a_token_and_a_wrong_or_missing_one_is_refused(token_studio):
    assert token_studio.token and len(token_studio.token) >= 24
    base = token_studio.base
    status, body, _ = get(base + "/")
    assert status == 403 and "token" in body
    assert get(base + "/?token=wrong" + "x" * 20)[0] == 403
    assert get(base + "/static/studio.js")[0] == 403
    status, body, headers = get(token_studio.url)
    assert status == 200 and "drivestudio studio" in body
    assert "drivestudio-token" in headers.get("Set-Cookie", "") and "HttpOnly" in headers["Set-Cookie"]

    async def socket_without_token():
        async with aiohttp.ClientSession() as http:
            with pytest.raises(aiohttp.WSServerHandshakeError) as err:
                await http.ws_connect(token_studio.ws_url + "?token=nope")
            return err.value.status
    assert run(socket_without_token()) == 403


def test_a_websocket_from_another_site_is_refused(sidewalk):
    async def attempt(origin):
        async with aiohttp.ClientSession() as http:
            try:
                ws = await http.ws_connect(sidewalk.ws_url, headers={"Origin": origin})
            except aiohttp.WSServerHandshakeError as e:
                return e.status
            await ws.close()
            return 101
    assert run(attempt("http://evil.example")) == 403
    assert run(attempt(sidewalk.base)) == 101      # its own page's origin


def test_a_loopback_studio_answers_only_to_loopback_names(sidewalk):
    port = sidewalk.base.rsplit(":", 1)[1]
    status, body, _ = get(sidewalk.base + "/", headers={"Host": f"rebound.example:{port}"})
    assert status == 403 and "127.0.0.1" in body
    assert get(sidewalk.base + "/", headers={"Host": f"localhost:{port}"})[0] == 200


def test_only_the_pages_own_files_are_served(sidewalk):
    assert get(sidewalk.base + "/static/studio.js")[0] == 200
    assert get(sidewalk.base + "/static/studio.css")[0] == 200
    for bad in ("/static/index.html.bak", "/static/..%2F..%2Fpyproject.toml", "/static/%2e%2e/session.py",
                "/etc/passwd", "/static/"):
        assert get(sidewalk.base + bad)[0] == 404, bad
    _, _, headers = get(sidewalk.base + "/")
    assert "default-src 'self'" in headers["Content-Security-Policy"]


def test_malformed_messages_are_answered_and_change_nothing(sidewalk):
    async def go():
        async with aiohttp.ClientSession() as http:
            c = await connect(http, sidewalk)
            await c.receive(lambda c: len(c.states) >= 3)
            t0 = c.states[-1]["t"]
            bad = ["{", "[]", '{"type": "fly"}', '{"type": "pause", "x": 1}', '{"type": "driver", "name": "../x"}',
                   '{"type": "driver", "name": "nobody"}', '{"type": "reset", "track": "oval"}',
                   '{"type": "mode", "mode": "sideways"}', '{"type": "input", "gamepad": {"steer": 9}}',
                   '{"type": "record", "on": true, "name": "../../outside"}', "x" * 5000]
            for text in bad:
                await c.send(text)
            await c.ws.send_bytes(b"\x00\x01")
            await c.receive(lambda c: len(c.errors()) >= len(bad) + 1)
            n = len(c.states)
            await c.receive(lambda c: len(c.states) >= n + 5)
            assert c.states[-1]["t"] > t0           # still running, as before
            await c.send({"type": "pause"})         # and a good message still works
            await c.receive(lambda c: c.states and c.states[-1]["paused"])
            await c.send({"type": "resume"})
            await c.receive(lambda c: not c.states[-1]["paused"])
            await c.ws.close()
            return c.errors()
    errors = run(go())
    assert any("not JSON" in e for e in errors) and any("unknown message type 'fly'" in e for e in errors)
    assert any("no driver 'nobody'" in e for e in errors)
    assert any("has a path, not a track" in e for e in errors)
    assert any("not binary" in e for e in errors) and any("too long" in e for e in errors)
    assert not (sidewalk.out / "outside").exists() and not (sidewalk.out.parent / "outside").exists()


def test_a_second_page_watches_and_takes_the_wheel_only_when_it_is_free(sidewalk):
    async def go():
        async with aiohttp.ClientSession() as http:
            first = await connect(http, sidewalk)
            await first.receive(lambda c: c.hello is not None and c.states)
            second = await connect(http, sidewalk)
            await second.receive(lambda c: c.hello is not None and len(c.states) >= 2)
            assert first.hello["role"] == "driver" and second.hello["role"] == "watcher"
            await second.send({"type": "pause"})
            await second.send({"type": "claim"})
            await second.receive(lambda c: len(c.errors()) >= 2)
            assert "watching" in second.errors()[0] and "another page holds the wheel" in second.errors()[1]
            await first.ws.close()
            await second.receive(lambda c: any(t["type"] == "role" and t["wheel_free"] for t in c.texts))
            await second.send({"type": "claim"})
            await second.receive(lambda c: any(t["type"] == "role" and t["role"] == "driver" for t in c.texts))
            await second.send({"type": "pause"})
            await second.receive(lambda c: c.states[-1]["paused"])
            await second.send({"type": "resume"})
            await second.receive(lambda c: not c.states[-1]["paused"])
            await second.ws.close()
    run(go())


@pytest.mark.long
def test_a_recording_killed_at_any_moment_is_a_dataset_up_to_its_last_whole_shard(tmp_path):
    s = Studio(["studio", "--world", "sidewalk", "--port", "0", "--model", "expert", "--fast", "--shard-steps", "30",
                "--out", str(tmp_path)], tmp_path)
    try:
        async def go():
            async with aiohttp.ClientSession() as http:
                c = await connect(http, s)
                await c.receive(lambda c: c.states)
                await c.send({"type": "record", "on": True, "name": "killed"})
                await c.receive(lambda c: c.states[-1]["recording"] and c.states[-1]["recording"]["shards"] >= 2)
                s.proc.send_signal(signal.SIGKILL)     # no chance to finish anything
        run(go())
        s.proc.wait(timeout=10)
    finally:
        s.stop()
    root = tmp_path / "recordings" / "killed"
    manifest = read_manifest(root)
    assert not manifest["complete"] and len(manifest["shards"]) >= 2
    ds = Dataset(root)
    assert ds.frames() == 30 * len(ds.shards)
    for shard in ds.shards:
        assert ds.verify(shard) is None
        assert len(ds.reader(shard)) == 30
    r = subprocess.run([sys.executable, "-m", "drivestudio", "stats", str(root)], cwd=REPO, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "behaviour" in r.stdout or "mode" in r.stdout


def test_closing_the_page_mid_recording_completes_the_dataset(sidewalk):
    async def go():
        async with aiohttp.ClientSession() as http:
            c = await connect(http, sidewalk)
            await c.receive(lambda c: c.states)
            await c.send({"type": "record", "on": True, "name": "closed"})
            await c.receive(lambda c: c.states[-1]["recording"] and c.states[-1]["recording"]["steps"] >= 45)
            await c.ws.close()     # the page holding the wheel goes away mid-episode
    run(go())
    root = sidewalk.out / "recordings" / "closed"
    for _ in range(100):
        if (root / "manifest.json").exists() and read_manifest(root)["complete"]:
            break
        time.sleep(0.1)
    manifest = read_manifest(root)
    assert manifest["complete"]
    assert manifest["frames"] >= 45 and len(manifest["shards"]) >= 2     # the last, shorter episode too
    assert Dataset(root).frames() == manifest["frames"]


def _busy_port() -> socket.socket:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(1)
    return s


@pytest.mark.parametrize("verb", [["studio", "--port"], ["drive", "--in-process", "--seconds", "1", "--view"]])
def test_a_port_in_use_gets_one_line_and_exit_status_2(verb, tmp_path):
    busy = _busy_port()
    try:
        port = str(busy.getsockname()[1])
        r = subprocess.run([sys.executable, "-m", "drivestudio", *verb, port, "--out", str(tmp_path / "run")],
                           cwd=REPO, capture_output=True, text=True, timeout=120)
    finally:
        busy.close()
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"port {port} on 127.0.0.1 is in use" in lines[0]
    assert not (tmp_path / "run").exists()      # refused before any work


def test_bad_studio_options_get_one_line_and_exit_status_2(tmp_path, run_cli):
    for args, says in ((["--checkpoint", str(tmp_path / "missing.pt")], "no such file"),
                       (["--checkpoint", str(tmp_path)], "holds no *.pt"),
                       (["--world", "sidewalk", "--track", "oval"], "belongs to the highway world"),
                       (["--port", "70000"], "must be an integer from 0 to 65535"),
                       (["--world", "sidewalk", "--path", "procedural:x"], "procedural")):
        r = run_cli("studio", "--port", "0", *args, "--out", tmp_path / "run")
        assert r.returncode == 2, (args, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1 and says in r.stderr, (args, r.stderr)


def test_the_hello_says_what_the_page_may_choose(sidewalk):
    async def go():
        async with aiohttp.ClientSession() as http:
            c = await connect(http, sidewalk)
            await c.receive(lambda c: c.hello is not None and c.states)
            await c.ws.close()
            return c.hello, c.states[-1]
    hello, state = run(go())
    assert hello["world"] == "sidewalk" and hello["cameras"] == ["left", "right"]
    assert hello["drivers"][:2] == ["human", "expert"] and hello["modes"] == ["direct", "follow", "furtive"]
    assert "park" in hello["scenes"] and hello["scene_key"] == "path"
    assert [label["name"] for label in state["labels"]] == ["steer", "motor"]
    assert {i["name"] for i in state["images"]} == {"left", "right", "topdown"}
    json.dumps(state)


def test_every_control_works_over_the_socket(sidewalk):
    """Pause, step, pace, mode, driver, operation and reset, each seen in the published state."""
    async def go():
        async with aiohttp.ClientSession() as http:
            c = await connect(http, sidewalk)
            await c.receive(lambda c: c.states)
            last = lambda c: c.states[-1]   # noqa: E731
            await c.send({"type": "pause"})
            await c.receive(lambda c: last(c)["paused"])
            t = last(c)["t"]
            await c.send({"type": "step"})
            await c.receive(lambda c: last(c)["t"] > t)
            assert abs(last(c)["t"] - t - 1 / 30) < 1e-3                   # one step of 33 ms
            await c.send({"type": "pace", "realtime": True})
            await c.send({"type": "mode", "mode": "follow"})
            await c.send({"type": "driver", "name": "poor"})
            await c.send({"type": "operation", "operation": "autonomous"})
            await c.send({"type": "resume"})
            await c.receive(lambda c: not last(c)["paused"] and last(c)["driver"] == "poor" and
                            last(c)["controller"]["behavioural mode"] == "follow" and
                            last(c)["controller"]["operation"] == "autonomous" and last(c)["realtime"])
            await c.send({"type": "reset", "seed": 5, "path": "forest"})
            await c.receive(lambda c: last(c)["scene"] == {"path": "forest", "seed": 5} and last(c)["t"] < 1.0)
            # the page's choices outlive the reset: the mode, the driver, its operation
            assert last(c)["controller"]["behavioural mode"] == "follow" and last(c)["driver"] == "poor"
            await c.send({"type": "driver", "name": "expert"})
            await c.send({"type": "pace", "realtime": False})
            await c.receive(lambda c: last(c)["driver"] == "expert" and not last(c)["realtime"], timeout=60)
            await c.ws.close()
    run(go())


def test_a_missing_checkpoint_is_refused_naming_the_checkpoint_option(tmp_path):
    r = subprocess.run([sys.executable, "-m", "drivestudio", "studio", "--port", "0", "--checkpoint",
                        str(tmp_path / "nonexistent.pt"), "--out", str(tmp_path / "run")], cwd=REPO,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "--checkpoint" in lines[0] and "--model" not in lines[0], lines
    assert str(tmp_path / "nonexistent.pt") in lines[0]


def test_a_studio_on_all_interfaces_prints_a_url_a_browser_here_opens(tmp_path):
    s = Studio(["studio", "--world", "sidewalk", "--host", "0.0.0.0", "--port", "0", "--model", "expert", "--fast",
                "--out", str(tmp_path)], tmp_path)
    try:
        assert s.url.startswith("http://127.0.0.1:") and "?token=" in s.url, s.url
        assert socket.gethostname() not in s.url or socket.gethostname() == "127.0.0.1"
        note = s._wait_for("all interfaces", 30)
        assert "this machine's address" in note
        status, body, _ = get(s.url)
        assert status == 200 and "drivestudio studio" in body
    finally:
        s.stop()


def test_the_state_carries_the_live_speed_and_one_simulated_time(sidewalk):
    async def go():
        async with aiohttp.ClientSession() as http:
            c = await connect(http, sidewalk)
            await c.receive(lambda c: len(c.states) >= 2 and c.states[-1]["metrics"] and c.states[-1]["t"] > 1.0)
            await c.ws.close()
            return c.states[-1]
    state = run(go())
    assert 0.5 < state["speed"] < 9.0          # the expert drives 0.9-4.5 m/s
    assert state["off_road"] is False and state["behind"] is None       # on its path; as fast as it can
    assert "simulated_time_s" not in state["metrics"] and "mean_speed_mps" in state["metrics"]


def test_the_model_is_read_as_the_one_driver_spec_with_its_filters(tmp_path):
    """`studio --model CKPT@pass_memory=15`: the page offers the checkpoint by its file name and drives it with the
    filters; a filter the world does not have is refused in one line."""
    import argparse

    from drivestudio import worlds
    from drivestudio.commands.studio import _checkpoints
    from drivestudio.errors import UsageError

    ckpt = tmp_path / "net.pt"
    ckpt.write_bytes(b"a checkpoint")
    args = argparse.Namespace(checkpoint=[], model=f"{ckpt}@pass_memory=15")
    assert _checkpoints(args, worlds.get("highway")) == {"net.pt": f"{ckpt}@pass_memory=15"}
    assert args.model == "net.pt"
    with pytest.raises(UsageError, match="wobble"):
        _checkpoints(argparse.Namespace(checkpoint=[], model=f"{ckpt}@wobble=1"), worlds.get("highway"))


def test_a_studio_running_as_fast_as_it_can_publishes_at_most_its_frame_rate(sidewalk):
    """The sidewalk studio's loop runs hundreds of steps a second; a page that acknowledges every frame at once gets
    no more than STUDIO_FPS of them a second, and the loop does not wait for it."""
    async def frames() -> tuple[list[dict], float]:
        async with aiohttp.ClientSession() as session:
            c = await connect(session, sidewalk)
            await c.receive(lambda c: len(c.states) >= 5)
            first, t0 = len(c.states), time.monotonic()
            await c.receive(lambda c: time.monotonic() - t0 >= 2.0)
            return c.states[first - 1:], time.monotonic() - t0
    states, seconds = run(frames())
    assert len(states) - 1 <= STUDIO_FPS * seconds + 2
    steps = states[-1]["step"] - states[0]["step"]
    assert steps > 2 * (len(states) - 1)            # the loop ran on between the frames

"""The studio's server shares its process with the loop (drivestudio/studio/server.py): while a page is connected the
GIL changes hands within PAGE_SWITCH_INTERVAL, and Python's own interval holds otherwise."""
from __future__ import annotations

import asyncio
import socket
import sys
import time

import aiohttp
import pytest

from drivestudio.studio.publisher import Publisher
from drivestudio.studio.server import PAGE_SWITCH_INTERVAL, Server
from tests.studio.helpers import connect, run


class _Address:
    """What helpers.connect needs of a studio: its WebSocket's URL."""

    def __init__(self, port: int):
        self.ws_url, self.token = f"ws://127.0.0.1:{port}/ws", None


def test_the_switch_interval_is_short_while_a_page_is_connected_and_pythons_own_otherwise():
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen()
    server = Server(sock, Publisher(), hello=lambda client: {}, handle=lambda msg, client: None,
                    leave=lambda client: None)
    own = sys.getswitchinterval()
    server.start()
    try:
        assert sys.getswitchinterval() == own               # no page yet

        async def page_comes_and_goes() -> list[float]:
            seen = []
            async with aiohttp.ClientSession() as session:
                first = await connect(session, _Address(server.port))
                await first.receive(lambda c: c.hello is not None)
                seen.append(sys.getswitchinterval())
                second = await connect(session, _Address(server.port))
                await second.receive(lambda c: c.hello is not None)
                await first.ws.close()
                await _until(lambda: len(server.clients) == 1)
                seen.append(sys.getswitchinterval())        # one page still there
                await second.ws.close()
                await _until(lambda: not server.clients)
                seen.append(sys.getswitchinterval())
            return seen
        # Python keeps the interval in whole microseconds
        assert run(page_comes_and_goes()) == pytest.approx([PAGE_SWITCH_INTERVAL, PAGE_SWITCH_INTERVAL, own], abs=1e-6)
    finally:
        server.stop()
        sys.setswitchinterval(own)


async def _until(condition, timeout: float = 10.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "timed out"
        await asyncio.sleep(0.01)

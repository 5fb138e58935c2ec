"""The studio's web server (aiohttp), in a thread of its own beside the loop: the page, its two static files, and
one WebSocket per page.

Safe by default (docs/studio.md):
- it listens on 127.0.0.1 unless told otherwise; on a loopback address it answers only requests addressed to a
  loopback name (a page of another site that rebinds its DNS name to 127.0.0.1 is refused);
- with --host it asks for the token of the URL it prints (as Jupyter does): in the query (`?token=`) or in the
  cookie the page receives with it; a wrong or missing token gets 403;
- a WebSocket whose Origin is not this server's own is refused (another site's page cannot drive);
- one page at a time holds the wheel (`Client.wheel`); the others watch, and may claim the wheel when it is free;
- a page's message is checked (drivestudio/studio/protocol.py); a bad one is answered with an error and changes
  nothing.
"""
from __future__ import annotations

import asyncio
import errno
import hmac
import ipaddress
import secrets
import socket
import sys
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from importlib import resources

from aiohttp import WSMsgType, web

from drivestudio.errors import UsageError
from drivestudio.studio import protocol
from drivestudio.studio.publisher import IN_FLIGHT, Publisher, encode

STATIC = {"studio.js": "text/javascript", "studio.css": "text/css"}
COOKIE = "drivestudio-token"
WS_LIMIT = 64 * 1024          # [bytes] a larger WebSocket message closes the socket (protocol.MAX_MESSAGE is refused)
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
GOING_AWAY = 1001             # the WebSocket close code of a server that stops
# [s] the GIL's switch interval while a page is connected. The loop's thread lets the GIL go only for an instant in
# its C calls and takes it back at once, so a thread waiting for it gets it when the interval runs out; the server's
# and the encoder's threads take it dozens of times a frame, and at Python's 5 ms a page of a loop running as fast as
# it can got 6-10 frames a second (docs/benchmarks.md). Without a page the interval is Python's own.
PAGE_SWITCH_INTERVAL = 1e-4


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def bind(host: str, port: int) -> socket.socket:
    """A listening socket, or UsageError in one line (a port in use, an unknown host): before any work."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as e:
        raise UsageError(f"--host {host}: cannot listen there ({e.strerror})") from None
    family, kind, proto, _, address = infos[0]
    sock = socket.socket(family, kind, proto)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(address)
        sock.listen(128)
    except OSError as e:
        sock.close()
        if e.errno == errno.EADDRINUSE:
            raise UsageError(f"port {port} on {host} is in use (another studio or server?); choose another with "
                             "--port") from None
        raise UsageError(f"cannot listen on {host} port {port}: {e.strerror}") from None
    return sock


@dataclass(eq=False)
class Client:
    """One connected page."""

    ws: web.WebSocketResponse
    number: int
    wheel: bool = False
    in_flight: int = 0
    sent: int = 0
    refused: list = field(default_factory=list)

    @property
    def role(self) -> str:
        return "driver" if self.wheel else "watcher"


class Server:
    """The web server of a studio (`drives=True`: the page holding the wheel may drive, pace, reset, record) or of a
    watched run (`--view`: read-only, or pause / resume / step with `controls=True`).

    hello(client) -> dict: what a page is told when it connects; handle(message, client) -> None or an error line
    (the loop's work is queued by it); leave(client): the page holding the wheel went away."""

    def __init__(self, sock: socket.socket, publisher: Publisher, hello: Callable[[Client], dict],
                 handle: Callable[[protocol.Message, Client], str | None], leave: Callable[[Client], None],
                 token: str | None = None, drives: bool = True, controls: bool = True):
        self.sock, self.publisher = sock, publisher
        self.hello, self.handle, self.leave = hello, handle, leave
        self.token, self.drives, self.controls = token, drives, controls
        host, self.port = sock.getsockname()[:2]
        self.loopback = is_loopback(host)
        self.clients: list[Client] = []
        self._numbers = iter(range(1, 1 << 62))
        self._loop: asyncio.AbstractEventLoop | None = None
        self._runner: web.AppRunner | None = None
        self._thread: threading.Thread | None = None
        self._encoder = ThreadPoolExecutor(max_workers=1, thread_name_prefix="studio-encoder")
        self._encoding = False
        self._started = threading.Event()
        self._error: BaseException | None = None
        self._reason = "the studio stopped"
        self._switch_interval: float | None = None     # Python's own, while a page is connected

    # --- lifecycle -------------------------------------------------------------------------------------------
    def url(self, host: str) -> str:
        """The URL a browser on this machine opens: a wildcard address (listening on every interface) is no address
        to open, so its loopback stands for it (the note of `where` says the rest)."""
        shown = {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}.get(host, host)
        shown = f"[{shown}]" if ":" in shown else shown
        return f"http://{shown}:{self.port}/" + (f"?token={self.token}" if self.token else "")

    @staticmethod
    def where(host: str) -> str | None:
        """A line for a server that listens on every interface (--host 0.0.0.0 or ::), or None."""
        if host not in ("0.0.0.0", "::", ""):
            return None
        return ("it listens on all interfaces: from another machine, open the same URL with this machine's "
                "address in place of " + ("[::1]" if host == "::" else "127.0.0.1"))

    def start(self) -> None:
        self._thread = threading.Thread(target=self._serve, name="studio-server", daemon=True)
        self._thread.start()
        self._started.wait(timeout=30)
        if self._error is not None:
            raise self._error

    def _serve(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(self._setup())
        except BaseException as e:   # reported to start()'s caller in the main thread
            self._error = e
            self._started.set()
            return
        self.publisher.notify = lambda: loop.call_soon_threadsafe(self._publish)
        self._started.set()
        loop.run_forever()
        loop.run_until_complete(self._teardown(self._reason))
        loop.close()

    async def _setup(self) -> None:
        app = web.Application(middlewares=[self._guard])
        app.router.add_get("/", self._index)
        app.router.add_get("/static/{name}", self._static)
        app.router.add_get("/ws", self._socket)
        self._runner = web.AppRunner(app, access_log=None, shutdown_timeout=1.0)
        await self._runner.setup()
        await web.SockSite(self._runner, self.sock, shutdown_timeout=1.0).start()

    async def _teardown(self, reason: str) -> None:
        for c in list(self.clients):     # the pages say why they lost the connection
            await c.ws.close(code=GOING_AWAY, message=reason.encode()[:120])
        if self._runner is not None:
            await self._runner.cleanup()

    def stop(self, reason: str = "the studio stopped") -> None:
        """Close every page's socket with `reason` (the page shows it) and stop serving."""
        self._reason = reason
        if self._loop is not None and self._thread is not None and self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(timeout=10)
        self._encoder.shutdown(wait=False)
        self.sock.close()

    # --- safety ----------------------------------------------------------------------------------------------
    def _token_ok(self, request: web.Request) -> bool:
        if self.token is None:
            return True
        given = request.query.get("token") or request.cookies.get(COOKIE) or ""
        return hmac.compare_digest(given.encode(), self.token.encode())

    @web.middleware
    async def _guard(self, request: web.Request, handler):
        host = (request.url.host or "").strip("[]")
        if self.loopback and self.token is None and host not in LOOPBACK_NAMES:
            return web.Response(status=403, text=f"drivestudio: this studio answers only at 127.0.0.1, not at "
                                                 f"{host or 'an unnamed host'}\n")
        if not self._token_ok(request):
            return web.Response(status=403, text="drivestudio: wrong or missing token; open the URL the studio "
                                                 "printed (it ends in ?token=...)\n")
        return await handler(request)

    # --- pages -----------------------------------------------------------------------------------------------
    async def _index(self, request: web.Request) -> web.Response:
        page = resources.files("drivestudio.studio").joinpath("static/index.html").read_text()
        response = web.Response(text=page, content_type="text/html", headers=_HEADERS)
        if self.token is not None:
            response.set_cookie(COOKIE, self.token, httponly=True, samesite="Strict", path="/")
        return response

    async def _static(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        if name not in STATIC:    # a fixed list: nothing else of the machine is ever served
            raise web.HTTPNotFound(text=f"drivestudio: no {name!r} here\n")
        body = resources.files("drivestudio.studio").joinpath(f"static/{name}").read_bytes()
        return web.Response(body=body, content_type=STATIC[name], headers=_HEADERS)

    async def _socket(self, request: web.Request) -> web.StreamResponse:
        origin = request.headers.get("Origin")
        if origin is not None and origin != f"{request.scheme}://{request.host}":
            return web.Response(status=403, text=f"drivestudio: a WebSocket from {origin} is refused: open the "
                                                 "studio's own page\n")
        ws = web.WebSocketResponse(compress=False, max_msg_size=WS_LIMIT, heartbeat=20.0)
        await ws.prepare(request)
        client = Client(ws, next(self._numbers))
        if self._wheel_free():
            client.wheel = True
        self.clients.append(client)
        self._pages_changed()
        try:
            await ws.send_str(protocol.text("hello", **self.hello(client), role=client.role,
                                            wheel_free=self._wheel_free()))
            self.publisher.ready()
            async for msg in ws:
                if msg.type == WSMsgType.TEXT:
                    await self._message(client, msg.data)
                elif msg.type == WSMsgType.BINARY:
                    await ws.send_str(protocol.text("error", message="the studio takes JSON text messages, not "
                                                                     "binary ones"))
                else:
                    break
        finally:
            self.clients.remove(client)
            self._pages_changed()
            if client.wheel:
                self.leave(client)
                await self._roles()
        return ws

    def _pages_changed(self) -> None:
        """The GIL's switch interval: PAGE_SWITCH_INTERVAL while a page is connected, Python's own otherwise."""
        if self.clients and self._switch_interval is None:
            self._switch_interval = sys.getswitchinterval()
            sys.setswitchinterval(min(self._switch_interval, PAGE_SWITCH_INTERVAL))
        elif not self.clients and self._switch_interval is not None:
            sys.setswitchinterval(self._switch_interval)
            self._switch_interval = None

    def _wheel_free(self) -> bool:
        return (self.drives or self.controls) and not any(c.wheel for c in self.clients)

    async def _roles(self) -> None:
        for c in self.clients:
            await _send(c, protocol.text("role", role=c.role, wheel_free=self._wheel_free()))

    async def _message(self, client: Client, data: str) -> None:
        try:
            msg = protocol.parse(data)
        except protocol.ProtocolError as e:
            await client.ws.send_str(protocol.text("error", message=str(e)))
            return
        if msg.type == "ack":
            client.in_flight = max(0, client.in_flight - 1)
            self.publisher.ready()
            return
        if msg.type == "claim":
            if not self._wheel_free():
                why = "another page holds the wheel" if self.drives or self.controls else \
                    "this run is only watched here (start it with --view PORT,control to pause it from a page)"
                await client.ws.send_str(protocol.text("error", message=f"cannot take the wheel: {why}"))
                return
            client.wheel = True
            await self._roles()
            return
        error = self._allowed(client, msg)
        if error is None:
            error = self.handle(msg, client)
        if error is not None:
            await client.ws.send_str(protocol.text("error", message=error, about=msg.type))

    def _allowed(self, client: Client, msg: protocol.Message) -> str | None:
        if msg.who == "any":
            return None
        if not client.wheel:
            return ("this page is watching: another page holds the wheel (take it when it is free)" if self.drives
                    else "this run is only watched here: pause, resume and step need --view PORT,control")
        if msg.who == "wheel" and not self.drives:
            return f"'{msg.type}' is the studio's: a run watched with --view can only be paused, resumed and stepped"
        return None

    # --- frames ----------------------------------------------------------------------------------------------
    def _publish(self) -> None:
        """A new snapshot: encode it off the event loop and send it to every page ready for one."""
        if self._encoding:
            return      # the encoder is busy; the snapshot stays and is taken when it is done
        snap = self.publisher.take()
        if snap is None:
            return
        self._encoding = True
        asyncio.ensure_future(self._send_frame(snap))

    async def _send_frame(self, snap) -> None:
        try:
            data = await asyncio.get_running_loop().run_in_executor(self._encoder, encode, snap)
            for c in list(self.clients):
                if c.in_flight < IN_FLIGHT and not c.ws.closed:
                    c.in_flight += 1
                    c.sent += 1
                    await _send(c, data)
        finally:
            self._encoding = False
        if any(c.in_flight < IN_FLIGHT for c in self.clients):
            self.publisher.ready()
        self._publish()

    def broadcast(self, kind: str, **fields) -> None:
        """A text message to every page (from any thread)."""
        if self._loop is None:
            return
        text = protocol.text(kind, **fields)

        async def send_all() -> None:
            for c in list(self.clients):
                await _send(c, text)
        self._loop.call_soon_threadsafe(lambda: asyncio.ensure_future(send_all()))


_HEADERS = {"Cache-Control": "no-store",
            # nothing but this server: no CDN, no other site, no inline script
            "Content-Security-Policy": "default-src 'self'; img-src 'self' blob: data:; connect-src 'self'; "
                                       "style-src 'self'; script-src 'self'; frame-ancestors 'none'",
            "X-Content-Type-Options": "nosniff"}


async def _send(client: Client, data) -> None:
    try:
        if isinstance(data, bytes):
            await client.ws.send_bytes(data)
        else:
            await client.ws.send_str(data)
    except (ConnectionError, RuntimeError):
        pass    # the page went away meanwhile: its handler cleans up


def new_token() -> str:
    return secrets.token_urlsafe(24)

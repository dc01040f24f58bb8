"""The live view's web server: aiohttp on its own asyncio loop in a background thread.

`ViewServer(hub).start()` serves the page (static files of this package: index.html, view.js,
view.css), a websocket at /ws and POST /command (a command as JSON, for scripts). Each websocket
connection polls the hub at its rate and sends its newest state when it changed and the last send is
done (`ViewHub.message_for`): a slow browser skips frames, a browser that goes away only ends its own
connection; the run never waits for either, nor wakes this thread. Commands a page sends ({"cmd": ...}) go to
`ViewHub.command`.

Only the view's own page may read or command it (`Guard`): every request must name the server in its Host
header (no DNS name of another site rebound to this address), a websocket's Origin must be the page's own, and
POST /command takes JSON only (Content-Type application/json: a form or a no-cors fetch of another site sends
text/plain), from the page's own Origin or from a client that sends none (a script); a cross-site fetch of
JSON would need a CORS preflight, which this server never grants. Bodies over `max_body` bytes are refused
(413), malformed JSON and commands the view does not take are 400 with one line of text, never a traceback
on the run's terminal. At most `max_clients` connections are open at once (each is a file descriptor of the
run's process): an idle one (no byte for `idle_timeout` s, websockets aside) is closed, and when all are
busy a new one gets 503 at once. The server's failures are logged once each, as one line; the run goes on.
"""

from __future__ import annotations

import asyncio
import errno
import ipaddress
import json
import logging
import re
import socket
import threading
from importlib import resources
from typing import Any

from aiohttp import WSMsgType, web

from robotexp.errors import ConfigError
from robotexp.view.feed import ViewClient, ViewHub, command_problem

__all__ = ["ViewServer", "Guard"]

log = logging.getLogger(__name__)

_TYPES = {".html": "text/html", ".js": "text/javascript", ".css": "text/css", ".png": "image/png"}
_HOST = re.compile(r"(?:\[([0-9a-f:.]+)\]|([a-z0-9_.-]+))(?::([0-9]{1,5}))?")
_WILDCARD = ("0.0.0.0", "::", "")
# every response: no page of another site may frame the view (and click its buttons)
_HEADERS = {"X-Frame-Options": "DENY", "Content-Security-Policy": "frame-ancestors 'none'",
            "X-Content-Type-Options": "nosniff", "Referrer-Policy": "no-referrer"}
_BUSY = (b"HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\nContent-Length: 41\r\n"
         b"Retry-After: 1\r\nConnection: close\r\n\r\nthe live view has too many connections now\n")


_ACCEPT_BATCH = 16           # most connections accepted in one turn of the server's loop
_ACCEPT_PAUSE = 0.5          # [s] accepting waits this long after the process ran out of file descriptors


def _listen(host: str, port: int, backlog: int = 100) -> list[socket.socket]:
    """Listening sockets on every address `host` names ("" or None: every interface), all on one port (port 0:
    the one the system chooses for the first); non-blocking, IPv6 ones for IPv6 only.

    Raises:
        OSError: `host` is unknown, or an address cannot be listened on (the port is in use ...).
    """
    infos = socket.getaddrinfo(host or None, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    addresses = list(dict.fromkeys((family, address) for family, _, _, _, address in infos))
    for attempt in range(5):                        # port 0: another family may have the chosen port taken
        socks: list[socket.socket] = []
        try:
            chosen = port
            for family, address in addresses:
                sock = socket.socket(family, socket.SOCK_STREAM)
                socks.append(sock)
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                if family == socket.AF_INET6:
                    sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
                sock.bind((address[0], chosen, *address[2:]))
                chosen = sock.getsockname()[1]
                sock.listen(backlog)
                sock.setblocking(False)
            return socks
        except OSError as exc:
            for sock in socks:
                sock.close()
            if port != 0 or exc.errno != errno.EADDRINUSE or attempt == 4 or len(socks) < 2:
                raise
    raise AssertionError("unreachable")


def _ip(name: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        return ipaddress.ip_address(name)
    except ValueError:
        return None


class Guard:
    """Which requests come from the view's own page: the Host and Origin rules of the module's docstring.

    Args:
        host: the address the server listens on (127.0.0.1, ::1, localhost, 0.0.0.0, ::, an address or a
            name of this machine).
        port: its TCP port.

    A Host header is taken when it names an IP address (no DNS name, so nothing to rebind; on a loopback
    server a loopback address) or a name of this server: "localhost", the name it listens on, and with
    0.0.0.0 / :: / a non-loopback address also this machine's host name and its fully qualified name.
    Anything else (evil.example, a name that only resolves here) is refused. Its port is not checked: a
    rebinding page names its own host, whatever the port, and a port forwarded under another number (ssh -L
    9000:127.0.0.1:PORT) still reaches the page; the Origin check compares the whole host:port.
    """

    def __init__(self, host: str, port: int) -> None:
        self.port = port
        bound = host.strip("[]").lower()
        ip = _ip(bound)
        self.loopback = bound == "localhost" or (ip is not None and ip.is_loopback)
        self.names = {"localhost"}
        if ip is None and bound not in _WILDCARD:
            self.names.add(bound)
        if not self.loopback:
            for name in (socket.gethostname(), socket.getfqdn()):
                if name:
                    self.names.add(name.lower())

    def host_ok(self, value: str | None) -> bool:
        """Whether a request's Host header names this server."""
        match = _HOST.fullmatch((value or "").strip().lower())
        if match is None:
            return False
        literal, name, _ = match.groups()
        ip = _ip(literal if literal is not None else name)
        if literal is not None and ip is None:
            return False
        if ip is not None:
            return ip.is_loopback or not self.loopback
        return name in self.names

    def same_origin(self, request: web.BaseRequest) -> bool:
        """Whether a request comes from the page's own origin, or from no browser page at all (no Origin, as
        a script's): Origin is http:// and the Host the request names; Sec-Fetch-Site, when sent, is
        same-origin or none."""
        site = request.headers.get("Sec-Fetch-Site")
        if site is not None and site.lower() not in ("same-origin", "none"):
            return False
        origin = request.headers.get("Origin")
        return origin is None or origin.lower() == f"http://{request.headers.get('Host', '').strip().lower()}"


class _OneLine(logging.Filter):
    """aiohttp's reports of a client's bad requests (a malformed request line or header, a connection cut
    mid-request) become one debug line on the view's logger: a visitor cannot print tracebacks on the run's
    terminal."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        if exc is not None:
            record.msg, record.args = f"{record.getMessage()}: {type(exc).__name__}: {exc}", ()
        record.exc_info, record.exc_text = None, None
        record.levelno, record.levelname = logging.DEBUG, "DEBUG"
        return True


_http_log = logging.getLogger("robotexp.view.http")
_http_log.addFilter(_OneLine())


class _Conn(asyncio.Protocol):
    """One connection, counted by its server: aiohttp's protocol behind it, and when a byte came last."""

    def __init__(self, server: ViewServer, inner: asyncio.Protocol, now: float) -> None:
        self.server, self.inner, self.last = server, inner, now
        self.transport: asyncio.BaseTransport | None = None
        self.websocket = False

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = transport
        self.server._by_transport[transport] = self
        self.inner.connection_made(transport)

    def connection_lost(self, exc: Exception | None) -> None:
        self.server._conns.discard(self)
        if self.transport is not None:
            self.server._by_transport.pop(self.transport, None)
        self.inner.connection_lost(exc)

    def close(self) -> None:
        """Close the connection (it no longer counts)."""
        self.server._conns.discard(self)
        if self.transport is not None:
            self.transport.close()

    def data_received(self, data: bytes) -> None:
        self.last = self.server._now()
        self.inner.data_received(data)

    def eof_received(self) -> bool | None:
        return self.inner.eof_received()

    def pause_writing(self) -> None:
        self.inner.pause_writing()

    def resume_writing(self) -> None:
        self.inner.resume_writing()


class ViewServer:
    """Serves `hub` on http://HOST:PORT/ from a background thread.

    Args:
        hub: the view's state.
        host: the address to listen on (127.0.0.1: this machine only).
        port: the TCP port (0: a free one, see `port` after `start`).
        max_rate: [1/s] most messages per second to one browser (each redraws the page).
        busy_rate: [1/s] most messages per second while the producer goes as fast as it can (a
            simulated run at speed "max", status speed None): each page update costs the browser
            8-11 ms of CPU whatever changed (headless Chromium, benchmarks/speed/bench_view_page.py), which
            on a busy machine is taken from the run; a paced run has that time to spare.
        max_clients: most connections open at once (a browser takes one for its websocket and a few
            for the page's files).
        idle_timeout: [s] an open connection that sends nothing this long is closed (websockets aside:
            their heartbeat answers every 20 s).
        max_body: [bytes] the largest body POST /command reads.
    """

    def __init__(self, hub: ViewHub, host: str = "127.0.0.1", port: int = 0, max_rate: float = 10.0,
                 busy_rate: float = 4.0, *, max_clients: int = 32, idle_timeout: float = 10.0,
                 max_body: int = 4096) -> None:
        self.hub, self.host, self.port = hub, host, port
        self.min_interval = 1.0 / max_rate
        self.busy_interval = 1.0 / min(busy_rate, max_rate)
        self.max_clients, self.idle_timeout, self.max_body = max_clients, idle_timeout, max_body
        self.guard = Guard(host, port)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._runner: web.AppRunner | None = None
        self._listening: list[socket.socket] = []
        self._sweeper: asyncio.Task[None] | None = None
        self._sockets: set[web.WebSocketResponse] = set()
        self._connecting: set[asyncio.Task[None]] = set()
        self._conns: set[_Conn] = set()         # counted from their protocol's making (before connection_made)
        self._by_transport: dict[asyncio.BaseTransport, _Conn] = {}
        self._reported: set[str] = set()
        self.clients = 0           # browsers connected now
        self.sent = 0              # messages sent to browsers so far
        self.refused = 0           # connections refused (503) over max_clients

    @property
    def connections(self) -> int:
        """Connections open now (websockets and requests)."""
        return len(self._conns)

    @property
    def url(self) -> str:
        """The page's address."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    def start(self) -> str:
        """Start serving; returns the page's URL.

        Raises:
            ConfigError: the address cannot be listened on (port in use, unknown host).
        """
        ready = threading.Event()
        failure: list[BaseException] = []

        def main() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            asyncio.set_event_loop(loop)
            loop.set_exception_handler(self._loop_error)
            try:
                loop.run_until_complete(self._open())
            except BaseException as exc:      # noqa: BLE001 - handed to the starting thread
                failure.append(exc)
                ready.set()
                loop.close()
                return
            ready.set()
            try:
                loop.run_forever()
            finally:
                loop.run_until_complete(self._shutdown())
                loop.close()

        self._thread = threading.Thread(target=main, name="robotexp-view", daemon=True)
        self._thread.start()
        ready.wait()
        if failure:
            exc = failure[0]
            if isinstance(exc, socket.gaierror):
                raise ConfigError(f"live view: cannot listen on {self.host}: {exc.strerror or exc}; give --view-host "
                                  "an address or a name of this machine (127.0.0.1: this machine only)") from None
            if isinstance(exc, OSError):
                why = "the port is in use" if exc.errno == errno.EADDRINUSE else (exc.strerror or str(exc))
                raise ConfigError(f"live view: cannot listen on {self.host}:{self.port}: {why}; "
                                  "choose another --view-port or leave it out for a free one") from None
            raise ConfigError(f"live view: cannot listen on {self.host}:{self.port}: {exc}") from None
        return self.url

    def _loop_error(self, loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        """The server thread's failures that no handler took (say, accept() out of file descriptors): one
        line each, once; the run goes on."""
        exc = context.get("exception")
        what = f"{context.get('message', 'error')}" + (f": {type(exc).__name__}: {exc}" if exc is not None else "")
        if what not in self._reported and len(self._reported) < 20:
            self._reported.add(what)
            log.warning("live view: %s", what)

    def _now(self) -> float:
        assert self._loop is not None
        return self._loop.time()

    async def _open(self) -> None:
        app = web.Application(middlewares=[self._check_host], client_max_size=self.max_body)
        app.on_response_prepare.append(self._headers)
        app.router.add_get("/", self._index)
        app.router.add_get("/ws", self._websocket)
        app.router.add_get("/static/{name}", self._static)
        app.router.add_post("/command", self._command)
        self._runner = web.AppRunner(app, access_log=None, handle_signals=False, logger=_http_log)
        await self._runner.setup()
        loop = asyncio.get_running_loop()
        # the listening sockets are this server's own, and it accepts from them itself (`_accept_ready`): a
        # connection over the limit is answered and closed before the next is accepted, so a burst of them
        # never holds more than one of the process's file descriptors (asyncio's server accepts up to its
        # backlog at once and closes the refused ones later: a burst could use the run's last descriptors)
        self._listening = _listen(self.host, self.port)
        self.port = self._listening[0].getsockname()[1]
        self.guard.port = self.port
        for sock in self._listening:
            loop.add_reader(sock.fileno(), self._accept_ready, sock)
        self._sweeper = loop.create_task(self._close_idle())

    def _accept_ready(self, listening: socket.socket) -> None:
        """Connections wait on `listening`: accept them one at a time (`_ACCEPT_BATCH` at most per turn of
        the loop). Out of file descriptors (or kernel memory), accepting pauses for `_ACCEPT_PAUSE` s: the
        connections wait in the kernel's queue meanwhile, and the failure is said once."""
        loop = asyncio.get_running_loop()
        for _ in range(_ACCEPT_BATCH):
            try:
                sock, _addr = listening.accept()
            except (BlockingIOError, InterruptedError, ConnectionAbortedError):
                return
            except OSError as exc:
                if exc.errno not in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM):
                    raise
                self._loop_error(loop, {"message": "cannot accept a connection now", "exception": exc})
                loop.remove_reader(listening.fileno())
                loop.call_later(_ACCEPT_PAUSE, self._resume_accepting, listening)
                return
            self._take(sock)

    def _resume_accepting(self, listening: socket.socket) -> None:
        if listening in self._listening:
            asyncio.get_running_loop().add_reader(listening.fileno(), self._accept_ready, listening)

    def _take(self, sock: socket.socket) -> None:
        """An accepted connection: served behind a counter, or when `max_clients` are open and none of them is
        idle (the one that sent nothing longest, for 0.1 s or more, is closed to make room) told 503 and
        closed at once."""
        assert self._runner is not None and self._runner.server is not None
        sock.setblocking(False)
        now = self._now()
        if len(self._conns) >= self.max_clients:
            idle = [c for c in self._conns if not c.websocket and c.transport is not None and now - c.last >= 0.1]
            if idle:
                min(idle, key=lambda c: c.last).close()
        if len(self._conns) >= self.max_clients:
            self.refused += 1
            try:
                sock.send(_BUSY)          # a fresh socket's send buffer takes these 200 bytes whole
            except OSError:
                pass
            sock.close()
            return
        conn = _Conn(self, self._runner.server(), now)
        self._conns.add(conn)
        task = asyncio.get_running_loop().create_task(self._connect(conn, sock))
        self._connecting.add(task)
        task.add_done_callback(self._connecting.discard)

    async def _connect(self, conn: _Conn, sock: socket.socket) -> None:
        try:
            await asyncio.get_running_loop().connect_accepted_socket(lambda: conn, sock)
        except OSError:                 # the peer went away meanwhile
            self._conns.discard(conn)
            sock.close()

    async def _close_idle(self) -> None:
        """Close the connections that sent nothing for `idle_timeout` s (websockets aside)."""
        while True:
            await asyncio.sleep(min(1.0, self.idle_timeout / 4))
            now = self._now()
            for conn in list(self._conns):
                if not conn.websocket and now - conn.last > self.idle_timeout:
                    conn.close()            # (one never connected is dropped too)

    async def _shutdown(self) -> None:
        if self._sweeper is not None:
            self._sweeper.cancel()
        loop = asyncio.get_running_loop()
        for sock in self._listening:
            loop.remove_reader(sock.fileno())
            sock.close()
        self._listening = []
        for ws in list(self._sockets):
            await ws.close()
        if self._runner is not None:
            await self._runner.cleanup()
        for conn in list(self._conns):
            conn.close()

    def close(self) -> None:
        """Stop serving (closes the browsers' connections)."""
        loop, thread = self._loop, self._thread
        if loop is not None and thread is not None and thread.is_alive():
            loop.call_soon_threadsafe(loop.stop)
            thread.join(timeout=5)

    def __enter__(self) -> ViewServer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @staticmethod
    def _file(name: str) -> bytes | None:
        if "/" in name or "\\" in name or name.startswith("."):
            return None
        res = resources.files("robotexp.view").joinpath("static", name)
        return res.read_bytes() if res.is_file() else None

    @web.middleware
    async def _check_host(self, request: web.Request, handler: Any) -> web.StreamResponse:
        """Every request must name this server in its Host header (`Guard.host_ok`)."""
        if not self.guard.host_ok(request.headers.get("Host")):
            raise web.HTTPForbidden(text="this live view answers to its own address only (Host)\n")
        response: web.StreamResponse = await handler(request)
        return response

    @staticmethod
    async def _headers(request: web.Request, response: web.StreamResponse) -> None:
        response.headers.update(_HEADERS)

    async def _index(self, request: web.Request) -> web.Response:
        body = self._file("index.html")
        assert body is not None
        return web.Response(body=body, content_type="text/html", headers={"Cache-Control": "no-store"})

    async def _static(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        body = self._file(name)
        suffix = name[name.rfind("."):] if "." in name else ""
        if body is None or suffix not in _TYPES:
            raise web.HTTPNotFound()
        return web.Response(body=body, content_type=_TYPES[suffix], headers={"Cache-Control": "no-store"})

    async def _command(self, request: web.Request) -> web.Response:
        """POST /command with a JSON command, as a page sends it on the websocket ({"cmd": "seek",
        "value": 12.5}): 204 when handed over (commands the view does not offer now are ignored); 415 when
        not application/json, 403 from another origin, 413 over `max_body` bytes, 400 with one line of text
        when the body is no command the view takes (`command_problem`)."""
        if request.content_type != "application/json":
            raise web.HTTPUnsupportedMediaType(text='POST /command takes Content-Type: application/json, '
                                                    'like {"cmd": "pause"}\n')
        if not self.guard.same_origin(request):
            raise web.HTTPForbidden(text="POST /command from another origin is refused\n")
        if request.content_length is not None and request.content_length > self.max_body:
            raise web.HTTPRequestEntityTooLarge(max_size=self.max_body, actual_size=request.content_length)
        body = await request.read()         # at most max_body (client_max_size): else 413
        data = _json(body)
        problem = command_problem(data)
        if problem is not None:
            raise web.HTTPBadRequest(text=problem + "\n")
        self.hub.command(data)
        return web.Response(status=204)

    async def _websocket(self, request: web.Request) -> web.WebSocketResponse:
        if not self.guard.same_origin(request):
            raise web.HTTPForbidden(text="a websocket from another origin is refused\n")
        conn = self._by_transport.get(request.transport) if request.transport is not None else None
        if conn is not None:
            conn.websocket = True
        # no permessage-deflate: the map tiles are compressed already, and deflating every frame would cost
        # the run's process CPU for a few kB of laser and path
        ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=self.max_body, compress=False)
        await ws.prepare(request)
        # the sender polls the hub at its rate: the producer never wakes this thread (each wake-up would
        # take the GIL from the run's thread, and on a busy machine a thread that holds it may wait long
        # for a CPU while the run waits for it); the listener only counts the browser as watching
        def watching() -> None:
            pass

        self._sockets.add(ws)
        self.clients += 1
        self.hub.add_listener(watching)
        lock = asyncio.Lock()
        sender = asyncio.create_task(self._send_loop(ws, lock))
        try:
            async for msg in ws:
                if msg.type == WSMsgType.TEXT:
                    data = _json(msg.data.encode("utf-8", "replace"), quiet=True)
                    if data is None:
                        continue
                    problem = command_problem(data)
                    if problem is None:
                        self.hub.command(data)
                    else:
                        async with lock:
                            await ws.send_str(json.dumps({"type": "refused", "reason": problem}))
                elif msg.type == WSMsgType.ERROR:
                    break
        except (ConnectionError, RuntimeError) as exc:
            log.debug("view client gone: %s", exc)
        finally:
            self.hub.remove_listener(watching)
            sender.cancel()
            self._sockets.discard(ws)
            self.clients -= 1
        return ws

    async def _send_loop(self, ws: web.WebSocketResponse, lock: asyncio.Lock) -> None:
        """Send the newest state when it changed, at most `max_rate` times a second (`busy_rate` while the
        run goes at max speed); stale frames are skipped, a slow browser delays only its own messages."""
        client = ViewClient()
        try:
            while not ws.closed:
                msg = self.hub.message_for(client)
                if msg is not None:
                    async with lock:
                        await ws.send_str(json.dumps(msg, separators=(",", ":")))
                    self.sent += 1
                busy = self.hub.status.get("speed", 0) is None and self.hub.status.get("state") == "running"
                await asyncio.sleep(self.busy_interval if busy else self.min_interval)
        except (ConnectionError, RuntimeError) as exc:
            log.debug("view client gone: %s", exc)


def _json(body: bytes, quiet: bool = False) -> Any:
    """The JSON value of a command's body (None from the websocket, `quiet`, when it is none).

    Raises:
        HTTPBadRequest: not UTF-8 JSON, or nested too deep for the parser (a command is one flat object).
    """
    try:
        return json.loads(body.decode("utf-8"))
    except (ValueError, RecursionError):
        if quiet:
            return None
        raise web.HTTPBadRequest(text='expected a JSON object like {"cmd": "pause"}\n') from None

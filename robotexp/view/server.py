"""The live view's web server: aiohttp on its own asyncio loop in a background thread.

`ViewServer(hub).start()` serves the page (static files of this package: index.html, view.js,
view.css), a websocket at /ws and POST /command (a command as JSON, for scripts). Each websocket
connection polls the hub at its rate and sends its newest state when it changed and the last send is
done (`ViewHub.message_for`): a slow browser skips frames, a browser that goes away only ends its own
connection; the run never waits for either, nor wakes this thread. Commands a page sends ({"cmd": ...}) go to
`ViewHub.command`.
"""

from __future__ import annotations

import asyncio
import errno
import json
import logging
import threading
from importlib import resources
from typing import Any

from aiohttp import WSMsgType, web

from robotexp.errors import ConfigError
from robotexp.view.feed import ViewClient, ViewHub

__all__ = ["ViewServer"]

log = logging.getLogger(__name__)

_TYPES = {".html": "text/html", ".js": "text/javascript", ".css": "text/css", ".png": "image/png"}


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
    """

    def __init__(self, hub: ViewHub, host: str = "127.0.0.1", port: int = 0, max_rate: float = 10.0,
                 busy_rate: float = 4.0) -> None:
        self.hub, self.host, self.port = hub, host, port
        self.min_interval = 1.0 / max_rate
        self.busy_interval = 1.0 / min(busy_rate, max_rate)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._runner: web.AppRunner | None = None
        self._sockets: set[web.WebSocketResponse] = set()
        self.clients = 0           # browsers connected now
        self.sent = 0              # messages sent to browsers so far

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
            if isinstance(exc, OSError):
                why = "the port is in use" if exc.errno == errno.EADDRINUSE else (exc.strerror or str(exc))
                raise ConfigError(f"live view: cannot listen on {self.host}:{self.port}: {why}; "
                                  "choose another --view-port or leave it out for a free one") from None
            raise ConfigError(f"live view: cannot listen on {self.host}:{self.port}: {exc}") from None
        return self.url

    async def _open(self) -> None:
        app = web.Application()
        app.router.add_get("/", self._index)
        app.router.add_get("/ws", self._websocket)
        app.router.add_get("/static/{name}", self._static)
        app.router.add_post("/command", self._command)
        self._runner = web.AppRunner(app, access_log=None, handle_signals=False)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port)
        await site.start()
        server = site._server        # the listening sockets: the port the system chose for port 0
        sockets = getattr(server, "sockets", None) or ()
        if sockets:
            self.port = sockets[0].getsockname()[1]

    async def _shutdown(self) -> None:
        for ws in list(self._sockets):
            await ws.close()
        if self._runner is not None:
            await self._runner.cleanup()

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
        "value": 12.5}): 204 when handed over (commands the view does not offer are ignored), 400 when
        the body is no JSON object."""
        try:
            data = await request.json()
        except ValueError:
            data = None
        if not isinstance(data, dict) or not isinstance(data.get("cmd"), str):
            raise web.HTTPBadRequest(text='expected a JSON object like {"cmd": "pause"}\n')
        self.hub.command(data)
        return web.Response(status=204)

    async def _websocket(self, request: web.Request) -> web.WebSocketResponse:
        # no permessage-deflate: the map tiles are compressed already, and deflating every frame would cost
        # the run's process CPU for a few kB of laser and path
        ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=1 << 16, compress=False)
        await ws.prepare(request)
        # the sender polls the hub at its rate: the producer never wakes this thread (each wake-up would
        # take the GIL from the run's thread, and on a busy machine a thread that holds it may wait long
        # for a CPU while the run waits for it); the listener only counts the browser as watching
        def watching() -> None:
            pass

        self._sockets.add(ws)
        self.clients += 1
        self.hub.add_listener(watching)
        sender = asyncio.create_task(self._send_loop(ws))
        try:
            async for msg in ws:
                if msg.type == WSMsgType.TEXT:
                    try:
                        data: Any = json.loads(msg.data)
                    except ValueError:
                        continue
                    if isinstance(data, dict):
                        self.hub.command(data)
                elif msg.type == WSMsgType.ERROR:
                    break
        finally:
            self.hub.remove_listener(watching)
            sender.cancel()
            self._sockets.discard(ws)
            self.clients -= 1
        return ws

    async def _send_loop(self, ws: web.WebSocketResponse) -> None:
        """Send the newest state when it changed, at most `max_rate` times a second (`busy_rate` while the
        run goes at max speed); stale frames are skipped, a slow browser delays only its own messages."""
        client = ViewClient()
        try:
            while not ws.closed:
                msg = self.hub.message_for(client)
                if msg is not None:
                    await ws.send_str(json.dumps(msg, separators=(",", ":")))
                    self.sent += 1
                busy = self.hub.status.get("speed", 0) is None and self.hub.status.get("state") == "running"
                await asyncio.sleep(self.busy_interval if busy else self.min_interval)
        except (ConnectionError, RuntimeError) as exc:
            log.debug("view client gone: %s", exc)

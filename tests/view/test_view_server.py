"""The live view's server through real sockets: the page and its files, the websocket's
frames and commands, a port in use as one clear error, and a browser that never reads (or goes
away) never slowing the producer while another browser keeps getting the newest state."""

from __future__ import annotations

import asyncio
import base64
import json
import os
import socket
import time
import urllib.request
from typing import Any

import aiohttp
import pytest

from robotexp.errors import ConfigError
import numpy as np

from robotexp.view.feed import Frame, ViewHub
from robotexp.view.server import ViewServer

META = {"geo": {"origin_x": 0.0, "origin_y": 0.0, "cell": 0.1, "rows": 100, "cols": 100}, "radius": 0.2,
        "title": "test"}


def _get(url: str) -> tuple[int, str, bytes]:
    with urllib.request.urlopen(url, timeout=5) as r:
        return r.status, r.headers.get("Content-Type", ""), r.read()


def test_serves_page_and_static_files() -> None:
    with ViewServer(ViewHub()) as server:
        assert server.url.startswith("http://127.0.0.1:") and server.port > 0
        status, kind, body = _get(server.url)
        assert status == 200 and kind.startswith("text/html") and b'<canvas id="map"' in body
        assert b"/static/view.js" in body and b"http" not in body.replace(b"http-equiv", b"")  # no CDN
        for name, kind_want in (("view.js", "text/javascript"), ("view.css", "text/css")):
            status, kind, body = _get(server.url + "static/" + name)
            assert status == 200 and kind.startswith(kind_want) and len(body) > 500
        with pytest.raises(urllib.error.HTTPError) as err:
            _get(server.url + "static/..%2Fserver.py")
        assert err.value.code == 404
        err.value.close()


def test_port_in_use_is_one_clear_error() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(ConfigError, match=f"cannot listen on 127.0.0.1:{port}: the port is in use"):
            ViewServer(ViewHub(), port=port).start()
    with pytest.raises(ConfigError, match="cannot listen on no-such-host.invalid: .*give --view-host an address"):
        ViewServer(ViewHub(), host="no-such-host.invalid").start()


def test_every_address_of_a_name_listens_on_one_port() -> None:
    """"" listens on every interface (IPv4 and, where the system has it, IPv6), on one port."""
    with ViewServer(ViewHub(), host="") as server:
        ports = {sock.getsockname()[1] for sock in server._listening}
        assert ports == {server.port} and server.port > 0
        families = {sock.family for sock in server._listening}
        assert socket.AF_INET in families
        with urllib.request.urlopen(f"http://127.0.0.1:{server.port}/", timeout=5) as page:
            assert page.status == 200


async def _frames(url: str, n: int, commands: list[dict[str, Any]] = ()) -> list[dict[str, Any]]:  # type: ignore[assignment]
    out: list[dict[str, Any]] = []
    async with aiohttp.ClientSession() as session, session.ws_connect(url + "ws") as ws:
        for cmd in commands:
            await ws.send_str(json.dumps(cmd))
        while len(out) < n:
            msg = await asyncio.wait_for(ws.receive(), 10)
            out.append(json.loads(msg.data))
    return out


def test_websocket_frames_and_commands() -> None:
    got: list[dict[str, Any]] = []
    hub = ViewHub(on_command=got.append)
    hub.start(META)
    hub.publish(Frame(time=1.5, pose=(1.0, 2.0, 0.5), path=[1.0, 2.0], map=np.ones((100, 100), np.uint8)))
    with ViewServer(hub) as server:
        frames = asyncio.run(_frames(server.url, 1, [{"cmd": "pause"}, {"cmd": "stop"}, "junk"]))  # type: ignore[list-item]
        deadline = time.monotonic() + 5
        while len(got) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
    first = frames[0]
    assert first["meta"]["title"] == "test" and first["t"] == 1.5 and first["pose"] == [1.0, 2.0, 0.5]
    assert first["path"] == [1.0, 2.0] and first["map"]["rows"] == 100 and len(first["map"]["tiles"]) == 2 * 16
    assert [g["cmd"] for g in got] == ["pause", "stop"]


def _stuck_client(port: int) -> socket.socket:
    """A websocket client that completes the handshake and then never reads."""
    s = socket.create_connection(("127.0.0.1", port))
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    key = base64.b64encode(os.urandom(16)).decode()
    s.sendall((f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
               f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
    return s


def test_stuck_and_vanished_browsers_never_slow_the_producer(cpu_wait: Any) -> None:
    hub = ViewHub()
    hub.start(META)
    laser = [float(i) for i in range(720)]
    with ViewServer(hub) as server:
        stuck = [_stuck_client(server.port) for _ in range(3)]
        gone = _stuck_client(server.port)
        gone.close()                                      # a browser that went away
        time.sleep(0.3)
        t0, mark = time.perf_counter(), cpu_wait.total()
        n = 3000
        for k in range(n):                                # ~6 MB of frames nobody stuck can read
            hub.publish(Frame(time=k * 0.1, pose=(k, 0.0, 0.0), laser=laser, path=[k * 0.01, 0.0]))
        # the time the producer's thread had: a loaded machine's waits for a CPU meanwhile do not count
        per_frame = (time.perf_counter() - t0 - cpu_wait.since(mark)) / n
        frames = asyncio.run(_frames(server.url, 1))      # a healthy browser meanwhile: the newest state
        for s in stuck:
            s.close()
    assert per_frame < 2e-3, f"publish took {per_frame * 1e3:.2f} ms per frame with stuck browsers"
    assert frames[0]["t"] == pytest.approx((n - 1) * 0.1) and len(frames[0]["path"]) == 2 * n


def test_post_command() -> None:
    """POST /command hands a JSON command to the hub (204); anything else is a 400 naming the form."""
    got: list[dict[str, Any]] = []
    hub = ViewHub(controls=("pause", "seek"), on_command=got.append)
    with ViewServer(hub) as server:
        def post(body: bytes) -> int:
            req = urllib.request.Request(server.url + "command", data=body, method="POST",
                                         headers={"Content-Type": "application/json"})
            try:
                with urllib.request.urlopen(req, timeout=5) as r:
                    return int(r.status)
            except urllib.error.HTTPError as err:
                err.close()
                return int(err.code)

        assert post(b'{"cmd": "seek", "value": 12.5}') == 204
        assert post(b'{"cmd": "stop"}') == 204                # not offered here: ignored
        assert post(b"seek 12") == 400 and post(b"[1]") == 400
    assert got == [{"cmd": "seek", "value": 12.5}]

"""The live view refuses what does not come from its own page, through real sockets: a foreign Host (DNS
rebinding), a websocket or POST /command from another origin, a command that is not JSON (text/plain: a
form or a no-cors fetch), bodies over 4 KiB, malformed or deeply nested JSON (400, nothing on the terminal),
speeds outside 0.01x..1000x; and it caps its connections, so idle ones cannot take the descriptors a run needs."""

from __future__ import annotations

import asyncio
import http.client
import json
import logging
import os
import re
import resource
import socket
import threading
import time
from typing import Any

import aiohttp
import pytest

from robotexp.view.feed import ViewHub
from robotexp.view.server import ViewServer

META = {"geo": {"origin_x": 0.0, "origin_y": 0.0, "cell": 0.1, "rows": 10, "cols": 10}, "radius": 0.2,
        "title": "guarded"}


def _request(port: int, method: str, path: str, body: bytes | None = None, *, host: str | None = None,
             headers: dict[str, str] | None = None) -> tuple[int, dict[str, str], bytes]:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    try:
        conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
        conn.putheader("Host", host if host is not None else f"127.0.0.1:{port}")
        for k, v in (headers or {}).items():
            conn.putheader(k, v)
        if body is not None:
            conn.putheader("Content-Length", str(len(body)))
        conn.endheaders(body)
        r = conn.getresponse()
        return r.status, {k.lower(): v for k, v in r.getheaders()}, r.read()
    finally:
        conn.close()


def _server(commands: list[dict[str, Any]], **kwargs: Any) -> ViewServer:
    hub = ViewHub(on_command=commands.append)
    hub.start(META)
    return ViewServer(hub, **kwargs)


def test_foreign_host_is_refused() -> None:
    with _server([]) as server:
        p = server.port
        # any port: a port forwarded under another number (ssh -L 9000:127.0.0.1:PORT) names its own
        for host in (f"127.0.0.1:{p}", f"localhost:{p}", f"[::1]:{p}", f"LOCALHOST:{p}", "127.0.0.1:9000", "localhost"):
            status, headers, body = _request(p, "GET", "/", host=host)
            assert status == 200 and b'<canvas id="map"' in body, host
            assert headers["x-frame-options"] == "DENY"
            assert "frame-ancestors 'none'" in headers["content-security-policy"]
        for host in (f"evil.example:{p}", "evil.example", f"localhost.evil.example:{p}", f"127.0.0.1:{p}@evil.example",
                     f"10.0.0.7:{p}", f"[fe80::1]:{p}", f"[evil.example]:{p}", f"127.0.0.1:{p}:1", ""):
            for path in ("/", "/static/view.js", "/ws"):
                status, _, body = _request(p, "GET", path, host=host)
                assert status in (400, 403) and b"canvas" not in body, (host, path, status)


def test_post_command_only_json_from_its_own_origin() -> None:
    got: list[dict[str, Any]] = []
    with _server(got) as server:
        p = server.port
        pause = b'{"cmd": "pause"}'
        own = {"Origin": f"http://127.0.0.1:{p}"}
        refused = [
            {"Content-Type": "text/plain"},                                  # a form or a no-cors fetch
            {"Content-Type": "text/plain", "Origin": "http://evil.example"},
            {"Content-Type": "application/x-www-form-urlencoded", **own},
            {"Content-Type": "multipart/form-data; boundary=x", **own},
            {"Content-Type": "application/json", "Origin": "http://evil.example"},
            {"Content-Type": "application/json", "Origin": "null"},
            {"Content-Type": "application/json", "Origin": f"http://127.0.0.1:{p + 1}"},
            {"Content-Type": "application/json", "Sec-Fetch-Site": "cross-site"},
            {},
        ]
        for headers in refused:
            status, _, _ = _request(p, "POST", "/command", pause, headers=headers)
            assert status in (403, 415), (headers, status)
        assert got == []
        for headers in ({"Content-Type": "application/json"},                          # a script (no Origin)
                        {"Content-Type": "application/json; charset=utf-8", **own},   # the page
                        {"Content-Type": "application/json", "Origin": f"http://localhost:{p}",
                         "Sec-Fetch-Site": "same-origin"}):
            host = f"localhost:{p}" if "localhost" in headers.get("Origin", "") else None
            status, _, _ = _request(p, "POST", "/command", pause, host=host, headers=headers)
            assert status == 204, (headers, status)
        assert got == [{"cmd": "pause"}] * 3


async def _ws_attempt(url: str, origin: str | None) -> dict[str, Any] | int:
    headers = {} if origin is None else {"Origin": origin}
    async with aiohttp.ClientSession() as session:
        try:
            async with session.ws_connect(url + "ws", headers=headers) as ws:
                await ws.send_str(json.dumps({"cmd": "stop"}))
                msg = await asyncio.wait_for(ws.receive(), 10)
                return dict(json.loads(msg.data))
        except aiohttp.WSServerHandshakeError as exc:
            return exc.status


def test_websocket_from_another_origin_is_refused() -> None:
    got: list[dict[str, Any]] = []
    with _server(got) as server:
        for origin in ("http://evil.example", "null", f"http://127.0.0.1:{server.port + 1}",
                       f"https://127.0.0.1:{server.port}"):
            assert asyncio.run(_ws_attempt(server.url, origin)) == 403, origin
        time.sleep(0.2)
        assert got == [] and server.clients == 0
        first = asyncio.run(_ws_attempt(server.url, f"http://127.0.0.1:{server.port}"))
        assert isinstance(first, dict) and first["meta"]["title"] == "guarded"
    assert got == [{"cmd": "stop"}]


def test_any_address_accepts_the_machines_names_not_foreign_ones() -> None:
    """Served on 0.0.0.0 on purpose: an address (any IP literal: no DNS name an attacker's page could rebind)
    or this machine's own name reaches the page; any other name is refused."""
    with _server([], host="0.0.0.0") as server:
        p = server.port
        for host in (f"192.0.2.7:{p}", f"127.0.0.1:{p}", f"{socket.gethostname()}:{p}", f"localhost:{p}",
                     f"[fe80::1]:{p}"):
            assert _request(p, "GET", "/", host=host)[0] == 200, host
        for host in (f"evil.example:{p}", f"{socket.gethostname()}.evil.example:{p}", "evil.example"):
            assert _request(p, "GET", "/", host=host)[0] == 403, host


def test_malformed_bodies_are_400_and_silent(capfd: pytest.CaptureFixture[str]) -> None:
    got: list[dict[str, Any]] = []
    with _server(got) as server:
        p = server.port
        json_type = {"Content-Type": "application/json"}
        for body in (b"[" * 4000, b'{"a":' * 800, b"\xff\xfe", b"{", b'"pause"', b"[1]", b'{"cmd": 5}',
                     b'{"cmd": "speed", "value": 1e-300}', b'{"cmd": "speed", "value": 1e-6}',
                     b'{"cmd": "speed", "value": 1e9}', b'{"cmd": "speed", "value": "fast"}',
                     b'{"cmd": "speed", "value": NaN}', b'{"cmd": "seek", "value": "Infinity"}'):
            status, _, text = _request(p, "POST", "/command", body, headers=json_type)
            assert status == 400, (body[:20], status)
            assert len(text) < 200 and b"Traceback" not in text
        status, _, _ = _request(p, "POST", "/command", b"[" * 200_000, headers=json_type)
        assert status == 413
        status, _, _ = _request(p, "POST", "/command", b'{"cmd": "pause", "pad": "' + b" " * 5000 + b'"}',
                                headers=json_type)
        assert status == 413

        for raw in (b"GARBAGE\r\n\r\n", b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX: " + b"a" * 20000 + b"\r\n\r\n",
                    b"POST /command HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: -5\r\n\r\n",
                    b"GET /\x00 HTTP/1.1\r\n\r\n"):
            with socket.create_connection(("127.0.0.1", p), timeout=5) as raw_sock:
                raw_sock.sendall(raw)
                assert re.match(rb"HTTP/1\.[01] 4", raw_sock.recv(100)), raw[:20]

        async def ws_junk() -> dict[str, Any]:
            async with aiohttp.ClientSession() as session, session.ws_connect(server.url + "ws") as ws:
                await ws.receive()                                   # the first frame
                for junk in ("[" * 4000, '{"a":' * 800, "{", '{"cmd": "speed", "value": 1e-300}'):
                    await ws.send_str(junk)
                await ws.send_str('{"cmd": "pause"}')
                while True:
                    msg = json.loads((await asyncio.wait_for(ws.receive(), 10)).data)
                    if msg.get("type") == "refused":
                        return dict(msg)

        refused = asyncio.run(ws_junk())
        assert "0.01" in refused["reason"] and "1000" in refused["reason"]
        deadline = time.monotonic() + 5
        while not got and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.2)
    assert got == [{"cmd": "pause"}]
    out, err = capfd.readouterr()
    assert err == "" and "Traceback" not in out


BUSY = b"HTTP/1.1 503 Service Unavailable"


def _until_closed(s: socket.socket) -> bytes:
    """The first line the server sent before closing `s` (b"": none); fails when it stays open 2 s."""
    s.settimeout(2.0)
    got = b""
    try:
        while chunk := s.recv(4096):
            got += chunk
    except ConnectionResetError:
        pass
    return got.split(b"\r\n")[0]


def test_connections_are_capped_and_idle_ones_closed() -> None:
    with _server([], max_clients=8, idle_timeout=1.0) as server:
        p = server.port
        idle = [socket.create_connection(("127.0.0.1", p)) for _ in range(40)]
        try:
            time.sleep(0.3)
            assert server.connections <= 8
            t0 = time.monotonic()
            status, _, body = _request(p, "GET", "/")    # a browser still gets the page: an idle one makes room
            assert status == 200 and b"canvas" in body and time.monotonic() - t0 < 2.0
            deadline = time.monotonic() + 5
            while server.connections > 0 and time.monotonic() < deadline:
                time.sleep(0.05)
            assert server.connections == 0                # idle connections are closed after idle_timeout
            answers = [_until_closed(s) for s in idle]     # each was closed: refused (503) or idle
            assert all(a in (b"", BUSY) for a in answers) and answers.count(BUSY) >= 40 - 8 - 1, answers
        finally:
            for s in idle:
                s.close()


def _limit_new_descriptors(room: int) -> int:
    """Lower this process's soft RLIMIT_NOFILE so that exactly `room` more files can be opened; returns the
    soft limit to restore. (The limit bounds descriptor numbers: free numbers below it are the room.)"""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    taken = {int(name) for name in os.listdir("/proc/self/fd")}
    limit, free = 0, 0
    while free < room:
        if limit not in taken:
            free += 1
        limit += 1
    resource.setrlimit(resource.RLIMIT_NOFILE, (limit, hard))
    return soft


def test_a_burst_of_connections_costs_few_descriptors(caplog: pytest.LogCaptureFixture) -> None:
    """90 connections wait in the kernel's queue while the server's loop is busy; when it comes back it takes
    them with a few of the process's file descriptors at a time (max_clients held, each refused one answered
    and closed before the next is accepted): with room for only 28 more files in the process, no accept
    fails and every connection over the limit gets its 503."""
    with _server([], max_clients=8, idle_timeout=30.0) as server:
        assert server._loop is not None
        gate, held = threading.Event(), threading.Event()
        server._loop.call_soon_threadsafe(lambda: (held.set(), gate.wait(10)))
        assert held.wait(5)
        clients = [socket.create_connection(("127.0.0.1", server.port)) for _ in range(90)]
        soft = _limit_new_descriptors(28)
        try:
            with caplog.at_level(logging.WARNING, logger="robotexp.view"):
                gate.set()
                answers = [_until_closed(s) for s in clients[8:]]
        finally:
            resource.setrlimit(resource.RLIMIT_NOFILE, (soft, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
            for s in clients:
                s.close()
        assert not [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
        assert answers.count(BUSY) >= 82 - 2 and server.refused >= 80, answers

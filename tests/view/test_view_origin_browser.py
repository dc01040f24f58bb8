"""Through a real browser (Debian's headless Chromium, driven by playwright): a page served from another
origin cannot read or command the live view of a run. It tries a no-cors text/plain POST /command, a JSON
POST, a form posting a JSON-looking text/plain body, reading the page, and a websocket to the view; none of
them pauses or stops the run and the socket gets no state. A name rebound to the view's address (DNS
rebinding, emulated with Chromium's host resolver rules) gets 403. The view's own page still commands it."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import numpy as np

from robotexp.view.feed import Frame, ViewHub
from robotexp.view.server import ViewServer
from test_view_browser import CHROMIUM, CHROMIUM_ARGS, _need_browser

META = {"geo": {"origin_x": 0.0, "origin_y": 0.0, "cell": 0.1, "rows": 40, "cols": 40}, "radius": 0.2,
        "title": "the run"}

ATTACK = """<!doctype html><html><body>
<iframe name="sink" id="sink"></iframe>
<form id="form" method="POST" action="VIEW/command" enctype="text/plain" target="sink">
<input name='{"cmd":"pause","x":"' value='"}'></form>
<script>
const view = "VIEW";
window.result = {fetch: "pending", json: "pending", read: "pending", ws: "pending", wsMessages: 0, form: "pending"};
fetch(view + "/command", {method: "POST", mode: "no-cors", headers: {"Content-Type": "text/plain"},
                          body: '{"cmd":"pause"}'}).then(r => result.fetch = r.type, e => result.fetch = "error");
fetch(view + "/command", {method: "POST", headers: {"Content-Type": "application/json"}, body: '{"cmd":"stop"}'})
  .then(r => r.text()).then(t => result.json = "read", e => result.json = "error");
fetch(view + "/").then(r => r.text()).then(t => result.read = "read", e => result.read = "error");
const ws = new WebSocket(view.replace("http:", "ws:") + "/ws");
ws.onopen = () => { result.ws = "open"; ws.send('{"cmd":"stop"}'); };
ws.onmessage = () => { result.wsMessages++; };
ws.onerror = () => { if (result.ws === "pending") result.ws = "error"; };
ws.onclose = () => { if (result.ws === "pending") result.ws = "closed"; };
document.getElementById("sink").onload = () => { result.form = "sent"; };
document.getElementById("form").submit();
</script></body></html>"""


@contextmanager
def _attacker(view: str) -> Iterator[str]:
    """An HTTP server of another origin (127.0.0.1, another port) serving the attacking page."""
    page = ATTACK.replace("VIEW", view.rstrip("/")).encode()

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 - the stdlib's name
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(page)))
            self.end_headers()
            self.wfile.write(page)

        def log_message(self, *args: Any) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


def test_another_origin_cannot_read_or_command_the_view() -> None:
    _need_browser()
    from playwright.sync_api import sync_playwright

    got: list[dict[str, Any]] = []
    hub = ViewHub(on_command=got.append)
    hub.start(META)
    hub.publish(Frame(time=2.0, pose=(1.0, 1.0, 0.0), path=[1.0, 1.0], map=np.ones((40, 40), np.uint8)))
    with ViewServer(hub) as view, _attacker(view.url) as evil, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=[
            *CHROMIUM_ARGS, "--host-resolver-rules=MAP rebound.test 127.0.0.1"])
        try:
            page = browser.new_page()
            page.goto(evil)
            # (a form whose POST is answered 204 loads nothing in its frame: it is not waited for)
            page.wait_for_function("['fetch', 'json', 'read', 'ws'].every((k) => window.result[k] !== 'pending')",
                                   timeout=20_000)
            time.sleep(1.0)                          # anything that got through has reached the hub by now
            result = page.evaluate("window.result")
            assert got == [], (got, result)
            assert result["ws"] in ("error", "closed") and result["wsMessages"] == 0, result
            assert result["json"] == "error" and result["read"] == "error", result    # no CORS: nothing read
            assert view.clients == 0

            rebound = page.goto(view.url.replace("127.0.0.1", "rebound.test"))
            assert rebound is not None and rebound.status == 403
            assert page.locator("#map").count() == 0
            assert got == []

            page.goto(view.url)                      # the view's own page: it shows the run and commands it
            page.wait_for_function("Number(document.body.dataset.t) === 2", timeout=20_000)
            page.click("#pause")
            deadline = time.monotonic() + 10
            while not got and time.monotonic() < deadline:
                time.sleep(0.02)
            assert got == [{"cmd": "pause"}]
            status = page.evaluate("""() => fetch('/command', {method: 'POST', headers: {'Content-Type':
                'application/json'}, body: JSON.stringify({cmd: 'resume'})}).then((r) => r.status)""")
            assert status == 204 and got[-1] == {"cmd": "resume"}
        finally:
            browser.close()

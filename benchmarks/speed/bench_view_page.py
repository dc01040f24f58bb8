"""What a page update of the live view costs the browser: headless Chromium's CPU while the page gets
messages at a given rate (a synthetic run on a 172 x 222-cell map: the robot moving, a 181-beam scan,
the path and curve growing, a map row changing every sixth frame), and with the page open and nothing
sent. This is the cost the server's rates (`ViewServer` max_rate, busy_rate) trade against smoothness.

Run: python benchmarks/speed/bench_view_page.py [--rates 1,2,4,10] [--seconds 10] [--chromium /usr/bin/chromium]
Prints, per rate, Chromium's CPU [% of one core] and per message [ms], and the machine's load.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_view import close_browser, descendants_cpu, open_browser

from robotexp.robot import LaserScan
from robotexp.view.feed import Frame, ViewHub
from robotexp.view.server import ViewServer

ROWS, COLS = 172, 222


def measure(chromium: str, rate: float, seconds: float) -> tuple[float, int]:
    """Chromium's CPU [s] over `seconds` of messages at `rate` per second (0: none sent), and the messages."""
    hub = ViewHub()
    server = ViewServer(hub, max_rate=max(rate, 0.01), busy_rate=max(rate, 0.01))
    server.start()
    hub.start({"geo": {"origin_x": 0.0, "origin_y": 0.0, "cell": 0.1, "rows": ROWS, "cols": COLS}, "radius": 0.25,
               "title": "bench_view_page", "start": [5.0, 5.0, 0.0]})
    scan = LaserScan(np.linspace(-1.5, 1.5, 181), np.full(181, 2.5), 4.0)
    classes = np.zeros((ROWS, COLS), np.uint8)
    with tempfile.TemporaryDirectory(prefix="bench_view_page_") as profile:
        browser = open_browser(chromium, server.url, Path(profile))
        try:
            deadline = time.monotonic() + 60
            while server.sent == 0 and time.monotonic() < deadline:
                time.sleep(0.05)
            time.sleep(3.0)                         # start-up done
            cpu0, sent0, t0, k = descendants_cpu(os.getpid()), server.sent, time.monotonic(), 0
            while time.monotonic() - t0 < seconds:
                if rate > 0:
                    k += 1
                    x, y = 5 + 5 * np.sin(k / 50), 5 + 3 * np.cos(k / 50)
                    frame = Frame(time=k * 0.1, pose=(x, y, k / 10), scan=scan, path=[x, y],
                                  curve=[k * 0.1, min(1.0, k / 3000)])
                    if k % 6 == 0:
                        classes = classes.copy()
                        classes[(k // 6) % ROWS, :] = 1 + (k // 6 // ROWS) % 2
                        frame.map = classes
                    hub.publish(frame)
                time.sleep(0.04)
            cpu = descendants_cpu(os.getpid()) - cpu0
            sent = server.sent - sent0
        finally:
            close_browser(browser)
            server.close()
    return cpu, sent


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rates", default="0,1,2,4,10", help="Messages a second to try (0: page open, none sent).")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    a = ap.parse_args()
    try:
        rates = [float(r) for r in a.rates.split(",")]
    except ValueError:
        rates = []
    if not rates or any(r < 0 for r in rates) or not a.seconds > 0:
        print("bench_view_page: --rates is a list of numbers >= 0, --seconds > 0", file=sys.stderr)
        return 2
    if not Path(a.chromium).exists():
        print(f"bench_view_page: no Chromium at {a.chromium}; install Debian's chromium or pass --chromium PATH",
              file=sys.stderr)
        return 2
    print(f"load average (1 min) {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; {a.seconds:g} s per rate")
    idle = None
    for rate in rates:
        cpu, sent = measure(a.chromium, rate, a.seconds)
        share = cpu / a.seconds
        if rate == 0:
            idle = share
            print(f"  page open, nothing sent: Chromium {share * 100:.1f} % of one core")
            continue
        extra = "" if idle is None or not sent else \
            f", {(cpu - idle * a.seconds) / sent * 1000:.1f} ms per message above the idle page"
        print(f"  {rate:g} messages/s asked, {sent / a.seconds:.1f} sent: Chromium {share * 100:.1f} % of one core"
              f"{extra}")
    print(f"load average (1 min) at the end {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""What the live view costs a simulated run (issue 16, item 1: at most 10 % of its speed with a browser
watching): robot time / wall time of the same run (a world, an explorer, a robot-time limit) without the
view, with the view at --view-speed max and no browser, and with the view and headless Chromium watching
the page, measured in one process, the three settings interleaved `--repeats` times (the median of each).

Run: python benchmarks/bench_view.py [--world dense] [--method frontier] [--max-time 300] [--repeats 3]
         [--chromium /usr/bin/chromium]
Prints each setting's speed and the ratios to the run without the view; exit 1 when the watched run is
more than 10 % slower, 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

from robotexp.experiment import RunSpec, run_experiment
from robotexp.view.feed import ViewHub
from robotexp.view.observer import ViewObserver
from robotexp.view.server import ViewServer

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def chromium_cpu() -> float:
    """[s] CPU time (user + system) used so far by every process whose name contains "chrom"."""
    total = 0
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        if "chrom" in stat[stat.find("(") + 1:stat.rfind(")")]:
            fields = stat[stat.rfind(")") + 2:].split()
            total += int(fields[11]) + int(fields[12])
    return total / os.sysconf("SC_CLK_TCK")


def one_run(spec: RunSpec, setting: str, browser: Any) -> tuple[float, float, float, float, int]:
    """(robot time, wall time, this process's CPU time, Chromium's CPU time, maps the page drew) of `spec`
    in `setting`: "none", "view" or "browser"."""
    observers = []
    server = page = None
    if setting != "none":
        hub = ViewHub()
        observers.append(ViewObserver(hub, speed=None))
        server = ViewServer(hub)
        server.start()
        if setting == "browser":
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            page.goto(server.url)
            page.wait_for_function("document.body.dataset.state === 'waiting'", timeout=10_000)
    t0, cpu0, chrome0 = time.perf_counter(), time.process_time(), chromium_cpu()
    out = run_experiment(spec, None, observers=observers, image=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    chrome = chromium_cpu() - chrome0 if setting == "browser" else 0.0
    frames = 0
    if page is not None:
        page.wait_for_function("document.body.dataset.state === 'ended'", timeout=30_000)
        frames = int(page.evaluate("Number(document.getElementById('map').dataset.mapVersion)"))
        page.close()
    if server is not None:
        server.close()
    return out.record.robot_time_s, wall, cpu, chrome, frames


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--world", default="dense")
    ap.add_argument("--method", default="frontier")
    ap.add_argument("--max-time", type=float, default=300.0, help="Robot-time limit of each run [s].")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    a = ap.parse_args()
    if a.repeats < 1 or not a.max_time > 0:
        print("bench_view: --repeats must be >= 1 and --max-time > 0", file=sys.stderr)
        return 2
    if not Path(a.chromium).exists():
        print(f"bench_view: no Chromium at {a.chromium}; install Debian's chromium or pass --chromium PATH",
              file=sys.stderr)
        return 2
    from playwright.sync_api import sync_playwright

    spec = RunSpec(world=a.world, method=a.method, max_time=a.max_time)
    run_experiment(RunSpec(world=a.world, method=a.method, max_time=5.0), None, image=False)   # warm-up: JIT
    speeds: dict[str, list[float]] = {"none": [], "view": [], "browser": []}
    cpus: dict[str, list[float]] = {"none": [], "view": [], "browser": []}
    frames: list[int] = []
    chrome: list[float] = []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=a.chromium, args=CHROMIUM_ARGS)
        try:
            for _ in range(a.repeats):
                for setting in speeds:
                    robot, wall, cpu, chrome_cpu, n = one_run(spec, setting, browser)
                    speeds[setting].append(robot / wall)
                    cpus[setting].append(cpu)
                    if setting == "browser":
                        frames.append(n)
                        chrome.append(chrome_cpu / wall)
        finally:
            browser.close()
    base, base_cpu = statistics.median(speeds["none"]), statistics.median(cpus["none"])
    print(f"{a.world} {a.method}, {a.max_time:g} s robot time, {a.repeats} runs each (medians; the machine's "
          f"other load moves the speeds, the CPU time of this process less so):")
    for setting, label in (("none", "without the view"), ("view", "view, no browser"),
                           ("browser", "view, Chromium watching")):
        med, cpu = statistics.median(speeds[setting]), statistics.median(cpus[setting])
        print(f"  {label:24s} {med:8.1f} x real time  speed ratio {med / base:5.3f}   CPU {cpu:6.2f} s  "
              f"ratio {cpu / base_cpu:5.3f}   (speeds: {', '.join(f'{s:.1f}' for s in speeds[setting])})")
    print(f"  maps the page drew per watched run: {frames}; Chromium's CPU while watching: "
          f"{statistics.median(chrome) * 100:.0f} % of one core")
    ratio = statistics.median(speeds["browser"]) / base
    print(f"watched run at {ratio * 100:.1f} % of the speed without the view (target >= 90 %)")
    return 0 if ratio >= 0.9 else 1


if __name__ == "__main__":
    sys.exit(main())

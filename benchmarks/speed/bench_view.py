"""What the live view costs a simulated run (target: at most 10 % of its speed with a browser
watching): robot time / wall time of the run loop (the record's wall time: planning and world loading
left out) of the same run (a world, an explorer, a robot-time limit) without the view, with the view at
--view-speed max and no browser, and with the view and headless Chromium watching the page, in one
process. The three settings are interleaved `--repeats` times (their order rotating), so that each
repeat's runs share the machine's load of the moment: the figure judged is the median over repeats of
the watched run's speed over the unwatched one's of the same repeat.

The browser is Chromium started as a user would (its own session, `chromium --headless URL`, a fresh
profile, 1280 x 800), once per watched run, connected before the run starts: no driver process runs
beside it (a playwright driver would sit in this process's session and take its CPU from the run).

Run: python benchmarks/speed/bench_view.py [--world dense] [--method frontier] [--max-time 600] [--repeats 5]
         [--chromium /usr/bin/chromium] [--page-rate HZ] [--busy-rate HZ]
Prints each setting's speeds, the ratios, the CPU time of this process and of its Chromium, the
messages the page got and the machine's load average; exit 1 when the watched run is more than 10 %
slower, 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.view.feed import ViewHub
from robotexp.view.observer import ViewObserver
from robotexp.view.server import ViewServer

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
SETTINGS = ("none", "view", "browser")
LABELS = {"none": "without the view", "view": "view, no browser", "browser": "view, Chromium watching"}


def descendants_cpu(root: int) -> float:
    """[s] CPU time (user + system) used so far by the processes descending from `root` (this process's
    Chromium, started by playwright; not other users' browsers)."""
    children: dict[int, list[int]] = {}
    cpu: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        fields = stat[stat.rfind(")") + 2:].split()
        children.setdefault(int(fields[1]), []).append(int(entry))
        cpu[int(entry)] = int(fields[11]) + int(fields[12])
    total, todo = 0, list(children.get(root, []))
    while todo:
        pid = todo.pop()
        total += cpu.get(pid, 0)
        todo += children.get(pid, [])
    return total / os.sysconf("SC_CLK_TCK")


def _wait(what: str, done: Any, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not done():
        if time.monotonic() > deadline:
            raise RuntimeError(f"bench_view: {what} within {timeout:g} s")
        time.sleep(0.05)


def open_browser(chromium: str, url: str, profile: Path) -> subprocess.Popen[bytes]:
    """Headless Chromium showing `url`, in a session of its own (as a user's browser would be)."""
    return subprocess.Popen([chromium, *CHROMIUM_ARGS, f"--user-data-dir={profile}", "--window-size=1280,800", url],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


def close_browser(proc: subprocess.Popen[bytes]) -> None:
    """End Chromium and every process it started (its session's process group)."""
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=10)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def one_run(spec: RunSpec, setting: str, chromium: str, page_rate: float | None,
            busy_rate: float | None) -> dict[str, float]:
    """Speed [robot s / wall s of the loop], this process's CPU [s], Chromium's CPU [s], the loop's wall
    time [s], messages the page got and the 1-minute load average, of `spec` in `setting`."""
    observers = []
    server = browser = None
    profile = None
    if setting != "none":
        hub = ViewHub()
        observers.append(ViewObserver(hub, speed=None))
        rates: dict[str, float] = {}
        if page_rate is not None:
            rates["max_rate"] = page_rate
        if busy_rate is not None:
            rates["busy_rate"] = busy_rate
        server = ViewServer(hub, **rates)
        server.start()
        if setting == "browser":
            profile = tempfile.TemporaryDirectory(prefix="bench_view_")
            browser = open_browser(chromium, server.url, Path(profile.name))
            s = server
            _wait("the page did not connect", lambda: s.clients > 0 and s.sent > 0, 60)
            time.sleep(1.0)                 # the browser's start-up work done before the run starts
    me = os.getpid()
    sent0 = server.sent if server is not None else 0
    cpu0, chrome0 = time.process_time(), descendants_cpu(me)
    out = run_experiment(spec, None, observers=observers, image=False)
    cpu, chrome = time.process_time() - cpu0, descendants_cpu(me) - chrome0
    sent = 0
    if server is not None:
        sent = server.sent - sent0
        server.close()
    if browser is not None:
        close_browser(browser)
    if profile is not None:
        profile.cleanup()
    wall = out.run.wall_time
    return {"speed": out.record.robot_time_s / wall, "cpu": cpu, "chrome": chrome if browser else 0.0,
            "wall": wall, "sent": sent, "load": os.getloadavg()[0]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--world", default="dense")
    ap.add_argument("--method", default="frontier")
    ap.add_argument("--max-time", type=float, default=600.0, help="Robot-time limit of each run [s].")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    ap.add_argument("--page-rate", type=float, default=None, help="Most messages a second to the page "
                    "(default: the server's).")
    ap.add_argument("--busy-rate", type=float, default=None, help="Most messages a second to the page while "
                    "the run goes at max speed (default: the server's).")
    a = ap.parse_args()
    if a.repeats < 1 or not a.max_time > 0:
        print("bench_view: --repeats must be >= 1 and --max-time > 0", file=sys.stderr)
        return 2
    if not Path(a.chromium).exists():
        print(f"bench_view: no Chromium at {a.chromium}; install Debian's chromium or pass --chromium PATH",
              file=sys.stderr)
        return 2
    spec = RunSpec(world=a.world, method=a.method, max_time=a.max_time)
    run_experiment(RunSpec(world=a.world, method=a.method, max_time=5.0), None, image=False)   # warm-up: JIT
    runs: dict[str, list[dict[str, float]]] = {s: [] for s in SETTINGS}
    for k in range(a.repeats):
        for i in range(len(SETTINGS)):
            setting = SETTINGS[(i + k) % len(SETTINGS)]
            runs[setting].append(one_run(spec, setting, a.chromium, a.page_rate, a.busy_rate))

    def med(setting: str, key: str) -> float:
        return statistics.median(r[key] for r in runs[setting])

    loads = [r["load"] for rs in runs.values() for r in rs]
    print(f"{a.world} {a.method}, {a.max_time:g} s robot time, {a.repeats} repeats of the three settings "
          f"interleaved; load average (1 min) {min(loads):.1f}-{max(loads):.1f} on {os.cpu_count()} CPUs:")
    base, base_cpu = med("none", "speed"), med("none", "cpu")
    for setting in SETTINGS:
        paired = statistics.median(r["speed"] / n["speed"] for r, n in zip(runs[setting], runs["none"], strict=True))
        speeds = ", ".join(f"{r['speed']:.0f}" for r in runs[setting])
        print(f"  {LABELS[setting]:24s} {med(setting, 'speed'):7.1f} x real time (loop {med(setting, 'wall'):.2f} s)"
              f"  ratio: of medians {med(setting, 'speed') / base:5.3f}, paired median {paired:5.3f}"
              f"  CPU {med(setting, 'cpu'):5.2f} s ({med(setting, 'cpu') / base_cpu:5.3f})  speeds: {speeds}")
    chrome = statistics.median(r["chrome"] / r["wall"] for r in runs["browser"])
    walls = ", ".join(f"{r['wall']:.1f}" for r in runs["browser"])
    print(f"  messages the page got per watched run: {[int(r['sent']) for r in runs['browser']]} (in {walls} s); "
          f"this Chromium's CPU while watching: {chrome * 100:.1f} % of one core")
    pairs = np.array([b["speed"] / n["speed"] for b, n in zip(runs["browser"], runs["none"], strict=True)])
    ratio = float(np.median(pairs))
    boot = np.median(np.random.default_rng(0).choice(pairs, (10_000, len(pairs))), axis=1)
    lo, hi = np.percentile(boot, [2.5, 97.5])
    print(f"watched run at {ratio * 100:.1f} % of the speed without the view (paired median; bootstrap 95 % "
          f"interval {lo * 100:.1f}-{hi * 100:.1f} %; target >= 90 %)")
    figures = [Figure(f"{LABELS[s].strip()}: robot time / wall time", med(s, "speed"), "x") for s in SETTINGS]
    figures += [Figure("watched run / run without the view (paired median)", ratio, "x",
                       f"bootstrap 95 % interval {lo:.3f}-{hi:.3f}; target >= 0.9"),
                Figure("Chromium's CPU while watching", chrome * 100, "% of one core")]
    record("view", figures, title="What the live view costs a run", section="output",
           parameters={"world": a.world, "method": a.method, "robot time": f"{a.max_time:g} s",
                       "repeats": a.repeats})
    return 0 if ratio >= 0.9 else 1


if __name__ == "__main__":
    sys.exit(main())

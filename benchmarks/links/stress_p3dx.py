"""Stress: emulated P3-DX explorations on a saturated CPU; how many lose their robot?

Run: python benchmarks/links/stress_p3dx.py [--runs 10] [--busy N] [--max-time 40] [--speedup 2] [--world dense]

Starts N busy processes (default: twice the cores) that spin in pure Python, then runs `--runs`
explorations at once, each in its own process: a P3-DX emulator of the world on TCP (a process of
its own, as MobileSim) and the frontier explorer connected to it through the real driver (the
robot-paced clock, the reader thread, the 1 s silence limit), for `--max-time` s of robot time.
Prints one line per run (its end reason, wall time and the longest pause of its reader thread)
and how many runs lost their robot (a reason starting with "robot error", or an exception). A
loaded laptop must not lose a robot: the expected answer is 0.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import re
import subprocess
import sys
import time


def _busy(stop: float) -> None:
    x = 0
    while time.monotonic() < stop:
        x += 1


def _explore(args: tuple[int, str, float, float]) -> tuple[int, str, float, bool, float]:
    """One exploration against its own emulator process (`robotexp emulate p3dx`, as MobileSim would
    be); (index, reason, wall seconds, lost the robot, longest pause of the reader thread [s]: the
    time between two of its reads returning, its starvation by the main thread and the load)."""
    index, world, max_time, speedup = args
    from robotexp.run.spec import RunSpec
    from robotexp.experiment import run_on_robot
    from robotexp_drivers.p3dx.robot import P3DXRobot

    t0 = time.monotonic()
    longest = [0.0]
    emulator = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "emulate", "p3dx", "--world", world,
                                 "--port", "0", "--speedup", str(speedup)], stdout=subprocess.PIPE, text=True)
    try:
        assert emulator.stdout is not None
        line = emulator.stdout.readline()
        address = re.search(r" at (\S+) \(speedup", line)
        if address is None:
            return index, f"the emulator did not start: {line!r}", time.monotonic() - t0, False, 0.0
        with P3DXRobot(address.group(1)) as robot:
            receive, last = robot._receive, [time.perf_counter()]

            def timed() -> bytes:
                data = receive()
                now = time.perf_counter()
                longest[0] = max(longest[0], now - last[0])
                last[0] = now
                return data

            robot._receive = timed  # type: ignore[method-assign]
            spec = RunSpec(world=world, method="frontier", max_time=max_time)
            out = run_on_robot(spec, robot, None, world, image=False)
    except Exception as exc:     # noqa: BLE001 (a lost robot before the run is counted, not raised)
        return index, f"{type(exc).__name__}: {exc}", time.monotonic() - t0, True, longest[0]
    finally:
        emulator.terminate()
        emulator.wait(timeout=10)
    reason = str(out.record["reason"])
    return index, reason, time.monotonic() - t0, reason.startswith("robot error"), longest[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--busy", type=int, default=2 * (os.cpu_count() or 1))
    parser.add_argument("--max-time", type=float, default=40.0, help="robot time of each run [s]")
    parser.add_argument("--speedup", type=float, default=2.0, help="emulator robot time per wall time")
    parser.add_argument("--world", default="dense")
    a = parser.parse_args()
    duration = a.max_time / a.speedup * 3 + 60
    ctx = mp.get_context("spawn")
    busy = [ctx.Process(target=_busy, args=(time.monotonic() + duration,), daemon=True) for _ in range(a.busy)]
    for p in busy:
        p.start()
    t0 = time.monotonic()
    try:
        with ctx.Pool(a.runs) as pool:
            results = pool.map(_explore, [(i, a.world, a.max_time, a.speedup) for i in range(a.runs)])
    finally:
        for p in busy:
            p.terminate()
    load = os.getloadavg()[0]
    for index, reason, wall, lost, pause in sorted(results):
        print(f"run {index}: {'LOST ' if lost else ''}{reason} ({wall:.0f} s wall, longest reader pause "
              f"{pause:.2f} s)")
    lost_n = sum(r[3] for r in results)
    print(f"{lost_n} of {a.runs} runs lost their robot; {a.busy} busy processes on {os.cpu_count()} cores, "
          f"load average {load:.1f}, {time.monotonic() - t0:.0f} s; longest reader pause "
          f"{max(r[4] for r in results):.2f} s (silence limit 1 s)")


if __name__ == "__main__":
    main()

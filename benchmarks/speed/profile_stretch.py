"""Where the CPU goes in stretches of one run: cProfile (CPU time) of the robot-time windows given.

The companion of bench_area_cost.py: once a run's CPU per robot-second is seen to grow with the explored
area, profile an early and a late stretch of the same run and compare what each function costs in them
(the functions whose share grows do work that follows the explored area). One run of `--method` on MAP
(default start, seed 0, the robot preset given), after a 5 s warm-up run on `dense` (numba kernels compiled
or loaded); the profiler runs only inside the windows, timed with the process's CPU clock.

Run: python benchmarks/speed/profile_stretch.py MAP.yaml --method frontier [--robot kobuki]
         [--windows 600:1200,3000:3600] [--top 30] [--save PREFIX]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

from robotexp.experiment import run_experiment
from robotexp.run.observers import RunObserver
from robotexp.run.spec import RunSpec


class Windows(RunObserver):
    """A profiler per window (start, end) [s] of robot time, enabled at the coverage samples inside it."""

    def __init__(self, windows: list[tuple[float, float]]) -> None:
        self.windows = windows
        self.profiles = [cProfile.Profile(time.process_time) for _ in windows]
        self.on: int | None = None

    def on_sample(self, run, time: float, coverage: float | None) -> None:  # type: ignore[no-untyped-def]
        if self.on is not None and time >= self.windows[self.on][1]:
            self.profiles[self.on].disable()
            self.on = None
        if self.on is None:
            for i, (a, b) in enumerate(self.windows):
                if a <= time < b:
                    self.profiles[i].enable()
                    self.on = i
                    break

    def on_end(self, run, record) -> None:  # type: ignore[no-untyped-def]
        if self.on is not None:
            self.profiles[self.on].disable()
            self.on = None


def windows_of(text: str) -> list[tuple[float, float]]:
    """"a:b,c:d" -> [(a, b), (c, d)] [s], each a < b; exits 2 with one line on bad input."""
    try:
        out = [(float(a), float(b)) for a, b in (w.split(":") for w in text.split(","))]
    except ValueError:
        sys.exit(f"profile_stretch: --windows {text!r}: give start:end pairs in seconds, e.g. 600:1200,3000:3600")
    if any(not 0 <= a < b for a, b in out):
        sys.exit(f"profile_stretch: --windows {text!r}: each window needs 0 <= start < end")
    return out


def main() -> None:
    """Profile the windows of one run and print each window's costliest functions."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("map")
    ap.add_argument("--method", default="frontier")
    ap.add_argument("--robot", default="kobuki")
    ap.add_argument("--windows", default="600:1200,3000:3600", help="start:end [s] of robot time, comma separated")
    ap.add_argument("--top", type=int, default=30, help="functions printed per window")
    ap.add_argument("--save", help="write each window's profile to PREFIX.<i> (pstats files)")
    args = ap.parse_args()
    windows = windows_of(args.windows)
    if not Path(args.map).is_file():
        sys.exit(f"profile_stretch: map {args.map} not found; give a ROS .yaml or MobileSim .map file")
    run_experiment(RunSpec(world="dense", method=args.method, max_time=5.0, robot=args.robot), None, image=False)
    prof = Windows(windows)
    out = run_experiment(RunSpec(world=str(Path(args.map).resolve()), method=args.method, robot=args.robot,
                                 max_time=max(b for _, b in windows)), None, observers=[prof], image=False)
    r = out.record
    print(f"{Path(args.map).stem} {args.method} ({args.robot}): coverage {float(r['coverage']):.4f}, robot time "
          f"{float(r['robot_time_s']):.0f} s, {r['reason']}")
    for i, (a, b) in enumerate(windows):
        print(f"\n=== robot time {a:g}-{b:g} s (CPU seconds) ===")
        if float(r["robot_time_s"]) <= a:
            print("not reached: the run ended before it")
            continue
        stats = pstats.Stats(prof.profiles[i])
        if args.save:
            stats.dump_stats(f"{args.save}.{i}")
        stats.sort_stats("cumulative").print_stats(args.top)


if __name__ == "__main__":
    main()

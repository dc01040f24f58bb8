"""Does an explorer's cost grow with the explored area on a real map? CPU per robot-second along one run.

One run per map and method (default start, seed 0, the robot preset given) with an observer that notes,
at every coverage sample, the process's CPU time (user + system, `resource.getrusage`) and the known
free area of the robot's map. The run is cut into stretches of `--stretch` seconds of robot time; each
stretch's CPU per robot-second is printed beside the free area known at its end. An explorer whose cost
per robot-second stays flat while the known area grows tenfold does no whole-map work per step; one whose
cost follows the area does. The figure quoted is the ratio of the last stretch's CPU per robot-second to
the first one past `--settle` [m2] of known area (the first seconds, when the map is tiny, cost less for
every explorer). The machine is shared, so CPU time, not wall time.

Run: python benchmarks/speed/bench_area_cost.py MAP.yaml [MAP ...] [--methods frontier,bvp]
     [--robot kobuki] [--max-time 7200] [--stretch 600] [--record]
The maps are any ROS .yaml or MobileSim .map files (the project's real-map corpus lives outside the
repository); `--record` writes benchmarks/results/area-cost.json.
"""

from __future__ import annotations

import argparse
import resource
import sys
from pathlib import Path

import numpy as np

from robotexp.experiment import run_experiment
from robotexp.run.observers import RunObserver
from robotexp.run.spec import RunSpec

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perflog import Figure, record  # noqa: E402


class AreaClock(RunObserver):
    """(robot time [s], CPU [s], known free area [m2]) at every coverage sample of the run."""

    def __init__(self) -> None:
        self.rows: list[tuple[float, float, float]] = []

    @staticmethod
    def _cpu() -> float:
        u = resource.getrusage(resource.RUSAGE_SELF)
        return u.ru_utime + u.ru_stime

    def on_start(self, run) -> None:  # type: ignore[no-untyped-def]
        self.rows = [(0.0, self._cpu(), 0.0)]

    def on_sample(self, run, time: float, coverage: float | None) -> None:  # type: ignore[no-untyped-def]
        free = float(np.count_nonzero(run.grid.free())) * run.grid.geo.cell ** 2
        self.rows.append((time, self._cpu(), free))


def stretches(rows: list[tuple[float, float, float]], stretch: float) -> list[tuple[float, float, float]]:
    """(robot time at the end [s], CPU per robot-second [ms], known free area at the end [m2]) per stretch."""
    out = []
    t0, c0, _ = rows[0]
    for t, c, area in rows[1:]:
        if t - t0 >= stretch:
            out.append((t, 1e3 * (c - c0) / (t - t0), area))
            t0, c0 = t, c
    return out


def main() -> None:
    """Print each stretch of each run; with --record, write the growth ratios."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="+")
    ap.add_argument("--methods", default="frontier,bvp,srt-laser,meta-ga,meta-firefly")
    ap.add_argument("--robot", default="kobuki")
    ap.add_argument("--max-time", type=float, default=7200.0, help="[s] robot time per run")
    ap.add_argument("--stretch", type=float, default=600.0, help="[s] robot time per stretch")
    ap.add_argument("--settle", type=float, default=100.0, help="[m2] known area before the first stretch counted")
    ap.add_argument("--record", action="store_true", help="write benchmarks/results/area-cost.json")
    args = ap.parse_args()
    methods = [m for m in args.methods.split(",") if m]
    figures: list[Figure] = []
    for method in methods:      # warm-up: numba kernels compiled or loaded from the cache
        run_experiment(RunSpec(world="dense", method=method, max_time=5.0, robot=args.robot), None, image=False)
    for path in args.maps:
        name = Path(path).stem
        for method in methods:
            clock = AreaClock()
            out = run_experiment(RunSpec(world=str(Path(path).resolve()), method=method, max_time=args.max_time,
                                         robot=args.robot), None, observers=[clock], image=False)
            r = out.record
            rows = stretches(clock.rows, args.stretch)
            print(f"{name} {method} {args.robot}: coverage {float(r['coverage']):.4f}, robot time "
                  f"{float(r['robot_time_s']):.0f} s, {r['reason']}", flush=True)
            for t, ms, area in rows:
                print(f"  to {t:6.0f} s: {ms:7.2f} ms CPU per robot-s, {area:7.0f} m2 known free", flush=True)
            counted = [s for s in rows if s[2] >= args.settle]
            if len(counted) >= 2:
                first, last = counted[0], counted[-1]
                ratio = last[1] / first[1]
                print(f"  last / first stretch past {args.settle:g} m2: {ratio:.2f} "
                      f"({first[1]:.2f} -> {last[1]:.2f} ms while the known area grew {first[2]:.0f} -> "
                      f"{last[2]:.0f} m2)", flush=True)
                figures.append(Figure(f"{name}, {method} ({args.robot}): CPU per robot-second, last / first "
                                      f"{args.stretch:g} s stretch", round(ratio, 2), "x",
                                      f"{first[1]:.2f} -> {last[1]:.2f} ms, known free area {first[2]:.0f} -> "
                                      f"{last[2]:.0f} m2"))
    if args.record and figures:
        record("area-cost", figures, section="speed",
               title="CPU per robot-second as the explored area grows, along runs on real maps")


if __name__ == "__main__":
    main()

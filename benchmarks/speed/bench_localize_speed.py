"""Speed of a simulated run with scan-matching localization against the same run without it.

Run: taskset -c 0 python benchmarks/speed/bench_localize_speed.py [--world dense] [--method srt-laser]
         [--speed 300] [--max-time 600] [--repeats 3] [--modes none,scan-match,slam] [--profile 25]

Each repeat runs, one after the other in this process, the same spec (P3-DX odometry preset, seed 0)
with `--localize none`, `--localize scan-match` and `--localize slam` (scan matching with online loop
closure), and the best robot time / wall time of the control loop of each is printed (best of the
repeats: the machine is shared), with the localizer's share of the wall time, its match counts and, with
loop closure, the iSAM2 update time per keyframe (median). `--profile N` adds a cProfile of one run of the
last mode (the N functions of most own time). Target: a simulated run with localization and loop closure
>= 200x real time on one core, the iSAM2 update <= 5 ms per keyframe (median).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402


def main() -> None:
    """Run the pairs and print the ratios."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="dense")
    ap.add_argument("--method", default="srt-laser")
    ap.add_argument("--speed", type=float, default=300.0, help="[mm/s]")
    ap.add_argument("--max-time", type=float, default=600.0, help="[s] robot time of each run")
    ap.add_argument("--odometry", default="p3dx", help="an --odometry-error spec")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--modes", default="none,scan-match,slam", help="--localize modes, comma-separated")
    ap.add_argument("--no-record", action="store_true", help="print only (benchmarks/results is left alone)")
    ap.add_argument("--profile", type=int, default=0, help="print a cProfile of a run of the last mode (N lines)")
    args = ap.parse_args()
    modes = args.modes.split(",")
    if modes[0] != "none" or len(modes) < 2:
        print("bench_localize_speed: --modes must start with none and name another mode", file=sys.stderr)
        sys.exit(2)

    def spec(localize: str) -> RunSpec:
        return RunSpec(world=args.world, method=args.method, speed=args.speed / 1000, max_time=args.max_time,
                       odometry=args.odometry, localize=localize)

    run_experiment(RunSpec(world="ufmg-static", method=args.method, max_time=5.0, odometry=args.odometry,
                           localize=modes[-1]), None, image=False)       # warm-up: compile / load the kernels
    best: dict[str, float] = {}
    last: dict[str, dict] = {}
    for _ in range(max(args.repeats, 1)):
        for mode in modes:
            r = run_experiment(spec(mode), None, image=False).record
            ratio = r["robot_time_s"] / max(r["wall_time_s"], 1e-9)
            best[mode] = max(best.get(mode, 0.0), ratio)
            last[mode] = r
    plain = best["none"]
    print(f"{args.world} / {args.method} at {args.speed:g} mm/s, odometry {args.odometry}, "
          f"{args.max_time:g} s of robot time, best of {args.repeats}:")
    print(f"  without localization: {plain:.0f}x real time (ATE {last['none']['ate_m']} m)")
    figures = [Figure("without localization: robot time / wall time", plain, "x", f"best of {args.repeats}")]
    names = {"scan-match": "with scan matching", "slam": "with scan matching and loop closure"}
    for mode in modes[1:]:
        loc, r = best[mode], last[mode]
        lc = r.get("loop_closure") or {}
        print(f"  {names.get(mode, mode)}: {loc:.0f}x real time (ATE {r['ate_m']} m, "
              f"robot {r['robot_time_s']:.0f} s, matches {r.get('matches')}{', ' + str(lc) if lc else ''}); "
              f"its share of the wall time "
              f"{1 - loc / plain:.1%}")
        figures += [Figure(f"{names.get(mode, mode)}: robot time / wall time", loc, "x", f"best of {args.repeats}"),
                    Figure(f"{names.get(mode, mode)} / without", loc / plain, "x")]
        if lc.get("update_ms") is not None:
            figures.append(Figure(f"{names.get(mode, mode)}: {lc['backend']} update per keyframe (median)",
                                  float(lc["update_ms"]), "ms",
                                  f"{lc['keyframes']} keyframes, {lc['loops']} loop edges"))
    if not args.no_record:
        record("localize-speed", figures, title="A run with scan-matching localization (and loop closure) against the "
               "same run without it",
               parameters={"world": args.world, "method": args.method, "speed": f"{args.speed:g} mm/s",
                           "robot time": f"{args.max_time:g} s", "odometry error": args.odometry})
    if args.profile:
        prof = cProfile.Profile()
        prof.enable()
        run_experiment(spec(modes[-1]), None, image=False)
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(args.profile)


if __name__ == "__main__":
    main()

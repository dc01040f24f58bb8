"""Speed of a simulated run with scan-matching localization against the same run without it.

Run: taskset -c 1 python benchmarks/speed/bench_localize_speed.py [--world dense] [--method srt-laser]
         [--speed 300] [--max-time 600] [--repeats 3] [--modes none,scan-match,slam] [--profile 25]
         [--against DIR]

Each repeat runs, one after the other, the same spec (P3-DX odometry preset, seed 0) with `--localize none`,
`--localize scan-match` and `--localize slam` (scan matching with online loop closure), each in a fresh
process (its kernels compiled or loaded and a 5 s warm-up run first), and the best robot time / wall time
of the control loop of each is printed (best of the repeats: the machine is shared), with the localizer's
share of the wall time, its match counts and, with loop closure, the iSAM2 update time per keyframe
(median). `--against DIR` runs every mode of another checkout of robotexp too (a directory holding
robotexp/ and plugins/, e.g. `mkdir /tmp/before && git archive HEAD~3 | tar -x -C /tmp/before`),
interleaved with this one's (repeat by repeat, mode by mode, on the same core), and prints each mode's
ratio of the two: a speed-up measured in one run, which a shared machine's load does not skew the way two
separate runs' figures are. `--profile N` adds a cProfile of one run of the last mode (the N functions of
most own time). Target: a simulated run with localization and loop closure >= 200x real time on one core,
the iSAM2 update <= 5 ms per keyframe (median).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from robotexp.experiment import run_experiment
from robotexp.run.spec import RunSpec

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
CLOCKS = ("wall", "cpu")
NAMES = {"none": "without localization", "scan-match": "with scan matching",
         "slam": "with scan matching and loop closure"}
# one run in a fresh process, its figures printed as JSON on the last line (argv[1]: the settings)
RUNNER = """
import json, sys, time
from robotexp.experiment import run_experiment
from robotexp.run.loop import ExplorationRun
from robotexp.run.spec import RunSpec
a = json.loads(sys.argv[1])
run_experiment(RunSpec(world="ufmg-static", method=a["method"], max_time=5.0, odometry=a["odometry"],
                       localize=a["mode"]), None, image=False)     # warm-up: compile / load the kernels
loop, cpu = ExplorationRun._loop, []
def timed(self):                                                   # the control loop's CPU time
    t0 = time.process_time()
    try:
        loop(self)
    finally:
        cpu.append(time.process_time() - t0)
ExplorationRun._loop = timed
r = run_experiment(RunSpec(world=a["world"], method=a["method"], speed=a["speed"], max_time=a["max_time"],
                           odometry=a["odometry"], localize=a["mode"]), None, image=False).record
out = {k: r.get(k) for k in ("robot_time_s", "wall_time_s", "ate_m", "coverage", "matches", "loop_closure")}
print(json.dumps({**out, "loop_cpu_s": cpu[-1]}))
"""


def _importable(checkout: Path, into: Path) -> Path:
    """A directory that, first on PYTHONPATH, imports robotexp, robotexp_plugins and robotexp_drivers from
    `checkout`."""
    into.mkdir(parents=True, exist_ok=True)
    for name, src in (("robotexp", "robotexp"), ("robotexp_plugins", "plugins"), ("robotexp_drivers", "drivers")):
        (into / name).symlink_to(checkout / src, target_is_directory=True)
    return into


def _label(checkout: Path) -> str:
    """The checkout's commit (short), or its path outside git."""
    try:
        return subprocess.run(["git", "-C", str(checkout), "rev-parse", "--short=10", "HEAD"], check=True,
                              capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return str(checkout)


def _run(path: Path, settings: dict[str, object]) -> dict:
    """One run of `settings` in a fresh process importing robotexp from `path` (see `_importable`)."""
    env = {**os.environ, "PYTHONPATH": str(path)}
    out = subprocess.run([sys.executable, "-c", RUNNER, json.dumps(settings)], env=env, check=True,
                         capture_output=True, text=True, cwd=path)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _ratio(r: dict, clock: str) -> float:
    """Robot time / the control loop's wall (`clock` "wall") or CPU ("cpu") time."""
    return r["robot_time_s"] / max(r["wall_time_s"] if clock == "wall" else r["loop_cpu_s"], 1e-9)


def _figures(best: dict[tuple[str, str, str], float], last: dict[tuple[str, str], dict], modes: list[str],
             repeats: int) -> list[Figure]:
    """Print this tree's ratios of each mode (wall and CPU time); their figures."""
    figures = []
    for mode in modes:
        r, name = last["this", mode], NAMES.get(mode, mode)
        lc = r.get("loop_closure") or {}
        wall, cpu = best["this", mode, "wall"], best["this", mode, "cpu"]
        plain_wall, plain_cpu = best["this", "none", "wall"], best["this", "none", "cpu"]
        print(f"  {name}: {wall:.0f}x real time, {cpu:.0f}x CPU time (ATE {r['ate_m']} m, coverage {r['coverage']}, "
              f"robot {r['robot_time_s']:.0f} s, matches {r.get('matches')}{', ' + str(lc) if lc else ''})"
              + ("" if mode == "none" else f"; its share of the wall time {1 - wall / plain_wall:.1%}, of the CPU "
                 f"time {1 - cpu / plain_cpu:.1%}"))
        figures += [Figure(f"{name}: robot time / wall time", wall, "x", f"best of {repeats}"),
                    Figure(f"{name}: robot time / CPU time", cpu, "x", f"best of {repeats}")]
        if mode != "none":
            figures += [Figure(f"{name} / without (wall time)", wall / plain_wall, "x"),
                        Figure(f"{name} / without (CPU time)", cpu / plain_cpu, "x")]
        if lc.get("update_ms") is not None:
            figures.append(Figure(f"{name}: {lc['backend']} update per keyframe (median)", float(lc["update_ms"]),
                                  "ms", f"{lc['keyframes']} keyframes, {lc['loops']} loop edges"))
    return figures


def main() -> None:
    """Run the modes (of both checkouts with --against) and print the ratios."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="dense")
    ap.add_argument("--method", default="srt-laser")
    ap.add_argument("--speed", type=float, default=300.0, help="[mm/s]")
    ap.add_argument("--max-time", type=float, default=600.0, help="[s] robot time of each run")
    ap.add_argument("--odometry", default="p3dx", help="an --odometry-error spec")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--modes", default="none,scan-match,slam", help="--localize modes, comma-separated")
    ap.add_argument("--against", type=Path, default=None, metavar="DIR",
                    help="another checkout of robotexp (robotexp/ and plugins/ in it) to run beside this one")
    ap.add_argument("--no-record", action="store_true", help="print only (benchmarks/results is left alone)")
    ap.add_argument("--profile", type=int, default=0, help="print a cProfile of a run of the last mode (N lines)")
    args = ap.parse_args()
    modes = args.modes.split(",")
    if modes[0] != "none" or len(modes) < 2:
        print("bench_localize_speed: --modes must start with none and name another mode", file=sys.stderr)
        sys.exit(2)
    if args.against is not None and not ((args.against / "robotexp").is_dir() and (args.against / "plugins").is_dir()):
        print(f"bench_localize_speed: --against {args.against}: no robotexp/ and plugins/ there; give a checkout "
              "of robotexp (e.g. mkdir /tmp/before && git archive HEAD~3 | tar -x -C /tmp/before)", file=sys.stderr)
        sys.exit(2)

    tmp = Path(tempfile.mkdtemp(prefix="localize-speed-"))
    best: dict[tuple[str, str, str], float] = {}
    last: dict[tuple[str, str], dict] = {}
    try:
        trees = {"this": _importable(ROOT, tmp / "this")}
        if args.against is not None:
            trees["other"] = _importable(args.against.resolve(), tmp / "other")
        for _ in range(max(args.repeats, 1)):
            for mode in modes:
                for tree, path in trees.items():
                    r = _run(path, {"world": args.world, "method": args.method, "speed": args.speed / 1000,
                                    "max_time": args.max_time, "odometry": args.odometry, "mode": mode})
                    for clock in CLOCKS:
                        best[tree, mode, clock] = max(best.get((tree, mode, clock), 0.0), _ratio(r, clock))
                    last[tree, mode] = r
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"{args.world} / {args.method} at {args.speed:g} mm/s, odometry {args.odometry}, "
          f"{args.max_time:g} s of robot time, best of {args.repeats} (robot time / the control loop's wall "
          f"time, and / its CPU time):")
    figures = _figures(best, last, modes, args.repeats)
    if args.against is not None:
        other = _label(args.against)
        print(f"  against {other} ({args.against}), run beside it:")
        for mode in modes:
            o = last["other", mode]
            print(f"    {NAMES.get(mode, mode)}: ATE {o['ate_m']} m, coverage {o['coverage']} there")
            for clock in CLOCKS:
                here, there = best["this", mode, clock], best["other", mode, clock]
                print(f"      {clock}: {there:.0f}x there, {here:.0f}x here: {here / there:.2f} times as fast")
                figures.append(Figure(f"{NAMES.get(mode, mode)}, {clock} time: this tree / {other}", here / there,
                                      "x", f"{here:.0f}x against {there:.0f}x real time, run beside each other"))
    if not args.no_record:
        record("localize-speed", figures, title="A run with scan-matching localization (and loop closure) against the "
               "same run without it",
               parameters={"world": args.world, "method": args.method, "speed": f"{args.speed:g} mm/s",
                           "robot time": f"{args.max_time:g} s", "odometry error": args.odometry})
    if args.profile:
        prof = cProfile.Profile()
        spec = RunSpec(world=args.world, method=args.method, speed=args.speed / 1000, max_time=args.max_time,
                       odometry=args.odometry, localize=modes[-1])
        prof.enable()
        run_experiment(spec, None, image=False)
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(args.profile)


if __name__ == "__main__":
    main()

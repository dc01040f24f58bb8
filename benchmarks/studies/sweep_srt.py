"""Sweep of the SRT explorers over the start poses of the built-in worlds.

For each (world, pose, method) one run (default 100 mm/s, seed 0) on the embedded simulator: coverage,
collisions, distance [m] of the robot's true end position from its start, path length [m], nodes,
detours, robot time [s] and the reason the run ended. Prints a Markdown table; `--jobs 2` runs two
processes at once (the machine is shared: keep it at 2 or fewer).

Run: python benchmarks/studies/sweep_srt.py [--worlds dense sparse] [--methods srt-laser srt-star] [--poses 1 2]
[--speed 40] [--seed 1] [-p frontier=false ...] [--jobs 1]
Default: dense poses 1-9 with srt-laser and srt-star, sparse poses 1-5 with all three; `-p` sets an
explorer parameter of every run (e.g. `--methods srt-star -p frontier=false`: the thesis's VALIDATE
alone, without srt-star's frontier rescue).
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.run.loop import ExplorationRun

DEFAULT = [("dense", str(p), m) for m in ("srt-laser", "srt-star") for p in range(1, 10)] + \
          [("sparse", str(p), m) for m in ("srt-laser", "srt-star", "srt-ball") for p in range(1, 6)]


def parse_param(text: str) -> tuple[str, object]:
    """`key=value` -> (key, value): value as int, float, bool (true/false) or else the string."""
    key, sep, raw = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"-p expects key=value, got {text!r}")
    value: object = raw
    if raw.lower() in ("true", "false"):
        value = raw.lower() == "true"
    else:
        for kind in (int, float):
            try:
                value = kind(raw)
                break
            except ValueError:
                pass
    return key, value


def one(job: tuple[str, str, str, float, int, dict[str, object]]) -> dict[str, object]:
    """Run one (world, pose, method, speed [m/s], seed, explorer params); return its row."""
    world, pose, method, speed, seed, params = job
    holder: dict[str, ExplorationRun] = {}
    out = run_experiment(RunSpec(world=world, method=method, pose=pose, speed=speed, seed=seed, params=dict(params)),
                         None, image=False, on_run=lambda run: holder.update(run=run))
    rec = out.record
    run = holder["run"]
    end = run.state.true_pose if run.state is not None else None
    start = run.start_pose
    home = math.hypot(end.x - start.x, end.y - start.y) if end is not None and start is not None else math.nan
    fields = run.explorer.result_fields()
    return {"world": world, "pose": pose, "method": method, "coverage": rec["coverage"],
            "collisions": rec["collisions"], "home_m": home, "path_m": rec["path_length_m"],
            "nodes": fields.get("nodes"), "detours": fields.get("detours"), "time_s": rec["robot_time_s"],
            "reason": rec["reason"]}


def main() -> None:
    """Run the sweep and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="*", default=None)
    ap.add_argument("--methods", nargs="*", default=None)
    ap.add_argument("--poses", nargs="*", default=None)
    ap.add_argument("--speed", type=float, default=100.0, help="[mm/s]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1, help="processes at once (at most 2 on a shared machine)")
    ap.add_argument("-p", "--param", action="append", type=parse_param, default=[],
                    help="explorer parameter key=value for every run (repeatable)")
    args = ap.parse_args()
    params = dict(args.param)
    jobs = [(w, p, m, args.speed / 1000, args.seed, params) for w, p, m in DEFAULT
            if (args.worlds is None or w in args.worlds) and (args.methods is None or m in args.methods)
            and (args.poses is None or p in args.poses)]
    print("| world | pose | method | coverage | collisions | home [m] | path [m] | nodes | detours | time [s] | end |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with ProcessPoolExecutor(max_workers=max(1, min(args.jobs, 2))) as pool:
        for r in pool.map(one, jobs):
            print(f"| {r['world']} | {r['pose']} | {r['method']} | {r['coverage']:.3f} | {r['collisions']} | "
                  f"{r['home_m']:.3f} | {r['path_m']:.1f} | {r['nodes']} | {r['detours']} | {r['time_s']:.0f} | "
                  f"{r['reason']} |", flush=True)


if __name__ == "__main__":
    main()

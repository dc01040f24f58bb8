"""Speed of a whole run in two checkouts: the same `robotexp` run (default: frontier on `dense`, to its end)
timed in a child process of each checkout in turn, pinned to one core, `--repeats` times each, alternating
so that both see the same machine. Each child runs the explorer once to warm numba's cache, then times
the run (CPU time of the process: robot time / CPU, and the whole run's CPU seconds) and the process time
spent in a few methods (`PARTS`, where the checkout has them): where a difference comes from.

Run: python benchmarks/speed/bench_checkouts.py --before /work/main --after . [--python-before PY]
         [--python-after PY] [--world dense] [--method frontier] [--robot p3dx] [--repeats 3] [--core 1]
         [--no-record]
Target: the after checkout's whole run no slower than the before's.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))   # perflog
from perflog import Figure, record  # noqa: E402

CHILD = """
import json, sys, time
from robotexp.experiment import run_experiment
try:
    from robotexp.run.spec import RunSpec
except ImportError:     # a checkout from before the run package
    from robotexp.experiment import RunSpec
world, method, robot = sys.argv[1:4]
run_experiment(RunSpec(world=world, method=method, robot=robot, max_time=5.0), None, image=False)
parts = {}
def timed(module, cls, name):
    # the process time spent in one method, where the checkout has it
    import importlib
    try:
        owner = getattr(importlib.import_module(module), cls)
    except (ImportError, AttributeError):
        return
    real, label = getattr(owner, name), f"{cls}.{name}"
    def wrapper(*a, **k):
        t = time.process_time()
        try:
            return real(*a, **k)
        finally:
            parts[label] = parts.get(label, 0.0) + time.process_time() - t
    setattr(owner, name, wrapper)
for spec in PARTS:
    timed(*spec)
t0 = time.process_time()
out = run_experiment(RunSpec(world=world, method=method, robot=robot), None, image=False)
cpu = time.process_time() - t0
r = out.record
print(json.dumps({"cpu": cpu, "robot": r["robot_time_s"], "coverage": r["coverage"], "reason": r["reason"],
                  "parts": parts}))
"""
# the methods whose process time each run also reports (module, class, method): the map's scan integration,
# the planners' costs, the path follower, the memory of walls
PARTS = [("robotexp.mapping.grid", "OccupancyGrid", "update"), ("robotexp.planning.targets", "PlanCosts", "update"),
         ("robotexp.planning.follower", "PathFollower", "twist"), ("robotexp.planning.targets", "WallMemory", "note")]


def once(checkout: Path, python: str, args: argparse.Namespace) -> dict[str, float]:
    """One timed run in `checkout`'s code."""
    cmd = ["taskset", "-c", str(args.core), python, "-c", f"PARTS = {PARTS!r}\n" + CHILD, args.world, args.method,
           args.robot]
    done = subprocess.run(cmd, cwd=checkout, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True)
    ap.add_argument("--after", type=Path, required=True)
    ap.add_argument("--python-before", default=sys.executable)
    ap.add_argument("--python-after", default=sys.executable)
    ap.add_argument("--world", default="dense")
    ap.add_argument("--method", default="frontier")
    ap.add_argument("--robot", default="p3dx")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--core", type=int, default=1)
    ap.add_argument("--no-record", action="store_true")
    args = ap.parse_args()
    sides = {"before": (args.before.resolve(), args.python_before), "after": (args.after.resolve(), args.python_after)}
    got: dict[str, list[dict[str, float]]] = {"before": [], "after": []}
    for k in range(args.repeats):
        for side, (checkout, python) in (sides.items() if k % 2 == 0 else reversed(sides.items())):
            r = once(checkout, python, args)
            got[side].append(r)
            print(f"{side:<6} cpu {r['cpu']:6.3f} s robot {r['robot']:7.1f} s ratio {r['robot'] / r['cpu']:6.1f} "
                  f"coverage {r['coverage']} {r['reason']}", flush=True)
    cpu = {s: statistics.median(r["cpu"] for r in v) for s, v in got.items()}
    per = {s: statistics.median(r["cpu"] / r["robot"] * 1000 for r in v) for s, v in got.items()}
    print(f"median whole-run CPU: before {cpu['before']:.3f} s, after {cpu['after']:.3f} s "
          f"(after / before {cpu['after'] / cpu['before']:.3f}); CPU per robot-second: before {per['before']:.2f} ms, "
          f"after {per['after']:.2f} ms")
    labels = sorted({label for v in got.values() for r in v for label in r.get("parts", {})})
    part = {s: {label: statistics.median(r.get("parts", {}).get(label, 0.0) for r in v) for label in labels}
            for s, v in got.items()}
    for label in labels:
        print(f"  {label}: before {part['before'][label]:.3f} s, after {part['after'][label]:.3f} s")
    if not args.no_record:
        what = f"{args.method} on {args.world} ({args.robot}), whole run"
        record("checkouts", [Figure(f"{what}: CPU before", cpu["before"], "s"),
                             Figure(f"{what}: CPU after", cpu["after"], "s"),
                             Figure(f"{what}: after / before", cpu["after"] / cpu["before"], "x"),
                             Figure(f"{what}: CPU per robot-second before", per["before"], "ms"),
                             Figure(f"{what}: CPU per robot-second after", per["after"], "ms")]
               + [Figure(f"{what}: in {label} {s}", part[s][label], "s", "process time spent in the method")
                  for label in labels for s in ("before", "after")],
               title="A whole run in two checkouts (before and after a change)",
               parameters={"world": args.world, "method": args.method, "robot": args.robot, "repeats": args.repeats,
                           "before": _named(args.before), "after": _named(args.after)})


def _named(tree: Path) -> str:
    """`tree` with the commit it holds, when it is a git checkout (a temporary path alone names nothing)."""
    done = subprocess.run(["git", "-C", str(tree), "rev-parse", "--short=10", "HEAD"], capture_output=True, text=True)
    return f"{tree} (commit {done.stdout.strip()})" if done.returncode == 0 and done.stdout.strip() else str(tree)


if __name__ == "__main__":
    main()

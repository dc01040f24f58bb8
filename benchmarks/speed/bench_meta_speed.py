"""Speed of an explorer's runs against another source tree of robotexp, measured in one run.

Runs the same cases (world, method, robot-time cut) with this tree and with `--before`, a checkout or
`git archive` export of the code to compare with (e.g. `git archive main | tar -x -C /tmp/before`),
each run in its own child process that imports robotexp and the plugins from its tree. Prints per case
and tree the robot time, the wall and CPU time of the run (set-up included, after a short warm-up run
that loads the numba caches), robot seconds per wall and per CPU second, the ratio after / before, and
whether the two records agree (every field but wall times, and the SHA-256 of the coverage curve and of
the true path).

    python benchmarks/speed/bench_meta_speed.py --before /tmp/before \\
        --case generated:office:0:meta-ga --case generated:warehouse:0:meta-firefly --max-time 600 \
        [--after-param near_frontier=false --after-param population=20 --after-param iterations=100]

The machine is shared: CPU seconds are the steadier figure; the load average is printed with each run.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

IGNORED = {"wall_time_s"}
HERE = Path(__file__).resolve().parent.parent


def _child(world: str, method: str, max_time: float, params: dict[str, Any]) -> None:
    """Run one case in this process and print its record, wall and CPU time as one JSON line."""
    from robotexp.run.spec import RunSpec
    from robotexp.experiment import run_experiment

    spec = RunSpec(world=world, method=method, params=params)
    spec.max_time = max_time
    with tempfile.TemporaryDirectory() as tmp:
        t0, c0 = time.perf_counter(), time.process_time()
        result = run_experiment(spec, Path(tmp), image=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        rec: dict[str, Any] = dict(result.record)
        for kind in ("coverage", "path"):
            f = Path(tmp) / f"{rec['run']}.{kind}.csv"
            rec[f"{kind}_sha256"] = hashlib.sha256(f.read_bytes()).hexdigest() if f.exists() else None
    import robotexp
    import robotexp_plugins
    print(json.dumps({"record": rec, "wall": wall, "cpu": cpu, "tree": str(Path(robotexp.__file__).parent.parent),
                      "plugins": str(Path(robotexp_plugins.__file__).resolve().parent.parent)}))


def _run(tree: Path, world: str, method: str, max_time: float, params: dict[str, Any] | None = None) -> dict[str, Any]:
    # the plugins and drivers are imported as robotexp_plugins / robotexp_drivers (pyproject's package-dir):
    # names linked to the tree's plugins/ and drivers/ in a directory ahead of the installed ones
    links = Path(tempfile.gettempdir()) / f"bench_meta_speed_{abs(hash(str(tree.resolve())))}"
    links.mkdir(exist_ok=True)
    for name, folder in (("robotexp_plugins", "plugins"), ("robotexp_drivers", "drivers")):
        if not (links / name).is_symlink():
            (links / name).symlink_to(tree.resolve() / folder)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tree), str(links)]))
    out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child", world, method, str(max_time),
                          json.dumps(params or {})],
                         env=env, cwd=tempfile.gettempdir(), capture_output=True, text=True, check=False)
    if out.returncode:
        sys.exit(f"bench_meta_speed: the run of {world} {method} with {tree} failed:\n{out.stderr[-2000:]}")
    got: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    for key in ("tree", "plugins"):
        if Path(got[key]).resolve() != tree.resolve():
            sys.exit(f"bench_meta_speed: the child imported its {key} from {got[key]}, not {tree}")
    return got


def _split(case: str) -> tuple[str, str]:
    world, _, method = case.rpartition(":")
    if not world or not method:
        sys.exit(f"bench_meta_speed: --case must be WORLD:METHOD (e.g. generated:office:0:meta-ga), got {case!r}")
    return world, method


def main() -> None:
    """Command line (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True, help="source tree of the code to compare with")
    ap.add_argument("--case", action="append", default=[], help="WORLD:METHOD (repeatable)")
    ap.add_argument("--max-time", type=float, default=600.0, help="[s] robot time per run (default 600)")
    ap.add_argument("--after-param", action="append", default=[], metavar="KEY=JSON",
                    help="explorer parameter of the runs with this tree (repeatable), e.g. near_frontier=false "
                         "to run code that changed behaviour as the code before")
    args = ap.parse_args()
    after: dict[str, Any] = {}
    for item in args.after_param:
        key, sep, value = item.partition("=")
        try:
            after[key] = json.loads(value)
        except json.JSONDecodeError:
            sep = ""
        if not key or not sep:
            sys.exit(f"bench_meta_speed: --after-param must be KEY=JSON (e.g. population=20), got {item!r}")
    if not (args.before / "robotexp" / "__init__.py").is_file():
        sys.exit(f"bench_meta_speed: --before {args.before} holds no robotexp package; give a source tree")
    cases = [_split(c) for c in (args.case or ["generated:office:0:meta-ga"])]
    trees = {"before": args.before, "after": HERE}
    for tree in trees.values():      # warm-up: numba caches, imports
        _run(tree, "dense", "meta-ga", 5.0)
    for world, method in cases:
        res = {}
        for label, tree in trees.items():
            load = os.getloadavg()[0]
            res[label] = r = _run(tree, world, method, args.max_time, after if label == "after" else None)
            robot = float(r["record"]["robot_time_s"])
            print(f"{world} {method} {label:6s}: {robot:8.1f} s robot, {r['wall']:7.1f} s wall, {r['cpu']:7.1f} s CPU"
                  f" -> {robot / r['wall']:6.1f}x wall, {robot / r['cpu']:6.1f}x CPU (load {load:.1f}); "
                  f"coverage {r['record']['coverage']}, {r['record']['reason']}", flush=True)
        b, a = res["before"], res["after"]
        diffs = [k for k in sorted(set(a["record"]) | set(b["record"]))
                 if k not in IGNORED and a["record"].get(k) != b["record"].get(k)]
        rb, ra = float(b["record"]["robot_time_s"]), float(a["record"]["robot_time_s"])
        print(f"{world} {method}: after / before: {(ra / a['cpu']) / (rb / b['cpu']):.2f}x robot s per CPU s, "
              f"{(ra / a['wall']) / (rb / b['wall']):.2f}x per wall s; records "
              + ("identical" if not diffs else "differ in " + ", ".join(diffs)), flush=True)


if __name__ == "__main__":
    if len(sys.argv) == 6 and sys.argv[1] == "--child":
        _child(sys.argv[2], sys.argv[3], float(sys.argv[4]), json.loads(sys.argv[5]))
    else:
        main()

"""Maps from real laser logs: `robotexp map`'s pipeline on every CARMEN log given, one line each.

Run: python benchmarks/studies/bench_log_maps.py LOG_OR_DIR... [--odometry-noise 0.02,1] [--seed 0] [--cell 0.05]
         [--range-max 20] [--no-loop-closure] [--jobs 2]

A folder stands for the `*.log`, `*.log.gz`, `*.clf` and `*.clf.gz` files in it. For each log, the pipeline
of `robotexp map LOG --odometry-noise ... --localize scan-match` (the logged poses are the truth, odometry
is them perturbed by the noise, scan matching and loop closure recover them); a log too large for
`--cell` is mapped at the first of `logmap.COARSER_CELLS` (0.1, 0.2, 0.5, 1 m) that fits, and says so.
Printed: scans, the cell, the odometry's ATE, the estimate's ATE (no alignment) and after a rigid
alignment, loop edges, wall time.
Target on the Intel, ACES and CSAIL logs: ATE <= 0.3 m with 0.02,1.
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from robotexp.errors import ConfigError
from robotexp.localization.carmen import read_carmen
from robotexp.localization.logmap import COARSER_CELLS, map_log, parse_noise
from robotexp.localization.posegraph import LoopConfig

PATTERNS = ("*.log", "*.log.gz", "*.clf", "*.clf.gz")


def one(job: tuple[Path, argparse.Namespace]) -> dict[str, Any]:
    """Map one log; its figures (or the error)."""
    path, args = job
    t0 = time.monotonic()
    log = read_carmen(path)
    noise = parse_noise(args.odometry_noise)
    for cell in (args.cell, *(c for c in COARSER_CELLS if c > args.cell)):
        try:
            res = map_log(log, cell=cell, noise=noise, localize="scan-match", seed=args.seed, range_max=args.range_max,
                          loops=None if args.no_loop_closure else LoopConfig())
        except ConfigError as e:
            if "--cell" in str(e):
                continue
            return {"log": path.name, "error": str(e)}
        return {"log": path.name, "scans": len(log.scans), "cell": cell, "odometry": res.odometry_ate_m,
                "ate": res.ate_m, "rigid": res.ate_rigid_m, "loops": res.counts.get("loop-edges", 0),
                "s": time.monotonic() - t0}
    return {"log": path.name, "error": "too large at every cell tried"}


def main() -> None:
    """Every log, in --jobs processes; a line each."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+", type=Path, metavar="LOG_OR_DIR")
    ap.add_argument("--odometry-noise", default="0.02,1", help="DIST,DEG_PER_M as robotexp map takes it")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cell", type=float, default=0.05, help="[m]")
    ap.add_argument("--range-max", type=float, default=20.0, help="[m]")
    ap.add_argument("--no-loop-closure", action="store_true")
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args()
    logs: list[Path] = []
    for p in args.paths:
        if p.is_dir():
            logs += sorted({f for pat in PATTERNS for f in p.glob(pat)})
        elif p.is_file():
            logs.append(p)
        else:
            print(f"bench_log_maps: {p}: no such file or folder", file=sys.stderr)
            sys.exit(2)
    if not logs or args.jobs < 1 or not args.cell > 0:
        print("bench_log_maps: no log given (or --jobs < 1, --cell <= 0)", file=sys.stderr)
        sys.exit(2)
    try:
        parse_noise(args.odometry_noise)
    except ConfigError as e:
        print(f"bench_log_maps: {e}", file=sys.stderr)
        sys.exit(2)
    print(f"{'log':36s} {'scans':>6s} {'cell m':>6s} {'odometry ATE m':>14s} {'ATE m':>7s} {'rigid m':>7s} "
          f"{'loops':>5s} {'wall s':>6s}", flush=True)
    with ProcessPoolExecutor(args.jobs) as pool:
        for r in pool.map(one, [(p, args) for p in logs]):
            if "error" in r:
                print(f"{r['log']:36s} error: {r['error']}", flush=True)
                continue
            print(f"{r['log']:36s} {r['scans']:6d} {r['cell']:6.2f} {r['odometry']:14.3f} {r['ate']:7.3f} "
                  f"{r['rigid']:7.3f} {r['loops']:5d} {r['s']:6.1f}", flush=True)


if __name__ == "__main__":
    main()

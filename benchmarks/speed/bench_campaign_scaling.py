"""Scaling of a campaign with the number of workers: the same campaign on 1, 2, ... workers.

Run: python benchmarks/speed/bench_campaign_scaling.py [FILE] [--workers 1,2] [--backend pool|dask|both]
                                                 [--seeds 16] [--max-time 15] [--out DIR]

Without FILE the campaign is 64 runs: frontier in ufmg-static from poses path1 and path2 at 300 and
200 mm/s, seeds 0..15 (--seeds), each cut at --max-time seconds of robot time. `--backend pool` is the
local process pool (--jobs N); `dask` is `--cluster local:N` (a Dask LocalCluster, its start-up
included in the time); `both` runs the two in turn at each worker count. Prints per worker count the
wall time, the CPU time of the worker processes and of this process, the load, the speedup over the
first count and the efficiency (speedup / workers ratio); the runs go to DIR/BACKEND-N (default
out/bench-scaling).
On a machine shared with other work the wall times, and so the efficiency, are only what this run saw.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path

from robotexp.campaign.spec import load_campaign
from robotexp.campaign.runner import run_campaign

DEFAULT = """
[campaign]
name = "scaling"
max_time_s = {max_time}
[[set]]
world = "ufmg-static"
poses = ["path1", "path2"]
methods = ["frontier"]
speeds_mm_s = [300, 200]
seeds = {seeds}
"""


def main() -> None:
    """Run the campaign once per worker count and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", nargs="?", default=None, help="campaign file (default: the 64-run campaign above)")
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts (default 1,2)")
    ap.add_argument("--backend", choices=("pool", "dask", "both"), default="pool",
                    help="both: the pool and Dask in turn at each worker count, compared in one run")
    ap.add_argument("--seeds", type=int, default=16, help="seeds of the default campaign (4 runs per seed)")
    ap.add_argument("--max-time", type=float, default=15.0, help="[s] robot time limit of the default campaign")
    ap.add_argument("--out", default="out/bench-scaling")
    args = ap.parse_args()
    counts = [int(x) for x in args.workers.split(",")]
    backends = ["pool", "dask"] if args.backend == "both" else [args.backend]
    rows: dict[str, list[tuple[int, float, float, float, float]]] = {b: [] for b in backends}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(args.file) if args.file else Path(tmp) / "scaling.toml"
        if not args.file:
            path.write_text(DEFAULT.format(max_time=args.max_time, seeds=list(range(args.seeds))), encoding="utf-8")
        camp = load_campaign(path)
        for n in counts:
            for backend in backends:
                out = Path(args.out) / f"{backend}-{n}"
                if out.exists():
                    shutil.rmtree(out)
                before = _cpu()
                load0 = os.getloadavg()[0]
                t0 = time.perf_counter()
                records = run_campaign(camp, out, jobs=n, cluster=f"local:{n}" if backend == "dask" else None)
                wall = time.perf_counter() - t0
                after = _cpu()
                rows[backend].append((n, wall, after[0] - before[0], after[1] - before[1],
                                      (load0 + os.getloadavg()[0]) / 2))
                print(f"{backend}, {n} worker(s): {len(records)} runs in {wall:.1f} s", flush=True)
    print(f"\ncampaign {camp.name}: {len(camp.runs)} runs, {os.cpu_count()} cores")
    print(f"{'backend':>8} {'workers':>8} {'wall (s)':>9} {'speedup':>8} {'efficiency':>10} {'CPU workers (s)':>16} "
          f"{'CPU here (s)':>13} {'load':>5}")
    for backend, table in rows.items():
        n0, wall0 = table[0][0], table[0][1]
        for n, wall, kids, here, load in table:
            speedup = wall0 / wall * n0
            print(f"{backend:>8} {n:>8} {wall:>9.1f} {speedup:>8.2f} {speedup / n:>10.2f} {kids:>16.1f} {here:>13.1f} "
                  f"{load:>5.1f}")
    if len(backends) == 2:
        ratios = ", ".join(f"{n} worker(s) {d[1] / p[1]:.2f}" for (n, *_), p, d in zip(
            rows["pool"], rows["pool"], rows["dask"], strict=True))
        print(f"Dask wall / pool wall: {ratios}")
    print("(CPU workers: the worker processes, ended; CPU here: this process, the client and, with dask, the "
          "LocalCluster's scheduler; load: the 1-minute load average at start and end, averaged)")


def _cpu() -> tuple[float, float]:
    """CPU seconds so far of the ended child processes and of this process."""
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    me = resource.getrusage(resource.RUSAGE_SELF)
    return kids.ru_utime + kids.ru_stime, me.ru_utime + me.ru_stime


if __name__ == "__main__":
    main()

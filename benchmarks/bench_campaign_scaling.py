"""Scaling of a campaign with the number of workers: the same campaign on 1, 2, ... workers.

Run: python benchmarks/bench_campaign_scaling.py [FILE] [--workers 1,2] [--backend pool|dask]
                                                 [--seeds 16] [--max-time 15] [--out DIR]

Without FILE the campaign is 64 runs: frontier in ufmg-static from poses path1 and path2 at 300 and
200 mm/s, seeds 0..15 (--seeds), each cut at --max-time seconds of robot time. `--backend pool` is the
local process pool (--jobs N); `dask` is `--cluster local:N` (a Dask LocalCluster, its start-up
included in the time). Prints per worker count the wall time, the speedup over the first count and
the efficiency (speedup / workers ratio); the runs of each count go to DIR/N (default out/bench-scaling).
On a machine shared with other work the wall times, and so the efficiency, are only what this run saw.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from robotexp.campaign import load_campaign, run_campaign

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
    ap.add_argument("--backend", choices=("pool", "dask"), default="pool")
    ap.add_argument("--seeds", type=int, default=16, help="seeds of the default campaign (4 runs per seed)")
    ap.add_argument("--max-time", type=float, default=15.0, help="[s] robot time limit of the default campaign")
    ap.add_argument("--out", default="out/bench-scaling")
    args = ap.parse_args()
    counts = [int(x) for x in args.workers.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(args.file) if args.file else Path(tmp) / "scaling.toml"
        if not args.file:
            path.write_text(DEFAULT.format(max_time=args.max_time, seeds=list(range(args.seeds))), encoding="utf-8")
        camp = load_campaign(path)
        walls: list[float] = []
        for n in counts:
            out = Path(args.out) / str(n)
            if out.exists():
                shutil.rmtree(out)
            t0 = time.perf_counter()
            records = run_campaign(camp, out, jobs=n, cluster=f"local:{n}" if args.backend == "dask" else None)
            walls.append(time.perf_counter() - t0)
            print(f"{n} worker(s): {len(records)} runs in {walls[-1]:.1f} s", flush=True)
    print(f"\ncampaign {camp.name}: {len(camp.runs)} runs, backend {args.backend}")
    print(f"{'workers':>8} {'wall (s)':>9} {'speedup':>8} {'efficiency':>10}")
    for n, wall in zip(counts, walls, strict=True):
        speedup = walls[0] / wall * counts[0]
        print(f"{n:>8} {wall:>9.1f} {speedup:>8.2f} {speedup / n:>10.2f}")


if __name__ == "__main__":
    main()

"""Wall time of a whole campaign (default: the thesis's 66 runs) on this machine.

Run: python benchmarks/bench_campaign.py [campaigns/thesis.toml] [--jobs N] [--out DIR]
Target (issue "thesis experiments"): the thesis campaign within 10 minutes on 2 cores.
Prints the wall time, runs per minute, the sum of robot time / wall time and the CPU time the runs took
(on a machine shared with other work the wall time grows, the CPU time much less); the results stay in --out
(default out/bench-<name>) for `robotexp campaign report`.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import time
from pathlib import Path

from robotexp.campaign import load_campaign, run_campaign


def main() -> None:
    """Run the campaign from scratch and print its timing."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", nargs="?", default=str(Path(__file__).parents[1] / "campaigns" / "thesis.toml"))
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    camp = load_campaign(args.file)
    out = Path(args.out or f"out/bench-{camp.name}")
    if out.exists():
        shutil.rmtree(out)
    t0 = time.perf_counter()

    def progress(done: int, total: int, record: dict | None) -> None:
        if record is not None:
            print(f"  {done:3d}/{total} {time.perf_counter() - t0:6.0f} s  {record['run']}: "
                  f"{record['path_length_m']:.1f} m, coverage {record['coverage']}, {record['reason']}", flush=True)

    records = run_campaign(camp, out, jobs=args.jobs, progress=progress)
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = usage.ru_utime + usage.ru_stime
    robot = sum(r["robot_time_s"] for r in records)
    print(f"campaign {camp.name}: {len(records)} runs in {wall:.0f} s wall ({wall / 60:.1f} min) on {args.jobs} jobs; "
          f"{len(records) / wall * 60:.1f} runs/min; robot time {robot:.0f} s = {robot / wall:.0f}x wall time")
    print(f"CPU time of the runs {cpu:.0f} s = {cpu / 60:.1f} min; / {args.jobs} jobs = "
          f"{cpu / args.jobs / 60:.1f} min, "
          f"the wall time on {args.jobs} idle cores with perfect balance (wall/that = "
          f"{wall / (cpu / args.jobs):.2f}: above 1 means other work shared the cores or the jobs waited)")
    print(f"incomplete runs: {sum(not r['completed'] for r in records)}; report: robotexp campaign report "
          f"{out / 'results.jsonl'}")


if __name__ == "__main__":
    main()

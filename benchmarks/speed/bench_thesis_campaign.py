"""Where a whole campaign's seconds go (default: the thesis's 66 runs, campaigns/thesis.toml).

Run: python benchmarks/speed/bench_thesis_campaign.py [FILE] [--jobs 2] [--cluster local:2] [--max-time S]
                                                [--sample] [--out DIR] [--top 8]

Runs the campaign from scratch as `robotexp campaign run FILE --jobs N` does (or on `--cluster`), with
every run timed in its worker (`robotexp.campaign.jobs.RunTiming`), and prints:
- the campaign's wall time, and the machine's load average (os.getloadavg) before, during and after;
- load-independent figures: the CPU seconds of all runs; the longest run against total / jobs (the
  critical path: no schedule beats the larger of the two); the wall time a list schedule of the measured
  CPU times, in the order the runs were started, would take on `jobs` idle cores;
- per-run set-up (wall time in the worker outside the run loop: imports and numba cache loads in a
  worker's first run; world, ground truth, robot and files in every run) and the workers' start-up;
- the longest runs; how long the workers idled at the end (the last run running alone).
Each run's timing goes to DIR/timings.csv, the results stay in DIR for `robotexp campaign report`.
`--sample` runs one start pose per group and estimates the whole campaign from it (a quick look).
`--max-time S` cuts every run at S s of robot time (the records then differ from the campaign's).
On a machine shared with other work the wall times grow with the load; the CPU figures much less.
"""

from __future__ import annotations

import argparse
import csv
import os
import resource
import shutil
import statistics
import threading
import time
from pathlib import Path

from robotexp.campaign.jobs import RunTiming
from robotexp.campaign.spec import load_campaign, record_key
from robotexp.campaign.runner import run_campaign, run_order
from robotexp.run.spec import RunSpec


def list_schedule(durations: list[float], workers: int) -> float:
    """The makespan of handing `durations` in this order to the first of `workers` to come free."""
    free = [0.0] * max(workers, 1)
    for d in durations:
        i = free.index(min(free))
        free[i] += d
    return max(free)


class LoadSampler(threading.Thread):
    """The 1-minute load average every `period` seconds while the campaign runs."""

    def __init__(self, period: float = 5.0) -> None:
        super().__init__(daemon=True)
        self.period, self.samples, self.stop = period, [os.getloadavg()[0]], threading.Event()

    def run(self) -> None:
        while not self.stop.wait(self.period):
            self.samples.append(os.getloadavg()[0])


def main() -> None:
    """Run the campaign and print where its time went."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", nargs="?", default=str(Path(__file__).parents[1] / "campaigns" / "thesis.toml"))
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--cluster", default=None, help="a Dask cluster (local:N or tcp://HOST:PORT) instead of the pool")
    ap.add_argument("--max-time", type=float, default=None, help="[s] cut every run at this robot time")
    ap.add_argument("--out", default=None, help="output folder (default out/bench-<name>; emptied first)")
    ap.add_argument("--top", type=int, default=8, help="longest runs to list")
    ap.add_argument("--sample", action="store_true",
                    help="run only the first start pose of each (world, method, speed, seed, sweep) and estimate "
                         "the whole campaign's CPU time and schedule from them (each run standing for its group)")
    args = ap.parse_args()
    camp = load_campaign(args.file)
    if args.max_time is not None:
        for spec in camp.runs:
            spec.max_time = min(spec.max_time, args.max_time)
    weight: dict[str, int] = {}         # with --sample: run name -> runs of the campaign it stands for
    if args.sample:
        groups: dict[tuple[object, ...], list[RunSpec]] = {}
        for spec in camp.runs:
            key = camp.key(spec)
            groups.setdefault((key[0], key[1], key[3], key[4], key[5]), []).append(spec)
        camp.runs = [g[0] for g in groups.values()]
        stand_for = {id(g[0]): len(g) for g in groups.values()}
    workers = args.jobs
    if args.cluster and args.cluster.startswith("local:"):
        workers = int(args.cluster.split(":", 1)[1])
    out = Path(args.out or f"out/bench-{camp.name}")
    if out.exists():
        shutil.rmtree(out)
    timings: list[RunTiming] = []
    load0 = os.getloadavg()
    sampler = LoadSampler()
    sampler.start()
    t0 = time.time()

    def progress(done: int, total: int, record: object) -> None:
        if record is not None and timings:
            t = timings[-1]
            print(f"  {done:3d}/{total} {time.time() - t0:6.0f} s  {t.run}: {t.wall_s:.1f} s wall, "
                  f"{t.cpu_s:.1f} s CPU", flush=True)

    self0 = resource.getrusage(resource.RUSAGE_SELF)
    records = run_campaign(camp, out, jobs=args.jobs, progress=progress, cluster=args.cluster, timings=timings)
    if args.sample:
        by_key = {camp.key(spec): stand_for[id(spec)] for spec in camp.runs}
        weight = {r.run: by_key[record_key(r)] for r in records}
    wall = time.time() - t0
    self1 = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)     # the worker processes (and a cluster's nannies), ended
    sampler.stop.set()
    load1 = os.getloadavg()
    where = f"cluster {args.cluster}" if args.cluster else f"{args.jobs} jobs (process pool)"
    cut = f", each run cut at {args.max_time:g} s robot time" if args.max_time is not None else ""
    print(f"\ncampaign {camp.name}: {len(records)} runs on {where}{cut}, {os.cpu_count()} cores here")
    robot = sum(r.robot_time_s for r in records)
    print(f"wall time {wall:.1f} s = {wall / 60:.2f} min; {len(records) / wall * 60:.1f} runs/min; robot time "
          f"{robot:.0f} s = {robot / wall:.0f}x the wall time; incomplete: {sum(not r.completed for r in records)}")
    print(f"load average (1 min): {load0[0]:.2f} before, {statistics.fmean(sampler.samples):.2f} mean during "
          f"(max {max(sampler.samples):.2f}), {load1[0]:.2f} after")
    if not timings:
        return
    with open(out / "timings.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["run", "worker", "start_s", "end_s", "wall_s", "cpu_s", "loop_s", "setup_s", "first_in_worker"])
        for t in sorted(timings, key=lambda t: t.start):
            w.writerow([t.run, t.worker, f"{t.start - t0:.3f}", f"{t.end - t0:.3f}", f"{t.wall_s:.3f}",
                        f"{t.cpu_s:.3f}", f"{t.loop_s:.3f}", f"{t.setup_s:.3f}", int(t.first_in_worker)])
    cpu = sum(t.cpu_s for t in timings)
    run_wall = sum(t.wall_s for t in timings)
    longest = max(timings, key=lambda t: t.cpu_s)
    by_start = sorted(timings, key=lambda t: t.start)
    predicted = list_schedule([t.cpu_s for t in by_start], workers)
    print("\nload-independent (CPU time of the runs, measured in their workers):")
    print(f"  CPU of all runs {cpu:.1f} s; / {workers} workers = {cpu / workers:.1f} s")
    print(f"  critical path: longest run {longest.run} {longest.cpu_s:.1f} s CPU vs total / {workers} = "
          f"{cpu / workers:.1f} s: the campaign cannot take less than {max(longest.cpu_s, cpu / workers):.1f} s "
          f"on {workers} idle cores")
    print(f"  list schedule of these CPU times in the order the runs started, on {workers} idle cores: "
          f"{predicted:.1f} s = {predicted / 60:.2f} min")
    print(f"  wall / CPU of the runs {run_wall / cpu:.2f} (1.0 on idle cores; above it the runs waited for a core)")
    here = self1.ru_utime + self1.ru_stime - self0.ru_utime - self0.ru_stime
    print(f"  CPU of the worker processes {kids.ru_utime + kids.ru_stime:.1f} s (the runs, their start-up and "
          f"what else the workers do); of this process {here:.1f} s (the client: writing results; with "
          "local:N also the Dask scheduler)")
    first = [t for t in timings if t.first_in_worker]
    rest = [t for t in timings if not t.first_in_worker]
    print("\nper-run set-up (wall time in the worker outside the run loop):")
    if first:
        print(f"  a worker's first run: mean {statistics.fmean(t.setup_s for t in first):.2f} s "
              f"(imports, numba cache loads, world, ground truth, robot, files; {len(first)} workers)")
    if rest:
        print(f"  every other run: mean {statistics.fmean(t.setup_s for t in rest):.2f} s, "
              f"max {max(t.setup_s for t in rest):.2f} s, total {sum(t.setup_s for t in rest):.1f} s "
              f"of {run_wall:.1f} s run wall ({sum(t.setup_s for t in rest) / run_wall:.1%})")
    per_worker: dict[str, list[RunTiming]] = {}
    for t in by_start:
        per_worker.setdefault(t.worker, []).append(t)
    starts = [ts[0].start - t0 for ts in per_worker.values()]
    print(f"  workers' start-up (campaign start to their first run): {min(starts):.2f}-{max(starts):.2f} s")
    end = max(t.end for t in timings)
    idle = [end - ts[-1].end for ts in per_worker.values()] + [end - t0] * max(workers - len(per_worker), 0)
    busy = sum(t.wall_s for t in timings)
    print("\nbalance:")
    print(f"  workers busy {busy / (workers * wall):.1%} of {workers} x {wall:.1f} s; idle at the end: "
          f"{', '.join(f'{x:.1f}' for x in sorted(idle))} s ({sum(idle) / (workers * wall):.1%} of the worker time); "
          f"last run: {max(timings, key=lambda t: t.end).run}")
    print(f"\nlongest runs (of {len(timings)}):")
    print(f"  {'run':<32} {'CPU s':>7} {'wall s':>7} {'loop s':>7} {'set-up s':>8}")
    for t in sorted(timings, key=lambda t: -t.cpu_s)[:args.top]:
        print(f"  {t.run:<32} {t.cpu_s:>7.1f} {t.wall_s:>7.1f} {t.loop_s:>7.1f} {t.setup_s:>8.2f}")
    if weight:
        est = [(t.cpu_s, weight[t.run]) for t in timings]
        total = sum(c * w for c, w in est)
        # the whole campaign in its own order (longest expected first): each sampled run as often as its group
        full = load_campaign(args.file)
        key_of = {r.run: record_key(r) for r in records}
        cpu_of = {(k[0], k[1], k[3], k[4], k[5]): t.cpu_s for t in timings for k in [key_of[t.run]]}
        seq = [cpu_of[(k[0], k[1], k[3], k[4], k[5])] for k in (full.key(s) for s in run_order(full, full.runs))]
        print(f"\n--sample: {len(timings)} runs standing for {sum(w for _, w in est)}: the whole campaign would take "
              f"{total:.1f} s CPU; longest run {max(seq):.1f} s; list schedule in the campaign's order on {workers} "
              f"idle cores {list_schedule(seq, workers):.1f} s = {list_schedule(seq, workers) / 60:.2f} min "
              "(start poses of a group differ: see the full campaign's timings)")
    print(f"\ntimings: {out / 'timings.csv'}; tables: robotexp campaign report {out / 'results.jsonl'}")


if __name__ == "__main__":
    main()

"""Benchmark of Santos's target search: objective surface, GA, firefly and exhaustive on 400 x 300 cells.

Map states come from a frontier-explorer run on the dense world, mapped at 5 cm (Santos's cell) over
x -10..10 m, y 0..15 m (400 x 300 cells), sampled evenly over the run. For each state the proportional
objective is built as the metaheuristic plugins build it (targets on reachable cells) and the GA and
firefly targets are compared with the exhaustive optimum.

Run: python benchmarks/studies/bench_metaheuristics.py [--states 100]
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.run.loop import ExplorationRun
from robotexp.planning.grid_planner import dijkstra
from robotexp.planning.metaheuristics import exhaustive, firefly_search, genetic_search
from robotexp.planning.objective import PRESETS, Objective
from robotexp.planning.targets import plan_costs, usable_frontier

RADIUS = 0.25       # [m] P3-DX


def collect_states(n: int) -> list[tuple]:
    """(grid copy, robot (x, y) [cells], visited mask) at `n` moments of a frontier run."""
    snaps: list[tuple] = []

    def grab(run: ExplorationRun) -> None:
        st = run.state
        if st is None:
            return
        g = run.grid.copy()
        visited = np.zeros(g.shape, dtype=bool)
        for r, c in run.metrics.visited:
            if g.geo.contains(r, c):
                visited[r, c] = True
        geo = g.geo
        snaps.append((g, ((st.pose.x - geo.origin_x) / geo.cell, (st.pose.y - geo.origin_y) / geo.cell), visited))

    spec = RunSpec(world="dense", method="frontier", cell=0.05, map_bounds=(-10.0, 0.0, 10.0, 15.0))
    run_experiment(spec, None, image=False, on_run=grab)
    keep = np.linspace(1, len(snaps) - 1, n).round().astype(int)
    return [snaps[i] for i in keep]


def build(state: tuple, timings: list[float] | None = None) -> Objective:
    """The plugins' objective of one map state; appends the time of the surface alone to `timings`."""
    grid, robot, visited = state
    cost = plan_costs(grid, RADIUS, 0.3)
    r, c = int(robot[1]), int(robot[0])
    cost[r, c] = min(float(cost[r, c]), 1.0)          # plan out of the robot's own cell
    reachable = np.isfinite(dijkstra(cost, (r, c))[0])
    frontier = usable_frontier(grid, reachable, 3 * 1.5 + 1.0)
    occupied = grid.occupied()
    t = time.perf_counter()
    obj = Objective(PRESETS["proportional"], frontier, occupied, visited, robot, reachable, cell=0.05)
    if timings is not None:
        timings.append(time.perf_counter() - t)
    return obj


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--states", type=int, default=100)
    args = ap.parse_args()
    t0 = time.perf_counter()
    states = collect_states(args.states)
    print(f"collected {len(states)} map states of {states[0][0].shape[1]} x {states[0][0].shape[0]} cells "
          f"in {time.perf_counter() - t0:.0f} s")
    # warm-up (numba compile)
    obj = build(states[len(states) // 2])
    firefly_search(obj.surface, np.random.default_rng(0))
    genetic_search(obj.surface, np.random.default_rng(0))

    times: dict[str, list[float]] = {"surface": [], "exhaustive": [], "firefly": [], "ga": []}
    dist: dict[str, list[float]] = {"firefly": [], "ga": []}
    rel: dict[str, list[float]] = {"firefly": [], "ga": []}
    for i, st in enumerate(states):
        obj = build(st, times["surface"])
        t = time.perf_counter()
        opt = exhaustive(obj.surface)
        times["exhaustive"].append(time.perf_counter() - t + times["surface"][-1])
        for name, fn in (("firefly", firefly_search), ("ga", genetic_search)):
            t = time.perf_counter()
            res = fn(obj.surface, np.random.default_rng(i))
            times[name].append(time.perf_counter() - t)
            dist[name].append(math.dist(res.cell, opt.cell))
            rel[name].append(res.value / opt.value if opt.value < 0 else float("nan"))
    ms = {k: 1000 * statistics.median(v) for k, v in times.items()}
    print(f"\nper map state (median of {len(states)}), 400 x 300 cells:")
    print(f"  objective surface (3 convolutions)  {ms['surface']:6.1f} ms")
    print(f"  exhaustive optimum incl. surface   {ms['exhaustive']:6.1f} ms   (target < 50 ms; the plugins' "
          f"reachability search and lists not included)")
    print(f"  firefly target (20 x 100 it.)      {ms['firefly']:6.1f} ms   (target < 20 ms)")
    print(f"  GA target (1024, 60 gen. x 64)     {ms['ga']:6.1f} ms   (target < 200 ms)")
    print("\n| search | mean dist [cells] | median | max | at optimum | <= 5 cells | f / f_opt (median) |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name in ("firefly", "ga"):
        d = np.array(dist[name])
        q = np.array([v for v in rel[name] if not math.isnan(v)])
        print(f"| {name} | {d.mean():.1f} | {np.median(d):.1f} | {d.max():.1f} | {np.mean(d == 0):.0%} | "
              f"{np.mean(d <= 5):.0%} | {np.median(q):.3f} |")


if __name__ == "__main__":
    main()

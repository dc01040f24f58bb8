"""Speed of a team: eight simulated P3-DX exploring a large map together (frontier, a coordinator), robot time /
wall time of the control loop, before and after the team's hot spots were reworked, measured in one process.

The "before" run puts back, for its duration, what the team code did before (kept below as it was): every
robot's frontier explorer kept its own plan costs of the one map they share, the scan filter that keeps
teammates out of the map built its arrays for every teammate, the simulator's tick deleted rows out of
the robots' array for each robot, the coordinator's round matched each robot's target to the candidates
cell by cell in Python, the cells each robot saw were marked through a boolean index, the distances kept
near what the scans changed (plan costs, each explorer's wall memory) were recomputed on one box holding
every scan since the last update (robots far apart: most of the map), and the team's traffic rules
looked at each teammate in turn in Python, and every explorer's memory of the walls (and the team's) noted
every robot's scans of the map they share and kept its own distance to them, each for itself. The "after" run is
the code as it is. Both runs must give the same record (path, coverage, collisions: the rework changes no
result), which the script checks.

Figures: team time (the one clock all robots share) / wall time of the loop, and robot-seconds (team time
x robots) / wall time; the single robot's ratio on the same map and time, measured alongside, bounds what a
team of n can reach on team time: each of its robots costs at least one single robot's steps. So does, lower
down, the sensing alone: the single robot's laser cast again from each pose it scanned at and each scan
integrated into a fresh map, timed with nothing else (no explorer, no physics, no loop); and the frontier
explorer's own calls in the same lone run, timed alone. Both are printed per robot step beside what a team of n
at 100x on team time leaves each robot step (the period / (100 n)).

Run (maps are not in the repository; any ROS .yaml or MobileSim .map):

    taskset -c 1 nice -n 5 python benchmarks/speed/bench_team_speed.py /work/shared/maps/ipa_office_h.yaml
        [--robots 8] [--coordinator greedy] [--max-time 120] [--repeat 1] [--no-record]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))   # perflog

from bench_cost_growth import CpuClock  # noqa: E402
from perflog import Figure, record  # noqa: E402

from robotexp.experiment import run_experiment, run_team  # noqa: E402
from robotexp.run.spec import RunSpec  # noqa: E402
from robotexp.mapping.grid import OccupancyGrid  # noqa: E402
from robotexp.robot import LaserScan, Twist, sensor_origin, wrap_angle  # noqa: E402
from robotexp.run.observers import RunObserver  # noqa: E402
from robotexp.run.record import EndReason  # noqa: E402
from robotexp.run.team import (  # noqa: E402
    _RING,
    GIVE_WAY_ANGLE,
    GIVE_WAY_GAP,
    GIVE_WAY_SPEED,
    TEAMMATE_MARGIN,
    TeamRun,
    TeamSpec,
)
from robotexp.run.teamshare import SeenCells  # noqa: E402
from robotexp.sim.team import SimTeam  # noqa: E402


# -- the team code as it was (the "before" run) --------------------------------------------------------
def _without_teammates_before(self: TeamRun, robot: int, state: Any) -> Any:
    scan = state.laser
    p = state.pose
    others = [m.state.true_pose or m.state.pose for j, m in enumerate(self.members)
              if j != robot and m.state is not None]
    if not others:
        return scan
    radii = np.array([m.robot.radius for j, m in enumerate(self.members) if j != robot and m.state is not None])
    xy = np.array([(q.x, q.y) for q in others])
    sx = p.x + scan.offset_x * math.cos(p.theta)
    sy = p.y + scan.offset_x * math.sin(p.theta)
    near = np.hypot(xy[:, 0] - sx, xy[:, 1] - sy) <= radii + TEAMMATE_MARGIN + scan.range_max
    if not near.any():
        return scan
    hit = np.isfinite(scan.ranges)
    ex = sx + np.where(hit, scan.ranges, 0.0) * np.cos(p.theta + scan.angles)
    ey = sy + np.where(hit, scan.ranges, 0.0) * np.sin(p.theta + scan.angles)
    on = np.zeros(len(scan.ranges), bool)
    for (x, y), r in zip(xy[near], radii[near], strict=True):
        on |= hit & (np.hypot(ex - x, ey - y) <= r + TEAMMATE_MARGIN)
    if not on.any():
        return scan
    return replace(scan, ranges=np.where(on, np.nan, scan.ranges))


def _advance_before(self: SimTeam, dt: float) -> None:
    discs = self._discs()
    for i, robot in enumerate(self.robots):
        if i:
            robot.engine.set_peers(np.delete(discs, i, axis=0))
        robot.advance(dt)
        p = robot.true_pose
        discs[i, 0], discs[i, 1] = p.x, p.y
    for i, robot in enumerate(self.robots):
        robot.engine.set_peers(np.delete(discs, i, axis=0))
    self.time += dt


def _plan_costs_before(self: Any, grid: Any) -> Any:
    from robotexp.planning.targets import PlanCosts

    if getattr(self, "_own_costs", None) is None:
        self._own_costs = PlanCosts(self.ctx.radius, self.clearance)
    self.costs = self._own_costs        # the explorer's planner reads each cell's best point from it
    return self._own_costs


def _held_targets_before(cand: Any, targets: Any) -> list[int | None]:
    from robotexp.planning.team import label_cells

    return [None if t is None else label_cells(cand, t) for t in targets]


def _note_before(self: SeenCells, robot: int, grid: Any) -> None:
    box = grid.changed_box(grid.scans - 1)
    if box is None:
        return
    r0, r1, c0, c1 = box
    touched = grid.stamp[r0:r1, c0:c1] == grid.scans
    self.bits[r0:r1, c0:c1][touched] |= self._one[robot]


def _changed_boxes_before(self: OccupancyGrid, since: int, grow: int = 0) -> list[tuple[int, int, int, int]]:
    box = self.changed_box(since)        # one bounding box of every scan since: robots far apart span the map
    return [] if box is None else [box]


def _lower_ahead_before(self: TeamRun, robot: int, m: Any, p: Any) -> bool:
    for j in range(robot):
        other = self.members[j]
        t = other.state
        if t is None or other.end is not EndReason.UNKNOWN or abs(t.velocity.v) < GIVE_WAY_SPEED:
            continue
        q = t.true_pose or t.pose
        dx, dy = q.x - p.x, q.y - p.y
        gap = math.hypot(dx, dy) - m.robot.footprint.swing - other.robot.footprint.swing
        if gap < GIVE_WAY_GAP and abs(wrap_angle(math.atan2(dy, dx) - p.theta)) < GIVE_WAY_ANGLE:
            return True
    return False


def _keep_clear_before(self: TeamRun, robot: int, m: Any, d: Twist, s: Any) -> None:
    p = s.true_pose or s.pose
    rings = []
    closing = 0.0
    for j, other in enumerate(self.members):
        t = other.state
        if j == robot or t is None:
            continue
        q = t.true_pose or t.pose
        if math.hypot(q.x - p.x, q.y - p.y) > 2.0 + other.robot.footprint.swing:
            continue
        r = other.robot.footprint.swing
        v = abs(t.velocity.v)
        closing = max(closing, v * v / (2.0 * max(other.robot.limits.a_max, 1e-6)) + v * 0.2)
        rings.append(np.column_stack([q.x + r * np.cos(_RING), q.y + r * np.sin(_RING)]))
    if rings:
        self._cut_command(robot, m, d, p, np.concatenate(rings), closing)


def _own_wall_memory_before(grid: Any, reach: float) -> Any:
    from robotexp.planning.targets import FirmCells, WallMemory

    return WallMemory(reach, FirmCells())   # every memory of walls notes every scan itself, keeps its own distances


def _before() -> list[tuple[Any, str, Any]]:
    """What the "before" run patches: (owner, attribute, value)."""
    import robotexp.planning.targets as targets_module
    import robotexp.run.team as team_module
    import robotexp_plugins.frontier as frontier_module
    import robotexp_plugins.metaheuristic as meta_module
    from robotexp_plugins.frontier import FrontierExplorer

    return [*[(module, "shared_wall_memory", _own_wall_memory_before)
              for module in (targets_module, team_module, frontier_module, meta_module)],
            (TeamRun, "_without_teammates", _without_teammates_before), (SimTeam, "advance", _advance_before),
            (FrontierExplorer, "_plan_costs", _plan_costs_before), (team_module, "held_targets", _held_targets_before),
            (SeenCells, "note", _note_before), (OccupancyGrid, "changed_boxes", _changed_boxes_before),
            (TeamRun, "_lower_ahead", _lower_ahead_before), (TeamRun, "_keep_clear", _keep_clear_before)]


class SensingFloor(RunObserver):
    """The sensing every robot's tick needs, alone: at the end of a single robot's run, its laser cast again from
    each pose the run mapped a scan at, and each scan integrated into a fresh map of the run's geometry, timed
    on CPU time (no explorer, no plan, no physics step). Its robot-seconds per CPU second bound any team of
    simulated robots that scan and map at the run's period: a team of n reaches at most that / n on team
    time."""

    def __init__(self) -> None:
        self.poses: list[Any] = []
        self.cpu = math.nan          # [s] CPU of the casts and map updates
        self.robot_time = 0.0        # [s] robot time the scans stand for
        self.period = math.nan       # [s] the run's control period

    def on_step(self, run: Any, step: Any) -> None:
        if step.map_updated:
            self.poses.append(step.state.true_pose or step.state.pose)

    def on_end(self, run: Any, record: Any) -> None:
        robot, grid = run.robot, run.grid
        cfg = robot.laser_config
        fresh = OccupancyGrid(grid.geo, model=grid.model, range_max=grid.range_max)
        t0 = time.process_time()
        for p in self.poses:
            sx, sy = sensor_origin(p, cfg.offset_x)
            ranges = robot._cast_fan(sx, sy, cfg.height, p.theta + robot._angles, cfg.range_max)
            fresh.update(p, LaserScan(robot._angles, ranges, cfg.range_max, cfg.offset_x))
        self.cpu = time.process_time() - t0
        self.robot_time = len(self.poses) * run.period
        self.period = run.period


class ExplorerSteps:
    """The CPU time [s] a run's explorer spends in its own calls (`step` and the calls around it), summed over
    the run: in place while a `with` block runs (`ExplorationRun._explorer_call` timed)."""

    def __init__(self) -> None:
        self.cpu = 0.0
        self.calls = 0

    def __enter__(self) -> ExplorerSteps:
        from robotexp.run.loop import ExplorationRun

        self._saved = ExplorationRun.__dict__["_explorer_call"]
        saved = self._saved

        def timed(run: Any, method: Any, *args: Any) -> Any:
            t0 = time.process_time()
            try:
                return saved(run, method, *args)
            finally:
                self.cpu += time.process_time() - t0
                self.calls += 1
        ExplorationRun._explorer_call = timed    # type: ignore[method-assign]
        return self

    def __exit__(self, *exc: Any) -> None:
        from robotexp.run.loop import ExplorationRun

        ExplorationRun._explorer_call = self._saved    # type: ignore[method-assign]


def _team(spec: RunSpec, team: TeamSpec, patches: list[tuple[Any, str, Any]]) -> tuple[Any, float, float]:
    """The record of a team run with `patches` in place, its wall time with set-up [s] and the CPU time of
    its loop [s]."""
    saved = [(owner, name, owner.__dict__[name]) for owner, name, _ in patches]
    for owner, name, value in patches:
        setattr(owner, name, value)
    try:
        clock = CpuClock()
        t0 = time.perf_counter()
        out = run_team(spec, team, None, image=False, observers=[clock])
        return out.record, time.perf_counter() - t0, clock.figures()[0]
    finally:
        for owner, name, value in saved:
            setattr(owner, name, value)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("map", type=Path, help="a large map (ROS .yaml or MobileSim .map)")
    ap.add_argument("--robots", type=int, default=8)
    ap.add_argument("--coordinator", default="greedy")
    ap.add_argument("--max-time", type=float, default=120.0, help="[s] robot time of each run")
    ap.add_argument("--repeat", type=int, default=1, help="before/after pairs, and runs of one robot alone (the best "
                                                          "CPU time of each counts)")
    ap.add_argument("--no-record", action="store_true", help="print only, write no benchmarks/results file")
    args = ap.parse_args()
    if not args.map.is_file():
        print(f"bench_team_speed: no map {str(args.map)!r}", file=sys.stderr)
        return 2
    world = str(args.map)
    # warm-up: the kernels compiled (or loaded from the cache) before anything is timed
    run_team(RunSpec(world="ufmg-static", method="frontier", max_time=5.0),
             TeamSpec(robots=("p3dx",) * 2, coordinator=args.coordinator), None, image=False)
    spec = RunSpec(world=world, method="frontier", max_time=args.max_time)
    team = TeamSpec(robots=("p3dx",) * args.robots, coordinator=args.coordinator)
    print(f"load average before: {os.getloadavg()[0]:.1f} (1 min)")
    one_cpu = sensing = explorer = 0.0
    for _ in range(args.repeat):        # one robot's loop takes well under a second: the best of the repeats
        clock, floor = CpuClock(), SensingFloor()
        single = run_experiment(spec, None, image=False, observers=[clock, floor]).record
        one_cpu = max(one_cpu, single.robot_time_s / clock.figures()[0])
        sensing = max(sensing, floor.robot_time / floor.cpu)
        with ExplorerSteps() as steps:      # the same run again, its explorer's own calls timed
            run_experiment(spec, None, image=False)
        explorer = max(explorer, single.robot_time_s / steps.cpu)
    rows = []
    for _ in range(args.repeat):        # before and after in turn: a load that comes and goes hits both
        rows.append(("before", *_team(spec, team, _before())))
        rows.append(("after", *_team(spec, team, [])))
    keys = ("path_length_m", "coverage", "collisions", "robot_collisions", "overlap_ratio", "reason", "robot_time_s")
    first = rows[0][1]
    same = all(r[k] == first[k] for _, r, _, _ in rows for k in keys) and \
        all([x["path_length_m"] for x in r.robots] == [x["path_length_m"] for x in first.robots] for _, r, _, _ in rows)
    n = args.robots
    one = single.robot_time_s / single.wall_time_s
    print(f"{Path(world).stem}, {n} P3-DX, frontier, coordinator {args.coordinator}, {args.max_time:g} s of robot time")
    print(f"  one robot alone: {one:.0f}x on wall time, {one_cpu:.0f}x on CPU time (loop): a team of {n} costs at "
          f"least {n} robots' steps, ~{one_cpu / n:.0f}x on team time")
    print(f"  its laser cast and map update alone (no explorer, no physics): {sensing:.0f}x on CPU time: {n} robots "
          f"scanning and mapping every {floor.period:g} s stay below "
          f"~{sensing / n:.0f}x on team time")
    budget = floor.period / (100.0 * n)      # [s] CPU per robot step for n robots at 100x on team time
    print(f"  per robot step of {floor.period:g} s: the laser cast and map update alone "
          f"{1e6 * floor.period / sensing:.0f} us, the frontier explorer's own calls in that lone run "
          f"{1e6 * floor.period / explorer:.0f} us, its whole loop {1e6 * floor.period / one_cpu:.0f} us; "
          f"{n} robots at 100x on team time leave {1e6 * budget:.0f} us per robot step")
    for label, r, total, cpu in rows:
        print(f"  {label:>6}: coverage {r.coverage:.4f}, path {r.path_length_m:.1f} m, loop {r.wall_time_s:.2f} s wall "
              f"(with set-up {total:.2f} s), {cpu:.2f} s CPU: team time / wall {r.robot_time_s / r.wall_time_s:.1f}x, "
              f"/ CPU {r.robot_time_s / cpu:.1f}x; robot-seconds / CPU {n * r.robot_time_s / cpu:.0f}x")
    best = {label: min(cpu for lab, _, _, cpu in rows if lab == label) for label in ("before", "after")}
    wall = {label: min(r.wall_time_s for lab, r, _, _ in rows if lab == label) for label in ("before", "after")}
    t = first.robot_time_s
    print(f"  best of {args.repeat}: CPU before {best['before']:.2f} s, after {best['after']:.2f} s: the loop "
          f"{best['before'] / best['after']:.2f}x faster; team time / CPU {t / best['before']:.1f}x -> "
          f"{t / best['after']:.1f}x, robot-seconds / CPU {n * t / best['before']:.0f}x -> "
          f"{n * t / best['after']:.0f}x; "
          f"same record in every run: {same}; load average after: {os.getloadavg()[0]:.1f}")
    if not same:
        print("bench_team_speed: the rework changed the record", file=sys.stderr)
        return 1
    if not args.no_record:
        label = f"{Path(world).stem}, {n} P3-DX, {args.coordinator}, {args.max_time:g} s"
        # one record per coordinator ("team-speed": greedy's, the default)
        record("team-speed" if args.coordinator == "greedy" else f"team-speed-{args.coordinator}", [
            Figure(f"{label}: team time / CPU time of the loop, before", round(t / best["before"], 1), "x"),
            Figure(f"{label}: team time / CPU time of the loop, after", round(t / best["after"], 1), "x"),
            Figure(f"{label}: robot-seconds / CPU time of the loop, after", round(n * t / best["after"]), "x",
                   "team time x robots"),
            Figure(f"{label}: team time / wall time of the loop, after", round(t / wall["after"], 1), "x"),
            Figure(f"{Path(world).stem}: one robot alone, robot time / CPU time of the loop", round(one_cpu), "x",
                   "a team of n on team time stays below this / n"),
            Figure(f"{Path(world).stem}: one robot's laser cast and map update alone, robot time / CPU time",
                   round(sensing), "x", "no explorer, no physics: a team of n scanning at the run's period stays "
                                        "below this / n"),
            Figure(f"{Path(world).stem}: one robot's frontier explorer, its own calls alone, robot time / CPU time",
                   round(explorer), "x", "a team of n whose robots each run it stays below this / n"),
            Figure(f"{Path(world).stem}: CPU per robot step (period {floor.period:g} s): laser cast and map update",
                   round(1e6 * floor.period / sensing), "us"),
            Figure(f"{Path(world).stem}: CPU per robot step: the frontier explorer's own calls",
                   round(1e6 * floor.period / explorer), "us"),
            Figure(f"{Path(world).stem}: CPU per robot step left to {n} robots at 100x on team time",
                   round(1e6 * budget), "us", "the period / (100 x robots)"),
        ], title="A team of eight robots on a large map", parameters={"map": Path(world).name, "robots": n,
                                                                      "coordinator": args.coordinator,
                                                                      "max_time_s": args.max_time,
                                                                      "repeat": args.repeat})
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Exploration under the P3-DX odometry error, with and without scan-matching localization.

Run: taskset -c 0 python benchmarks/bench_localized_explore.py [--worlds dense,sparse]
         [--methods frontier,srt-laser] [--max-time 1800] [--speed 0.3] [--seed 0] [--odometry p3dx]

For each world and method, three runs from the same start and seed: "exact" (perfect odometry), the
odometry error alone (the map is built on odometry), and the odometry error corrected by scan matching
(`LocalizedRobot`: the mapper and the explorer get the corrected pose). Printed per run: coverage, map IoU
against the ground truth, ATE [m] (RMSE of the pose the explorer used against the true pose, sampled
every second of robot time, no alignment), the localizer's match counts, robot time / wall time.
Targets (issue 14): with scan matching ATE <= 0.10 m and map IoU within 0.03 of the exact run; a
simulated run with localization >= 200x real time on one core.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from robotexp.experiment import DEFAULT_CELL, MAP_MARGIN, make_explorer, resolve_pose
from robotexp.explorer import ExplorationRun
from robotexp.localization import ate
from robotexp.localization.robot import LocalizedRobot
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.mapping.groundtruth import ground_truth, map_iou
from robotexp.robot import Robot
from robotexp.sim import LaserConfig, SimRobot, odometry_error, preset
from robotexp.world.loader import load_world


def run_one(world_name: str, method: str, odometry: str, localize: bool, args: argparse.Namespace) -> dict:
    """One run; returns its figures."""
    world = load_world(world_name)
    explorer = make_explorer(method, {})
    rp = preset("p3dx")
    start, _ = resolve_pose(world, None, rp.radius)
    cell = explorer.preferred_cell or DEFAULT_CELL
    assert world.bounds is not None
    geo = GridGeometry.covering(*world.bounds, cell=cell, margin=MAP_MARGIN)
    truth = ground_truth(world, geo, robot_radius=rp.radius, laser_range=args.laser_range, start=start)
    laser = LaserConfig(beams=rp.laser.beams, fov=rp.laser.fov, range_max=args.laser_range, height=rp.laser.height)
    grid = OccupancyGrid(geo, model=explorer.grid_model, range_max=args.laser_range)
    samples: list[tuple[float, float, float, float]] = []
    with SimRobot(world, robot=rp, pose=start, seed=args.seed, laser=laser, max_speed=args.speed,
                  sonar=explorer.uses_sonar, odometry=odometry_error(odometry)) as sim:
        robot: Robot = sim
        if localize:
            # the matching map: 5 cm cells over the same extent (the explorer's cells may be coarser)
            mgeo = GridGeometry.covering(*world.bounds, cell=0.05, margin=MAP_MARGIN)
            robot = LocalizedRobot(sim, mgeo, range_max=args.laser_range)
        run: ExplorationRun

        def sample(t: float, cov: float | None) -> None:
            s = run.state
            if s is not None and s.true_pose is not None:
                samples.append((s.pose.x, s.pose.y, s.true_pose.x, s.true_pose.y))

        run = ExplorationRun(robot, explorer, grid, truth=truth, max_time=args.max_time, seed=args.seed,
                             on_sample=sample)
        run.run()
        counts = robot.localizer.counts if isinstance(robot, LocalizedRobot) else {}
    arr = np.array(samples)
    return {"coverage": run.coverage() or 0.0, "iou": map_iou(grid.states(), truth),
            "ate": ate(arr[:, :2], arr[:, 2:]) if len(arr) else math.nan,
            "ratio": run.robot_time / max(run.wall_time, 1e-9), "robot_time": run.robot_time,
            "reason": run.reason, "counts": counts}


def main() -> None:
    """Run the grid of runs and print one line each, and the IoU drops."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", default="dense,sparse")
    ap.add_argument("--methods", default="frontier,srt-laser")
    ap.add_argument("--max-time", type=float, default=1800.0)
    ap.add_argument("--speed", type=float, default=0.3, help="[m/s]")
    ap.add_argument("--laser-range", type=float, default=3.0, help="[m]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--odometry", default="p3dx", help="an --odometry-error spec (robotexp.sim.odometry_error)")
    args = ap.parse_args()
    print(f"{'world':7s} {'method':10s} {'mode':22s} {'coverage':>8s} {'IoU':>7s} {'dIoU':>7s} {'ATE m':>7s} "
          f"{'x real':>7s}  reason / matches")
    for world in args.worlds.split(","):
        for method in args.methods.split(","):
            base = None
            for label, odo, loc in (("exact", "none", False), (f"{args.odometry}", args.odometry, False),
                                    (f"{args.odometry}+scan-match", args.odometry, True)):
                r = run_one(world, method, odo, loc, args)
                base = r["iou"] if base is None else base
                print(f"{world:7s} {method:10s} {label:22s} {r['coverage']:8.4f} {r['iou']:7.4f} "
                      f"{r['iou'] - base:+7.4f} {r['ate']:7.3f} {r['ratio']:7.0f}  {r['reason']} {r['counts']}",
                      flush=True)


if __name__ == "__main__":
    main()

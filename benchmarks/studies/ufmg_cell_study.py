"""The UFMG cell-size study: the same run mapped at 0.01, 0.05 and 0.1 m cells.

One run of the `waypoints` explorer (Kobuki preset, uniform +-10 cm laser noise, log-odds grid
clamped at +-3.5) on ufmg-static by default. Every scan goes into three grids, one per cell size,
through the numba kernel, each update timed on its own: the three sizes see exactly the same scans
and the same machine load. The robot steers on the 0.05 m grid (its detours use the map).

Prints the mean and median time per map update at each cell size and their ratios to 0.1 m, and
saves the three maps (with the robot's path) as PNG images.

Run: python benchmarks/studies/ufmg_cell_study.py [--world ufmg-static] [--path path1] [--out out/ufmg_cells]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from PIL import Image

from robotexp.run.loop import ExplorationRun
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.output.render import render_map, save_png
from robotexp.robot import LaserScan, Pose
from robotexp.sim import LaserConfig, SimRobot, preset
from robotexp.world.builtin import builtin_world
from robotexp_plugins.waypoints import WaypointsExplorer

CELLS = (0.01, 0.05, 0.1)   # [m] the study's cell sizes
STEER = 0.05                # [m] the grid the explorer reads
RANGE = 5.0                 # [m] laser range
NOISE = 0.10                # [m] uniform laser noise half-width
MARGIN = 1.0                # [m] map beyond the world's walls


class TimedGrids(OccupancyGrid):
    """The steering grid; each update also goes into the other grids, every update timed alone."""

    def __init__(self, grids: dict[float, OccupancyGrid]) -> None:
        steer = grids[STEER]
        self.__dict__.update(steer.__dict__)            # share the arrays of the steering grid
        self.grids = grids
        self.times: dict[float, list[float]] = {c: [] for c in grids}

    def update(self, pose: Pose, scan: LaserScan) -> int:
        """Integrate `scan` into every grid; keep the steering grid's counters in step."""
        n = 0
        for cell, grid in self.grids.items():
            t0 = time.perf_counter()
            k = grid.update(pose, scan)
            self.times[cell].append(time.perf_counter() - t0)
            if cell == STEER:
                n = k
        self.scans, self.cells_updated = self.grids[STEER].scans, self.grids[STEER].cells_updated
        return n


def main() -> None:
    """Run the study and print its table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="ufmg-static", choices=["ufmg-static", "ufmg-dynamic"])
    ap.add_argument("--path", default="path1", choices=["path1", "path2"])
    ap.add_argument("--speed", type=float, default=0.3, help="[m/s]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("out/ufmg_cells"))
    args = ap.parse_args()

    world = builtin_world(args.world)
    assert world.bounds is not None
    grids = {c: OccupancyGrid(GridGeometry.covering(*world.bounds, cell=c, margin=MARGIN), range_max=RANGE)
             for c in CELLS}
    # compile (or load from cache) the kernel before anything is timed
    warm = OccupancyGrid(GridGeometry(0, 0, 0.1, 10, 10))
    warm.update(Pose(0.5, 0.5, 0.0), LaserScan(np.zeros(1), np.ones(1), 5.0))
    timed = TimedGrids(grids)
    kobuki = preset("kobuki")
    laser = LaserConfig(range_max=RANGE, uniform=NOISE, height=kobuki.laser.height)
    with SimRobot(world, robot=kobuki, pose=world.poses[args.path], seed=args.seed, laser=laser,
                  max_speed=args.speed, sonar=False) as robot:
        run = ExplorationRun(robot, WaypointsExplorer(), timed, goals=world.goals, start_name=args.path,
                             seed=args.seed, max_time=1800.0).run()
    print(f"{args.world} {args.path}: {run.reason}; {run.metrics.path_length:.1f} m in {run.robot_time:.0f} s "
          f"robot time, {run.metrics.collisions} collisions, {len(timed.times[STEER])} scans of "
          f"{kobuki.laser.beams} beams, laser {RANGE:g} m +-{NOISE * 100:g} cm")
    base, base_med = float(np.mean(timed.times[0.1])), float(np.median(timed.times[0.1]))
    print(f"{'cell [m]':>9} {'cells':>10} {'mean [ms]':>10} {'median [ms]':>12} {'mean x':>7} {'median x':>9} "
          f"{'occupied':>9}   (x: time / time at 0.1 m)")
    args.out.mkdir(parents=True, exist_ok=True)
    path = np.array(run.metrics.path)
    for cell, grid in grids.items():
        t = np.array(timed.times[cell]) * 1000
        print(f"{cell:9.2f} {grid.geo.rows * grid.geo.cols:10d} {t.mean():10.3f} {np.median(t):12.3f} "
              f"{t.mean() / 1000 / base:7.1f} {np.median(t) / 1000 / base_med:9.1f} "
              f"{np.count_nonzero(grid.occupied()):9d}")
        image = render_map(grid.states(), grid.geo, path=path, start=run.start_pose,
                           title=f"{args.world} {args.path} - cell {cell * 100:g} cm - log-odds, +-10 cm noise")
        save_png(image, args.out / f"{args.world}_{args.path}_cell{round(cell * 1000)}mm.png")
        grey = (255 * (1.0 - grid.probability())).astype(np.uint8)[::-1]     # the study's grey map
        Image.fromarray(grey).save(args.out / f"{args.world}_{args.path}_cell{round(cell * 1000)}mm_p.png")
    print(f"maps saved in {args.out}/")


if __name__ == "__main__":
    main()

"""Speed of the mapping kernels: scan integration (numba vs the numpy reference) and ground truth.

Run: python benchmarks/speed/bench_grid_kernel.py
"""

from __future__ import annotations

import math
import time

import numpy as np

from robotexp.mapping.geometry import GridGeometry
from robotexp.world.groundtruth import ground_truth
from robotexp.mapping.kernels import LogOddsModel, integrate_scan_logodds
from robotexp.mapping.reference import integrate_scan_logodds_ref
from robotexp.robot import Pose
from robotexp.world.builtin import builtin_world
from robotexp.world.model import World
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402

BEAMS = 181
RANGE = 3.0      # [m]
CELL = 0.05      # [m]


def _scans(count: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    angles = np.linspace(-math.pi / 2, math.pi / 2, BEAMS)
    out = []
    for _ in range(count):
        pose = np.array([rng.uniform(3, 17), rng.uniform(3, 17), rng.uniform(-math.pi, math.pi)])
        ranges = rng.uniform(0.3, RANGE, BEAMS)
        ranges[rng.random(BEAMS) < 0.3] = math.inf
        out.append((pose, angles, ranges))
    return out


def _rate(fn, scans, geo: GridGeometry, model: LogOddsModel) -> tuple[float, float]:
    """(cells updated per second, scans per second); a cell counts once per scan."""
    grid = np.zeros((geo.rows, geo.cols), np.float32)
    stamp = np.zeros(grid.shape, np.int32)
    t0 = time.perf_counter()
    cells = sum(fn(grid, stamp, k, geo, pose, angles, ranges, model)
                for k, (pose, angles, ranges) in enumerate(scans, start=1))
    dt = time.perf_counter() - t0
    return cells / dt, len(scans) / dt


def _tiled(world: World, nx: int, ny: int) -> World:
    """`world` repeated nx x ny times side by side (a bigger office for timing)."""
    xmin, ymin, xmax, ymax = world.obstacle_bounds()
    w, h = xmax - xmin, ymax - ymin
    boxes = [world.boxes + [i * w, j * h, 0, 0, 0] for i in range(nx) for j in range(ny)]
    discs = [world.discs + [i * w, j * h, 0] for i in range(nx) for j in range(ny)]
    return World(f"{world.name}-{nx}x{ny}", np.vstack(boxes), np.vstack(discs), poses=world.poses)


def main() -> None:
    """Print the scan-integration rates and the ground-truth times."""
    geo = GridGeometry(0.0, 0.0, CELL, 400, 400)
    model = LogOddsModel(math.log(1 / 9), math.log(9), -3.5, 3.5, RANGE)
    _rate(integrate_scan_logodds, _scans(2), geo, model)                 # compile
    fast, fast_scans = _rate(integrate_scan_logodds, _scans(2000), geo, model)
    slow, slow_scans = _rate(integrate_scan_logodds_ref, _scans(20), geo, model)
    print(f"integrate_scan_logodds, {BEAMS} beams of {RANGE} m, {CELL} m cells "
          f"(distinct cells updated per scan):")
    print(f"  numba     {fast / 1e6:8.2f} M cells/s, {fast_scans:8.0f} scans/s")
    print(f"  numpy ref {slow / 1e6:8.2f} M cells/s, {slow_scans:8.0f} scans/s")
    print(f"  ratio     {fast_scans / slow_scans:8.0f} x")
    figures = [Figure("integrate_scan_logodds, numba", fast / 1e6, "M cells/s", f"{fast_scans:.0f} scans/s"),
               Figure("integrate_scan_logodds: numba / numpy reference", fast_scans / slow_scans, "x")]
    dense = builtin_world("dense")
    big = _tiled(dense, 2, 2)      # four closed copies: one ground truth per copy's start
    w, h = dense.size
    for world, starts in ((dense, [(0.0, 0.0)]), (big, [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)])):
        bounds = world.obstacle_bounds()
        gg = GridGeometry.covering(*bounds, 0.1)
        p = world.poses["1"]
        poses = [Pose(p.x + dx, p.y + dy) for dx, dy in starts]
        ground_truth(world, gg, robot_radius=0.25, laser_range=3.0, start=poses[0])   # compile / cache
        t0 = time.perf_counter()
        gts = [ground_truth(world, gg, robot_radius=0.25, laser_range=3.0, start=q) for q in poses]
        dt = time.perf_counter() - t0
        reach = sum(int(g.reachable.sum()) for g in gts)
        expl = sum(int(g.explorable.sum()) for g in gts)
        print(f"ground_truth {world.name} ({bounds[2] - bounds[0]:.0f} x {bounds[3] - bounds[1]:.0f} m, "
              f"{gg.rows} x {gg.cols} cells, {len(poses)} start(s)): {dt * 1e3:.0f} ms, "
              f"reachable {reach}, explorable {expl} cells")
        figures.append(Figure(f"ground truth of {world.name}, {len(poses)} start(s)", dt * 1e3, "ms",
                              f"{gg.rows} x {gg.cols} cells"))
    record("grid-kernel", figures, title="The mapping kernels and the ground truth",
           parameters={"beams": BEAMS, "range": f"{RANGE} m", "cell": f"{CELL} m"})

if __name__ == "__main__":
    main()

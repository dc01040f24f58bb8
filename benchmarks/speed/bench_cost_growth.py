"""Does an explorer's cost grow with the building? CPU time per robot-second on `dense` tiled 1x1, 2x2, 3x3.

The dense world's ground truth (its walls rasterized at 5 cm) is tiled nx x ny times into a ROS map
(YAML + PGM in a temporary folder); each tile is a closed copy, so the robot explores the same office
from the same pose (dense pose 1 in the first tile) while the map, and every whole-map step of the
explorer, grows with the tiling. CPU time (user + system, `resource.getrusage`) is taken over the control
loop only (a run observer's on_start .. on_end: no world loading, ground truth or compilation), divided by
the run's robot time. The machine is shared, so CPU time, not wall time; the ratios of one run are the
figure to quote.

Run: python benchmarks/speed/bench_cost_growth.py [--methods frontier,bvp] [--tiles 1,2,3] [--speed 300]
Target: 3x3 / 1x1 within 1.5x for frontier and bvp.
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
from pathlib import Path

import numpy as np

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.mapping.geometry import GridGeometry
from robotexp.world.groundtruth import occupancy
from robotexp.run.observers import RunObserver
from robotexp.world.builtin import builtin_world
from robotexp.world.rosmap import save_ros_map

MAP_CELL = 0.05     # [m] the ROS map's resolution


# `dense`'s doors between tiles (--connect), in the first tile's coordinates [m]: through its east wall at
# the corridor (y 6.6-8.4) into the next tile's corridor, through its north wall from its north-west room
EAST_DOOR_Y = (7.0, 8.0)
NORTH_DOOR_X = (-8.0, -7.0)
DOOR_DEPTH = 0.3        # [m] cut into the walls on both sides of the tiles' common edge


def tiled_map(folder: Path, world: str, n: int, connect: bool = False) -> Path:
    """Write `world`'s walls tiled n x n as a ROS map in `folder`; the first tile keeps the world's coordinates.

    Args:
        connect: cut doors between neighbouring tiles (`dense` only), so the robot explores all of them.

    Returns:
        the YAML path.
    """
    w = builtin_world(world)
    x0, y0, x1, y1 = w.obstacle_bounds()
    geo = GridGeometry(x0, y0, MAP_CELL, int(round((y1 - y0) / MAP_CELL)), int(round((x1 - x0) / MAP_CELL)))
    tile = np.where(occupancy(w, geo), 100, 0).astype(np.int8)
    values = np.tile(tile, (n, n))
    if connect:
        rows, cols = tile.shape
        depth = int(round(DOOR_DEPTH / MAP_CELL))
        ey = [int((v - y0) / MAP_CELL) for v in EAST_DOOR_Y]
        nx = [int((v - x0) / MAP_CELL) for v in NORTH_DOOR_X]
        for i in range(n):
            for j in range(n):
                if i > 0:       # through the west wall of tile (i, j) and the east wall of its neighbour
                    values[j * rows + ey[0]:j * rows + ey[1], i * cols - depth:i * cols + depth] = 0
                if j > 0:       # through the south wall of tile (i, j) and the north wall of its neighbour
                    values[j * rows - depth:j * rows + depth, i * cols + nx[0]:i * cols + nx[1]] = 0
    big = GridGeometry(x0, y0, MAP_CELL, values.shape[0], values.shape[1])
    path = folder / f"{world}-{n}x{n}{'-connected' if connect else ''}.yaml"
    save_ros_map(path, values, big)
    return path


class CpuClock(RunObserver):
    """CPU time, system time and page faults of this process over the control loop (on_start .. on_end)."""

    def __init__(self) -> None:
        self.start: resource.struct_rusage | None = None
        self.end: resource.struct_rusage | None = None

    def on_start(self, run) -> None:  # type: ignore[no-untyped-def]
        self.start = resource.getrusage(resource.RUSAGE_SELF)

    def on_end(self, run, record) -> None:  # type: ignore[no-untyped-def]
        self.end = resource.getrusage(resource.RUSAGE_SELF)

    def figures(self) -> tuple[float, float, int]:
        """(user + system CPU [s], system CPU [s], minor page faults) over the loop."""
        assert self.start is not None and self.end is not None
        user = self.end.ru_utime - self.start.ru_utime
        system = self.end.ru_stime - self.start.ru_stime
        return user + system, system, self.end.ru_minflt - self.start.ru_minflt


def measure(yaml: Path, method: str, speed: float, pose: str, max_time: float,
            cell: float | None) -> dict[str, float | str]:
    """One run of `method` on the map `yaml`; its CPU per robot-second and what it did."""
    clock = CpuClock()
    out = run_experiment(RunSpec(world=str(yaml), method=method, pose=pose, speed=speed, max_time=max_time,
                                 cell=cell),
                         None, observers=[clock], image=False)
    r = out.record
    cpu, system, faults = clock.figures()
    return {"cpu": cpu, "sys": system, "faults": faults, "robot": float(r["robot_time_s"]),
            "coverage": float(r["coverage"]), "path": float(r["path_length_m"]), "reason": str(r["reason"])}


def main() -> None:
    """Print CPU per robot-second per method and tiling, and the ratios to 1x1."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--methods", default="frontier,bvp")
    ap.add_argument("--tiles", default="1,2,3", help="tilings n (n x n), comma-separated; the first is the base")
    ap.add_argument("--world", default="dense")
    ap.add_argument("--speed", type=float, default=300.0, help="[mm/s]")
    ap.add_argument("--cell", type=float, default=None, help="[mm] the run's map cell (default: the method's)")
    ap.add_argument("--connect", action="store_true",
                    help="doors between the tiles: the robot explores the whole building (dense only)")
    ap.add_argument("--max-time", type=float, default=14400.0, help="[s] robot time per run")
    args = ap.parse_args()
    methods = [m for m in args.methods.split(",") if m]
    try:
        tiles = [int(t) for t in args.tiles.split(",") if t]
    except ValueError:
        sys.exit(f"--tiles: expected integers such as 1,2,3, got {args.tiles!r}")
    if not tiles or min(tiles) < 1:
        sys.exit(f"--tiles: expected integers >= 1, got {args.tiles!r}")
    cell = None if args.cell is None else args.cell / 1000
    p = builtin_world(args.world).poses["1"]
    pose = f"{p.x * 1000:.0f},{p.y * 1000:.0f},{np.degrees(p.theta):.0f}"
    with tempfile.TemporaryDirectory() as tmp:
        maps = {n: tiled_map(Path(tmp), args.world, n, args.connect) for n in tiles}
        for method in methods:      # warm-up: numba kernels compiled or loaded from the cache
            measure(maps[tiles[0]], method, args.speed / 1000, pose, 5.0, cell)
        print(f"{args.world} tiled n x n as ROS maps at {MAP_CELL * 1000:g} mm, {args.speed:g} mm/s, from pose 1; "
              "CPU = user + system over the control loop")
        results: dict[tuple[str, int], dict[str, float | str]] = {}
        for method in methods:
            for n in tiles:
                f = results[method, n] = measure(maps[n], method, args.speed / 1000, pose, args.max_time, cell)
                print(f"  {method:9s} {n}x{n}: {1e3 * float(f['cpu']) / float(f['robot']):6.2f} ms CPU per robot-s "
                      f"(system {100 * float(f['sys']) / max(float(f['cpu']), 1e-9):4.1f} %, "
                      f"{int(f['faults'])} page faults), robot time {float(f['robot']):.0f} s, "
                      f"coverage {float(f['coverage']):.4f}, path {float(f['path']):.1f} m, {f['reason']}",
                      flush=True)
        base = tiles[0]
        for method in methods:
            per = {n: float(results[method, n]["cpu"]) / float(results[method, n]["robot"]) for n in tiles}
            ratios = ", ".join(f"{n}x{n}/{base}x{base} {per[n] / per[base]:.2f}" for n in tiles if n != base)
            print(f"{method}: {ratios}")


if __name__ == "__main__":
    main()

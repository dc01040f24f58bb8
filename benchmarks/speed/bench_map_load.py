"""Loading large real-like maps: seconds and peak memory, each measured in a fresh child process.

Generates (in a temporary folder) a laser-built-like ARIA point map of N points (walls of 20 mm
points with the jitter of a scan matcher, so runs break as in real maps) and a ROS map of W x W m
at 5 cm (rooms, clutter, unknown space around the building), then, for each, in a child process:
`load_world`, the simulator (`SimRobot`: pybullet client, ray index, collision test) with one scan,
and the ground truth on the 5 cm run grid. Prints seconds per stage and the child's peak RSS.

    python benchmarks/speed/bench_map_load.py [--points 60000] [--ros-size 50] [--map FILE ...]

`--map` adds existing map files (e.g. AriaCoda's maps/columbia.map: 63 k points).
Target: a 60 k-point map in < 3 s and < 300 MB; a 50 x 50 m ROS map in seconds.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np


def point_map(path: Path, n_points: int, seed: int = 0) -> Path:
    """An office-like point map: a grid of rooms whose walls are 20 mm points with jitter."""
    rng = np.random.default_rng(seed)
    side_m = max(10.0, (n_points * 0.02 / 6.0) ** 0.5 * 1.2)     # wall length ~ 6 rooms' worth per side
    room = 5.0
    k = int(side_m // room)
    pts: list[np.ndarray] = []
    for i in range(k + 1):                       # walls along x and along y every `room` m
        t = np.arange(0, k * room * 1000, 20)
        jitter = rng.choice([-20, 0, 0, 0, 20], size=len(t))
        keep = rng.random(len(t)) > 0.1          # gaps: doors and missed returns
        pts.append(np.column_stack([t[keep], (i * room * 1000 + jitter)[keep]]))
        jitter = rng.choice([-20, 0, 0, 0, 20], size=len(t))
        pts.append(np.column_stack([(i * room * 1000 + jitter)[keep], t[keep]]))
    walls = np.vstack(pts)
    extra = max(n_points - len(walls), 0)
    clutter = rng.integers(0, int(k * room * 1000) // 20, size=(extra, 2)) * 20
    allp = np.vstack([walls, clutter])[:n_points].astype(np.int64)
    home = int(room * 500)
    allp = allp[np.hypot(allp[:, 0] - home, allp[:, 1] - home) > 600]     # the home is clear
    path.write_text(f"2D-Map\nMinPos: 0 0\nMaxPos: {int(k * room * 1000)} {int(k * room * 1000)}\n"
                    f"NumPoints: {len(allp)}\nResolution: 20\n"
                    f"Cairn: RobotHome {home} {home} 0 \"\" ICON \"\"\nDATA\n"
                    + "\n".join(f"{x} {y}" for x, y in allp.tolist()) + "\n")
    return path


def ros_map(path: Path, size_m: float, seed: int = 0) -> Path:
    """A size_m x size_m ROS map at 5 cm: rooms with doors, clutter, unknown space all around."""
    from robotexp.mapping.geometry import GridGeometry
    from robotexp.world.rosmap import save_ros_map

    rng = np.random.default_rng(seed)
    n = int(round(size_m / 0.05))
    v = np.full((n, n), -1, np.int8)
    m = n // 10
    v[m:n - m, m:n - m] = 0
    for k in range(m, n - m + 1, 100):           # walls every 5 m, doors of 1 m
        v[k:k + 3, m:n - m] = 100
        v[m:n - m, k:k + 3] = 100
        for d in range(m + 40, n - m, 100):
            v[k:k + 3, d:d + 20] = 0
            v[d:d + 20, k:k + 3] = 0
    cl = rng.integers(m, n - m - 4, size=(n * 2, 2))
    for r, c in cl:
        v[r:r + 4, c:c + 4] = 100
    v[n // 2 - 10:n // 2 + 10, m + 45:m + 65] = 0      # the start, kept clear
    save_ros_map(path, v, GridGeometry(0.0, 0.0, 0.05, n, n))
    return path


def child(path: str) -> None:
    import resource
    import time

    t0 = time.perf_counter()
    from robotexp.mapping.geometry import GridGeometry
    from robotexp.world.groundtruth import ground_truth
    from robotexp.robot import Pose
    from robotexp.sim import SimRobot
    from robotexp.world.loader import load_world
    t_import = time.perf_counter()
    world = load_world(path)
    t_load = time.perf_counter()
    if world.home is not None:
        start = world.home
    else:
        x0, y0, x1, y1 = world.bounds
        start = Pose(x0 + (x1 - x0) * 0.1 + 2.75, (y0 + y1) / 2, 0.0)
    with SimRobot(world, pose=start, sonar=False) as robot:
        robot.scan()
    t_sim = time.perf_counter()
    geo = GridGeometry.covering(*world.bounds, cell=0.05, margin=0.5)
    ground_truth(world, geo, robot_radius=0.25, laser_range=3.0, start=start)
    t_gt = time.perf_counter()
    print(json.dumps({"boxes": len(world.boxes), "import_s": t_import - t0, "load_s": t_load - t_import,
                      "sim_s": t_sim - t_load, "truth_s": t_gt - t_sim, "cells": geo.rows * geo.cols,
                      "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))


def measure(path: Path) -> dict[str, float]:
    out = subprocess.run([sys.executable, __file__, "--child", str(path)], capture_output=True, text=True,
                         timeout=1800)
    if out.returncode != 0:
        return {"error": out.stderr.strip().splitlines()[-1] if out.stderr.strip() else f"exit {out.returncode}"}
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, nargs="*", default=[60_000])
    ap.add_argument("--ros-size", type=float, nargs="*", default=[50.0])
    ap.add_argument("--map", nargs="*", default=[])
    ap.add_argument("--child")
    args = ap.parse_args()
    if args.child:
        child(args.child)
        return
    with tempfile.TemporaryDirectory() as tmp:
        maps = [point_map(Path(tmp) / f"points_{n}.map", n) for n in args.points]
        maps += [ros_map(Path(tmp) / f"ros_{s:g}m.yaml", s) for s in args.ros_size]
        maps += [Path(m) for m in args.map]
        print(f"{'map':<24} {'boxes':>7} {'cells':>9} {'load s':>7} {'sim s':>6} {'truth s':>7} "
              f"{'load+sim s':>10} {'peak RSS MB':>11}")
        for m in maps:
            r = measure(m)
            if "error" in r:
                print(f"{m.name:<24} error: {r['error']}")
                continue
            print(f"{m.name:<24} {r['boxes']:>7} {r['cells']:>9} {r['load_s']:>7.2f} {r['sim_s']:>6.2f} "
                  f"{r['truth_s']:>7.2f} {r['load_s'] + r['sim_s']:>10.2f} {r['peak_rss_mb']:>11.0f}")


if __name__ == "__main__":
    main()

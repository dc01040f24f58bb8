"""Are generated worlds fair tests? Per kind and seed, what the default start can reach.

For each `generated:KIND:SEED` (default: office, warehouse, cave, seeds 0-9) and each map file given
(real buildings, to compare) this prints, for a P3-DX
(radius 0.25 m) with a 3 m laser and the run's 5 cm grid:

- `regions`: places where the robot fits with 5 cm to spare (robotexp.world.start), and `cut off`: the
  area [m2] of the closed ones (not open to the map's edge) the start's region does not hold - rooms
  behind furniture or a passage too narrow (they are not in the ground truth either);
- `explorable`: the ground truth the run's coverage is measured against [m2] (robotexp.world.groundtruth,
  the robot's exact radius), and `tight`: the share of it that is only reachable through a gap a planner
  keeping `--margin` (default 0.075 m, more than the planners' 2 cm from the walls' surface) from the walls
  cannot pass - coverage a method could not get without touching a wall.

    python benchmarks/studies/generated_fairness.py [--kinds office,warehouse,cave,building] [--seeds 0-9] [--scanned]
        [--size WxH] [MAP_FILES...]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np


def main() -> int:
    from robotexp.mapping.geometry import GridGeometry
    from robotexp.world.groundtruth import ground_truth, occupancy
    from robotexp.mapping.kernels import clearance_mask, flood8, label8
    from robotexp.world.loader import load_world
    from robotexp.world.start import default_start

    START_MARGIN = 0.05     # [m] room to spare beyond the radius for a "tight" place here

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("maps", nargs="*", help="map files to look at too (the real maps' tight share)")
    ap.add_argument("--kinds", default="office,warehouse,cave", help="comma-separated; empty: none")
    ap.add_argument("--seeds", default="0-9", help="A-B, inclusive")
    ap.add_argument("--scanned", action="store_true", help="the worlds with scan artefacts")
    ap.add_argument("--size", default="", help="WxH [m] of the worlds (default: each kind's)")
    ap.add_argument("--radius", type=float, default=0.25, help="[m] robot radius (P3-DX)")
    ap.add_argument("--laser-range", type=float, default=3.0, help="[m]")
    ap.add_argument("--margin", type=float, default=0.075, help="[m] a planner's margin beyond the radius")
    args = ap.parse_args()
    a, _, b = args.seeds.partition("-")
    seeds = range(int(a), int(b or a) + 1)
    print(f"{'world':<28} {'regions':>7} {'cut off m2':>11} {'explorable m2':>13} {'tight':>7}  start")
    worst = 0.0
    t0 = time.perf_counter()
    extra = (f":{args.size}" if args.size else "") + (":scanned" if args.scanned else "")
    names = [f"generated:{kind}:{seed}{extra}" for kind in filter(None, args.kinds.split(",")) for seed in seeds]
    for spec in names + args.maps:
        world = load_world(spec)
        choice = default_start(world, args.radius)
        assert world.bounds is not None
        geo = GridGeometry.covering(*world.bounds, cell=0.05, margin=0.5)
        gt = ground_truth(world, geo, robot_radius=args.radius, laser_range=args.laser_range, start=choice.pose)
        occ = occupancy(world, geo)
        fits = clearance_mask(occ, (args.radius + START_MARGIN) / geo.cell)
        labels, _ = label8(fits)
        edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
        r, c = geo.cell_of(choice.pose.x, choice.pose.y)
        inner = (labels > 0) & ~np.isin(labels, edge) & (labels != labels[r, c])
        cut_off = float(np.count_nonzero(inner)) * geo.cell ** 2      # [m2] closed places the start misses
        wide = clearance_mask(occ, (args.radius + args.margin) / geo.cell)
        reach_wide = flood8(wide, r, c) if wide[r, c] else np.zeros_like(wide)
        # reachable cells (exact radius) farther than the margin (and a cell) from everywhere a
        # robot keeping the margin reaches: behind a gap only the exact robot passes
        far = clearance_mask(reach_wide, (args.margin + geo.cell) / geo.cell) if reach_wide.any() \
            else np.ones_like(wide)
        tight_cells = gt.reachable & far
        explorable = float(np.count_nonzero(gt.explorable))
        tight = float(np.count_nonzero(tight_cells)) / max(explorable, 1.0)
        worst = max(worst, tight)
        print(f"{spec:<28} {choice.regions:>7} {cut_off:>11.1f} {explorable * geo.cell ** 2:>13.1f} "
              f"{tight:>7.4f}  ({choice.pose.x:.2f}, {choice.pose.y:.2f})")
    print(f"worst tight share {worst:.4f}; {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Time per scan of the scan matcher: 181-beam scans at 5 cm cells, numba kernels against the numpy references.

Run: python benchmarks/speed/bench_scan_match.py [--world dense] [--scans 200] [--reach 8] [--cell 0.05]
Target: scan matching <= 2 ms per 181-beam scan at 5 cm cells.

Scans are cast exactly (the simulator's ray caster) from random free poses. The map is built from
--map-scans of them at their true poses (log-odds grid and hit points, as the Localizer keeps it);
each of the other --scans is matched from a prediction off by up to 0.15 m and 3 deg. Printed, in
one run: the whole `ScanMatcher.match` (the likelihood field of the window around the robot, coarse
and fine correlative search, Gauss-Newton) with the default bilinear field and with the exact field
of whole runs (`RUN_MATCHER`), and its parts; the same steps with the numpy references; and how often
the pose was recovered within one cell and 0.5 deg.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from robotexp.localization import HitMap, ScanMatcher, scan_points
from robotexp.localization.matcher import MatcherConfig
from robotexp.localization import kernels as K
from robotexp.localization.reference import (
    hit_points_ref,
    pool_max_ref,
    refine_hits_ref,
    refine_ref,
    search_ref,
    splat_field_ref,
)
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.world.groundtruth import occupancy
from robotexp.robot import LaserScan, Pose
from robotexp.world.raycast import RayIndex
from robotexp.world.builtin import builtin_world


def main() -> None:
    """Build the map and the scans, time both implementations, print ms per scan."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="dense")
    ap.add_argument("--scans", type=int, default=200)
    ap.add_argument("--reach", type=float, default=8.0, help="laser range [m]")
    ap.add_argument("--cell", type=float, default=0.05)
    ap.add_argument("--map-scans", type=int, default=400, help="scans from other poses that make the map")
    ap.add_argument("--ref-scans", type=int, default=10, help="scans for the (slow) numpy reference")
    args = ap.parse_args()
    world = builtin_world(args.world)
    geo = GridGeometry.covering(*world.obstacle_bounds(), args.cell, margin=0.5)
    occ = occupancy(world, geo)
    index = RayIndex(world.boxes, world.discs, 2.0)
    angles = np.radians(np.linspace(-90.0, 90.0, 181))
    rng = np.random.default_rng(0)
    free = np.argwhere(~occ)
    cases = []
    # the map: scans from --map-scans other random poses, as a robot would have built it
    grid = OccupancyGrid(geo, p_occ=0.9, p_free=0.4)
    hits = HitMap(geo)
    while len(cases) < args.scans + args.map_scans:
        r, c = free[rng.integers(len(free))]
        x, y = geo.center_of(int(r), int(c))
        frac = index.cast(np.tile([x, y], (181, 1)), 0.0 + angles, 0.3, 0.3)
        if frac.min() < 1.0:                 # within 0.3 m of something: not a robot pose
            continue
        truth = Pose(x, y, float(rng.uniform(-math.pi, math.pi)))
        frac = index.cast(np.tile([x, y], (181, 1)), truth.theta + angles, args.reach, 0.3)
        scan = LaserScan(angles, np.where(frac >= 1.0, np.inf, frac * args.reach), args.reach, 0.0)
        px, py = scan_points(scan)
        if len(px) < 40:
            continue
        off = Pose(float(rng.uniform(-0.15, 0.15)), float(rng.uniform(-0.15, 0.15)),
                   math.radians(float(rng.uniform(-3.0, 3.0))))
        c0, s0 = math.cos(truth.theta), math.sin(truth.theta)
        pred = Pose(truth.x + c0 * off.x - s0 * off.y, truth.y + s0 * off.x + c0 * off.y, truth.theta + off.theta)
        if len(cases) < args.map_scans:
            grid.update(truth, scan)
            hits.add(truth, scan)
        cases.append((truth, pred, px, py))
    cases = cases[args.map_scans:]
    walls = grid.occupied()
    results = {}
    for exact in (False, True):       # the default (logs) and the whole runs' (`RUN_MATCHER`: exact field)
        sm = ScanMatcher(MatcherConfig(exact_field=exact))
        sm.match(walls, geo, cases[0][2], cases[0][3], cases[0][1], hits)    # compile (cached after the first run)
        ok = 0
        t_all = time.perf_counter()
        for truth, pred, px, py in cases:
            m = sm.match(walls, geo, px, py, pred, hits)
            ok += math.hypot(m.pose.x - truth.x, m.pose.y - truth.y) <= args.cell and \
                abs(math.remainder(m.pose.theta - truth.theta, 2 * math.pi)) <= math.radians(0.5)
        results[exact] = ((time.perf_counter() - t_all) / len(cases) * 1e3, ok)
    cfg = sm.config
    # the parts, numba and numpy, on the same fields and windows
    reach = math.ceil(3 * cfg.sigma / args.cell)
    parts = {"field": [0.0, 0.0], "search": [0.0, 0.0], "refine (bilinear field)": [0.0, 0.0],
             "hit points (exact field)": [0.0, 0.0], "refine_hits (exact field, whole runs)": [0.0, 0.0]}
    n_ref = min(args.ref_scans, len(cases))
    for _truth, pred, px, py in cases[:n_ref]:
        radius = float(np.hypot(px, py).max()) + cfg.window_xy + 4 * cfg.sigma + args.cell
        r0, c0 = geo.cell_of(pred.x - radius, pred.y - radius)
        r1, c1 = geo.cell_of(pred.x + radius, pred.y + radius)
        r0, c0, r1, c1 = max(r0, 0), max(c0, 0), min(r1 + 1, geo.rows), min(c1 + 1, geo.cols)
        sub = np.ascontiguousarray(walls[r0:r1, c0:c1])
        off_x, off_y = hits.offsets(r0, r1, c0, c1)
        ox, oy = geo.origin_x + c0 * args.cell, geo.origin_y + r0 * args.cell
        dth_c = math.atan2(args.cell * cfg.coarse, float(np.hypot(px, py).max()))
        nth = math.ceil(cfg.window_theta / dth_c)
        nxy = math.ceil(cfg.window_xy / (args.cell * cfg.coarse))
        prior = (pred.x, pred.y, pred.theta, cfg.prior * len(px) / cfg.window_xy ** 2,
                 cfg.prior * len(px) / cfg.window_theta ** 2)
        for impl, (fld, pool, srch, ref, pts, ref_hits) in enumerate((
                (K.splat_field, K.pool_max, K.search, K.refine, K.hit_points, K.refine_hits),
                (splat_field_ref, pool_max_ref, search_ref, refine_ref, hit_points_ref, refine_hits_ref))):
            t = time.perf_counter()
            f = fld(sub, off_x, off_y, args.cell, cfg.sigma, reach)
            coarse = pool(f, cfg.coarse)
            parts["field"][impl] += time.perf_counter() - t
            t = time.perf_counter()
            x, y, th, _ = srch(coarse, ox, oy, args.cell * cfg.coarse, px, py, pred.x, pred.y, pred.theta,
                               nxy, 1, nth, dth_c, *prior)
            parts["search"][impl] += time.perf_counter() - t
            t = time.perf_counter()
            ref(f, ox, oy, args.cell, px, py, x, y, th, cfg.iterations, pred.x, pred.y, pred.theta,
                cfg.motion_sigma_xy ** -2, cfg.motion_sigma_theta ** -2)
            parts["refine (bilinear field)"][impl] += time.perf_counter() - t
            t = time.perf_counter()
            points = pts(sub, off_x, off_y)
            parts["hit points (exact field)"][impl] += time.perf_counter() - t
            t = time.perf_counter()
            ref_hits(points, ox, oy, args.cell, cfg.sigma, reach, px, py, x, y, th, cfg.iterations, pred.x, pred.y,
                     pred.theta, cfg.motion_sigma_xy ** -2, cfg.motion_sigma_theta ** -2)
            parts["refine_hits (exact field, whole runs)"][impl] += time.perf_counter() - t
    print(f"world {args.world}, {geo.cols} x {geo.rows} cells of {args.cell} m, 181 beams to {args.reach} m, "
          f"{len(cases)} scans, mean {np.mean([len(c[2]) for c in cases]):.0f} hits a scan")
    for exact, name in ((False, "bilinear field (the default)"), (True, "exact field (whole runs)")):
        t_all, ok = results[exact]
        print(f"ScanMatcher.match (numba), {name}: {t_all:.3f} ms per scan; recovered within one cell and "
              f"0.5 deg: {ok}/{len(cases)}")
    print(f"parts over {n_ref} scans (ms per scan)              numba      numpy   numpy/numba")
    for name, (nb, ref_t) in parts.items():
        print(f"  {name:43s} {nb / n_ref * 1e3:8.3f}   {ref_t / n_ref * 1e3:8.3f}   {ref_t / max(nb, 1e-12):8.1f}x")


if __name__ == "__main__":
    main()

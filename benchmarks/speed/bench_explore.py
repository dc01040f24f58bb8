"""Speed of a whole exploration: robot time / wall time of a frontier run of `dense`, the laser's ray
casting (the exact kernel against pybullet's ray test) and the rate of the mapping kernel (numba)
against its numpy reference, measured in the same process.

Run: python benchmarks/speed/bench_explore.py [--world dense] [--method frontier] [--speed 300]
Target (issue "Foundation"): robot time / wall time >= 200 on one core.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))   # perflog

from bench_cost_growth import CpuClock  # noqa: E402
from bench_grid_kernel import CELL, RANGE, _rate, _scans  # noqa: E402
from perflog import Figure, record  # noqa: E402

from robotexp.run.spec import RunSpec  # noqa: E402
from robotexp.experiment import run_experiment
from robotexp.mapping.geometry import GridGeometry  # noqa: E402
from robotexp.mapping.kernels import LogOddsModel, integrate_scan_logodds  # noqa: E402
from robotexp.mapping.reference import integrate_scan_logodds_ref  # noqa: E402
from robotexp.sim.engine import Engine  # noqa: E402
from robotexp.world.builtin import builtin_world  # noqa: E402


def scan_cost(world: str, rays: str, repeats: int) -> float:
    """[s] per 181-beam scan of 3 m from the world's first start pose, with ray caster `rays`."""
    w = builtin_world(world)
    engine = Engine(w, 0.25, 0.5, rays)
    try:
        pose = next(iter(w.poses.values()))
        origins = np.tile([pose.x, pose.y], (181, 1))
        headings = pose.theta + np.radians(np.arange(-90.0, 91.0))
        engine.cast_from(origins, headings, 3.0, 0.3)
        t0 = time.perf_counter()
        for _ in range(repeats):
            engine.cast_from(origins, headings, 3.0, 0.3)
        return (time.perf_counter() - t0) / repeats
    finally:
        engine.close()


def main() -> None:
    """Print the exploration speed ratio and the kernel rates."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="dense")
    ap.add_argument("--method", default="frontier")
    ap.add_argument("--speed", type=float, default=300.0, help="[mm/s]")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    # warm-up: compile (or load cached) kernels so the timed run measures the steady state
    run_experiment(RunSpec(world="ufmg-static", method=args.method, max_time=5.0), None, image=False)
    print(f"load average before: {os.getloadavg()[0]:.1f} (1 min)")
    clock = CpuClock()
    t0 = time.perf_counter()
    out = run_experiment(RunSpec(world=args.world, method=args.method, speed=args.speed / 1000, seed=args.seed),
                         None, image=False, observers=[clock])
    total = time.perf_counter() - t0
    r = out.record
    print(f"exploration {args.world} / {args.method} at {args.speed:g} mm/s: {r['reason']}")
    print(f"  path {r['path_length_m']:.1f} m, coverage {r['coverage']:.4f}, collisions {r['collisions']}")
    print(f"  robot time {r['robot_time_s']:.1f} s, control loop wall time {r['wall_time_s']:.2f} s "
          f"(with set-up and ground truth {total:.2f} s)")
    print(f"  robot time / wall time = {r['robot_time_s'] / r['wall_time_s']:.0f}x (loop), "
          f"{r['robot_time_s'] / total:.0f}x (whole run)")
    cpu = clock.figures()[0]
    print(f"  robot time / CPU time (user + system) of the loop = {r['robot_time_s'] / cpu:.0f}x "
          f"({cpu:.2f} s of CPU; less sensitive to other processes than wall time, not immune: caches are shared); "
          f"load average after: {os.getloadavg()[0]:.1f}")

    exact, bullet = scan_cost(args.world, "exact", 5000), scan_cost(args.world, "pybullet", 1000)
    print(f"laser scan (181 rays of 3 m in {args.world}): exact kernel {exact * 1e6:.1f} us, pybullet ray test "
          f"{bullet * 1e6:.1f} us: {bullet / exact:.1f}x")

    geo = GridGeometry(0.0, 0.0, CELL, int(20 / CELL), int(20 / CELL))
    model = LogOddsModel(-2.1972246, 2.1972246, -3.5, 3.5, RANGE)
    fast_cells, fast_scans = _rate(integrate_scan_logodds, _scans(400), geo, model)
    slow_cells, slow_scans = _rate(integrate_scan_logodds_ref, _scans(20), geo, model)
    print(f"grid update kernel (181 beams of {RANGE:g} m, {CELL:g} m cells): numba {fast_cells / 1e6:.1f} M cells/s "
          f"({fast_scans:.0f} scans/s), numpy reference {slow_cells / 1e6:.2f} M cells/s "
          f"({slow_scans:.0f} scans/s): {fast_cells / slow_cells:.0f}x")
    record("explore", [
        Figure(f"{args.method} on {args.world}: robot time / wall time of the control loop",
               r["robot_time_s"] / r["wall_time_s"], "x", f"{r['robot_time_s']:.0f} s of robot time"),
        Figure("robot time / wall time of the whole run (set-up and ground truth included)",
               r["robot_time_s"] / total, "x"),
        Figure("robot time / CPU time of the control loop", r["robot_time_s"] / cpu, "x"),
        Figure("laser scan, 181 rays of 3 m: exact kernel", exact * 1e6, "us"),
        Figure("laser scan: pybullet ray test / exact kernel", bullet / exact, "x"),
        Figure(f"grid update kernel, numba ({CELL:g} m cells)", fast_cells / 1e6, "M cells/s"),
        Figure("grid update kernel: numba / numpy reference", fast_cells / slow_cells, "x"),
    ], title="A whole exploration and its kernels",
        parameters={"world": args.world, "method": args.method, "speed": f"{args.speed:g} mm/s",
                    "coverage": round(r["coverage"], 4), "path": f"{r['path_length_m']:.1f} m"})


if __name__ == "__main__":
    main()

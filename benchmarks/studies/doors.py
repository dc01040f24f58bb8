"""Explorers through doors a robot just fits: five 4 x 4 m rooms in a row joined by off-centre doors
(`robotexp.world.builtin.rooms_in_a_row`), 0.65 m doors for the P3-DX preset (a 0.5 m disc), 0.50 m for
the Kobuki (0.35 m), from the middle of the first room.

Run: python benchmarks/studies/doors.py [--methods frontier,bvp,srt-laser,meta-ga,meta-firefly]
         [--robots p3dx,kobuki] [--max-time 1800]

Per run: the rooms entered (of five), coverage of the explorable space, collisions, robot time, wall time
and the end reason. Success: coverage >= 0.95, no collision, ended by the explorer (`completed`: its
"explored", not stopped by the run's check).
"""

from __future__ import annotations

import argparse
import time

from robotexp.experiment import run_experiment
from robotexp.run.spec import RunSpec
from robotexp.world.builtin import rooms_in_a_row

DOORS = {"p3dx": 0.65, "kobuki": 0.50, "p3dx-body": 0.65}      # [m] door width per robot preset


def run(method: str, robot: str, max_time: float, door: float | None = None) -> dict[str, object]:
    """One run; its figures."""
    world = rooms_in_a_row(DOORS[robot] if door is None else door)
    spec = RunSpec(world=world, method=method, robot=robot, max_time=max_time)   # type: ignore[arg-type]
    t0 = time.perf_counter()
    out = run_experiment(spec, None)
    wall = time.perf_counter() - t0
    r = out.record
    rooms = 1 + max(int(x // 4.0) for x, _ in out.run.metrics.path)
    ok = (r["coverage"] or 0.0) >= 0.95 and r["collisions"] == 0 and bool(r["completed"])
    return {"method": method, "robot": robot, "rooms": min(rooms, 5), "coverage": r["coverage"] or 0.0,
            "collisions": r["collisions"], "time": r["robot_time_s"], "wall": wall, "reason": r["reason"], "ok": ok}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--methods", default="frontier,bvp,srt-laser,meta-ga,meta-firefly")
    ap.add_argument("--robots", default="p3dx,kobuki,p3dx-body")
    ap.add_argument("--max-time", type=float, default=1800.0)
    ap.add_argument("--door", type=float, help="door width [m] for every robot (default: 0.65 P3-DX, 0.50 Kobuki)")
    args = ap.parse_args()
    total = 0.0
    wins = 0
    n = 0
    for method in args.methods.split(","):
        for robot in args.robots.split(","):
            f = run(method, robot, args.max_time, args.door)
            total += float(f["wall"])      # type: ignore[arg-type]
            wins += bool(f["ok"])
            n += 1
            print(f"{method:<13} {robot:<7} rooms {f['rooms']}/5 coverage {100 * float(f['coverage']):5.1f} % "  # type: ignore[arg-type]
                  f"collisions {f['collisions']} robot {float(f['time']):6.0f} s wall {float(f['wall']):5.1f} s "  # type: ignore[arg-type]
                  f"{'OK' if f['ok'] else '--'} {f['reason']}", flush=True)
    print(f"{wins}/{n} succeeded; wall time {total:.0f} s in all")


if __name__ == "__main__":
    main()

"""A team over the real drivers on `dense`: two emulated P3-DX on TCP and an emulated Kobuki with an RPLidar on
pseudo-terminals in one simulated world (`robotexp emulate p3dx,p3dx,kobuki+rplidar:pty`), explored with
`robotexp explore --team ADDRESSES` until the explorers are done or the time limit, beside the same team of
simulated robots (`--team p3dx,p3dx,kobuki`, one stepped clock, from the same starts).

Prints each run's end, coverage, robot and wall time, paths and collisions (robot-robot ones as the emulators
count them) and writes the records to OUT/results.jsonl.

    python benchmarks/studies/team_drivers_study.py [--world dense] [--pose 1] [--coordinator greedy]
        [--speedup 5] [--max-time 900] [--out out/team_drivers]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def main() -> int:
    from robotexp.experiment import run_team, run_team_on_robots
    from robotexp.run.spec import RunSpec
    from robotexp.run.team import TeamSpec
    from robotexp.run.teamrobots import connect_team, emulate_team, parse_emulated, parse_members

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--world", default="dense")
    ap.add_argument("--pose", default="1")
    ap.add_argument("--coordinator", default="greedy")
    ap.add_argument("--speedup", type=float, default=5.0, help="the emulators' robot time per wall time")
    ap.add_argument("--max-time", type=float, default=900.0, help="[s] robot time")
    ap.add_argument("--out", type=Path, default=Path("out/team_drivers"))
    args = ap.parse_args()
    spec = RunSpec(world=args.world, method="frontier", pose=args.pose, max_time=args.max_time, localize="none")
    names = ("p3dx", "p3dx", "kobuki")
    rows = []
    t0 = time.perf_counter()
    simulated = run_team(spec, TeamSpec(robots=names, coordinator=args.coordinator), args.out, image=False).record
    rows.append(("simulated", simulated, time.perf_counter() - t0, None))
    devices = emulate_team(parse_emulated("p3dx,p3dx,kobuki+rplidar:pty"), args.world, pose=args.pose, port=0,
                           speedup=args.speedup)
    try:
        where = dict((label, d.address) for label, d in devices)
        members = parse_members(f"p3dx:{where['robot 1']},p3dx:{where['robot 2']},"
                                f"kobuki:{where['robot 3']}+rplidar:{where['laser 3']}")
        robots = connect_team(members)
        try:
            t0 = time.perf_counter()
            team = TeamSpec(robots=names, coordinator=args.coordinator, members=tuple(m.text for m in members))
            driven = run_team_on_robots(spec, team, robots, args.out, args.world, image=False).record
        finally:
            for robot in reversed(robots):
                robot.close()
        hits = [d.sim.robot_collisions for label, d in devices if label.startswith("robot")]
        rows.append((f"drivers at {args.speedup:g}x", driven, time.perf_counter() - t0, hits))
    finally:
        for _, device in reversed(devices):
            device.close()
    print(f"{args.world} from {args.pose}, p3dx,p3dx,kobuki, frontier, coordinator {args.coordinator}")
    for label, r, wall, hits in rows:
        paths = ", ".join(f"{x['path_length_m']:.1f}" for x in r.robots)
        rr = r.robot_collisions if hits is None else sum(hits)
        print(f"  {label:<16} {r.reason}: coverage {r.coverage:.4f}, robot time {r.robot_time_s:.0f} s, "
              f"wall {wall:.0f} s, paths {paths} m, collisions {r.collisions} (robot-robot {rr}), "
              f"time to 95 % {r['time_to_coverage_95_s']}")
    print(f"records: {args.out / 'results.jsonl'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

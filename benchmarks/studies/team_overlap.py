"""Where a team's overlap comes from: the cells a robot's scans touch that a teammate's scans touched before,
split by what the robot was doing then.

For each start pose and coordinator, one team run of `--team` P3-DX robots with the frontier explorer on
`--world`; every cell a robot's scan touches for the first time (for that robot) that some teammate's scan
touched earlier is counted once (these are the cells that make `overlap_ratio`, each counted at its first
second robot) in one of:

- start: in the first `--start` seconds (the robots stand together where they start);
- transit: the robot's goal is farther than `--far` [m] (straight line) from it: it crosses the map;
- near: the robot is within `--far` of its goal, or has none;
- late: the team's map covers 95 % or more (the last frontiers, which draw every robot).

Also the seconds robots spent driving to a coordinator target none of whose cells is frontier any more
(`stale s`: sampled once a second). Prints a row per run and the sums per coordinator.

    python benchmarks/studies/team_overlap.py [--world dense] [--poses 1,2,3] [--coordinators none,burgard,minpos]
        [--team 4] [--start 15] [--far 3.0] [--max-time 1800]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np


def main() -> int:
    from robotexp.experiment import run_team
    from robotexp.run.observers import RunObserver
    from robotexp.run.spec import RunSpec
    from robotexp.run.team import TeamSpec

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--world", default="dense")
    ap.add_argument("--poses", default="1")
    ap.add_argument("--coordinators", default="none,burgard,minpos")
    ap.add_argument("--team", type=int, default=4)
    ap.add_argument("--start", type=float, default=15.0, help="[s] the start phase")
    ap.add_argument("--far", type=float, default=3.0, help="[m] a goal farther than this: in transit")
    ap.add_argument("--max-time", type=float, default=1800.0)
    ap.add_argument("--out", type=Path, default=Path("out/team_overlap"))
    args = ap.parse_args()

    class Tally(RunObserver):
        def __init__(self) -> None:
            self.mine: np.ndarray | None = None
            self.counts = {"start": 0, "transit": 0, "near": 0, "late": 0}
            self.stale = 0.0
            self.coverage = 0.0

        def on_robot_step(self, run: Any, robot: int, step: Any) -> None:
            if not step.map_updated:
                return
            bits = run.seen.bits
            if self.mine is None:
                self.mine = np.zeros_like(bits)
            grid = run.members[robot].grid
            box = grid.changed_box(grid.scans - 1)
            if box is None:
                return
            r0, r1, c0, c1 = box
            one = bits.dtype.type(1 << robot)
            now, before = bits[r0:r1, c0:c1], self.mine[r0:r1, c0:c1]
            new = ((now & one) != 0) & ((before & one) == 0)
            again = int(np.count_nonzero(new & ((before & ~one) != 0) & ((before & (before - 1)) == 0)))
            before |= now
            if again:
                self.counts[self._phase(run, robot)] += again

        def _phase(self, run: Any, robot: int) -> str:
            if run.robot_time < args.start:
                return "start"
            if self.coverage >= 0.95:
                return "late"
            m = run.members[robot]
            goal = getattr(m.explorer, "goal", None)
            p = m.state.true_pose or m.state.pose
            if goal is not None and math.hypot(goal[0] - p.x, goal[1] - p.y) > args.far:
                return "transit"
            return "near"

        def on_sample(self, run: Any, time: float, coverage: float | None) -> None:
            self.coverage = coverage or 0.0
            for m in run.members:
                cells = getattr(m.explorer, "assigned", None)
                if cells is None or len(cells) == 0 or m.end.value != "unknown":
                    continue
                mask, off = m.explorer.target_frontier(m.grid)
                local = cells - off
                ok = (local[:, 0] >= 0) & (local[:, 0] < mask.shape[0]) & (local[:, 1] >= 0) & \
                    (local[:, 1] < mask.shape[1])
                local = local[ok]
                if not mask[local[:, 0], local[:, 1]].any():
                    self.stale += 1.0

    print(f"{'coordinator':<12} {'pose':>4} {'overlap':>7} {'seen':>7} {'start':>6} {'transit':>7} {'near':>6} "
          f"{'late':>6} {'stale s':>7} {'t95 s':>6} {'cov':>6}")
    sums: dict[str, list[float]] = {}
    for pose in args.poses.split(","):
        spec = RunSpec(world=args.world, method="frontier", pose=None if pose == "default" else pose,
                       max_time=args.max_time)
        for name in args.coordinators.split(","):
            tally = Tally()
            out = run_team(spec, TeamSpec(robots=("p3dx",) * args.team, coordinator=name), args.out, image=False,
                           observers=[tally])
            r = out.record
            seen, several = out.run.seen.counts()
            c = tally.counts
            print(f"{name:<12} {pose:>4} {r.overlap_ratio:>7.3f} {seen:>7} {c['start'] / seen:>6.3f} "
                  f"{c['transit'] / seen:>7.3f} {c['near'] / seen:>6.3f} {c['late'] / seen:>6.3f} {tally.stale:>7.0f} "
                  f"{r.time_to_coverage_95_s or math.nan:>6.0f} {r.coverage:>6.4f}", flush=True)
            s = sums.setdefault(name, [0.0] * 5)
            for k, v in enumerate((c["start"] / seen, c["transit"] / seen, c["near"] / seen, c["late"] / seen,
                                   tally.stale)):
                s[k] += v
    n = len(args.poses.split(","))
    print("\nmeans: start, transit, near, late (shares of the cells seen), stale s")
    for name, s in sums.items():
        print(f"{name:<12} " + " ".join(f"{v / n:.3f}" for v in s[:4]) + f" {s[4] / n:.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

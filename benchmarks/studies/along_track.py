"""How far the localizer's estimate runs ahead of or falls behind the robot along its own motion.

A scan matcher that cannot see along a corridor should keep odometry's distance there; one that is pulled
along it by something in the map (the end of the walls mapped so far, for one) comes out short or long on
every metre. For each step of a run the true motion is projected on its own direction and compared with
the estimate's motion and odometry's length, and the differences are summed per `--bin` metres of path.

Run: python benchmarks/studies/along_track.py [--world MAPS/eb_loop.yaml] [--method frontier]
     [--localize scan-match] [--odometry p3dx] [--seed 0] [--laser-range 3] [--bin 10]

Prints one line per bin: metres driven, the estimate's along-track error and odometry's length error [m]
(negative: short). Nothing is recorded.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from robotexp.experiment import run_experiment
from robotexp.localization.robot import LocalizedRobot
from robotexp.run.spec import RunSpec


def along_errors(track: list, odometry: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per step with motion: (true length [m], the estimate's along-track error [m], odometry's length
    error [m]) from `LocalizedRobot.track` ((estimate, truth) pairs) and `LocalizedRobot.odometry`."""
    est = np.array([[p.x, p.y] for p, _ in track])
    true = np.array([[t.x, t.y] for _, t in track])
    odo = np.array([[p.x, p.y] for p in odometry])
    dt, de, do = np.diff(true, axis=0), np.diff(est, axis=0), np.diff(odo, axis=0)
    length = np.hypot(dt[:, 0], dt[:, 1])
    moved = length > 1e-4
    unit = dt[moved] / length[moved, None]
    along = np.sum(de[moved] * unit, axis=1) - length[moved]
    odo_err = np.hypot(do[moved, 0], do[moved, 1]) - length[moved]
    return length[moved], along, odo_err


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--world", default="dense")
    ap.add_argument("--method", default="frontier")
    ap.add_argument("--localize", default="scan-match", choices=["scan-match", "slam"])
    ap.add_argument("--odometry", default="p3dx")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--laser-range", type=float, default=3.0)
    ap.add_argument("--max-time", type=float, default=3600.0)
    ap.add_argument("--bin", type=float, default=10.0, help="[m] of path per line")
    args = ap.parse_args(argv)
    spec = RunSpec(world=args.world, method=args.method, odometry=args.odometry, localize=args.localize,
                   seed=args.seed, laser_range=args.laser_range, max_time=args.max_time)
    out = run_experiment(spec, None, image=False)
    robot = out.run.robot
    if not isinstance(robot, LocalizedRobot):
        print("the run was not localized", file=sys.stderr)
        return 2
    length, along, odo = along_errors(robot.track, robot.odometry)
    driven = np.cumsum(length)
    print(f"{out.record.get('run')}: ATE {out.record.get('ate_m')} m, {driven[-1]:.1f} m driven, estimate "
          f"{along.sum():+.3f} m along its motion, odometry {odo.sum():+.3f} m")
    print(f"{'path m':>12} {'estimate m':>11} {'odometry m':>11}")
    for a in np.arange(0.0, driven[-1], args.bin):
        k = (driven >= a) & (driven < a + args.bin)
        print(f"{a:5.0f}-{a + args.bin:<5.0f} {along[k].sum():+11.3f} {odo[k].sum():+11.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

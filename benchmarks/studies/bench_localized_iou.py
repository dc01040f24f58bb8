"""Where a localized run's map IoU goes: the map rebuilt from the same scans at other poses, split into
its occupied and free parts (dense, P3-DX preset, scan matching).

Run: python benchmarks/studies/bench_localized_iou.py [--world dense] [--method frontier] [--max-time 3600]
         [--speed 300] [--seed 0] [--offsets 0.002,0.02] [--loop-closure]
         [--window T0,T1]

One `--localize scan-match` run under the P3-DX odometry preset (the `robotexp explore` path), keeping
every step's scan, estimated pose, true pose and odometry. Printed, each as map IoU (the record's
`map_iou`, mean of the two parts) / occupied IoU / free IoU, for the explorer's map model:

- the run's own map, and the same scans integrated again at the estimated poses (equal when the map
  got the pose the localizer returned for each scan, nothing older, and the explorer marks no cells
  itself: srt-laser marks its safe regions, 0.003 of IoU);
- the same scans at the true poses (what the run would have mapped with a perfect pose, along the
  same path), and at the true poses moved by constant offsets (`--offsets`, metres in x and -y);
- the localizer replayed on the run's odometry and scans with an oracle matching map (each scan put
  into the matching map at its true pose): the matcher's own accuracy, without its map's drift;

- with `--loop-closure`, the optional stage of `robotexp map` on the run: keyframes every 0.3 m or 15 deg of
  the estimated path (the localizer's map updates), loop edges from `posegraph.find_loops` with the run's
  matcher (`RUN_MATCHER`, a 0.3 m / 3 deg window), each loop edge's error against the true relative pose,
  the keyframes' error before and after `posegraph.optimize`, and the scans rebuilt at the corrected poses
  (each step moved with its keyframe);

- with `--window T0,T1` [s], each match between those times replayed three ways: the run's (prediction and
  result), the same scan matched from the true pose against the localizer's own map (where that map puts
  the pose: its offset there), and from the prediction against an oracle map (each scan put in at its true
  pose: what the scan itself fixes);

and the pose error at the integrated scans (median, 90th percentile; heading while turning faster
than 0.5 rad/s and slower), and the error after the first 10 s (the first turn in place).
"""

from __future__ import annotations

import argparse
import copy
import math
import types
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.run.loop import ExplorationRun
from robotexp.localization import posegraph as PG
from robotexp.localization.matcher import Localizer, compose, relative, scan_points
from robotexp.localization.robot import RUN_MATCHER, LocalizedRobot
from robotexp.mapping.grid import OccupancyGrid
from robotexp.world.groundtruth import GroundTruth, map_iou, map_iou_parts
from robotexp.run.observers import RunObserver, StepEvent
from robotexp.robot import LaserScan, Pose


KEY_TRAVEL, KEY_TURN = 0.3, math.radians(15.0)      # [m], [rad]: keyframes as the localizer's map updates


@dataclass
class Step:
    """One control step of the run."""

    time: float
    pose: Pose               # what the map and the explorer got
    truth: Pose
    odometry: Pose
    scan: LaserScan
    turn_rate: float


@dataclass
class Recorder(RunObserver):
    """Keeps every step and the localizer as it was after the first scan (for replays)."""

    steps: list[Step] = field(default_factory=list)
    start: Localizer | None = None

    def on_step(self, run: ExplorationRun, event: StepEvent) -> None:
        """Keep the step."""
        robot = run.robot
        s = event.state
        if not isinstance(robot, LocalizedRobot) or s.laser is None or s.true_pose is None:
            return
        if self.start is None:
            self.start = copy.deepcopy(robot.localizer)
        self.steps.append(Step(event.time, s.pose, s.true_pose, robot.odometry[-1], s.laser, s.velocity.w))


def iou_parts(states: np.ndarray, gt: GroundTruth) -> tuple[float, float, float]:
    """(map IoU, occupied IoU, free IoU): `robotexp.world.groundtruth.map_iou` and its two halves."""
    occ, free = map_iou_parts(states, gt)
    mean = map_iou(states, gt)
    assert abs(mean - (occ + free) / 2) < 1e-12      # the same definition as the record's
    return mean, occ, free


def rebuild(grid: OccupancyGrid, scans: list[tuple[Pose, LaserScan]]) -> np.ndarray:
    """The states of a fresh grid like `grid` with `scans` integrated at their poses."""
    g = OccupancyGrid(grid.geo, model=grid.model, range_max=grid.range_max)
    for pose, scan in scans:
        g.update(pose, scan)
    return g.states()


def replay(start: Localizer, steps: list[Step], oracle: bool) -> list[Pose]:
    """The localizer from after the first scan, run again on the steps' odometry and scans; with `oracle`,
    each scan goes into its matching map at the true pose."""
    loc = copy.deepcopy(start)
    truth: list[Pose] = [steps[0].truth]
    if oracle:
        def integrate(self: Localizer, pose: Pose, scan: LaserScan) -> None:
            Localizer.integrate(self, truth[0], scan)
        loc.integrate = types.MethodType(integrate, loc)          # type: ignore[method-assign]
    poses = [steps[0].pose]
    for s in steps[1:]:
        truth[0] = s.truth
        poses.append(loc.locate(s.odometry, s.scan, s.turn_rate))
    return poses


def errors(poses: list[Pose], steps: list[Step]) -> dict[str, Any]:
    """Position and heading errors of `poses` against the steps' true poses."""
    e = np.array([math.hypot(p.x - s.truth.x, p.y - s.truth.y) for p, s in zip(poses, steps, strict=True)])
    th = np.degrees(np.abs([math.remainder(p.theta - s.truth.theta, 2 * math.pi)
                            for p, s in zip(poses, steps, strict=True)]))
    fast = np.abs([s.turn_rate for s in steps]) > 0.5
    return {"ate": float(np.sqrt(np.mean(e * e))), "median": float(np.median(e)), "p90": float(np.percentile(e, 90)),
            "heading": float(th.mean()), "heading_p90": float(np.percentile(th, 90)),
            "heading_fast": float(th[fast].mean()) if fast.any() else math.nan,
            "heading_slow": float(th[~fast].mean())}


def loop_closure(steps: list[Step]) -> tuple[list[Pose], str]:
    """`--loop-closure`: the run's keyframes through the pose graph; every step's pose corrected with its
    keyframe, and a line on the loop edges and the keyframes' error."""
    kf = [0]
    for i, s in enumerate(steps):
        d = relative(steps[kf[-1]].pose, s.pose)
        if math.hypot(d.x, d.y) >= KEY_TRAVEL or abs(d.theta) >= KEY_TURN:
            kf.append(i)
    est = np.array([[steps[i].pose.x, steps[i].pose.y, steps[i].pose.theta] for i in kf])
    truth = [steps[i].truth for i in kf]
    cfg = PG.LoopConfig(window_xy=0.3, window_theta=math.radians(3.0))
    loops = PG.find_loops(est, [steps[i].scan for i in kf], 0.05, RUN_MATCHER, cfg)
    chain = [PG.Edge(k, k + 1, relative(Pose(*est[k]), Pose(*est[k + 1])), np.diag([0.005 ** -2, 0.005 ** -2,
                                                                                    math.radians(0.1) ** -2]))
             for k in range(len(est) - 1)]
    wrong = np.array([math.hypot(e.z.x - t.x, e.z.y - t.y) for e in loops
                      for t in [relative(truth[e.i], truth[e.j])]]) * 100
    out = PG.optimize(est, chain + loops, iterations=cfg.iterations, cauchy=cfg.cauchy)
    poses, j = [], 0
    for i, s in enumerate(steps):
        while j + 1 < len(kf) and kf[j + 1] <= i:
            j += 1
        poses.append(compose(Pose(*out[j]), relative(Pose(*est[j]), s.pose)))

    def rmse(p: np.ndarray) -> float:
        return float(np.sqrt(np.mean([(a[0] - t.x) ** 2 + (a[1] - t.y) ** 2 for a, t in zip(p, truth, strict=True)])))
    note = (f"{len(kf)} keyframes, {len(loops)} loop edges (error against the true relative pose: median "
            f"{np.median(wrong):.2f} cm, p90 {np.percentile(wrong, 90):.2f} cm, max {wrong.max():.1f} cm); "
            f"keyframe ATE {rmse(est) * 100:.2f} cm before, {rmse(out) * 100:.2f} cm after") if loops else \
        f"{len(kf)} keyframes, no loop edge"
    return poses, note


def window(start: Localizer, steps: list[Step], t0: float, t1: float) -> None:
    """`--window`: the matches between t0 and t1 [s] replayed three ways (see the module docstring)."""
    loc, oracle = copy.deepcopy(start), copy.deepcopy(start)
    truth: list[Pose] = [steps[0].truth]

    def integrate(self: Localizer, pose: Pose, scan: LaserScan) -> None:
        Localizer.integrate(self, truth[0], scan)
    oracle.integrate = types.MethodType(integrate, oracle)          # type: ignore[method-assign]
    prior = (0.02, math.radians(0.5))
    print(f"matches between {t0:g} and {t1:g} s: errors against the true pose, (x, y) mm and heading deg")
    for s in steps[1:]:
        if s.time > t1:
            break
        truth[0] = s.truth
        before = copy.deepcopy(loc) if s.time >= t0 else None
        pose = loc.locate(s.odometry, s.scan, s.turn_rate)
        pred = oracle.predict(s.odometry) if before is None else before.predict(s.odometry)
        oracle_before = copy.deepcopy(oracle) if before is not None else None
        oracle.locate(s.odometry, s.scan, s.turn_rate)
        if before is None or oracle_before is None or loc.status not in ("matched", "degenerate"):
            continue
        px, py = scan_points(s.scan, before.matcher.config.range_max)
        own = before.matcher.match(before.grid.values, before.grid.geo, px, py, s.truth, before.hits,
                                   before.grid.stamp, prior).pose
        ora = oracle_before.matcher.match(oracle_before.grid.values, oracle_before.grid.geo, px, py, pred,
                                          oracle_before.hits, oracle_before.grid.stamp, prior).pose

        def off(q: Pose, t: Pose = s.truth) -> str:
            return f"({(q.x - t.x) * 1000:+6.1f}, {(q.y - t.y) * 1000:+6.1f}) {math.degrees(q.theta - t.theta):+.2f}"
        print(f"  {s.time:6.1f} s {loc.status:10s} prediction {off(pred)} -> run {off(pose)} | own map from the truth "
              f"{off(own)} | oracle map from the prediction {off(ora)}")


def main() -> None:
    """Run, rebuild, print."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="dense")
    ap.add_argument("--method", default="frontier")
    ap.add_argument("--speed", type=float, default=300.0, help="[mm/s]")
    ap.add_argument("--max-time", type=float, default=3600.0, help="[s] robot time")
    ap.add_argument("--laser-range", type=float, default=3.0, help="[m]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--odometry", default="p3dx", help="an --odometry-error spec")
    ap.add_argument("--offsets", default="0.002,0.02", help="constant offsets [m] of the true poses, comma-separated")
    ap.add_argument("--loop-closure", action="store_true", help="also the run's keyframes through the pose graph")
    ap.add_argument("--window", default=None, metavar="T0,T1", help="[s] replay the matches between these times")
    args = ap.parse_args()
    offsets = [float(v) for v in args.offsets.split(",") if v]
    rec = Recorder()
    spec = RunSpec(world=args.world, method=args.method, speed=args.speed / 1000, laser_range=args.laser_range,
                   seed=args.seed, max_time=args.max_time, odometry=args.odometry, localize="scan-match")
    out = run_experiment(spec, None, observers=[rec], image=False)
    run = out.run
    gt = run.truth
    assert gt is not None and rec.start is not None
    steps = rec.steps
    print(f"{args.world} {args.method} {args.speed:g} mm/s, P3-DX preset + scan matching: coverage "
          f"{out.record['coverage']:.4f}, map IoU {out.record['map_iou']:.4f}, ATE {out.record['ate_m']:.4f} m "
          f"(sampled every second), {len(steps)} scans, {out.record['robot_time_s']:.0f} s")
    print(f"{'map':58s} {'IoU':>7s} {'occ':>7s} {'free':>7s}")

    def line(name: str, states: np.ndarray) -> None:
        print(f"{name:58s} {'%7.4f %7.4f %7.4f' % iou_parts(states, gt)}", flush=True)

    line("the run's map", run.grid.states())
    line("its scans at the estimated poses", rebuild(run.grid, [(s.pose, s.scan) for s in steps]))
    line("its scans at the true poses", rebuild(run.grid, [(s.truth, s.scan) for s in steps]))
    for d in offsets:
        line(f"... the true poses moved by ({d * 1000:g}, {-d * 1000:g}) mm",
             rebuild(run.grid, [(Pose(s.truth.x + d, s.truth.y - d, s.truth.theta), s.scan) for s in steps]))
    oracle = replay(rec.start, steps, oracle=True)
    line("localizer replayed with an oracle matching map", rebuild(run.grid, [(p, s.scan) for p, s in
                                                                              zip(oracle, steps, strict=True)]))
    if args.window:
        t0, t1 = (float(v) for v in args.window.split(","))
        window(rec.start, steps, t0, t1)
    if args.loop_closure:
        closed, note = loop_closure(steps)
        line("keyframes through the pose graph (--loop-closure)",
             rebuild(run.grid, [(p, s.scan) for p, s in zip(closed, steps, strict=True)]))
        print(f"  {note}")
    first = next((i for i, s in enumerate(steps) if s.time >= 10.0), len(steps) - 1)
    for name, poses in (("run", [s.pose for s in steps]), ("oracle-map replay", oracle)):
        e = errors(poses, steps)
        print(f"{name} pose error at every integrated scan: ATE {e['ate'] * 100:.2f} cm, median {e['median'] * 100:.2f}"
              f" cm, p90 {e['p90'] * 100:.2f} cm; heading mean {e['heading']:.3f} deg (p90 {e['heading_p90']:.3f}), "
              f"turning > 0.5 rad/s {e['heading_fast']:.3f}, slower {e['heading_slow']:.3f}")
        p, t = poses[first], steps[first].truth
        print(f"  at {steps[first].time:.1f} s (after the first turn): ({(p.x - t.x) * 100:+.2f}, "
              f"{(p.y - t.y) * 100:+.2f}) cm, {math.degrees(math.remainder(p.theta - t.theta, 2 * math.pi)):+.3f} deg")


if __name__ == "__main__":
    main()

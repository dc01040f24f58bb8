"""Localization in the run loop: `localized` puts a `LocalizedRobot` between the robot and the explorer
when a run asks for it, and `TrajectoryTracker` writes `ate_m` (and how the matches went) into every
record.

`RunSpec.localize`: "none" (the explorer and the map get the robot's own pose), "scan-match"
(the corrected pose), "slam" (scan matching with online loop closure, `robotexp.localization.online`: the
run's map is rebuilt from the corrected keyframes when a loop closes, `LoopClosureTracker`), or "auto": scan
matching in the simulator when its odometry error is on
(`RunSpec.odometry`), and on every other robot (a real robot's odometry always errs: the P3-DX's
unequal wheels, the Kobuki's slip).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING


import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.localization.correction import FrameCorrection
from robotexp.localization.matcher import compose, relative
from robotexp.localization.online import ScanBins, shifts
from robotexp.localization.robot import MAX_TURN_RATE, LocalizedRobot
from robotexp.mapping.geometry import GridGeometry
from robotexp.run.observers import RunObserver, StepEvent
from robotexp.robot import LaserScan, Pose, Robot, wrap_angle

if TYPE_CHECKING:
    from robotexp.run.spec import RunSpec
    from robotexp.run.loop import ExplorationRun

__all__ = ["LOCALIZE_MODES", "MATCH_CELL", "check_localize", "localized", "release", "TrajectoryTracker",
           "LoopClosureTracker"]

LOCALIZE_MODES = ("auto", "none", "scan-match", "slam")
# the memory bound of the scans the run's map is rebuilt from (`LoopClosureTracker`): 4 of each 0.5 m square and
# 45 deg sector of the poses they were taken at, those farthest apart
SCANS_PER_BIN, SCAN_BIN_XY, SCAN_BIN_THETA = 4, 0.5, math.radians(45.0)
REBUILD_TOL = 0.25   # [cells] a keyframe this far from where the map has it is mapped again at a rebuild
MATCH_CELL = 0.05     # [m] cells of the localizer's matching map (the explorer's may be coarser)
# the run's log-odds map when it is built at the estimated pose: a beam that crossed a cell counts logit(0.3),
# 0.39 of a hit's logit(0.9) (at the exact pose logit(0.1), as much), as OctoMap's defaults weigh a miss about
# half a hit. With misses as strong as hits, the one-cell walls of a map seen from poses a few centimetres off
# kept gaps (docs/how-to/localization.md: the five real maps)
MAP_P_FREE = 0.3


def check_localize(mode: str) -> None:
    """Raise ConfigError unless `mode` is one of LOCALIZE_MODES."""
    if mode not in LOCALIZE_MODES:
        raise ConfigError(f"--localize must be one of {', '.join(LOCALIZE_MODES)}, got {mode!r}")


def wants_localizer(spec: RunSpec, robot: Robot) -> bool:
    """True when a run of `spec` on `robot` gets the scan-matching localizer (`spec.localize`, "auto" as
    the module says)."""
    from robotexp.sim import SimRobot, odometry_error

    if spec.localize != "auto":
        return spec.localize in ("scan-match", "slam")
    if isinstance(robot, SimRobot):
        return odometry_error(spec.odometry).active
    return True


def release(robot: Robot) -> None:
    """After the run: a `LocalizedRobot` made by `localized` is done (marked closed; the robot it wraps
    stays open, as `run_on_robot` leaves it)."""
    if isinstance(robot, LocalizedRobot):
        robot.detach()


class TrajectoryTracker(RunObserver):
    """Samples (the pose the explorer gets, the true pose) at every coverage sample and keeps the
    record's `ate_m` [m] (RMSE, no alignment; None without ground truth), `localize`, `odometry_error`
    and, with a localizer, `matches` (its outcome counts) in `run.info.extra`."""

    def __init__(self, localize: str, odometry: str, robot: LocalizedRobot | None) -> None:
        self.localize, self.odometry, self.robot = localize, odometry, robot
        self.pairs: list[tuple[float, float, float, float]] = []
        self._sq = 0.0

    def on_start(self, run: ExplorationRun) -> None:
        """Name the settings in the record."""
        run.info.extra.update({"localize": self.localize, "odometry_error": self.odometry, "ate_m": None})

    def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
        """Add the current pair and refresh `ate_m`."""
        s = run.state
        if s is not None and s.true_pose is not None:
            self.pairs.append((s.pose.x, s.pose.y, s.true_pose.x, s.true_pose.y))
            # the running RMSE (`metrics.ate` over the pairs, without recomputing it at every sample)
            self._sq += (s.pose.x - s.true_pose.x) ** 2 + (s.pose.y - s.true_pose.y) ** 2
            value = math.sqrt(self._sq / len(self.pairs))
            run.info.extra["ate_m"] = round(value, 4) if math.isfinite(value) else None
        if self.robot is not None:
            run.info.extra["matches"] = dict(self.robot.localizer.counts)


class LoopClosureTracker(TrajectoryTracker):
    """`TrajectoryTracker` for "slam": keeps every scan the run's map took, attached to the localizer's latest
    keyframe by its pose relative to it, and when loop closure has corrected the keyframes (`OnlineGraph.rebuilds`
    counted up) rebuilds the run's map from all of them at the corrected poses and tells the explorer
    (`Explorer.map_rebuilt`). The record's `loop_closure` says how it went (keyframes, loop edges, rebuilds,
    the back end, its median update time [ms], the rebuilds' total time [s]).

    The map is rebuilt only once some keyframe has moved by half a cell of it (or turned by as much at the
    laser's range) from where the map has it, and only in the box the moved keyframes' scans reach (`_rebuild`):
    outside it the map keeps what the scans the memory bound has dropped put there. A box of more than half the
    map (an 8 m laser on a 20 m map) rebuilds the whole map from the kept scans, and walls only dropped scans
    had seen are lost there (see the memory bound below).

    A scan is kept as float32 ranges (a 181-beam scan: 724 bytes; its beam angles shared with the scan before
    when equal), and only while it is among the SCANS_PER_BIN of its pose's bin (SCAN_BIN_XY square,
    SCAN_BIN_THETA sector) whose positions lie farthest apart (`ScanBins` with `spread`): the scans kept are
    bounded by the area explored, at most 128 a square metre (93 kB of 181-beam scans), not by the run's length
    (at 10 Hz, 26 MB an hour without the bound). Keeping the newest 4 of a bin instead (the last 12 cm of the
    path through it), the map rebuilt whole on eb_loop (srt-laser, P3-DX preset, seed 3) lost the wall faces
    only the dropped scans had seen at grazing range: tolerant map IoU 0.953 (0.977 with the rebuilds left out,
    at the same ATE 0.027 m) against 1.000 with the spread bins."""

    def __init__(self, localize: str, odometry: str, robot: LocalizedRobot) -> None:
        super().__init__(localize, odometry, robot)
        self.slam = robot
        self.scans: dict[int, tuple[int, Pose, npt.NDArray[np.float32], npt.NDArray[np.float64], float, float]] = {}
        self.bins = ScanBins(SCANS_PER_BIN, SCAN_BIN_XY, SCAN_BIN_THETA, spread=True)
        self._count = 0                           # scans seen
        self.rebuilds = 0                         # the graph's corrections seen
        self.map_rebuilds = 0                     # the run's map rebuilt
        self.rebuild_time = 0.0
        self._angles: npt.NDArray[np.float64] | None = None
        self._built = np.zeros((0, 3))            # the keyframes' poses the map was last built at
        self._reported = -1                       # the keyframes counted in the record
        # the frames of the poses the explorer was given: from robot time t on, poses relative to keyframe k
        # sat where the explorer's coordinates have k at `frame` (the keyframe's `local`, then its pose at
        # each rebuild); `FrameCorrection` of a rebuild moves each by where k is now
        self._seg_t: list[float] = []
        self._seg_kf: list[int] = []
        self._seg_frame: list[Pose] = []
        self._seg_key: tuple[int, Pose] | None = None

    def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
        """Keep the scan the map took; rebuild the map when the keyframes were corrected."""
        graph = self.slam.graph
        laser = step.state.laser
        if graph is None:
            return
        if self.slam.keyframe >= 0:
            kf = graph.keyframes[self.slam.keyframe]
            if self._seg_key != (self.slam.keyframe, kf.local):     # a new keyframe, or a correction applied
                self._seg_key = (self.slam.keyframe, kf.local)
                self._seg_t.append(step.state.time)
                self._seg_kf.append(self.slam.keyframe)
                self._seg_frame.append(kf.local)
        if step.map_updated and laser is not None and self.slam.keyframe >= 0:
            kf = graph.keyframes[self.slam.keyframe]
            angles = np.asarray(laser.angles, np.float64)
            if self._angles is not None and self._angles.shape == angles.shape and np.array_equal(self._angles, angles):
                angles = self._angles
            self._angles = angles
            self.scans[self._count] = (self.slam.keyframe, relative(kf.local, step.state.pose),
                                       np.asarray(laser.ranges, np.float32), angles, laser.range_max, laser.offset_x)
            drop = self.bins.add(self._count, step.state.pose)
            if drop is not None:
                del self.scans[drop]
            self._count += 1
        if graph.rebuilds != self.rebuilds:
            self.rebuilds = graph.rebuilds
            if self._moved(run.grid.geo.cell / 2, graph.poses(), laser.range_max if laser is not None else 8.0):
                self._rebuild(run)
        if len(graph.keyframes) != self._reported:
            self._reported = len(graph.keyframes)
            median = graph.update_median
            run.info.extra["loop_closure"] = {
                "keyframes": len(graph.keyframes), "loops": graph.loops, "tried": graph.tried,
                "refused": dict(graph.refused), "corridor_loops": graph.corridor_loops,
                "rebuilds": graph.rebuilds, "map_rebuilds": self.map_rebuilds,
                "scans_kept": len(self.scans), "keyframe_scans_kept": len(graph.keyframes) - graph.bins.dropped,
                "backend": graph.backend,
                "update_ms": round(1e3 * median, 3) if median is not None else None,
                "rebuild_s": round(self.rebuild_time, 3)}

    def _map_poses(self, n: int) -> npt.NDArray[np.float64]:
        """(n, 3) where the run's map has each keyframe's scans: its pose at the last rebuild that moved it, else
        where the localizer had it when its scans were mapped (its `local` pose)."""
        graph = self.slam.graph
        assert graph is not None
        out = np.empty((n, 3))
        m = min(len(self._built), n)
        out[:m] = self._built[:m]
        for k in range(m, n):
            loc = graph.keyframes[k].local
            out[k] = (loc.x, loc.y, loc.theta)
        return out

    def _moved(self, tol: float, poses: npt.NDArray[np.float64], reach: float) -> bool:
        """True when a keyframe lies `tol` [m] or more from where the map has it (a turn counts at `reach`)."""
        if len(poses) == 0:
            return False
        return bool(shifts(poses, self._map_poses(len(poses)), reach).max() >= tol)

    def _rebuild(self, run: ExplorationRun) -> None:
        """Map the kept scans again at their keyframes' corrected poses where keyframes moved (`REBUILD_TOL` of
        a cell or more): the box their scans reach at both poses is mapped again, in order, into a grid of the
        box alone, which replaces the box's cells; outside it the map keeps what it had, the scans the memory
        bound has since dropped included. A box of more than half the map: the whole map is rebuilt from the
        kept scans."""
        import time

        graph = self.slam.graph
        assert graph is not None
        t0 = time.perf_counter()
        grid = run.grid
        geo = grid.geo
        poses = graph.poses()
        old = self._map_poses(len(poses))
        reach = max((v[4] + abs(v[5]) for v in self.scans.values()), default=0.0) + geo.cell
        moved = np.flatnonzero(shifts(poses, old, reach) >= REBUILD_TOL * geo.cell)
        kept = [(compose(graph.keyframes[k].pose, rel), ranges, angles, rmax, off)
                for k, rel, ranges, angles, rmax, off in self.scans.values()]
        box = geo.reach_box(np.vstack([poses[moved, :2], old[moved, :2]]), reach) if len(moved) else None
        if box is not None and (box[1] - box[0]) * (box[3] - box[2]) > geo.rows * geo.cols / 2:
            box = None
        if box is None:                       # the whole map, from the kept scans
            grid.values[...] = 0
            grid.stamp[...] = 0
            for pose, ranges, angles, rmax, off in kept:
                grid.update(pose, LaserScan(angles, ranges.astype(np.float64), rmax, off))
            old = poses
        else:
            part = geo.part(box)
            sub = grid.blank(part)
            x0, x1 = part.origin_x - reach, part.origin_x + part.width + reach
            y0, y1 = part.origin_y - reach, part.origin_y + part.height + reach
            for pose, ranges, angles, rmax, off in kept:
                if x0 <= pose.x <= x1 and y0 <= pose.y <= y1:
                    sub.update(pose, LaserScan(angles, ranges.astype(np.float64), rmax, off))
            grid.replace_box(box[0], box[2], sub)
            old[moved] = poses[moved]
        self.rebuild_time += time.perf_counter() - t0
        self._built = old
        self.map_rebuilds += 1
        run.explorer.map_rebuilt(grid, self._correction())

    def _correction(self) -> FrameCorrection:
        """Where the explorer's coordinates move at this rebuild (`FrameCorrection`); the frames advance to it."""
        graph = self.slam.graph
        assert graph is not None
        if not self._seg_t:
            return FrameCorrection.identity()
        moves = np.empty((len(self._seg_t), 3))
        for i, (k, old) in enumerate(zip(self._seg_kf, self._seg_frame, strict=True)):
            new = graph.keyframes[k].pose
            dth = wrap_angle(new.theta - old.theta)
            c, s = math.cos(dth), math.sin(dth)
            moves[i] = (new.x - (c * old.x - s * old.y), new.y - (s * old.x + c * old.y), dth)
            self._seg_frame[i] = new
        return FrameCorrection(self._seg_t, moves)


def localized(spec: RunSpec, robot: Robot, geo: GridGeometry) -> tuple[Robot, TrajectoryTracker]:
    """The robot the run loop should read (`robot`, or it wrapped in a `LocalizedRobot` whose matching map
    covers `geo` in MATCH_CELL cells) and the observer that records the trajectory error."""
    check_localize(spec.localize)
    if not wants_localizer(spec, robot):
        return robot, TrajectoryTracker("none", spec.odometry, None)
    mgeo = GridGeometry.covering(geo.origin_x, geo.origin_y, geo.origin_x + geo.width, geo.origin_y + geo.height,
                                 MATCH_CELL)
    from robotexp.sim import SimRobot

    turn = math.inf if isinstance(robot, SimRobot) else MAX_TURN_RATE     # real scans lag odometry a little
    slam = spec.localize == "slam"
    wrapped = LocalizedRobot(robot, mgeo, range_max=spec.laser_range, max_turn_rate=turn, loop_closure=slam)
    if slam:
        return wrapped, LoopClosureTracker("slam", spec.odometry, wrapped)
    return wrapped, TrajectoryTracker("scan-match", spec.odometry, wrapped)

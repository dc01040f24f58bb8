"""Online loop closure: keyframes, a pose graph optimised incrementally during the run, and loop edges
found by matching the current scan against a submap of an earlier part of the path.

`OnlineGraph` sits beside a `Localizer`. Every scan the localizer puts into its matching map (its map
update thresholds: 0.3 m or 15 deg of motion in whole runs) becomes a keyframe: the corrected pose,
the scan, the odometry and the path length so far. Consecutive keyframes are joined by a sequential edge
(their relative corrected pose; its information from how the scan was matched). When a keyframe lies
within `radius` of a keyframe at least `min_path` metres back along the path, the scan is matched
against a submap of the old keyframes around it (`posegraph._submap`); a good, well-conditioned match
whose correction lies within the gate of the drift the path between them can have adds a loop edge,
weighted by a Cauchy kernel (a wrong edge pulls little). The graph is optimised by GTSAM's iSAM2 when
`gtsam` can be imported (an update per `isam_batch` keyframes or loop edge: a fraction of a millisecond a
keyframe), else by the sparse
Gauss-Newton of `posegraph.optimize` after each loop edge. When a loop edge moves the current keyframe
by more than `apply_xy` or `apply_theta`, the correction is applied: the localizer's pose moves with its
keyframe and its matching map is rebuilt from the keyframes at their corrected poses, and `rebuilds`
counts up (the run's map follows: `robotexp.run.localize.LoopClosureTracker`).
"""

from __future__ import annotations

import bisect
import math
import time
from collections import deque
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.localization.matcher import (HitMap, Localizer, Match, MatcherConfig, ScanMatcher, compose, relative,
                                          scan_points)
from robotexp.localization.posegraph import Edge, _submap, optimize
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import LaserScan, Pose, wrap_angle

__all__ = ["OnlineLoopConfig", "OnlineGraph", "Keyframe", "ScanBins", "have_gtsam"]


def have_gtsam() -> bool:
    """True when GTSAM's Python module can be imported (the iSAM2 back end)."""
    try:
        import gtsam  # noqa: F401  # optional: the `slam` extra
    except ImportError:
        return False
    return True


@dataclass(frozen=True)
class OnlineLoopConfig:
    """Settings of online loop closure (SI units).

    Attributes:
        radius: [m] a loop is tried with the nearest keyframe whose estimated position lies within this ...
            (5 m: a laser that reaches 3-8 m sees an old part of the map from farther than 2.5 m, the radius
            before the loop match was scored on the seen part alone, see `min_score`)
        min_path: [m] ... and at least this far back along the path.
        every: try a loop at every `every`-th keyframe.
        submap: keyframes on each side of the old keyframe that make its submap.
        gate_xy: (a [m], b [m/m]): a loop match may move the current pose by at most a + b * the path
            length between the two keyframes (the drift scan matching can have made), capped by `cap_xy`;
            the matcher searches that window, and a match outside it is refused.
        gate_theta: (a [rad], b [rad/m]) the same for heading, capped by `cap_theta`.
        cap_xy: [m] the widest position gate.
        cap_theta: [rad] the widest heading gate.
        min_points: a loop match needs this many scan points ...
        min_score: ... this mean field value (0.95. With 0.8, dense bvp (P3-DX preset, seed 0) took 659 loop
            edges, 45 of them 5-116 cm off the true relative pose (their matches scored 0.92 median, the right
            ones' 0.99), and loop closure made its ATE 0.068 m against 0.026 m without it; with 0.95: 0.028 m.
            With 0.6 and loop edges of 5 cm and 0.5 deg, dense frontier's ATE was 0.065 m), the points that fall
            on cells the submap never saw left out (`MatcherConfig.drop_unseen`: a scan that reaches past what
            the old keyframes saw scored low at the right pose, and 206 of the 265 loop matches of a dense
            frontier run were refused as poor) ...
        min_conditioning: ... and this conditioning (not along a corridor, where it can slide).
        corridor_slide: [m] a loop match under `min_conditioning` (a corridor) that moved the pose more than this
            along the corridor is refused: along it the scan fixes nothing, and a long slide is its few features
            (a door frame, a bump) fitted to others (dense frontier, P3-DX preset, seed 1, loops tried from
            2.5 m: a match with conditioning 0.04 slid 0.73 m, and its loop edge took the ATE from 0.05 to 0.16 m).
        seq_xy: (a [m], b [m/m]) standard deviation of a sequential edge's position after d metres
            of motion: a + b d (a matched scan; `weak` times as much for an unmatched or degenerate one).
        seq_theta: (a [rad], b [rad/m], c [rad/rad]) heading: a + b d + c |turn|. (Twice these, 1 cm + 2 % and
            0.25 deg + 0.5 deg/m, let loop edges bend the scan-matched chain: dense bvp ATE 0.092 m against
            0.068 m, the ring corridor eb_loop 0.66 m against 0.58 m, frontier, P3-DX preset, seed 0.)
        weak: the factor of an edge whose scan was not matched well.
        loop_xy: [m] standard deviation of a loop edge's position.
        loop_theta: [rad] the same for heading.
        cauchy: [standard deviations] the scale of the Cauchy kernel on loop edges.
        jump_xy: [m] a localizer correction larger than this in one match is a jump (see `OnlineGraph.step`) ...
        jump_theta: [rad] ... or larger than this. Off by default: on `dense` (frontier, P3-DX preset, seed 0)
            5 cm and 1.5 deg took the ATE from 0.065 to 0.133 m (legitimate corrections after turns left out).
        apply_xy: [m] a correction of the current pose larger than this is applied (the localizer's pose and
            matching map, the run's map) ...
        apply_theta: [rad] ... or larger than this.
        corridor_edges: a loop match that fixes the position across a corridor but not along it becomes a loop
            edge weak along it (`cap_xy`); off: such matches are refused.
        backend: "isam2", "sparse" (`posegraph.optimize` after each loop edge) or "auto" (iSAM2 when
            gtsam can be imported).
        rebuild_xy: [m] when a correction is applied, the matching map is rebuilt only where a keyframe moved by
            more than this (or turned by as much at the laser's reach) since its scan was put in (`_rebuild`).
        scans_per_bin: the memory bound: keyframes keep their scans only while they are among the newest
            `scans_per_bin` whose pose fell in the same `bin_xy` square and `bin_theta` sector (`ScanBins`);
            the older ones keep their node in the graph and drop the scan. 0: every scan kept.
        bin_xy: [m] the side of a bin ...
        bin_theta: [rad] ... and its heading sector.
        isam_batch: new keyframes go to iSAM2 this many at a time (at once when a loop edge comes: `_Isam2`).
    """

    radius: float = 5.0
    min_path: float = 6.0
    every: int = 2
    submap: int = 8
    gate_xy: tuple[float, float] = (0.15, 0.05)
    gate_theta: tuple[float, float] = (math.radians(2.0), math.radians(0.5))
    cap_xy: float = 1.5
    cap_theta: float = math.radians(12.0)
    min_points: int = 60
    min_score: float = 0.95
    min_conditioning: float = 0.2
    corridor_slide: float = 0.15
    seq_xy: tuple[float, float] = (0.005, 0.01)
    seq_theta: tuple[float, float, float] = (math.radians(0.1), math.radians(0.25), 0.01)
    weak: float = 4.0
    loop_xy: float = 0.02
    loop_theta: float = math.radians(0.3)
    cauchy: float = 3.0
    jump_xy: float = math.inf
    jump_theta: float = math.inf
    apply_xy: float = 0.01
    apply_theta: float = math.radians(0.2)
    corridor_edges: bool = True
    backend: str = "auto"
    rebuild_xy: float = 0.002
    scans_per_bin: int = 4
    bin_xy: float = 0.5
    bin_theta: float = math.radians(45.0)
    isam_batch: int = 8

    def __post_init__(self) -> None:
        if self.backend not in ("auto", "isam2", "sparse"):
            raise ConfigError(f"loop closure: backend must be auto, isam2 or sparse, got {self.backend!r}")
        if min(self.every, self.min_points, self.isam_batch) < 1 or self.submap < 0 or self.scans_per_bin < 0:
            raise ConfigError(f"loop closure: every, min_points, isam_batch >= 1 and submap, scans_per_bin >= 0 "
                              f"expected, got {self}")
        if not (self.bin_xy > 0 and self.bin_theta > 0 and self.rebuild_xy >= 0):
            raise ConfigError(f"loop closure: bin_xy, bin_theta > 0 and rebuild_xy >= 0 expected, got {self}")
        if not (self.radius > 0 and self.min_path > 0 and self.loop_xy > 0 and self.loop_theta > 0
                and self.cauchy > 0 and self.seq_xy[0] > 0 and self.seq_theta[0] > 0 and self.weak > 0):
            raise ConfigError(f"loop closure: radius, min_path, sigmas and cauchy must be > 0, got {self}")


def shifts(poses: npt.NDArray[np.float64], old: npt.NDArray[np.float64], reach: float) -> npt.NDArray[np.float64]:
    """[m] how far each of the (n, 3) `poses` lies from its row of `old`: the larger of the position's move and the
    turn at `reach` [m] (how far a scan point that far away moved)."""
    d = np.hypot(poses[:, 0] - old[:, 0], poses[:, 1] - old[:, 1])
    turn = np.abs((poses[:, 2] - old[:, 2] + np.pi) % (2 * np.pi) - np.pi) * reach
    return np.maximum(d, turn)


def _weak(h: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """The unit vector (world frame) of the weak direction of the translation block of the normal matrix `h`:
    the direction a corridor's scan does not fix."""
    _, vecs = np.linalg.eigh(np.asarray(h, np.float64)[:2, :2])
    return vecs[:, 0]


class ScanBins:
    """The scan memory bound: each scan is filed under its pose's bin (an `xy` [m] square, a `theta` [rad]
    sector), and a bin keeps `per_bin` of them; `add` names the scan a new one pushes out. The scans kept
    are then at most `per_bin` times the bins the robot's poses fell in: bounded by the explored area (its
    square metres / xy^2 times 2 pi / theta sectors), not by the run's length.

    Which ones a bin keeps: the newest (`spread` False), or (`spread` True) those whose positions lie farthest
    apart: a new scan pushes out the older of the two closest, so the bin keeps views from across its square,
    not from the last few centimetres of the path through it (a robot at 0.3 m/s and 10 Hz takes ~17 scans
    in a 0.5 m bin; the newest 4 lie within 12 cm)."""

    def __init__(self, per_bin: int, xy: float, theta: float, *, spread: bool = False) -> None:
        self.per_bin, self.xy, self.theta = per_bin, xy, theta
        self.spread = spread
        self.bins: dict[tuple[int, int, int], deque[int]] = {}
        self.dropped = 0
        self._where: dict[int, tuple[float, float]] = {}     # the kept scans' positions (with `spread`)

    def add(self, key: int, pose: Pose) -> int | None:
        """File scan `key` taken at `pose`; the key of the scan it pushes out of its bin, or None."""
        if self.per_bin <= 0:
            return None
        b = (math.floor(pose.x / self.xy), math.floor(pose.y / self.xy),
             math.floor(wrap_angle(pose.theta) / self.theta))
        q = self.bins.setdefault(b, deque())
        q.append(key)
        if self.spread:
            self._where[key] = (pose.x, pose.y)
        if len(q) <= self.per_bin:
            return None
        self.dropped += 1
        if not self.spread:
            return q.popleft()
        keys = list(q)                        # oldest first
        best, drop = math.inf, keys[0]
        for i, a in enumerate(keys):
            ax, ay = self._where[a]
            for c in keys[i + 1:]:
                d = math.hypot(self._where[c][0] - ax, self._where[c][1] - ay)
                if d < best:
                    best, drop = d, a
        q.remove(drop)
        del self._where[drop]
        return drop


class Keyframe:
    """A keyframe: its pose (the graph's estimate), the scan taken there (None once dropped by the scan bound,
    `OnlineLoopConfig.scans_per_bin`), the odometry reading, the path length [m] of corrected motion from the
    start, how its scan was matched, and `local`: its pose in the localizer's frame (the localizer's poses
    after it are relative to that one; equal to `pose` after a correction was applied)."""

    __slots__ = ("_poses", "index", "scan", "odom", "path", "status", "local")

    def __init__(self, poses: _PoseArray, index: int, scan: LaserScan | None, odom: Pose, path: float, status: str,
                 local: Pose) -> None:
        self._poses, self.index = poses, index
        self.scan, self.odom, self.path, self.status, self.local = scan, odom, path, status, local

    @property
    def pose(self) -> Pose:
        """The graph's estimate of this keyframe."""
        x, y, th = self._poses.a[self.index]
        return Pose(float(x), float(y), float(th))

    @pose.setter
    def pose(self, pose: Pose) -> None:
        self._poses.a[self.index] = (pose.x, pose.y, pose.theta)


class _PoseArray:
    """(n, 3) poses in an array that grows by doubling (`a` is a view of the first n rows)."""

    def __init__(self) -> None:
        self._buf = np.zeros((64, 3))
        self.a = self._buf[:0]

    def append(self, row: tuple[float, float, float]) -> None:
        n = len(self.a)
        if n == len(self._buf):
            self._buf = np.concatenate([self._buf, np.zeros_like(self._buf)])
        self._buf[n] = row
        self.a = self._buf[:n + 1]


class _Isam2:
    """The iSAM2 back end: Pose2 keys 0..n-1, a tight prior on node 0. New keyframes and their sequential edges
    wait until `batch` of them are due, or a loop edge comes (`add`), and go to iSAM2 in one update: until a loop
    edge joins them, the estimate of a chain's new nodes is their initial guesses anyway (the chain composed),
    and a call costs about as much for one keyframe as for eight."""

    def __init__(self, cauchy: float, batch: int = 1) -> None:
        import gtsam

        self.g = gtsam
        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(0.01)
        params.relinearizeSkip = 1
        self.isam = gtsam.ISAM2(params)
        self.cauchy = cauchy
        self.batch = batch
        self.times: list[float] = []         # [s] each update's time per keyframe it added (at least one)
        self._sorted: list[float] = []       # the same, in order (the median at every keyframe, without a sort)
        self._graph = gtsam.NonlinearFactorGraph()
        self._values = gtsam.Values()
        self._waiting = 0                    # keyframes waiting for the next update

    def _noise(self, info: npt.NDArray[np.float64], robust: bool) -> Any:
        g = self.g
        base = g.noiseModel.Gaussian.Information(np.asarray(info, np.float64))
        if not robust:
            return base
        return g.noiseModel.Robust.Create(g.noiseModel.mEstimator.Cauchy.Create(self.cauchy), base)

    def add(self, k: int, guess: Pose, edges: list[Edge]) -> None:
        """Node `k` (-1: none, only edges) with its initial estimate and its edges; an iSAM2 update once `batch`
        keyframes wait or an edge is a loop edge."""
        g = self.g
        if k >= 0:
            self._values.insert(k, g.Pose2(guess.x, guess.y, guess.theta))
            self._waiting += 1
            if k == 0:
                self._graph.add(g.PriorFactorPose2(0, g.Pose2(guess.x, guess.y, guess.theta),
                                                   g.noiseModel.Diagonal.Sigmas(np.array([1e-6, 1e-6, 1e-8]))))
        for e in edges:
            self._graph.add(g.BetweenFactorPose2(e.i, e.j, g.Pose2(e.z.x, e.z.y, e.z.theta),
                                                 self._noise(e.info, e.loop)))
        if self._waiting >= self.batch or any(e.loop for e in edges):
            self.flush()

    def flush(self) -> None:
        """Hand the waiting keyframes and edges to iSAM2 (one update)."""
        if self._waiting == 0 and self._graph.size() == 0:
            return
        t0 = time.perf_counter()
        self.isam.update(self._graph, self._values)
        dt = (time.perf_counter() - t0) / max(self._waiting, 1)
        self.times.append(dt)
        bisect.insort(self._sorted, dt)
        self._graph = self.g.NonlinearFactorGraph()
        self._values = self.g.Values()
        self._waiting = 0

    def median(self) -> float | None:
        """[s] the median update time per keyframe so far (None before the first)."""
        n = len(self._sorted)
        if n == 0:
            return None
        return self._sorted[n // 2] if n % 2 else 0.5 * (self._sorted[n // 2 - 1] + self._sorted[n // 2])

    def settle(self, rounds: int = 3) -> None:
        """Extra iSAM2 updates (relinearisation steps) after a loop edge."""
        for _ in range(rounds):
            self.isam.update()

    def poses(self) -> npt.NDArray[np.float64]:
        """(n, 3) the current estimate (the waiting keyframes handed over first)."""
        self.flush()
        est = self.isam.calculateEstimate()
        return np.asarray(self.g.utilities.extractPose2(est), np.float64).reshape(-1, 3)


class OnlineGraph:
    """Keyframes and loop closure beside `localizer` (see the module docstring).

    Args:
        localizer: the localizer whose matched scans become keyframes and whose pose and matching map
            loop closure corrects.
        matcher: the scan matcher settings loop matches start from (the run's: `RUN_MATCHER`).
        config: the loop-closure settings.

    Attributes:
        keyframes: the keyframes, oldest first (their poses: the graph's estimate after the last loop edge).
        edges: every edge of the graph (sequential and loop).
        loops: loop edges added; `tried`: loop matches attempted; `refused`: by which test they failed.
        rebuilds: corrections applied (the matching map rebuilt that many times).
        backend: "isam2" or "sparse".
        update_times: [s] the back end's time per keyframe of each update (iSAM2 only).
    """

    def __init__(self, localizer: Localizer, matcher: MatcherConfig, config: OnlineLoopConfig | None = None) -> None:
        self.localizer = localizer
        self.config = c = config or OnlineLoopConfig()
        self.matcher_config = matcher
        self.keyframes: list[Keyframe] = []
        self._poses = _PoseArray()            # the keyframes' poses (the graph's estimate)
        self._mapped = _PoseArray()           # ... where their scans are in the localizer's matching map
        self._paths: list[float] = []
        self.bins = ScanBins(c.scans_per_bin, c.bin_xy, c.bin_theta)
        self.edges: list[Edge] = []
        self.loops = 0
        self.tried = 0
        self.refused: dict[str, int] = {}
        self.rebuilds = 0
        want = c.backend if c.backend != "auto" else ("isam2" if have_gtsam() else "sparse")
        if want == "isam2" and not have_gtsam():
            raise ConfigError("loop closure: the iSAM2 back end needs gtsam (pip install 'robotexp[slam]')")
        self.backend = want
        self._isam = _Isam2(c.cauchy, c.isam_batch) if want == "isam2" else None
        self._path = 0.0
        self._anchor: Pose | None = None     # the localizer's pose at the last keyframe (its frame)
        self._loc: Pose | None = None        # the localizer's last pose
        self._inc = Pose(0.0, 0.0, 0.0)      # the chain's motion since the last keyframe
        self.jumps = 0
        self.corridor_loops = 0
        self._scan_reach = 0.0               # [m] the farthest a keyframe's scan reaches from the robot
        self._last_submap: tuple[tuple[Any, ...], OccupancyGrid, HitMap] | None = None   # see `_submap_of`

    @property
    def update_times(self) -> list[float]:
        return [] if self._isam is None else self._isam.times

    @property
    def update_median(self) -> float | None:
        """[s] the median of `update_times` (None without one)."""
        return None if self._isam is None else self._isam.median()

    def poses(self) -> npt.NDArray[np.float64]:
        """(n, 3) the keyframes' poses."""
        return self._poses.a.copy()

    def _seq_info(self, rel: Pose, status: str) -> npt.NDArray[np.float64]:
        c = self.config
        d = math.hypot(rel.x, rel.y)
        f = 1.0 if status == "matched" else c.weak
        sxy = f * (c.seq_xy[0] + c.seq_xy[1] * d)
        sth = f * (c.seq_theta[0] + c.seq_theta[1] * d + c.seq_theta[2] * abs(rel.theta))
        return np.diag([sxy ** -2, sxy ** -2, sth ** -2])

    def _loop_info(self) -> npt.NDArray[np.float64]:
        c = self.config
        return np.diag([c.loop_xy ** -2, c.loop_xy ** -2, c.loop_theta ** -2])

    def step(self, prediction: Pose, pose: Pose) -> None:
        """One `Localizer.locate`: its prediction (odometry from its last pose) and its corrected pose. The
        chain between keyframes takes the corrected increments, except where the localizer's correction
        jumped (more than `jump_xy` or `jump_theta`: the scan matched an old part of the map the drifted
        path came back to): there it takes odometry's increment, and the loop edge the same place gives
        the graph carries the correction back along the loop instead of leaving it in one step."""
        if self._loc is None:
            self._loc = pose
            return
        c = self.config
        fix = relative(prediction, pose)
        jump = math.hypot(fix.x, fix.y) > c.jump_xy or abs(fix.theta) > c.jump_theta
        inc = relative(self._loc, prediction if jump else pose)
        self._inc = compose(self._inc, inc)
        self.jumps += int(jump)
        self._loc = pose

    def add_keyframe(self, pose: Pose, scan: LaserScan, odom: Pose, status: str = "matched") -> None:
        """A new keyframe at the localizer's corrected `pose` (its sequential edge added to the graph),
        then a loop tried from it."""
        new: list[Edge] = []
        guess = pose
        if self.keyframes:
            rel = Pose(self._inc.x, self._inc.y, wrap_angle(self._inc.theta))
            self._path += math.hypot(rel.x, rel.y)
            edge = Edge(len(self.keyframes) - 1, len(self.keyframes), rel, self._seq_info(rel, status))
            self.edges.append(edge)
            new = [edge]
            guess = compose(self.keyframes[-1].pose, rel)
            guess = Pose(guess.x, guess.y, wrap_angle(guess.theta))
        self._anchor = pose
        self._loc = pose
        self._inc = Pose(0.0, 0.0, 0.0)
        self._poses.append((guess.x, guess.y, guess.theta))
        self._mapped.append((pose.x, pose.y, pose.theta))     # the localizer mapped the scan at its own pose
        self._paths.append(self._path)
        self._scan_reach = max(self._scan_reach, scan.range_max + abs(scan.offset_x))
        self.keyframes.append(Keyframe(self._poses, len(self.keyframes), scan, odom, self._path, status, pose))
        drop = self.bins.add(len(self.keyframes) - 1, guess)
        if drop is not None:
            self.keyframes[drop].scan = None
        if self._isam is not None:
            self._isam.add(len(self.keyframes) - 1, guess, new)
        n = len(self.keyframes) - 1
        if n % self.config.every == 0:
            loop = self._find_loop(n)
            if loop is not None:
                self.add_loop(loop)

    def _refuse(self, why: str) -> None:
        self.refused[why] = self.refused.get(why, 0) + 1

    def _find_loop(self, n: int) -> Edge | None:
        c = self.config
        cur = self.keyframes[n]
        if cur.scan is None:
            return None
        paths = np.asarray(self._paths)
        m_old = int(np.searchsorted(paths, cur.path - c.min_path, side="right"))   # paths never decrease
        if m_old == 0:
            return None
        P = self._poses.a
        cx, cy = P[n, 0], P[n, 1]
        d = np.hypot(P[:m_old, 0] - cx, P[:m_old, 1] - cy)
        with_scan = np.fromiter((self.keyframes[k].scan is not None for k in np.flatnonzero(d <= c.radius)), bool)
        near = np.flatnonzero(d <= c.radius)[with_scan]
        if len(near) == 0:
            return None
        j = int(near[np.argmin(d[near])])
        wxy, wth = self.gate(j, n)
        self.tried += 1
        mc = self.matcher_config
        lo = max(j - c.submap, 0)
        hi = min(j + c.submap + 1, n - self._recent(n, c.min_path))
        if hi <= lo:
            return None
        window = [k for k in range(lo, hi) if self.keyframes[k].scan is not None]
        grid, hits = self._submap_of(window, j, mc.range_max + wxy)
        sm = ScanMatcher(replace(mc, window_xy=wxy, window_theta=wth, min_score=c.min_score, prior=0.0,
                                 motion_sigma_xy=wxy, motion_sigma_theta=wth, accept_score=2.0, drop_unseen=True))
        px, py = scan_points(cur.scan, mc.range_max)
        m = sm.match(grid.values, grid.geo, px, py, cur.pose, hits, grid.stamp)
        return self._loop_edge(j, n, m)

    def _loop_edge(self, j: int, n: int, m: Match) -> Edge | None:
        """The loop edge from keyframe `j` to keyframe `n` that match `m` of n's scan against j's submap gives, or
        None (the reason counted in `refused`): see `OnlineLoopConfig` (min_points, min_score, min_conditioning,
        corridor_edges, corridor_slide)."""
        c = self.config
        if m.status not in ("matched", "degenerate"):
            self._refuse(m.status)
            return None
        if m.points < c.min_points:
            self._refuse("few-points")
            return None
        info = self._loop_info()
        if m.status == "degenerate" or m.conditioning < c.min_conditioning:
            if not c.corridor_edges or m.info is None:
                self._refuse("degenerate")
                return None
            cur = self.keyframes[n].pose
            w = _weak(m.info)
            if abs(w[0] * (m.pose.x - cur.x) + w[1] * (m.pose.y - cur.y)) > c.corridor_slide:
                self._refuse("slide")
                return None
            info = self._corridor_info(m.info, m.pose.theta)
            self.corridor_loops += 1
        return Edge(j, n, relative(self.keyframes[j].pose, m.pose), info, loop=True)

    def _submap_of(self, window: list[int], j: int, reach: float) -> tuple[OccupancyGrid, HitMap]:
        """The submap of the keyframes `window` around `j` (`posegraph._submap`), the last one again when it was
        of the same keyframes at the same poses (consecutive tries near one old keyframe: 92 of 227 in a
        600 s dense frontier run). `reach` beyond every scan's own makes no difference to it (see `_submap`)."""
        cell = self.localizer.grid.geo.cell
        P = self._poses.a[window]
        key = (tuple(window), P.tobytes(), None if reach >= self._scan_reach + cell else reach)
        if self._last_submap is not None and self._last_submap[0] == key:
            return self._last_submap[1], self._last_submap[2]
        scans = [self.keyframes[k].scan for k in window]
        grid, hits = _submap(P, scans, window.index(j), len(window), cell, reach,  # type: ignore[arg-type]
                             fill=self.localizer.fill)
        self._last_submap = (key, grid, hits)
        return grid, hits

    def _corridor_info(self, h: npt.NDArray[np.float64], theta: float) -> npt.NDArray[np.float64]:
        """A loop edge's information where its scan does not fix the position along one direction (a corridor):
        `loop_xy` across it, `cap_xy` along it (the weak eigenvector of the match's translation information
        `h`, in the world frame, turned into the frame of the edge's error, the later keyframe's)."""
        c = self.config
        w = _weak(h)
        ct, st = math.cos(theta), math.sin(theta)
        wj = np.array([ct * w[0] + st * w[1], -st * w[0] + ct * w[1]])
        along = np.outer(wj, wj)
        out = np.zeros((3, 3))
        out[:2, :2] = (np.eye(2) - along) / c.loop_xy ** 2 + along / c.cap_xy ** 2
        out[2, 2] = c.loop_theta ** -2
        return out

    def _recent(self, n: int, path: float) -> int:
        """How many keyframes before `n` lie within `path` metres along the path (left out of a submap)."""
        k = n
        while k > 0 and self.keyframes[n].path - self.keyframes[k - 1].path < path:
            k -= 1
        return n - k

    def gate(self, i: int, j: int) -> tuple[float, float]:
        """([m], [rad]) how far a loop edge between keyframes i and j may move j from its estimate: the drift
        the path between them can have made (`gate_xy`, `gate_theta`, capped)."""
        c = self.config
        gap = abs(self.keyframes[j].path - self.keyframes[i].path)
        return (min(c.gate_xy[0] + c.gate_xy[1] * gap, c.cap_xy),
                min(c.gate_theta[0] + c.gate_theta[1] * gap, c.cap_theta))

    def add_loop(self, edge: Edge, *, check: bool = True) -> bool:
        """Add a loop edge (robust kernel), optimise, and apply the correction when it is large enough.
        With `check`, an edge that would move node j farther from its estimate than `gate` allows is
        refused (counted in `refused["inconsistent"]`) and False returned."""
        if not (0 <= edge.i < len(self.keyframes) and 0 <= edge.j < len(self.keyframes)):
            raise ConfigError(f"loop closure: edge {edge.i} -> {edge.j} outside the {len(self.keyframes)} keyframes")
        if check:
            dev = relative(self.keyframes[edge.j].pose, compose(self.keyframes[edge.i].pose, edge.z))
            gxy, gth = self.gate(edge.i, edge.j)
            if math.hypot(dev.x, dev.y) > gxy or abs(wrap_angle(dev.theta)) > gth:
                self._refuse("inconsistent")
                return False
        edge = replace(edge, loop=True)
        self.edges.append(edge)
        self.loops += 1
        if self._isam is not None:
            self._isam.add(-1, Pose(0.0, 0.0, 0.0), [edge])
            self._isam.settle()
            new = self._isam.poses()
        else:
            new = optimize(self.poses(), self.edges, iterations=10, cauchy=self.config.cauchy)
        self._set_poses(new)
        return True

    def _set_poses(self, new: npt.NDArray[np.float64]) -> None:
        self._poses.a[:] = new[:len(self.keyframes)]
        assert self._anchor is not None
        moved = relative(self._anchor, self.keyframes[-1].pose)
        c = self.config
        if math.hypot(moved.x, moved.y) > c.apply_xy or abs(moved.theta) > c.apply_theta:
            self._apply()

    def _apply(self) -> None:
        """Move the localizer's pose with the last keyframe and rebuild its matching map."""
        loc = self.localizer
        if loc._pose is not None and self._anchor is not None:
            moved = compose(self.keyframes[-1].pose, relative(self._anchor, loc._pose))
            loc._pose = Pose(moved.x, moved.y, wrap_angle(moved.theta))
            self._loc = compose(self.keyframes[-1].pose, relative(self._anchor, self._loc or self._anchor))
        self._anchor = self.keyframes[-1].pose
        self.keyframes[-1].local = self._anchor      # the localizer's poses from here on are in its new frame
        self._rebuild()
        self.rebuilds += 1

    def _rebuild(self) -> tuple[int, int, int, int] | None:
        """Rebuild the localizer's matching map where keyframes moved: the keyframes whose pose lies more than
        `rebuild_xy` from where their scan was mapped (a turn counts at the laser's reach) mark a box (their scans'
        reach at both poses); every kept scan that reaches into the box is mapped again, in order, at its
        keyframe's pose into a grid of the box alone, which then replaces the box's cells (the same cells a
        rebuild of the whole map gives there; outside the box nothing changed). A box of more than half the
        map: the whole map is rebuilt. Returns the box (rows r0..r1, columns c0..c1, half-open), None when no
        keyframe moved."""
        loc = self.localizer
        old = loc.grid
        n = len(self.keyframes)
        P, M = self._poses.a, self._mapped.a
        reach = (old.range_max if old.range_max is not None else self.matcher_config.range_max) + old.geo.cell
        if not math.isfinite(reach):
            reach = max(max((float(np.nanmax(np.where(np.isfinite(k.scan.ranges), k.scan.ranges, 0.0)))
                             for k in self.keyframes if k.scan is not None), default=0.0), 1.0) + old.geo.cell
        moved = np.flatnonzero(shifts(P, M, reach) > self.config.rebuild_xy)
        if len(moved) == 0:
            return None
        geo = old.geo
        cells = geo.reach_box(np.vstack([P[moved, :2], M[moved, :2]]), reach)
        if cells is None or (cells[1] - cells[0]) * (cells[3] - cells[2]) > geo.rows * geo.cols / 2:
            cells = (0, geo.rows, 0, geo.cols)
        r0, r1, c0, c1 = cells
        box = geo.part(cells)
        grid = old.blank(box)
        hits = HitMap(box)
        x0, x1 = box.origin_x - reach, box.origin_x + box.width + reach
        y0, y1 = box.origin_y - reach, box.origin_y + box.height + reach
        inside = np.flatnonzero((P[:n, 0] >= x0) & (P[:n, 0] <= x1) & (P[:n, 1] >= y0) & (P[:n, 1] <= y1))
        rmax = old.range_max if old.range_max is not None else math.inf
        for k in inside:
            scan = self.keyframes[k].scan
            if scan is None:
                continue
            pose = Pose(float(P[k, 0]), float(P[k, 1]), float(P[k, 2]))
            scan = loc.mapped(scan)
            grid.update(pose, scan)
            hits.add(pose, scan, rmax)
        if box.rows == geo.rows and box.cols == geo.cols:
            loc.grid, loc.hits = grid, hits
        else:
            old.values[r0:r1, c0:c1] = grid.values
            for a, b in ((loc.hits.sum_x, hits.sum_x), (loc.hits.sum_y, hits.sum_y), (loc.hits.count, hits.count)):
                a[r0:r1, c0:c1] = b
        self._mapped.a[moved] = P[moved]
        if box.rows == geo.rows and box.cols == geo.cols:
            self._mapped.a[:] = P
        loc.version += 1                  # the matcher's cached field is stale
        return r0, r1, c0, c1

    def pose_of(self, k: int) -> Pose:
        """The current estimate of keyframe `k`."""
        return self.keyframes[k].pose

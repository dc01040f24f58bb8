"""`--localize slam` in the run loop: `LoopClosureTracker` keeps every mapped scan beside its keyframe and,
when loop closure corrects the keyframes, rebuilds the run's map from all of them and tells the explorer."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
from ring_corridor import RingRobot, drifted, ring_path

from robotexp.localization.correction import FrameCorrection
from robotexp.localization.matcher import ScanMatcher, compose
from robotexp.localization.online import ScanBins
from robotexp.localization.robot import RUN_MATCHER, LocalizedRobot
from robotexp.run.localize import SCANS_PER_BIN, LoopClosureTracker
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.run.observers import StepEvent
from robotexp.robot import LaserScan, Pose


class Told:
    """An explorer's `map_rebuilt` as the tracker calls it."""

    def __init__(self) -> None:
        self.calls: list[OccupancyGrid] = []

    def map_rebuilt(self, grid: OccupancyGrid, moved: FrameCorrection) -> None:
        self.calls.append(grid)


def test_the_runs_map_is_rebuilt_from_every_scan_at_the_corrected_keyframes() -> None:
    truth = ring_path(1.3)
    odom = drifted(truth, 1.03, math.radians(1.0))
    # 2 cm cells: the map is rebuilt once a keyframe has moved by half a cell, and loop closure moves them by
    # about 2 cm here
    geo = GridGeometry.covering(-1, -1, 11, 11, 0.02)
    grid = OccupancyGrid(geo, range_max=4.0)
    told = Told()
    with RingRobot(truth, odom) as inner:
        # without skip_unseen, and with every match's correction taken along the corridors (fuse_ratio 0), the
        # matches drift round the ring (the ends of the walls mapped so far pull the scans back along them), and
        # loop closure has a correction to make when the ring closes
        drifting = ScanMatcher(replace(RUN_MATCHER, fuse_ratio=0.0))
        robot = LocalizedRobot(inner, GridGeometry.covering(-1, -1, 11, 11, 0.05), matcher=drifting, range_max=4.0,
                               loop_closure=True, skip_unseen=False)
        tracker = LoopClosureTracker("slam", "test", robot)
        run = SimpleNamespace(grid=grid, explorer=told, info=SimpleNamespace(extra={}), state=None)
        for k in range(len(truth)):
            state = robot.read()
            assert state.laser is not None
            grid.update(state.pose, state.laser)            # what the run loop does with each new scan
            tracker.on_step(run, StepEvent(0.1 * k, state, True, None))   # type: ignore[arg-type]
        robot.detach()
    g = robot.graph
    assert g is not None and g.loops >= 1 and g.rebuilds >= 1
    assert 1 <= tracker.map_rebuilds <= g.rebuilds
    assert len(told.calls) == tracker.map_rebuilds and all(c is grid for c in told.calls)   # the explorer was told
    assert len(tracker.scans) + tracker.bins.dropped == len(truth)   # every mapped scan kept or pushed out, none twice
    # the memory bound: at most SCANS_PER_BIN scans per pose bin, here and in the graph's keyframes
    assert tracker.bins.dropped > 0 and len(tracker.scans) <= SCANS_PER_BIN * len(tracker.bins.bins)
    kept = sum(k.scan is not None for k in g.keyframes)
    assert kept == len(g.keyframes) - g.bins.dropped <= g.config.scans_per_bin * len(g.bins.bins)
    # after the last rebuild the run's map is exactly the scans taken since it on top of all scans
    # up to it at their keyframes' corrected poses; rebuilt once more now, it is every scan at them
    again = OccupancyGrid(geo, range_max=4.0)
    for kf, rel, ranges, angles, rmax, off in tracker.scans.values():
        again.update(compose(g.keyframes[kf].pose, rel), LaserScan(angles, ranges.astype(np.float64), rmax, off))
    tracker._rebuild(run)                                   # type: ignore[arg-type]
    np.testing.assert_array_equal(grid.values, again.values)
    assert len(told.calls) == tracker.map_rebuilds
    info = run.info.extra["loop_closure"]
    assert info["loops"] == g.loops and info["rebuilds"] == g.rebuilds and info["keyframes"] == len(g.keyframes)


def test_the_scan_bound_keeps_the_newest_few_of_each_bin_however_long_the_run() -> None:
    bins = ScanBins(4, 0.5, math.radians(45.0))
    kept: set[int] = set()
    key = 0
    for lap in range(10):                           # back and forth along 2 m, 0.1 m apart, 10 times
        for i in range(20):
            x = 0.1 * i + 0.05 if lap % 2 == 0 else 1.95 - 0.1 * i
            kept.add(key)
            drop = bins.add(key, Pose(x, 0.3, 0.1 if lap % 2 == 0 else math.pi - 0.1))
            if drop is not None:
                kept.discard(drop)
            key += 1
        # 4 x-bins x 2 headings, 4 scans each at most: 32, from the second lap on
        assert len(kept) <= 4 * 4 * 2 and len(kept) + bins.dropped == key
    assert len(kept) == 32
    # each bin holds its newest: the last lap (headings near pi) and the one before (near 0) entirely,
    # 5 scans a bin on each lap, the newest 4 of them
    last, before = range(180, 200), range(160, 180)
    assert kept == {k for k in last if (k - 180) % 5 != 0} | {k for k in before if (k - 160) % 5 != 0}


def test_a_correction_at_one_end_rebuilds_the_map_there_and_keeps_the_rest() -> None:
    """A 30 m corridor mapped from keyframes every 0.5 m (3 m laser); the graph moves the last ten keyframes by
    5 cm and 0.5 deg. The rebuild maps the kept scans again in the box their keyframes' scans reach, at both
    poses: inside it the map is every kept scan at its corrected pose, outside it nothing changed, and the
    walls a scan the memory bound dropped put there stay."""
    from robotexp.localization.matcher import Localizer
    from robotexp.localization.online import OnlineGraph, OnlineLoopConfig
    from robotexp.world.raycast import RayIndex

    walls = [(15.0, -0.05, 15.1, 0.05, 0.0), (15.0, 2.05, 15.1, 0.05, 0.0), (-0.05, 1.0, 0.05, 1.1, 0.0),
             (30.05, 1.0, 0.05, 1.1, 0.0), (6.0, 0.15, 0.3, 0.1, 0.0), (24.0, 1.85, 0.3, 0.1, 0.0)]
    index = RayIndex(walls, np.zeros((0, 3)), 1.0)
    beams = np.radians(np.arange(-180.0, 180.0, 1.0))

    def scan_at(p: Pose) -> LaserScan:
        frac = index.cast(np.tile([p.x, p.y], (len(beams), 1)), p.theta + beams, 3.0, 0.5)
        return LaserScan(beams.copy(), np.where(frac < 1.0, frac * 3.0, np.inf), 3.0)

    geo = GridGeometry.covering(-1, -1, 31, 3, 0.1)
    g = OnlineGraph(Localizer(GridGeometry.covering(-1, -1, 31, 3, 0.05)), RUN_MATCHER,
                    OnlineLoopConfig(backend="sparse"))
    grid = OccupancyGrid(geo, range_max=3.0)
    poses = [Pose(0.5 + 0.5 * k, 1.0, 0.0) for k in range(59)]
    tracker = LoopClosureTracker("slam", "test", SimpleNamespace(graph=g, keyframe=-1))  # type: ignore[arg-type]
    for k, p in enumerate(poses):
        s = scan_at(p)
        g.step(p, p)
        g.add_keyframe(p, s, p)
        grid.update(p, s)                                   # the run's map takes every scan
        if k > 5:                                           # the memory bound dropped the first six, the only
            #                                                 ones that saw the west end wall
            tracker.scans[k] = (k, Pose(0.0, 0.0, 0.0), s.ranges.astype(np.float32), s.angles, 3.0, 0.0)
    assert g.loops == 0
    before = grid.values.copy()
    shift = np.array([0.05, 0.03, math.radians(0.5)])
    g._poses.a[-10:] += shift                               # what a loop edge's optimisation would do
    told = Told()
    run = SimpleNamespace(grid=grid, explorer=told, info=SimpleNamespace(extra={}))
    marks = grid.scans
    assert tracker._moved(geo.cell / 2, g.poses(), 3.0)
    tracker._rebuild(run)                                   # type: ignore[arg-type]
    box = grid.changed_box(marks)
    assert box is not None
    r0, r1, c0, c1 = box
    # the box: the moved keyframes (x 25.0-29.55 m) and 3.1 m of reach, and a cell more, each side
    assert c0 == math.floor((25.0 - 3.1 - geo.origin_x) / geo.cell) - 1 and c1 == geo.cols and (r0, r1) == (0, geo.rows)
    again = OccupancyGrid(geo, range_max=3.0)
    for k, _, ranges, angles, rmax, off in tracker.scans.values():
        again.update(g.keyframes[k].pose, LaserScan(angles, ranges.astype(np.float64), rmax, off))
    np.testing.assert_array_equal(grid.values[:, c0:c1], again.values[:, c0:c1])
    np.testing.assert_array_equal(grid.values[:, :c0], before[:, :c0])
    west = slice(0, 11)                                     # x -1.0 to 0.1 m: the west end wall (x -0.1 to 0)
    assert (before[:, west] > 1.0).sum() >= 20 and not (again.values[:, west] > 0).any()   # kept here
    assert len(told.calls) == 1 and tracker.map_rebuilds == 1
    assert not tracker._moved(geo.cell / 4, g.poses(), 3.0)             # the map has every keyframe where it is


def test_a_spread_bin_keeps_the_views_farthest_apart() -> None:
    """A robot drives through a bin (x 0 to 0.5 m) and lingers at its far end: the spread bound keeps its
    first view and the last, the newest-first bound the last two."""
    xs = [0.05, 0.45, 0.42, 0.40]
    bins = ScanBins(2, 0.5, math.radians(45.0), spread=True)
    drops = [bins.add(k, Pose(x, 0.2, 0.0)) for k, x in enumerate(xs)]
    assert drops == [None, None, 1, 2]          # the older of the two closest: 1 (3 cm from 2), then 2
    assert list(bins.bins[(0, 0, 0)]) == [0, 3] and bins.dropped == 2
    assert bins.add(9, Pose(0.05, 0.2, math.pi)) is None and len(bins.bins) == 2   # another sector: another bin
    newest = ScanBins(2, 0.5, math.radians(45.0))
    assert [newest.add(k, Pose(x, 0.2, 0.0)) for k, x in enumerate(xs)] == [None, None, 0, 1]
    assert list(newest.bins[(0, 0, 0)]) == [2, 3]

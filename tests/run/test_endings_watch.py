"""Honest endings and bounds: the stall watch's strikes, the frontier left at an explorer's "done",
scans clipped at the exploration bounds, walls along them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import LaserScan, Pose
from robotexp.run.endings import MAX_WINDOW, MIN_WINDOW, SLOW_SPEED, StallWatch, frontier_left
from robotexp.world.bounds import clip_scan, exploration_area, inside, parse_bounds, with_boundary_walls
from robotexp.world.model import World

GEO = GridGeometry(0.0, 0.0, 0.1, 60, 100)       # 10 x 6 m


class Giver:
    """An explorer stand-in that records the give-ups asked of it."""

    def __init__(self, has_target: bool = True) -> None:
        self.calls: list[float] = []
        self.has_target = has_target

    def give_up(self, grid: OccupancyGrid) -> bool:
        self.calls.append(len(self.calls))
        return self.has_target


def room_grid(opening: bool) -> OccupancyGrid:
    """A known room 5 x 4 m (walls occupied, inside free); with `opening`, a 1 m gap in its east wall
    onto unknown space."""
    grid = OccupancyGrid(GEO)
    free = np.zeros((GEO.rows, GEO.cols), dtype=bool)
    free[11:49, 11:59] = True
    wall = np.zeros_like(free)
    wall[10:50, 10:60] = True
    wall &= ~free
    if opening:
        wall[25:35, 59] = False
        free[25:35, 59] = True
    grid.mark_free(free)
    grid.mark_occupied(wall)
    return grid


def test_the_window_grows_with_the_map_and_the_speed():
    watch = StallWatch()
    watch.start(OccupancyGrid(GEO), 0.3)
    assert watch.window == MIN_WINDOW                     # 1.5 x 16 m / 0.3 m/s = 80 s < 120 s
    big = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 600, 800))   # 80 x 60 m
    watch.start(big, 1.0)
    assert watch.window == pytest.approx(1.5 * 140 / 1.0)
    watch.start(big, 0.3)
    assert watch.window == MAX_WINDOW
    # a slow robot gets bounds that span the same distance as at SLOW_SPEED (the thesis's 40 mm/s runs
    # crossed the sparse hall for longer than three 240 s windows without mapping anything new)
    watch.start(big, 0.04)
    assert watch.window == pytest.approx(MAX_WINDOW * SLOW_SPEED / 0.04)        # 600 s
    watch.start(OccupancyGrid(GEO), 0.04)
    assert watch.window == pytest.approx(1.5 * 16 / 0.04)                       # 600 s, within 300..600 s
    watch.start(OccupancyGrid(GEO), SLOW_SPEED)
    assert watch.window == pytest.approx(1.5 * 16 / SLOW_SPEED)                 # 240 s: as before


def test_three_strikes_without_new_cells_end_the_run_and_each_gives_up_a_target():
    grid = room_grid(True)
    watch, explorer = StallWatch(window=10.0), Giver()
    watch.start(grid, 0.3)
    reasons = [watch.sample(float(t), grid, explorer) for t in range(0, 30)]
    assert reasons == [None] * 30 and len(explorer.calls) == 2      # strikes at 10 and 20 s
    last = watch.sample(30.0, grid, explorer)
    assert last is not None and last.startswith("stalled: no newly known space for 3 x 10 s")
    assert "(3 targets given up)" in last and len(explorer.calls) == 3


def test_a_gain_clears_the_strikes_and_a_tiny_one_does_not_count():
    grid = room_grid(False)
    watch, explorer = StallWatch(window=10.0, min_gain=0.25), Giver(has_target=False)
    watch.start(grid, 0.3)
    assert watch.sample(0.0, grid, explorer) is None
    assert watch.sample(10.0, grid, explorer) is None and watch.strikes == 1
    tiny = np.zeros((GEO.rows, GEO.cols), dtype=bool)
    tiny[55, 70:74] = True                           # 0.04 m^2: below the gain
    grid.mark_free(tiny)
    assert watch.sample(20.0, grid, explorer) is None and watch.strikes == 2
    more = np.zeros_like(tiny)
    more[52:58, 75:90] = True                        # 0.9 m^2 new
    grid.mark_free(more)
    assert watch.sample(25.0, grid, explorer) is None and watch.strikes == 0
    assert watch.sample(34.9, grid, explorer) is None and watch.strikes == 0
    assert watch.sample(35.0, grid, explorer) is None and watch.strikes == 1
    assert watch.sample(45.0, grid, explorer) is None and watch.strikes == 2
    last = watch.sample(55.0, grid, explorer)
    assert last is not None and "(0 targets given up)" in last


def test_frontier_left_counts_a_reachable_opening_and_nothing_in_a_closed_room():
    assert frontier_left(room_grid(False), Pose(2.5, 3.0, 0.0), 0.25) == (0, 0.0)
    assert frontier_left(room_grid(True), Pose(2.5, 3.0, 0.0), 0.25)[0] >= 5
    # the same opening seen from outside the known space: nothing the robot can drive to
    assert frontier_left(room_grid(True), Pose(8.5, 5.5, 0.0), 0.25)[0] == 0
    # a robot that went up to the opening and looked: what stays frontier there is not counted
    far = np.array([[1.0 + 0.1 * k, 3.0] for k in range(20)])          # x 1..2.9 m: 3 m from the gap
    near = np.array([[2.0 + 0.1 * k, 3.0] for k in range(30)])         # up to x = 4.9 m, by the gap
    assert frontier_left(room_grid(True), Pose(2.5, 3.0, 0.0), 0.25, far)[0] >= 5
    assert frontier_left(room_grid(True), Pose(2.5, 3.0, 0.0), 0.25, near)[0] == 0
    # remembered walls (the same walls, here) leave a real opening an opening
    grid = room_grid(True)
    assert frontier_left(grid, Pose(2.5, 3.0, 0.0), 0.25, walls=grid.occupied()) == \
        frontier_left(grid, Pose(2.5, 3.0, 0.0), 0.25)


def test_the_unknown_behind_the_frontier_left_decides_whether_it_matters():
    from robotexp.run.endings import LEFT_REACH, unexplored_left

    # the opening leads into unknown space: what lies within LEFT_REACH of its frontier counts
    n, area = frontier_left(room_grid(True), Pose(2.5, 3.0, 0.0), 0.25)
    assert n >= 5 and 0.5 * math.pi * LEFT_REACH ** 2 * 0.8 < area < 1.2 * (LEFT_REACH + 1.0) * 2 * LEFT_REACH
    assert unexplored_left(room_grid(True), Pose(2.5, 3.0, 0.0), 0.25) == (n, area)   # > 2 m2 and > 5 % of 18 m2
    # a shadow: the unknown behind the opening is a 0.5 x 1 m pocket walled in
    grid = room_grid(True)
    wall = np.zeros((GEO.rows, GEO.cols), dtype=bool)
    wall[23:37, 59:66] = True
    wall[25:35, 59:65] = False
    grid.mark_occupied(wall)
    rest = grid.unknown()
    rest[25:35, 60:65] = False
    grid.mark_free(rest)
    # counted is at most the part of the pocket a robot's disc could enter were it free
    n, area = frontier_left(grid, Pose(2.5, 3.0, 0.0), 0.25)
    assert area <= 0.5 + 1e-9
    assert unexplored_left(grid, Pose(2.5, 3.0, 0.0), 0.25) is None


def test_scans_are_clipped_where_they_leave_the_area():
    area = (0.0, 0.0, 10.0, 6.0)
    angles = np.array([0.0, math.pi / 2, math.pi, -math.pi / 2, math.pi / 4])
    scan = LaserScan(angles, np.array([np.inf, 1.0, np.inf, 7.0, np.inf]), range_max=8.0, offset_x=0.1)
    clipped = clip_scan(scan, Pose(4.0, 2.0, 0.0), area)
    # the sensor is at (4.1, 2.0): east edge 5.9 m away, west 4.1 m, south 2.0 m; north reads 1.0 (a wall)
    np.testing.assert_allclose(clipped.ranges[:4], [5.9, 1.0, 4.1, 2.0])
    assert clipped.ranges[4] == pytest.approx(4.0 * math.sqrt(2))     # NE: leaves through y = 6 first
    short = LaserScan(angles, np.full(5, 1.0), range_max=8.0)
    assert clip_scan(short, Pose(4.0, 2.0, 0.0), area) is short


def test_clip_scan_far_from_the_edges_agrees_with_every_beam_clipped() -> None:
    """Readings all short of the area's nearest edge come back unchanged without clipping each beam; near an
    edge, with a reading or no echo past it, each beam is clipped: random poses, readings at the edge's
    distance itself, NaN and inf, against the beam-by-beam rule (the distance to the edge along the beam)."""
    area = (0.0, 0.0, 10.0, 6.0)
    rng = np.random.default_rng(3)
    angles = np.linspace(-math.pi, math.pi, 181)
    kept = 0
    for _ in range(300):
        pose = Pose(float(rng.uniform(0.5, 9.5)), float(rng.uniform(0.5, 5.5)), float(rng.uniform(-3, 3)))
        rmax = float(rng.choice([1.0, 3.0, 8.0]))
        ranges = rng.uniform(0.1, rmax, 181)
        ranges[rng.random(181) < 0.1] = np.nan
        ranges[rng.random(181) < 0.02] = np.inf
        scan = LaserScan(angles, ranges, range_max=rmax, offset_x=0.1)
        sx, sy = pose.x + 0.1 * math.cos(pose.theta), pose.y + 0.1 * math.sin(pose.theta)
        edge = min(sx, 10.0 - sx, sy, 6.0 - sy)
        if rng.random() < 0.5:
            ranges[rng.integers(181)] = edge    # a reading at the nearest edge's distance exactly
        a = pose.theta + angles
        with np.errstate(divide="ignore", invalid="ignore"):
            tx = np.where(np.cos(a) > 0, (10.0 - sx) / np.cos(a), np.where(np.cos(a) < 0, -sx / np.cos(a), np.inf))
            ty = np.where(np.sin(a) > 0, (6.0 - sy) / np.sin(a), np.where(np.sin(a) < 0, -sy / np.sin(a), np.inf))
        leave = np.maximum(np.minimum(tx, ty), 0.0)
        reading = np.where(np.isfinite(ranges), ranges, rmax)
        want = np.where(leave < reading, leave, ranges)
        got = clip_scan(scan, pose, area)
        np.testing.assert_array_equal(got.ranges, want)
        assert (got is scan) == (not (leave < reading).any())
        kept += got is scan
    assert 30 < kept < 270          # both ways taken

def test_bounds_parse_default_to_the_declared_area_and_become_walls():
    assert parse_bounds("-1000,-500,20000,15000") == (-1.0, -0.5, 20.0, 15.0)
    for bad in ("1,2,3", "0,0,-1,5", "0,0,nan,5", "a,b,c,d"):
        with pytest.raises(ConfigError, match="--bounds"):
            parse_bounds(bad)
    world = World("w", [(5.0, 3.0, 1.0, 1.0, 0.0)], declared=(0.0, 0.0, 10.0, 6.0))
    assert exploration_area(world, None) == (0.0, 0.0, 10.0, 6.0)
    assert exploration_area(world, (1.0, 1.0, 2.0, 2.0)) == (1.0, 1.0, 2.0, 2.0)
    walled = with_boundary_walls(world, (0.0, 0.0, 10.0, 6.0))
    assert len(walled.boxes) == 5 and walled.bounds == pytest.approx((-0.05, -0.05, 10.05, 6.05))
    from robotexp.world.groundtruth import occupancy
    occ = occupancy(walled, GridGeometry(-0.5, -0.5, 0.05, 140, 220))
    # the walls' inner faces lie on the area's edge: the cells just inside are free, just outside occupied
    assert not occ[10 + 5, 10 + 5] and occ[9, 15] and occ[15, 9]
    assert inside((0.0, 0.0, 10.0, 6.0), 10.05, 3.0, tol=0.1) and not inside((0.0, 0.0, 10.0, 6.0), 10.2, 3.0)


def test_time_an_explorer_spends_backtracking_is_no_stall():
    # SRT's drive back along its tree maps nothing by design: no strike while `backtracking`, and the
    # window starts again when it ends
    grid = room_grid(False)
    watch, explorer = StallWatch(window=10.0), Giver(has_target=False)
    watch.start(grid, 0.3)
    assert watch.sample(0.0, grid, explorer) is None
    explorer.backtracking = True  # type: ignore[attr-defined]
    assert all(watch.sample(float(t), grid, explorer) is None for t in range(1, 60)) and watch.strikes == 0
    explorer.backtracking = False  # type: ignore[attr-defined]
    assert watch.sample(68.9, grid, explorer) is None and watch.strikes == 0
    assert watch.sample(69.0, grid, explorer) is None and watch.strikes == 1


def test_a_window_in_which_the_explorer_resolved_frontier_to_a_new_low_is_no_strike():
    # the last specks of frontier on a large floor: each look resolves a few cells and maps less than the
    # gain. A window whose end finds the explorer's `frontier_left` below its lowest since the last gain
    # is no strike; one that does not (the same count, or a count back up) is
    grid = room_grid(False)
    watch, explorer = StallWatch(window=10.0), Giver(has_target=False)
    explorer.frontier_left = 12  # type: ignore[attr-defined]
    watch.start(grid, 0.3)
    assert watch.sample(0.0, grid, explorer) is None and watch.least_left == 12
    explorer.frontier_left = 9  # type: ignore[attr-defined]
    assert watch.sample(10.0, grid, explorer) is None and watch.strikes == 0 and watch.least_left == 9
    explorer.frontier_left = 11  # type: ignore[attr-defined]
    assert watch.sample(20.0, grid, explorer) is None and watch.strikes == 1
    explorer.frontier_left = 9  # type: ignore[attr-defined]
    assert watch.sample(30.0, grid, explorer) is None and watch.strikes == 2     # no lower than 9
    explorer.frontier_left = 4  # type: ignore[attr-defined]
    assert watch.sample(40.0, grid, explorer) is None and watch.strikes == 0
    # it ends: the count cannot fall forever
    reasons = [watch.sample(float(t), grid, explorer) for t in (50, 60, 70)]
    assert reasons[:2] == [None, None] and reasons[2] is not None and reasons[2].startswith("stalled")
    # a gain sets the low to the count at the gain (new space brings new frontier)
    watch.start(grid, 0.3)
    assert watch.sample(0.0, grid, explorer) is None and watch.least_left == 4
    more = np.zeros((GEO.rows, GEO.cols), dtype=bool)
    more[52:58, 70:90] = True
    grid.mark_free(more)
    explorer.frontier_left = 30  # type: ignore[attr-defined]
    assert watch.sample(5.0, grid, explorer) is None and watch.least_left == 30
    explorer.frontier_left = 25  # type: ignore[attr-defined]
    assert watch.sample(15.0, grid, explorer) is None and watch.strikes == 0
    # an explorer without the count (or with something else in its place) is watched on space alone
    other = Giver(has_target=False)
    other.frontier_left = True  # type: ignore[attr-defined]
    watch.start(grid, 0.3)
    assert watch.sample(0.0, grid, other) is None and watch.least_left is None
    assert watch.sample(10.0, grid, other) is None and watch.strikes == 1

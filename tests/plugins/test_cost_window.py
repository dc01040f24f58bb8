"""Cost that does not grow with the map: the window of touched cells, and plans on it equal to plans on the map.

Frontier and bvp plan on `OccupancyGrid.window` of `touched_box` (every cell outside it is unknown); the
run's coverage and stall watch count there too. These tests check the box holds every touched cell, that
the windowed planning helpers and relaxation give what the whole map gives (the numba sweeps against the
plain-Python reference), and that a whole run on a map three times as wide and tall drives the same path.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt

from robotexp.errors import ConfigError
from robotexp.run.loop import ExplorationRun
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.world.groundtruth import coverage, grid_coverage, ground_truth
from robotexp.planning.harmonic import (
    free_box,
    free_box_in,
    gauss_seidel_perturbed_ref,
    gauss_seidel_ref,
    relax,
)
from robotexp.planning.targets import PlanCosts, WallMemory, frontier_targets, known_window, plan_costs
from robotexp.robot import LaserScan, Pose
from robotexp.sim import LaserConfig, SimRobot
from robotexp.world.model import World, segment_box
from robotexp_plugins.bvp import BVPExplorer
from robotexp_plugins.frontier import FrontierExplorer

RANGE = 2.0


def _room() -> World:
    """Two 3 x 4 m rooms joined by a 1.1 m door in the wall x = 3 m, with a table in the right room."""
    t = 0.1
    return World("door", np.array([segment_box(0, 0, 6, 0, t), segment_box(0, 4, 6, 4, t),
                                   segment_box(0, 0, 0, 4, t), segment_box(6, 0, 6, 4, t),
                                   segment_box(3, 0, 3, 1.4, t), segment_box(3, 2.6, 3, 4, t),
                                   segment_box(4.2, 2.6, 5.0, 2.6, 0.4)]))


@pytest.mark.parametrize("model", ["logodds", "himm"])
def test_touched_box_holds_every_touched_cell(model: str) -> None:
    geo = GridGeometry(-1.0, -2.0, 0.1, 80, 120)
    grid = OccupancyGrid(geo, model=model)  # type: ignore[arg-type]
    assert grid.touched_box() is None
    rng = np.random.default_rng(3)
    angles = np.linspace(-math.pi, math.pi, 361)
    for k in range(40):
        # poses inside, near the edges and off the grid; ranges short, long, beyond range_max, inf
        pose = Pose(rng.uniform(-3, 13), rng.uniform(-4, 8), rng.uniform(-math.pi, math.pi))
        ranges = rng.choice([0.3, 1.7, 2.9, 3.0, 7.0, math.inf], size=angles.size)
        grid.update(pose, LaserScan(angles, ranges, 3.0, offset_x=0.2))
        box = grid.touched_box()
        touched = np.argwhere(grid.stamp > 0)
        if len(touched):
            assert box is not None
            r0, r1, c0, c1 = box
            assert (touched[:, 0] >= r0).all() and (touched[:, 0] < r1).all()
            assert (touched[:, 1] >= c0).all() and (touched[:, 1] < c1).all()
            assert 0 <= r0 < r1 <= geo.rows and 0 <= c0 < c1 <= geo.cols
            # and the box is the scans' reach, not the map: a scan of 3 m spans at most 63 cells
            if k == 0:
                assert r1 - r0 <= 64 and c1 - c0 <= 64
    mark = np.zeros(grid.shape, bool)
    mark[79, 119] = True
    grid.mark_occupied(mark)
    box = grid.touched_box()
    assert box is not None and box[1] == 80 and box[3] == 120


@pytest.mark.parametrize("model", ["logodds", "himm"])
def test_each_scan_changes_only_cells_in_its_box_and_the_box_is_its_beams(model: str) -> None:
    """Per scan, every cell whose value, stamp or box of endpoints changed lies in `changed_box` of that scan,
    and the box is the box of the beams' ends (a cell of slack), not the laser's reach: beams that hit 0.5 m
    off span 12 cells, not the 163 of an 8 m reach."""
    geo = GridGeometry(-5.0, -5.0, 0.1, 100, 100)
    grid = OccupancyGrid(geo, model=model)  # type: ignore[arg-type]
    rng = np.random.default_rng(5)
    angles = np.linspace(-math.pi, math.pi, 181, endpoint=False)
    for k in range(30):
        pose = Pose(rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-math.pi, math.pi))
        ranges = rng.choice([0.3, 0.5, 2.0, 8.0, math.inf, math.nan], size=angles.size) if k else np.full(181, 0.5)
        before = (grid.values.copy(), grid.stamp.copy(), grid.hit_box.copy())
        grid.update(pose, LaserScan(angles, ranges, 8.0))
        changed = ((grid.values != before[0]) | (grid.stamp != before[1]) | (grid.hit_box != before[2]).any(axis=2))
        box = grid.changed_box(grid.scans - 1)
        assert box is not None
        r0, r1, c0, c1 = box
        inside = np.zeros_like(changed)
        inside[r0:r1, c0:c1] = True
        assert not (changed & ~inside).any()
        if k == 0:
            assert r1 - r0 <= 13 and c1 - c0 <= 13 and changed.any()


def test_a_scan_beyond_any_index_changes_the_whole_grid_box_and_one_from_a_pose_not_finite_nothing() -> None:
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 50, 50))
    angles = np.linspace(-1.0, 1.0, 5)
    for pose, range_max, r in [(Pose(1e300, 2.0, 0.0), 8.0, 1.0), (Pose(2.0, 2.0, 0.0), 1e300, 1e299),
                               (Pose(2.0, 2.0, 0.0), math.inf, math.inf)]:
        grid.update(pose, LaserScan(angles, np.full(5, r), range_max))
        assert grid.changed_box(grid.scans - 1) == (0, 50, 0, 50)
    before = grid.values.copy()
    for pose in (Pose(math.nan, 2.0, 0.0), Pose(2.0, math.inf, 0.0), Pose(2.0, 2.0, math.nan)):   # changes nothing
        assert grid.update(pose, LaserScan(angles, np.full(5, 1.0), 8.0)) == 0
        assert grid.changed_box(grid.scans - 1) is None
    assert np.array_equal(grid.values, before)
    grid.update(Pose(2.0, 2.0, 0.0), LaserScan(angles, np.full(5, 1.0), 8.0))
    assert grid.changed_box(grid.scans - 1) == (10, 30, 19, 32)


def test_changed_boxes_keep_scans_far_apart_separate_and_merge_the_near_ones() -> None:
    """Two scans 6 m apart change two boxes of about 1 m, not their 7 m bounding box; boxes that overlap or
    touch once grown by `grow` cells are one box, and merging goes on with the merged box."""
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 100, 100))
    angles = np.linspace(-math.pi, math.pi, 90, endpoint=False)
    scan = LaserScan(angles, np.full(90, 0.5), 8.0)
    each = []
    for x, y in ((1.0, 1.0), (7.0, 7.0), (1.3, 1.0)):
        grid.update(Pose(x, y, 0.0), scan)
        each.append(grid.changed_box(grid.scans - 1))
    assert each == [(4, 16, 3, 17), (64, 76, 63, 77), (4, 16, 6, 20)]       # 0.5 m beams and cells of slack
    assert grid.changed_box(0) == (4, 76, 3, 77)                             # the one box: 72 x 74 cells
    assert sorted(grid.changed_boxes(0)) == [(4, 16, 3, 20), (64, 76, 63, 77)]      # 12 x 17 and 12 x 14
    assert sorted(grid.changed_boxes(1)) == [(4, 16, 6, 20), (64, 76, 63, 77)]
    assert grid.changed_boxes(2) == [each[2]] and grid.changed_boxes(3) == []
    # rows 48 cells apart: grown by 24 they touch (16 + 24 = 40 = 64 - 24), by 23 they do not
    assert grid.changed_boxes(0, 24) == [(4, 76, 3, 77)]
    assert sorted(grid.changed_boxes(0, 23)) == [(4, 16, 3, 20), (64, 76, 63, 77)]
    # a third box that meets both merges all three, in whichever order they come
    grid.update(Pose(4.0, 4.0, 0.0), LaserScan(angles, np.full(90, 3.2), 8.0))
    assert grid.changed_boxes(0) == [(4, 76, 3, 77)]


def test_window_shares_the_arrays_and_refuses_empty() -> None:
    geo = GridGeometry(0.0, 0.0, 0.1, 30, 40)
    grid = OccupancyGrid(geo)
    free = np.zeros(grid.shape, bool)
    free[5:10, 6:20] = True
    grid.mark_free(free)
    assert grid.touched_box() == (5, 10, 6, 20)
    view = grid.window(4, 12, 5, 25)
    assert view.shape == (8, 20) and view.geo.origin_x == pytest.approx(0.5) and view.geo.origin_y == pytest.approx(0.4)
    assert np.array_equal(view.free(), grid.free()[4:12, 5:25])
    assert np.shares_memory(view.values, grid.values)
    assert view.touched_box() == (1, 6, 1, 15)
    w, (r0, c0) = known_window(grid, 2)
    assert (r0, c0) == (3, 4) and w.shape == (9, 18)
    with pytest.raises(ConfigError, match="no cell"):
        grid.window(30, 40, 0, 5)


def _gs_case(seed: int) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]]:
    """A padded field whose cells outside the window's interior are all fixed (as bvp's window)."""
    rng = np.random.default_rng(seed)
    p = rng.random((40, 50))
    fixed = np.ones(p.shape, bool)
    window = (6, 31, 9, 44)
    fixed[7:30, 10:43] = rng.random((23, 33)) < 0.3
    return p, fixed, window


def test_relax_on_a_window_equals_the_reference_on_the_whole_field() -> None:
    p, fixed, window = _gs_case(0)
    assert free_box_in(fixed, 7, 30, 10, 43) == free_box(fixed)
    ref = p.copy()
    gauss_seidel_ref(ref, fixed, 9)
    fast = p.copy()
    relax(fast, fixed, 9, window=window)
    assert np.array_equal(fast, ref)                      # bit for bit, the numba sweep against Python
    eps = np.random.default_rng(1).uniform(-0.5, 0.5, p.shape)
    ref = p.copy()
    gauss_seidel_perturbed_ref(ref, fixed, 5, 0.2, -0.1, eps)
    fast = p.copy()
    relax(fast, fixed, 5, preferred=(0.2, -0.1), eps_abs=eps, window=window)
    assert np.array_equal(fast, ref)
    ref = p.copy()
    gauss_seidel_perturbed_ref(ref, fixed, 5, 0.0, 0.0, np.full(p.shape, 0.3))
    fast = p.copy()
    relax(fast, fixed, 5, eps_abs=0.3, window=window)      # a scalar eps(r)
    assert np.array_equal(fast, ref)
    with pytest.raises(ConfigError, match="window"):
        relax(p.copy(), fixed, 1, window=(0, 41, 0, 5))


def _run(explorer: FrontierExplorer | BVPExplorer, geo: GridGeometry, max_time: float) -> ExplorationRun:
    world, start = _room(), Pose(1.0, 1.0, math.pi)
    truth = ground_truth(world, geo, robot_radius=0.25, laser_range=RANGE, start=start)
    grid = OccupancyGrid(geo, model=explorer.grid_model, range_max=RANGE)
    with SimRobot(world, pose=start, seed=0, laser=LaserConfig(range_max=RANGE), max_speed=0.5, sonar=False) as robot:
        return ExplorationRun(robot, explorer, grid, truth=truth, max_time=max_time, seed=0).run()


@pytest.mark.parametrize("method", ["frontier", "bvp"])
def test_a_map_three_times_larger_drives_the_same_run(method: str) -> None:
    small = GridGeometry(-0.5, -0.5, 0.1, 50, 70)
    large = GridGeometry(-0.5, -0.5, 0.1, 150, 210)      # the same cells, and unknown space beyond
    make = FrontierExplorer if method == "frontier" else BVPExplorer
    a, b = _run(make(), small, 400.0), _run(make(), large, 400.0)
    assert a.completed and b.completed and a.reason == b.reason
    assert a.metrics.path == b.metrics.path
    assert a.coverage() == b.coverage() and a.coverage() is not None and a.coverage() > 0.97
    # the run's coverage counts in the window what the whole map counts
    assert b.truth is not None and b.coverage() == coverage(b.grid.free(), b.truth)
    assert grid_coverage(b.grid, b.truth) == coverage(b.grid.free(), b.truth)


def test_windowed_costs_and_frontier_equal_the_whole_maps() -> None:
    geo = GridGeometry(-0.5, -0.5, 0.1, 150, 210)
    run = _run(FrontierExplorer(), geo, 25.0)           # part way: frontier left
    grid = run.grid
    view, (r0, c0) = known_window(grid, 2)
    rows, cols = view.shape
    assert rows < geo.rows // 2 and cols < geo.cols // 2
    whole = plan_costs(grid, 0.25, 0.3)
    part = plan_costs(view, 0.25, 0.3)
    assert np.array_equal(part, whole[r0:r0 + rows, c0:c0 + cols])
    outside = np.ones(grid.shape, bool)
    outside[r0:r0 + rows, c0:c0 + cols] = False
    assert np.isinf(whole[outside]).all()
    t_whole, t_part = frontier_targets(grid, 5), frontier_targets(view, 5)
    assert t_part.any() and np.array_equal(t_part, t_whole[r0:r0 + rows, c0:c0 + cols])
    assert not t_whole[outside].any()


def test_plan_costs_kept_up_to_date_equal_the_whole_computation() -> None:
    geo = GridGeometry(-1.0, -2.0, 0.1, 90, 130)
    grid = OccupancyGrid(geo)
    cache = PlanCosts(0.25, 0.3)
    rng = np.random.default_rng(5)
    angles = np.linspace(-math.pi / 2, math.pi / 2, 181)
    assert np.isinf(cache.update(grid)).all()
    for k in range(60):
        pose = Pose(rng.uniform(0, 11), rng.uniform(-1, 6), rng.uniform(-math.pi, math.pi))
        grid.update(pose, LaserScan(angles, rng.uniform(0.2, 3.5, angles.size), 3.0))
        if k % 7 == 3:
            assert_same_costs(cache, grid)
    wall = np.zeros(grid.shape, bool)
    wall[40:43, 20:90] = True
    grid.mark_occupied(wall)
    assert_same_costs(cache, grid)
    other = grid.copy()                                   # another grid: computed afresh
    assert_same_costs(cache, other)
    assert np.count_nonzero(cache.points) > 50            # cells passable only off their centre, among the scans


def assert_same_costs(cache: PlanCosts, grid: OccupancyGrid) -> None:
    """The cache's costs and cell points equal `plan_costs` of the whole grid."""
    points = np.zeros(grid.shape, np.uint8)
    assert np.array_equal(cache.update(grid), plan_costs(grid, 0.25, 0.3, points))
    assert np.array_equal(cache.points, points)


def test_wall_memory_noted_after_scans_far_apart_has_the_exact_distance_within_reach() -> None:
    """Two robots mapping one grid 8 m apart, the memory noted every third scan (as each explorer of a team
    notes it at its own step): the cells ever firmly occupied and their distance within `reach` are those of
    the whole grid's (scipy's exact transform), computed box by box."""
    geo = GridGeometry(0.0, 0.0, 0.1, 120, 120)
    grid = OccupancyGrid(geo)
    memory = WallMemory(4.0)
    rng = np.random.default_rng(11)
    angles = np.linspace(-math.pi, math.pi, 181, endpoint=False)
    every = np.zeros(grid.shape, bool)
    for k in range(45):
        x, y = (2.0, 2.0) if k % 2 else (10.0, 10.0)
        pose = Pose(x + rng.uniform(-0.3, 0.3), y + rng.uniform(-0.3, 0.3), rng.uniform(-math.pi, math.pi))
        grid.update(pose, LaserScan(angles, rng.choice([0.8, 1.2, 1.5], size=angles.size), 3.0))
        if k % 3 == 2:
            dist = memory.distance(grid)
            every |= grid.firmly_occupied()
            assert np.array_equal(memory.ever, every)
            exact = distance_transform_edt(~every)
            near = exact <= 4.0
            assert near.sum() > 500
            assert np.allclose(dist[near], exact[near], atol=1e-5) and (dist[~near] > 4.0).all()

"""The frontier explorer plugin on small worlds, run end to end on the SimRobot with real ground truth.

Worlds are 6 x 4 m rooms (walls 0.1 m thick centred on x = 0, 6 m and y = 0, 4 m) split at x = 3 m
by an inner wall. The laser reaches 2 m so that the robot must
drive to see everything. Each run takes well under a second of wall time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.registry import make_explorer
from robotexp.run.loop import ExplorationRun
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.world.groundtruth import GroundTruth, ground_truth
from robotexp.planning.targets import cell_points, plan_costs, wall_distance
from robotexp.robot import LaserScan, Pose
from robotexp.sim import LaserConfig, SimRobot
from robotexp.world.model import World, segment_box
from robotexp_plugins.frontier import FrontierExplorer

T = 0.1             # [m] wall thickness
RANGE = 2.0         # [m] laser range
CELL = 0.1          # [m]
START = Pose(1.0, 1.0, math.pi)     # in the left room, facing its wall


def outer_walls() -> list[tuple[float, ...]]:
    return [segment_box(0, 0, 6, 0, T), segment_box(0, 4, 6, 4, T),
            segment_box(0, 0, 0, 4, T), segment_box(6, 0, 6, 4, T)]


def door_room() -> World:
    """Two 3 x 4 m rooms joined by a 1.1 m door (y 1.45..2.55 m) in the wall x = 3 m."""
    return World("door", np.array(outer_walls() + [segment_box(3, 0, 3, 1.4, T), segment_box(3, 2.6, 3, 4, T)]))


def gap_room(gap: float) -> World:
    """The same with a slit of `gap` [m] around y = 2 m instead of the door."""
    lo, hi = 2 - gap / 2 - T / 2, 2 + gap / 2 + T / 2     # segment_box reaches T/2 past each end
    return World("gap", np.array(outer_walls() + [segment_box(3, 0, 3, lo, T), segment_box(3, hi, 3, 4, T)]))


@dataclass
class Outcome:
    run: ExplorationRun
    end: Pose                   # true pose when the run ended
    truth: GroundTruth


def explore(world: World, *, seed: int = 0, sigma: float = 0.0, max_time: float = 600.0,
            **params: object) -> Outcome:
    geo = GridGeometry.covering(*world.bounds, cell=CELL, margin=0.5)
    truth = ground_truth(world, geo, robot_radius=0.25, laser_range=RANGE, start=START)
    grid = OccupancyGrid(geo, range_max=RANGE)
    laser = LaserConfig(range_max=RANGE, sigma=sigma)
    with SimRobot(world, pose=START, seed=seed, laser=laser, max_speed=0.5, sonar=False) as robot:
        run = ExplorationRun(robot, FrontierExplorer(**params), grid, truth=truth, max_time=max_time,  # type: ignore[arg-type]
                             seed=seed).run()
        end = robot.read().true_pose
    assert end is not None
    return Outcome(run, end, truth)


# -- whole runs ----------------------------------------------------------------------------

def test_explores_two_rooms_through_a_door() -> None:
    out = explore(door_room())
    run = out.run
    assert run.completed and run.reason == "no reachable frontier left"
    assert run.coverage() is not None and run.coverage() >= 0.99
    assert run.metrics.collisions == 0
    # the robot went into the right room (the door is its only way there)
    assert max(x for x, _ in run.metrics.path) > 3.3
    assert run.robot_time < 200.0
    assert run.metrics.milestones[0.99] is not None


def test_return_home_ends_at_the_start() -> None:
    out = explore(door_room(), return_home=True)
    assert out.run.completed and out.run.reason == "explored; back at the start"
    assert out.end.distance_to(START) < 0.2
    assert out.run.coverage() is not None and out.run.coverage() >= 0.99
    assert out.run.metrics.collisions == 0
    plain = explore(door_room())
    # driving home costs path: it is at least the distance from where plain exploration ended
    assert out.run.metrics.path_length > plain.run.metrics.path_length


def test_goes_through_a_slit_no_cell_centre_clears() -> None:
    # a 0.6 m slit (y 1.7..2.3 m) for a 0.5 m robot: its centre must keep within y 1.97..2.03 (the 2 cm
    # margin a side), and the cells' centres there lie at 1.95 and 2.05; a point a third of a cell off
    # the centre (1.983, 2.017) clears both faces
    out = explore(gap_room(0.6))
    run = out.run
    assert run.completed and run.reason == "no reachable frontier left"
    assert max(x for x, _ in run.metrics.path) > 3.5                 # through the slit
    assert run.metrics.collisions == 0
    assert run.coverage() is not None and run.coverage() >= 0.99


def test_a_region_behind_a_slit_narrower_than_the_robot_does_not_trap_the_run() -> None:
    world = gap_room(0.3)           # the robot is 0.5 m wide
    out = explore(world, max_time=600.0)
    run = out.run
    # the right room is seen through the slit (explorable) but cannot be reached
    assert not out.truth.reachable[:, out.truth.geo.cell_of(4.5, 2.0)[1]].any()
    assert out.truth.explorable[out.truth.geo.cell_of(3.5, 2.0)]
    assert run.completed and run.reason == "no reachable frontier left"
    assert run.robot_time < 300.0                          # ended on its own, long before max_time
    assert run.metrics.collisions == 0
    assert max(x for x, _ in run.metrics.path) < 3.0 - 0.05 - 0.25 + 0.01   # never through the slit
    assert run.coverage() is not None and run.coverage() >= 0.9


def test_same_seed_same_run() -> None:
    a = explore(door_room(), seed=3, sigma=0.02)
    b = explore(door_room(), seed=3, sigma=0.02)
    assert a.run.metrics.path_length == b.run.metrics.path_length
    assert a.run.robot_time == b.run.robot_time
    assert a.run.metrics.path == b.run.metrics.path
    assert np.array_equal(a.run.grid.values, b.run.grid.values)
    # the seed does matter (the laser is noisy): another one gives another map
    c = explore(door_room(), seed=4, sigma=0.02)
    assert not np.array_equal(a.run.grid.values, c.run.grid.values)


# -- parameters ----------------------------------------------------------------------------

@pytest.mark.parametrize(("params", "message"), [
    ({"min_group_cells": 0}, "min_group_cells must be >= 1, got 0"),
    ({"replan_period": 0.0}, "replan_period must be > 0, got 0.0"),
    ({"replan_period": math.nan}, "replan_period must be > 0"),
    ({"goal_timeout": -1.0}, "goal_timeout must be > 0, got -1.0"),
    ({"clearance": -0.1}, "clearance must be >= 0 m, got -0.1"),
])
def test_bad_parameters(params: dict[str, float], message: str) -> None:
    with pytest.raises(ConfigError, match=f"^frontier: {message}"):
        FrontierExplorer(**params)  # type: ignore[arg-type]


def test_parameters_through_the_registry() -> None:
    explorer = make_explorer("frontier", {"min_group_cells": 3, "return_home": True})
    assert isinstance(explorer, FrontierExplorer)
    assert explorer.min_group_cells == 3 and explorer.return_home
    with pytest.raises(ConfigError, match="method 'frontier'.*speed"):
        make_explorer("frontier", {"speed": 1.0})
    with pytest.raises(ConfigError, match="clearance"):
        make_explorer("frontier", {"clearance": -1.0})


@pytest.mark.parametrize(("method", "params", "message"), [
    ("frontier", {"return_home": "maybe"}, "'return_home' must be true or false, got 'maybe'"),
    ("frontier", {"return_home": 1}, "'return_home' must be true or false, got 1"),
    ("frontier", {"min_group_cells": 2.5}, "'min_group_cells' must be a whole number, got 2.5"),
    ("frontier", {"clearance": "wide"}, "'clearance' must be a number, got 'wide'"),
    ("frontier", {"clearance": True}, "'clearance' must be a number, got True"),
    ("srt-star", {"d_min": "auto"}, "'d_min' must be a number, got 'auto'"),
])
def test_parameter_types_are_checked_against_the_plugin(method: str, params: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=f"method '{method}': parameter {message}"):
        make_explorer(method, params)


def test_parameter_values_are_converted_where_exact() -> None:
    # a Lua or TOML number 3.0 for an int, 2 for a float; None where the plugin allows it
    explorer = make_explorer("frontier", {"min_group_cells": 3.0, "clearance": 1, "replan_period": 2})
    assert isinstance(explorer, FrontierExplorer)
    assert explorer.min_group_cells == 3 and isinstance(explorer.min_group_cells, int)
    assert explorer.clearance == 1.0 and isinstance(explorer.clearance, float)
    assert make_explorer("frontier", {"min_group_cells": None}).min_group_cells is None  # type: ignore[attr-defined]


# -- plan_costs ----------------------------------------------------------------------------

def tiny_grid(cell: float, size: int) -> OccupancyGrid:
    """A size x size grid, all free but the centre cell (occupied)."""
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, cell, size, size))
    free = np.ones((size, size), dtype=bool)
    c = size // 2
    free[c, c] = False
    grid.mark_free(free)
    grid.mark_occupied(~free)
    return grid


def test_plan_costs_blocks_radius_and_margin_from_a_cell_without_hits() -> None:
    # a cell marked occupied holds no laser endpoint: the wall may be anywhere in it, so the distance
    # is to its square. Cell 0.1 m, radius 0.25 m: blocked where every point of the cell (its centre and
    # eight more a third of a cell away) lies within (0.25 + 0.02) / 0.1 = 2.7 cells of the square of
    # (5, 5). The farthest point of the cell at (dr, dc) lies a third of a cell farther out on each axis
    # off the centre line: hypot(max(|dr| - 1/2 + 1/3, 0), max(|dc| - 1/2 + 1/3, 0))
    points = np.zeros((11, 11), np.uint8)
    cost = plan_costs(tiny_grid(0.1, 11), radius=0.25, clearance=0.0, points=points)
    for (r, c), blocked in {(5, 5): True, (5, 7): True, (7, 7): True, (7, 6): True,       # 0, 1.83, 2.59, 2.01
                            (5, 8): False, (8, 6): False, (2, 5): False,                  # 2.83, 2.95, 2.83
                            (5, 9): False, (8, 7): False, (0, 0): False}.items():         # centres 3.5, 2.92, 6.36
        assert np.isinf(cost[r, c]) == blocked, (r, c)
    # at their centres (5, 8), (8, 6) and (2, 5) lie 2.5, 2.55 and 2.5 cells off: they pass at the point a
    # third of a cell farther out, which the plan names (`SUB_POINTS`: 3 is (0, +1/3), 8 (+1/3, +1/3), 1
    # (-1/3, 0)); a cell whose centre is clear keeps its centre (0)
    assert (points[5, 8], points[8, 6], points[2, 5], points[5, 9], points[0, 0]) == (3, 8, 1, 0, 0)
    assert cell_points(GridGeometry(0.0, 0.0, 0.1, 11, 11), [(5, 8), (8, 6), (5, 9)], points) == \
        pytest.approx(np.array([[0.85 + 0.1 / 3, 0.55], [0.65 + 0.1 / 3, 0.85 + 0.1 / 3], [0.95, 0.55]]))
    # without a danger zone every other cell costs 1
    assert np.all((cost == 1.0) | np.isinf(cost))
    dr, dc = np.meshgrid(np.abs(np.arange(11) - 5) - 1 / 6, np.abs(np.arange(11) - 5) - 1 / 6, indexing="ij")
    assert np.array_equal(np.isinf(cost), np.hypot(np.maximum(dr, 0), np.maximum(dc, 0)) <= 2.7 + 1e-6)


def test_plan_costs_in_cells_of_5_cm() -> None:
    # cell 0.05 m: (0.25 + 0.02) / 0.05 = 5.4 cells from the occupied cell's square, at the cell's best point
    cost = plan_costs(tiny_grid(0.05, 17), radius=0.25, clearance=0.0)
    c = 8
    assert np.isinf(cost[c + 2, c + 5])           # hypot(1.83, 4.83) = 5.17 cells
    assert np.isinf(cost[c, c + 5])               # 4.83
    assert np.isfinite(cost[c + 3, c + 5])        # hypot(2.83, 4.83) = 5.60 (its centre: hypot(2.5, 4.5) = 5.15)
    assert np.isfinite(cost[c, c + 6])            # 5.83


def test_plan_costs_measure_to_the_laser_endpoints_in_a_cell() -> None:
    # a wall face at x = 1.03 m, seen from (0.55, 1.05): the endpoints lie in the cells of column 10
    # (x 1.0..1.1) at 0.3 of a cell from their left side. A cell centre at x = 0.75 m is 0.28 m from the
    # surface: free for a 0.25 m robot (0.27 m needed); the old rule (centres 3 cells apart, within
    # 3.5) blocked it. x = 0.85 m is 0.18 m away: blocked.
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 21, 21))
    angles = np.linspace(-0.4, 0.4, 41)
    scan = LaserScan(angles, 0.48 / np.cos(angles), range_max=3.0)
    grid.update(Pose(0.55, 1.05, 0.0), scan)
    box = grid.hit_box[10, 10]
    assert box.tolist()[:2] == [76, 77]           # 0.3 * 255 = 76.5, rounded outwards
    assert box[2] <= 26 and box[3] >= 229         # endpoints 1 cm apart across the cell's height (1.0..1.1 m)
    dist = wall_distance(grid, 10.0)
    assert dist[10, 7] * 0.1 == pytest.approx(0.28, abs=0.001)
    cost = plan_costs(grid, radius=0.25, clearance=0.0)
    assert np.isfinite(cost[10, 7]) and np.isinf(cost[10, 8])


def test_plan_costs_danger_zone_and_unknown_cells() -> None:
    grid = tiny_grid(0.1, 11)
    # clearance 0.2 m = 2 cells beyond 2.7: cost 1 + 4 (1 - (d - 2.7) / 2) for 2.7 < d <= 4.7, d to the square
    cost = plan_costs(grid, radius=0.25, clearance=0.2)
    assert cost[5, 9] == pytest.approx(1 + 4 * (1 - 0.8 / 2))                      # d = 3.5: 3.4
    assert cost[5, 10] == pytest.approx(1 + 4 * (1 - 1.8 / 2))                     # d = 4.5: 1.4
    assert cost[8, 7] == pytest.approx(1 + 4 * (1 - (math.hypot(2.5, 1.5) - 2.7) / 2), rel=1e-6)
    assert cost[0, 0] == 1.0                                                       # d = 6.36
    # unknown cells are never passable, however far from walls
    unknown_corner = OccupancyGrid(grid.geo)
    values = grid.values.copy()
    values[0, 0] = 0.0
    unknown_corner.values[:] = values
    cost2 = plan_costs(unknown_corner, radius=0.25, clearance=0.2)
    assert np.isinf(cost2[0, 0]) and cost2[0, 1] == 1.0


def _frontier_of(explorer: FrontierExplorer, grid: OccupancyGrid) -> np.ndarray:
    from robotexp.explorer import ExplorerContext
    from robotexp.planning.targets import known_window
    from robotexp.robot import Limits

    explorer.reset(ExplorerContext(radius=0.25, limits=Limits(v_max=0.3, w_max=1.0), period=0.1,
                                   start=Pose(1.0, 1.0, 0.0), laser_range=3.0, rng=np.random.default_rng(0)))
    view, off = known_window(grid, 2)
    out = np.zeros(grid.shape, bool)
    rows, cols = view.shape
    out[off[0]:off[0] + rows, off[1]:off[1] + cols] = explorer._frontier_targets(grid, view, off)
    return out


def test_grazed_wall_face_is_no_frontier_but_an_opening_is() -> None:
    """A 0.4 m wall seen from both sides whose face beams grazed clear over 1.1 m (its inside unknown),
    and a room open to the east onto unknown space: only the opening is a target by default."""
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 60, 60))
    free = np.zeros(grid.shape, bool)
    free[5:20, 5:40] = free[24:40, 5:40] = True        # two rooms either side of the wall (rows 20-23)
    wall = np.zeros(grid.shape, bool)
    wall[20, 5:40] = wall[23, 5:40] = True             # the wall's two faces; rows 21-22 never seen
    wall[23, 10:21] = False
    free[23, 10:21] = True                             # grazing beams cleared 11 face cells
    grid.mark_free(free)
    grid.mark_occupied(wall)
    old = _frontier_of(FrontierExplorer(face_reach=0.0), grid)
    new = _frontier_of(FrontierExplorer(), grid)
    face = np.zeros(grid.shape, bool)
    face[23, 10:21] = True
    assert (old & face).sum() >= 5 and not (new & face).any()
    opening = np.zeros(grid.shape, bool)
    opening[6:19, 39] = opening[25:39, 39] = True      # the rooms' east ends, unknown beyond
    # the opening stays a target, but for its cells within face_reach of the wall's corners
    assert (new & opening).sum() >= 20 and not (new & ~old).any()
    with pytest.raises(ConfigError, match="face_reach"):
        FrontierExplorer(face_reach=-1.0)


def test_worn_face_of_a_deep_shelf_is_no_frontier(shelf_aisles: Callable[[float], tuple]) -> None:
    """A shelf 1 m deep whose face was seen (occupied) and then worn free over 1.1 m by grazing beams
    (log-odds: a pass cancels a hit): its unknown inside lies 0.5 m from the walls left on the map, but
    one cell from walls the explorer saw; no target there. The room's open east end stays a target."""
    from robotexp.planning.targets import WallMemory, distance_transform

    grid, free, wall = shelf_aisles(0.1)     # aisles either side of the shelf's faces, rows 20 and 30
    old, new = FrontierExplorer(face_reach=0.0), FrontierExplorer()
    _frontier_of(old, grid)
    _frontier_of(new, grid)
    new.step(_state(), grid)        # the explorer notes the walls the map shows (after every scan)
    worn = np.zeros(grid.shape, bool)
    worn[30, 10:21] = True
    grid.mark_free(worn)            # grazing beams wore 11 face cells down to free
    face = np.zeros(grid.shape, bool)
    face[30, 10:21] = True
    opening = np.zeros(grid.shape, bool)
    opening[6:19, 39] = opening[32:44, 39] = True      # the aisles' east ends, unknown beyond
    got_old, got_new = _targets_now(old, grid), _targets_now(new, grid)
    # the map's own walls no longer explain the worn face: the explorer without wall memory (and face_reach on
    # the map's walls) sends the robot there
    assert (got_old & face).sum() >= 5
    assert not (got_new & face).any()
    assert (got_new & opening).sum() >= 20 and not (got_new & ~got_old).any()
    # the memory against its definition: the distance to every cell ever occupied, from scratch
    assert new.walls_seen is not None and (new.walls_seen.ever == wall).all()
    mem = WallMemory(3.0)
    mem.note(grid)
    assert (mem.ever == (wall & ~worn)).all()        # a fresh memory knows only the walls the map shows now
    want = distance_transform(wall)
    got = new.walls_seen.distance(grid)
    near = want <= 2.5
    assert np.allclose(got[near], want[near]) and (got[~near] > 2.5).all()


def _state() -> object:
    from robotexp.robot import RobotState, Twist

    return RobotState(time=0.0, pose=Pose(1.0, 1.0, 0.0), velocity=Twist.ZERO)


def _targets_now(explorer: FrontierExplorer, grid: OccupancyGrid) -> np.ndarray:
    """The explorer's targets on `grid` now, without resetting it (its memory kept)."""
    from robotexp.planning.targets import known_window

    memory = getattr(explorer, "walls_seen", None)
    if memory is not None:
        memory.note(grid)
    view, off = known_window(grid, 2)
    out = np.zeros(grid.shape, bool)
    rows, cols = view.shape
    out[off[0]:off[0] + rows, off[1]:off[1] + cols] = explorer._frontier_targets(grid, view, off)
    return out


@pytest.mark.parametrize("model", ["logodds", "himm"])
def test_wall_memory_keeps_walls_seen_twice_not_a_stray_hit(model: str) -> None:
    """A scan taken from a slightly wrong pose (a heading a packet old) puts one hit 0.6 m short of the
    wall, in free space; the next scans cross that cell. It must not stay a wall in the memory (a stray
    hit beside a doorway would hide the opening for the rest of the run), while the wall, hit by two
    scans and then worn down by grazing beams, stays one."""
    from robotexp.planning.targets import WallMemory
    from robotexp.robot import LaserScan

    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 40, 40), model=model)   # type: ignore[arg-type]
    beam = LaserScan(np.array([0.0]), np.array([2.0]), 5.0)      # from (0.55, 2.05) east: hits x = 2.55
    short = LaserScan(np.array([0.0]), np.array([1.4]), 5.0)     # the stray hit at x = 1.95
    pose = Pose(0.55, 2.05, 0.0)
    wall, stray = (20, 25), (20, 19)
    mem = WallMemory(3.0)
    grid.update(pose, short)            # the stray scan comes first, onto unknown cells
    mem.note(grid)
    assert grid.occupied()[stray] and not mem.ever[stray]
    grid.update(pose, beam)
    mem.note(grid)
    assert grid.occupied()[wall] and not grid.firmly_occupied()[wall]     # one hit: occupied, not firm
    grid.update(pose, beam)             # the next scans cross the stray cell and hit the wall again
    mem.note(grid)
    assert grid.firmly_occupied()[wall] and mem.ever[wall]
    assert grid.free()[stray] and not mem.ever[stray]
    grid.mark_free(np.pad(np.ones((1, 1), bool), ((20, 19), (25, 14))))    # grazing beams wear the wall
    mem.note(grid)
    assert not grid.occupied()[wall] and mem.ever[wall]
    assert mem.ever.sum() == 1


def test_firmly_occupied_thresholds() -> None:
    """Log-odds: two hits (2 logit(0.9) = 4.39, clamped to l_clamp) are firm, one (2.20) is not, and
    with a larger clamp two hits still are; HIMM: two hits (+3 each = 6) are, one (3) is not."""
    geo = GridGeometry(0.0, 0.0, 0.1, 1, 4)
    grid = OccupancyGrid(geo)
    grid.values[0] = [2.1972246, 3.5, 3.4, -3.5]
    assert grid.firmly_occupied()[0].tolist() == [False, True, False, False]
    wide = OccupancyGrid(geo, l_clamp=10.0)
    wide.values[0] = [2.1972246, 4.3944492, 4.3, 10.0]
    assert wide.firmly_occupied()[0].tolist() == [False, True, False, True]
    himm = OccupancyGrid(geo, model="himm")
    himm.values[0] = [3, 5, 6, 15]
    assert himm.firmly_occupied()[0].tolist() == [False, False, True, True]


class _CheckedGoalOpen(FrontierExplorer):
    """Frontier whose look near the goal is checked against the whole scanned window at every refresh."""

    def reset(self, ctx) -> None:  # type: ignore[no-untyped-def]
        super().reset(ctx)
        self.answers: list[tuple[bool, bool]] = []

    def _goal_open(self, grid: OccupancyGrid) -> bool:
        near = super()._goal_open(grid)
        if self.goal is not None and not self.follower.done and len(self.goal_cells):
            from robotexp.planning.targets import known_window
            view, off = known_window(grid, 2)
            local = self.goal_cells - off
            self.answers.append((near, bool(self._frontier_targets(grid, view, off)[local[:, 0], local[:, 1]].any())))
        return near


def test_the_goal_is_open_near_it_as_on_the_whole_window() -> None:
    # whether the goal's frontier is still there is asked near the goal only; along a whole run through a
    # door (the groups split, shrink below the smallest kept and vanish) the answer is the whole window's
    world = door_room()
    geo = GridGeometry.covering(*world.bounds, cell=CELL, margin=0.5)
    grid = OccupancyGrid(geo, range_max=RANGE)
    explorer = _CheckedGoalOpen(min_group_cells=10)     # groups 1 m long: their size matters
    with SimRobot(world, pose=START, seed=0, laser=LaserConfig(range_max=RANGE), max_speed=0.5, sonar=False) as robot:
        run = ExplorationRun(robot, explorer, grid, max_time=600.0, seed=0).run()  # type: ignore[arg-type]
    assert run.completed
    assert len(explorer.answers) >= 10
    assert all(near == whole for near, whole in explorer.answers)
    assert {whole for _, whole in explorer.answers} == {True, False}       # both answers were asked for


def test_a_coordinators_target_it_cannot_reach_leaves_the_robot_exploring() -> None:
    """A team's coordinator gives the robot a frontier it cannot reach (a patch seen through a gap, no way
    there on the map): the robot chooses alone among the frontier it can reach (its room's edges, unknown
    beyond), it does not end its exploration while that is left."""
    from robotexp.explorer import ExplorerContext
    from robotexp import Done
    from robotexp.robot import Limits, Twist

    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 60, 60))
    free = np.zeros(grid.shape, bool)
    free[5:30, 5:30] = True             # the robot's room, unknown all round
    free[45:52, 45:52] = True           # a patch beyond unknown space: frontier all round, no way to it
    grid.mark_free(free)
    explorer = FrontierExplorer()
    explorer.reset(ExplorerContext(radius=0.25, limits=Limits(v_max=0.3, w_max=1.0), period=0.1,
                                   start=Pose(1.0, 1.0, 0.0), laser_range=3.0, rng=np.random.default_rng(0)))
    patch = np.argwhere(_targets_now(explorer, grid) & (np.arange(60)[:, None] >= 45))
    assert len(patch) >= 20
    explorer.assign_targets(patch)
    decision = explorer.step(_state(), grid)
    assert isinstance(decision, Twist) and not isinstance(decision, Done)
    assert explorer.goal is not None and max(explorer.goal) < 3.0      # in its room


def test_explorers_on_one_map_share_one_memory_of_walls() -> None:
    """The explorers of a team plan on one map: they share one memory of the walls (`shared_wall_memory`), the
    cells ever firmly occupied noted once for all and one distance to them. A wall that is firm only between two
    of one explorer's notes (hit twice, then worn by grazing beams) is in its memory when a teammate noted it
    then; a map rebuilt after a loop closure starts the explorer's memory afresh, and a memory that holds the old
    cells (the run's check) keeps them."""
    from robotexp.localization import FrameCorrection
    from robotexp.planning.targets import WallMemory, shared_firm_cells
    from robotexp.robot import LaserScan

    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 40, 40))
    a, b = FrontierExplorer(), FrontierExplorer()
    _frontier_of(a, grid)
    _frontier_of(b, grid)
    mem_a, mem_b = a._memory(grid), b._memory(grid)
    assert mem_a is mem_b and mem_a.cells is shared_firm_cells(grid)
    beam = LaserScan(np.array([0.0]), np.array([2.0]), 5.0)      # from (0.55, 2.05) east: hits (20, 25)
    pose = Pose(0.55, 2.05, 0.0)
    wall = (20, 25)
    grid.update(pose, beam)
    grid.update(pose, beam)
    mem_a.note(grid)                    # robot A's step: the wall is firm now
    grid.mark_free(np.pad(np.ones((1, 1), bool), ((20, 19), (25, 14))))    # grazing beams wear it
    assert not grid.occupied()[wall]
    own = WallMemory(3.0)               # a memory of its own notes only what the map shows at its note
    own.note(grid)
    assert not own.ever[wall]
    mem_b.note(grid)                    # robot B's step, after the wear: B remembers the wall A saw firm
    assert mem_b.ever[wall] and mem_b.ever.sum() == 1
    # one distance for both, brought up to date by whoever asks first: 2 cells east of the wall, 2 cells away
    assert a._memory(grid).distance(grid) is b._memory(grid).distance(grid)
    assert b._memory(grid).distance(grid)[20, 27] == pytest.approx(2.0)
    kept = WallMemory(1.5, shared_firm_cells(grid))     # the run's check holds the same cells
    a.map_rebuilt(grid, FrameCorrection([0.0], [(0.0, 0.0, 0.0)]))
    fresh = a._memory(grid)
    fresh.note(grid)
    assert fresh.cells is not kept.cells and not fresh.ever[wall]
    assert kept.ever[wall] and mem_b.ever[wall]

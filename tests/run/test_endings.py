"""Honest endings through the run loop: a run that gains nothing ends stalled, an explorer's "done"
with reachable frontier left is not a completed run, and no explorer leaves the exploration area."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.explorer import Done, Explorer
from robotexp.run.loop import ExplorationRun
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.world.groundtruth import ground_truth
from robotexp.robot import Pose, RobotState, Twist
from robotexp.sim import LaserConfig, SimRobot, SimTeam
from robotexp.run.endings import RunWatch, StallWatch
from robotexp.run.record import EndReason
from robotexp.run.team import TeamRun
from robotexp.world.model import World, segment_box

T = 0.1
# a closed 10 x 6 m hall split by a wall at x = 4 m with a 1.2 m door: from the west room the east one is unseen
HALL = World("hall", np.array([segment_box(0, 0, 10, 0, T), segment_box(10, 0, 10, 6, T), segment_box(10, 6, 0, 6, T),
                               segment_box(0, 6, 0, 0, T), segment_box(4, 0, 4, 2.4, T), segment_box(4, 3.6, 4, 6, T)]))
GEO = GridGeometry.covering(*HALL.bounds, cell=0.1, margin=0.5)
LASER = LaserConfig(beams=360, fov=2 * math.pi, range_max=3.0)


class Spin(Explorer):
    """Turns on the spot for ever: after one turn it learns nothing more."""

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        return Twist(0.0, 0.5)


class QuitAtOnce(Explorer):
    """Says it has explored everything at its first step."""

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        return Done("explored")


class Wander(Explorer):
    """Drives ahead and turns away whenever its scan shows something within 0.6 m ahead."""

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        scan = state.laser
        assert scan is not None
        ahead = np.abs(scan.angles) < 0.4
        near = np.nanmin(np.where(np.isfinite(scan.ranges[ahead]), scan.ranges[ahead], np.inf))
        return Twist(0.0, 0.8) if near < 0.6 else Twist(0.3, 0.0)


def run(explorer: Explorer, watch: RunWatch, start: Pose, *, area=None, max_time: float = 300.0,
        world: World = HALL, geo: GridGeometry = GEO) -> ExplorationRun:
    with SimRobot(world, pose=start, laser=LASER, max_speed=0.3, sonar=False) as robot:
        truth = ground_truth(world, geo, robot_radius=robot.radius, laser_range=3.0, start=start)
        r = ExplorationRun(robot, explorer, OccupancyGrid(geo), truth=truth, max_time=max_time, observers=[watch],
                           area=area)
        return r.run()


def test_a_run_that_learns_nothing_ends_stalled_after_three_windows():
    r = run(Spin(), RunWatch(StallWatch(window=20.0)), Pose(2.0, 3.0, 0.0))
    assert not r.completed
    assert r.reason.startswith("stalled: no newly known space for 3 x 20 s")
    # one turn (12.6 s at 0.5 rad/s) maps the west room; then three empty windows of 20 s
    assert 60.0 <= r.robot_time <= 80.0


def test_done_with_reachable_frontier_left_is_not_a_completed_run():
    r = run(QuitAtOnce(), RunWatch(StallWatch()), Pose(2.0, 3.0, 0.0))
    assert not r.completed
    assert r.reason.startswith("stopped: the explorer ended (explored) with ") and "frontier cells left" in r.reason
    # the same explorer in a closed room it has seen whole: done is done
    room = World("room", np.array([segment_box(0, 0, 3, 0, T), segment_box(3, 0, 3, 3, T), segment_box(3, 3, 0, 3, T),
                                   segment_box(0, 3, 0, 0, T)]))
    geo = GridGeometry.covering(*room.bounds, cell=0.1, margin=0.5)
    r = run(QuitAtOnce(), RunWatch(StallWatch()), Pose(1.5, 1.5, 0.0), world=room, geo=geo)
    assert r.completed and r.reason == "explored"


class WearTheFaceThenQuit(Explorer):
    """Turns on the spot for 2 s (the scans hit the east wall's face again and again), then wears the
    face down to free as beams grazing it would, and says it has explored everything."""

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        if state.time < 2.0:
            return Twist(0.0, 0.2)
        face = np.zeros(grid.shape, bool)
        rows, cols = grid.geo.cells_of(np.array([[3.55, 0.6], [3.55, 2.4]])).T
        face[rows[0]:rows[1] + 1, cols[0]] = True
        grid.mark_free(face & grid.occupied())
        return Done("explored")


def test_a_worn_face_of_a_thick_wall_is_no_frontier_left():
    """A closed room whose east wall is 1 m thick: the robot sees its face, grazing beams then wear the
    face down to free, so the unknown inside of the wall borders free cells. The watch remembers the
    walls it saw (`WallMemory`): the explorer's "explored" stands. Asked of the worn map alone, the
    wall's inside is 2 m2 and more of unknown space behind reachable frontier."""
    from robotexp.run.endings import unexplored_left

    room = World("thick", np.array([segment_box(0, 0, 4, 0, T), segment_box(4, 0, 4, 3, 1.0),
                                    segment_box(4, 3, 0, 3, T), segment_box(0, 3, 0, 0, T)]))
    geo = GridGeometry.covering(*room.bounds, cell=0.1, margin=0.5)
    r = run(WearTheFaceThenQuit(), RunWatch(StallWatch()), Pose(1.5, 1.5, 0.0), world=room, geo=geo)
    assert r.completed and r.reason == "explored", r.reason
    left = unexplored_left(r.grid, Pose(1.5, 1.5, 0.0), 0.25, np.asarray(r.metrics.path))
    assert left is not None and left[1] >= 2.0


def test_a_worn_face_of_a_thick_wall_is_no_frontier_left_to_a_team():
    """As for one robot (above): two robots in a closed room whose east wall is 1 m thick
    see its face, grazing beams then wear it down to free. The team remembers the walls its map showed
    (`WallMemory`): the explorers' "explored" stands. Asked of the worn map alone, the wall's inside is 2 m2
    and more of unknown space behind frontier robot 1 can reach."""
    from robotexp.run.endings import unexplored_left

    room = World("thick", np.array([segment_box(0, 0, 4, 0, T), segment_box(4, 0, 4, 3, 1.0),
                                    segment_box(4, 3, 0, 3, T), segment_box(0, 3, 0, 0, T)]))
    grid = OccupancyGrid(GridGeometry.covering(*room.bounds, cell=0.1, margin=0.5))
    robots = [SimRobot(room, pose=Pose(1.2, 1.0, 0.0), laser=LASER, sonar=False),
              SimRobot(room, pose=Pose(1.2, 2.0, 0.0), laser=LASER, sonar=False)]
    with SimTeam(robots) as team:
        run = TeamRun(robots, [WearTheFaceThenQuit(), WearTheFaceThenQuit()], [grid, grid], team.make_clock(0.1),
                      max_time=30.0)
        run.run()
    assert run.record.end is EndReason.EXPLORED and run.completed, run.record.reason
    left = unexplored_left(grid, Pose(1.2, 1.0, 0.0), robots[0].radius, np.asarray(run.members[0].metrics.path))
    assert left is not None and left[1] >= 2.0


def test_scans_clipped_at_the_area_keep_a_scan_driven_explorer_inside_it():
    area = (0.5, 0.5, 3.5, 5.5)                  # the west room less 0.5 m: its edge is no wall
    r = run(Wander(), RunWatch(None, area), Pose(2.0, 3.0, 0.0), area=area, max_time=240.0)
    path = np.array(r.metrics.path)
    assert r.reason.startswith("time limit") and r.metrics.path_length > 20.0
    assert path[:, 0].min() >= 0.5 - 0.3 and path[:, 0].max() <= 3.5 + 0.3
    assert path[:, 1].min() >= 0.5 - 0.3 and path[:, 1].max() <= 5.5 + 0.3
    # without the clipped scans the same explorer leaves the area, and the guard ends the run
    r = run(Wander(), RunWatch(None, area), Pose(2.0, 3.0, 0.0), area=None, max_time=240.0)
    assert not r.completed and r.reason.startswith("stopped: the robot left the exploration area")


def open_map(tmp_path: Path) -> Path:
    """A 6 x 4 m room with a 1.5 m gap in its east wall; the header declares 1 m around it."""
    path = tmp_path / "open.map"
    path.write_text("2D-Map\nMinPos: -1000 -1000\nMaxPos: 7000 5000\nLineMinPos: 0 0\nLineMaxPos: 6000 4000\n"
                    "Cairn: RobotHome 1500 2000 0 \"\" ICON \"\"\n"
                    "LINES\n0 0 6000 0\n0 4000 6000 4000\n0 0 0 4000\n6000 0 6000 1250\n6000 2750 6000 4000\n")
    return path


def test_frontier_on_an_open_map_stays_in_the_declared_area_and_ends_on_its_own(tmp_path):
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["explore", "-w", str(open_map(tmp_path)), "-m", "frontier", "-o", str(out),
                                       "--max-time", "1800"])
    assert result.exit_code == 0, result.output
    record = json.loads((out / "results.jsonl").read_text().splitlines()[-1])
    assert record["completed"], record["reason"]
    assert record["coverage"] > 0.95
    path = np.loadtxt(next(out.glob("*.path.csv")), delimiter=",", skiprows=1)
    assert path[:, 0].max() <= 7.0 + 0.3 and path[:, 0].min() >= -1.0 - 0.3
    assert path[:, 1].max() <= 5.0 + 0.3 and path[:, 1].min() >= -1.0 - 0.3
    assert path[:, 0].max() > 6.2                  # it did go out through the gap


def test_bounds_on_the_command_line_and_as_walls(tmp_path):
    out = tmp_path / "out"
    args = ["explore", "-w", str(open_map(tmp_path)), "-m", "frontier", "-o", str(out), "--max-time", "900",
            "--bounds", "-200,-200,6200,4200", "--bounds-wall"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    record = json.loads((out / "results.jsonl").read_text().splitlines()[-1])
    assert record["completed"] and record["coverage"] > 0.95 and record["collisions"] == 0
    path = np.loadtxt(next(out.glob("*.path.csv")), delimiter=",", skiprows=1)
    assert path[:, 0].max() <= 6.2                 # the wall along x = 6.2 m closed the gap
    bad = CliRunner().invoke(main, ["explore", "-w", "dense", "-o", str(out), "--bounds", "1,2,3"])
    assert bad.exit_code == 2 and "--bounds '1,2,3'" in bad.output


def test_campaigns_take_generated_world_ranges_and_bounds(tmp_path):
    from robotexp.campaign.spec import load_campaign

    camp = tmp_path / "c.toml"
    camp.write_text('[campaign]\nname = "g"\nbounds_mm = [0, 0, 12000, 10000]\n'
                    '[[set]]\nworlds = "generated:office:0-2:12x10"\nmethods = ["frontier"]\n'
                    '[[set]]\nworld = "generated:cave:5:12x10"\nmethods = ["frontier", "bvp"]\n')
    runs = load_campaign(camp).runs
    assert [r.world for r in runs] == ["generated:office:0:12x10", "generated:office:1:12x10",
                                       "generated:office:2:12x10", "generated:cave:5:12x10", "generated:cave:5:12x10"]
    assert all(r.map_bounds == (0.0, 0.0, 12.0, 10.0) for r in runs)


def _gap_map(gap: int) -> OccupancyGrid:
    """3 x 3 m at 0.1 m: free below y = 1.5 m, a wall in row 15 (y 1.5..1.6 m, cells marked occupied: no
    endpoints, each counts as its whole square) with a gap of `gap` unknown cells from column 13, unknown
    above."""
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 30, 30))
    free = np.zeros((30, 30), dtype=bool)
    free[:15, :] = True
    wall = np.zeros((30, 30), dtype=bool)
    wall[15, :] = True
    wall[15, 13:13 + gap] = False
    grid.mark_free(free)
    grid.mark_occupied(wall)
    return grid


def test_frontier_left_counts_unknown_space_only_through_gaps_the_planners_pass() -> None:
    from robotexp.run.endings import frontier_left
    # a Kobuki (0.175 m) needs 0.195 m from the walls' surface (the planners' radius plus MARGIN). In a
    # gap of 4 cells (0.4 m) every cell centre lies 0.05 or 0.15 m from a side: closed to the planners, so
    # the unknown beyond is not space left (between cell centres the gap's middle cells are 0.2 m from the
    # wall cells' centres: open to a disc of the radius alone, as the check counted before)
    assert frontier_left(_gap_map(4), Pose(1.5, 0.7, 0.0), 0.175) == (0, 0.0)
    # 6 cells (0.6 m): the middle cells lie 0.25 m from the sides; the unknown beyond is space left, up to
    # LEFT_REACH (2 m) from the frontier cells, above the wall
    cells, area = frontier_left(_gap_map(6), Pose(1.5, 0.7, 0.0), 0.175)
    assert cells > 0 and area > 2.0

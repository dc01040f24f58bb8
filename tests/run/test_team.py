"""Team runs end to end: one record for the team, repeatable, maps shared within a communication range."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from robotexp import Coordinator, Done, Explorer, PluginError, RunRecord, Twist
from robotexp.errors import ConfigError
from robotexp.experiment import run_team
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import Pose
from robotexp.run.record import EndReason
from robotexp.run.spec import RunSpec
from robotexp.run.team import TeamRun, TeamSpec, parse_team
from robotexp.sim import LaserConfig, SimRobot, SimTeam
from robotexp.testing.explorer_contract import make_room
from robotexp.world.model import World, segment_box


def room_team(out, coordinator="burgard", robots=("p3dx", "p3dx"), max_time=40.0, **team):
    spec = RunSpec(world="conformance-room", method="frontier", max_time=max_time, laser_range=3.0)
    return run_team(spec, TeamSpec(robots=robots, coordinator=coordinator, **team), out, image=False,
                    world=make_room())


def test_a_team_run_writes_one_record_with_the_team_keys(tmp_path):
    out = room_team(tmp_path)
    r = out.record
    assert r.team_size == 2 and r.coordinator == "burgard" and r.comm_range_m is None
    robots = r.robots
    assert [x["robot"] for x in robots] == ["p3dx", "p3dx"]
    paths = [x["path_length_m"] for x in robots]
    assert all(p > 0 for p in paths)
    assert r.total_path_m == pytest.approx(sum(paths), abs=1e-3) and r.path_length_m == r.total_path_m
    assert r.max_path_m == pytest.approx(max(paths), abs=1e-4)
    assert r.collisions == sum(x["collisions"] for x in robots)
    assert r.robot_collisions == sum(x["robot_collisions"] for x in robots)
    assert r.idle_time_s == pytest.approx(sum(x["idle_time_s"] for x in robots))
    seen = [x["cells_seen"] for x in robots]
    assert 0 < r.overlap_ratio < 1
    assert r.coverage > 0.9 and r.time_to_coverage_90_s is not None
    starts = [x["start_pose"] for x in robots]
    assert math.dist(starts[0][:2], starts[1][:2]) >= 2 * 0.26 + 0.3 - 1e-9
    assert seen[0] > 0 and seen[1] > 0
    # one line in results.jsonl (checked against the schema by conftest), read back as it was written
    lines = (tmp_path / "results.jsonl").read_text().splitlines()
    assert len(lines) == 1
    data = json.loads(lines[0])
    assert RunRecord.from_dict(data).as_dict() == data == r.as_dict()
    assert list(data)[-10:] == ["team_size", "coordinator", "comm_range_m", "total_path_m", "max_path_m",
                                "overlap_ratio", "idle_time_s", "robot_collisions", "coordinator_rounds", "robots"]
    assert (tmp_path / f"{r.run}.robot_2.path.csv").is_file()


def test_a_team_run_repeats_for_a_seed():
    a, b = room_team(None, "minpos", max_time=15.0).record, room_team(None, "minpos", max_time=15.0).record
    assert a.as_dict() | {"wall_time_s": 0} == b.as_dict() | {"wall_time_s": 0}


def test_a_one_robot_record_has_no_team_keys_and_old_records_load():
    old = {"run": "r", "method": "frontier", "world": "dense", "start_pose": None, "max_speed_m_s": 0.3,
           "path_length_m": 1.0, "robot_time_s": 2.0, "wall_time_s": 0.1, "coverage": 0.5, "collisions": 0,
           "nodes": None, "visited_cells": 3, "seed": 0, "completed": False, "reason": "time limit of 2 s reached",
           "map_iou": None, "cell_m": 0.1}
    record = RunRecord.from_dict(old)
    assert record.team_size is None and record.robots is None
    assert list(record.as_dict()) == list(old) + [k for k in record.as_dict() if k not in old]
    assert "team_size" not in record.as_dict()


def test_reactive_explorers_need_coordinator_none_and_bad_teams_are_refused():
    spec = RunSpec(world="conformance-room", method="bvp", max_time=5.0)
    with pytest.raises(ConfigError, match="does not take targets"):
        run_team(spec, TeamSpec(robots=("p3dx", "p3dx"), coordinator="greedy"), None, world=make_room())
    with pytest.raises(PluginError, match="unknown coordinator"):
        run_team(spec, TeamSpec(robots=("p3dx",), coordinator="nobody"), None, world=make_room())
    with pytest.raises(ConfigError, match="one each"):
        TeamSpec(robots=("p3dx", "p3dx"), poses=("start",)).validate()
    assert parse_team("3", "kobuki") == ("kobuki",) * 3
    assert parse_team("p3dx, kobuki") == ("p3dx", "kobuki")
    for bad in ("0", "-1", " -3 ", "65", "1" * 30):
        with pytest.raises(ConfigError, match=r"a team has 1\.\.64 robots, got"):
            parse_team(bad)
    for bad, n in (("p3dx,,kobuki", 2), ("p3dx,kobuki,", 3), (",p3dx", 1)):      # a typo is not a smaller team
        with pytest.raises(ConfigError, match=rf"--team: robot {n} of '{bad}' is empty: give one preset per robot"):
            parse_team(bad)
    for bad in ("+-3", "--3"):      # not a number: read as preset names, refused as such by the run
        assert parse_team(bad) == (bad,)


class Drive(Explorer):
    """Drives straight ahead until its x passes `stop_x`."""

    def __init__(self, stop_x: float) -> None:
        self.stop_x = stop_x

    def step(self, state, grid):
        p = state.pose
        if (p.x - self.stop_x) * math.cos(p.theta) >= 0:
            return Done("there")
        return Twist(0.5, 0.0)


def hall() -> World:
    boxes = [segment_box(0, 0, 12, 0, 0.1), segment_box(12, 0, 12, 2, 0.1), segment_box(12, 2, 0, 2, 0.1),
             segment_box(0, 2, 0, 0, 0.1)]
    return World("hall", np.array(boxes, np.float64), bounds=(-0.1, -0.1, 12.1, 2.1))


def test_robots_out_of_range_keep_their_own_maps_and_merge_when_they_meet():
    world = hall()
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5)
    grids = [OccupancyGrid(geo, range_max=3.0) for _ in range(2)]
    team_grid = OccupancyGrid(geo, range_max=3.0)
    robots = [SimRobot(world, pose=Pose(1.0, 1.0, 0.0), sonar=False),
              SimRobot(world, pose=Pose(11.0, 1.0, math.pi), sonar=False)]
    far_east = geo.cell_of(9.5, 1.0)        # robot 1 sees it from its start; robot 0 never comes within 3 m
    far_west = geo.cell_of(2.5, 1.0)
    samples = []

    class Watch:
        def on_sample(self, run, time, coverage):
            samples.append((time, bool(run.members[0].grid.seen[far_east]), bool(run.members[1].grid.seen[far_west])))

    from robotexp.run.observers import RunObserver
    watch = type("W", (RunObserver,), {"on_sample": Watch.on_sample})()
    with SimTeam(robots) as team:
        run = TeamRun(robots, [Drive(5.2), Drive(6.8)], grids, team.make_clock(0.1), comm_range=2.0,
                      grid=team_grid, max_time=30.0, observers=[watch])
        run.run()
    # apart at first: robot 0's map holds nothing of robot 1's end of the hall, nor the reverse
    assert samples[0][1:] == (False, False)
    # they stop 1.6 m apart, within range: each map then holds what the other scanned from afar
    assert samples[-1][1:] == (True, True)
    met = next(t for t, a, b in samples if a)
    assert 4.0 < met < 12.0         # closing at 1 m/s from 10 m apart to 2 m: about 8 s plus the start
    record = run.record
    # the explorers said done with the hall's two ends unexplored: the team's end says so
    assert record.comm_range_m == 2.0 and record.end is EndReason.STOPPED and "frontier cells left" in record.reason
    assert record.method == "Drive" and [x["end"] for x in record.robots] == ["explored", "explored"]
    received = [x["scans_received"] for x in record.robots]
    assert all(n > 0 for n in received)
    # merged: both maps hold the union of every scan, as the team's map does (the same cells known; their
    # states may differ where the scans came in another order and the log-odds bound cut a sum short)
    known = team_grid.states() >= 0
    for g in grids:
        assert np.array_equal(g.states() >= 0, known)
        assert np.mean(g.states()[known] == team_grid.states()[known]) > 0.98


def test_teammates_are_not_mapped_as_walls_but_the_explorers_see_them():
    world = hall()
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5)
    grid = OccupancyGrid(geo, range_max=3.0)
    robots = [SimRobot(world, pose=Pose(3.0, 1.0, 0.0), sonar=False),
              SimRobot(world, pose=Pose(5.0, 1.0, math.pi), sonar=False)]
    seen = []

    class Look(Explorer):
        def step(self, state, grid):
            seen.append(float(state.laser.ranges[np.argmin(np.abs(state.laser.angles))]))
            return Done("looked")

    with SimTeam(robots) as team:
        raw = OccupancyGrid(geo, range_max=3.0)
        raw.update(robots[0].read().pose, robots[0].read().laser)
        run = TeamRun(robots, [Look(), Look()], [grid, grid], team.make_clock(0.1), max_time=5.0)
        run.run()
    r = robots[0].footprint.swing                     # a teammate is seen as the disc its body turns in
    assert seen == pytest.approx([2.0 - r, 2.0 - r])        # each explorer saw the other robot ahead
    rows, cols = np.nonzero(raw.occupied())
    xy = geo.centers_of(np.stack([rows, cols], axis=1))
    on_robot = np.hypot(xy[:, 0] - 5.0, xy[:, 1] - 1.0) <= r + 0.1
    assert on_robot.any()                                   # a scan alone maps the other robot
    rows, cols = np.nonzero(grid.occupied())
    xy = geo.centers_of(np.stack([rows, cols], axis=1))
    assert not (np.hypot(xy[:, 0] - 5.0, xy[:, 1] - 1.0) <= r + 0.2).any()
    assert not (np.hypot(xy[:, 0] - 3.0, xy[:, 1] - 1.0) <= r + 0.2).any()
    assert grid.occupied().any()                            # the walls still are


def test_a_robot_gives_way_to_a_moving_teammate_of_a_smaller_number_ahead():
    world = hall()
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5)
    grid = OccupancyGrid(geo, range_max=3.0)
    robots = [SimRobot(world, pose=Pose(3.0, 1.0, 0.0), sonar=False),
              SimRobot(world, pose=Pose(6.0, 1.0, math.pi), sonar=False)]
    with SimTeam(robots) as team:
        # Drive has no laser check: robot 1 gives way to robot 0, which drives on until the robots' rule of
        # keeping bodies clear of teammates stops it
        run = TeamRun(robots, [Drive(11.0), Drive(1.0)], [grid, grid], team.make_clock(0.1), max_time=8.0)
        run.run()
        ends = [r.true_pose for r in robots]
    body = robots[0].footprint
    r = body.swing              # the robots keep apart the discs they turn in
    first, second = run.record.robots
    gap = 3.0 - 2 * r
    assert second["give_way_s"] > 0
    # robot 1 braked at the latest when the gap closed to 0.6 m (half of it each, both at the same speed),
    # earlier when the bodies' rule saw both robots' stopping distances close it: it went no further than
    # its stopping distance at 0.5 m/s (a_max 0.3 m/s^2) and one control period past that point
    lim = robots[1].limits
    assert 0.5 < second["path_length_m"] < (gap - 0.6) / 2 + 0.5 ** 2 / (2 * lim.a_max) + 0.5 * 0.1
    # robot 0 stopped with its body's front short of robot 1's disc, by less than its stopping distance
    apart = math.hypot(ends[0].x - ends[1].x, ends[0].y - ends[1].y) - body.length / 2 - r
    assert 0.0 < apart < 0.5 ** 2 / (2 * lim.a_max) + 0.5 * 0.2 + 0.03
    assert first["give_way_s"] > 0
    assert run.record.robot_collisions == 0 and first["robot_collisions"] == second["robot_collisions"] == 0


@pytest.mark.parametrize(("method", "coordinator"), [("meta-exhaustive", "minpos"), ("bvp", "none")])
def test_target_choosing_and_reactive_explorers_explore_as_a_team(method, coordinator):
    spec = RunSpec(world="conformance-room", method=method, max_time=40.0)
    r = run_team(spec, TeamSpec(robots=("p3dx", "kobuki"), coordinator=coordinator), None, image=False,
                 world=make_room()).record
    assert r.coverage > 0.9 and r.robot == "p3dx,kobuki" and [x["robot"] for x in r.robots] == ["p3dx", "kobuki"]
    assert (r.coordinator_rounds or 0) > 0 if coordinator != "none" else r.coordinator_rounds is None


def test_observers_see_every_robots_tick_in_the_robots_order():
    from robotexp.run.observers import RunObserver

    class Ticks(RunObserver):
        def __init__(self):
            self.seen, self.steps = [], 0

        def on_step(self, run, step):           # a team has no single robot's tick
            self.steps += 1

        def on_robot_step(self, run, robot, step):
            m = run.members[robot]
            assert step.state is m.state and step.decision is m.decision
            self.seen.append((step.time, robot, step.map_updated))

    ticks = Ticks()
    spec = RunSpec(world="conformance-room", method="frontier", max_time=3.0, laser_range=3.0)
    out = run_team(spec, TeamSpec(robots=("p3dx", "kobuki"), coordinator="greedy"), None, image=False,
                   world=make_room(), observers=[ticks])
    assert ticks.steps == 0
    per_robot = [[t for t, r, _ in ticks.seen if r == i] for i in (0, 1)]
    # one call per tick and robot, as many as the points of its path; robot 1 first at each time
    assert [len(p) for p in per_robot] == [len(p) for p in out.run.paths]
    assert len(per_robot[0]) == 31 and 30 <= len(per_robot[1]) <= 31
    assert all(b > a for p in per_robot for a, b in itertools.pairwise(p))
    assert [r for _, r, _ in ticks.seen[:6]] == [0, 1, 0, 1, 0, 1]
    assert all(m for _, _, m in ticks.seen[:2])                     # the first scans go into the map


def test_the_teams_path_is_current_at_every_tick_not_only_at_its_samples():
    """The view and video frames read the run's path: a team's is the robots' total after every tick (it
    was brought up to date at coverage samples only, a second apart)."""
    from robotexp.run.observers import RunObserver

    class Paths(RunObserver):
        def __init__(self):
            self.gaps = []

        def on_robot_step(self, run, robot, step):
            if robot == run.active[-1]:               # every robot has moved for this tick
                self.gaps.append(abs(run.metrics.path_length - sum(m.metrics.path_length for m in run.members)))

        def on_end(self, run, record):
            self.last = (run.metrics.path_length, record.path_length_m)

    paths = Paths()
    spec = RunSpec(world="conformance-room", method="frontier", max_time=7.5, laser_range=3.0)
    run_team(spec, TeamSpec(robots=("p3dx", "p3dx"), coordinator="none"), None, image=False, world=make_room(),
             observers=[paths])
    assert max(paths.gaps) < 1e-9
    assert paths.last[0] == pytest.approx(paths.last[1], abs=1e-3) and paths.last[1] > 1.0


def test_held_targets_are_label_cells_of_every_target():
    from robotexp.coordinator import Candidates
    from robotexp.planning.team import label_cells
    from robotexp.run.team import held_targets

    rng = np.random.default_rng(3)
    for _ in range(50):
        k = int(rng.integers(1, 6))
        cells = tuple(rng.integers(0, 12, (int(rng.integers(1, 9)), 2)) for _ in range(k))
        cand = Candidates(points=np.zeros((k, 2)), cells=cells, cost=np.zeros((2, k)), positions=np.zeros((2, 2)))
        targets = [None, np.zeros((0, 2), np.int64)] + [rng.integers(-2, 14, (int(rng.integers(1, 9)), 2))
                                                         for _ in range(4)]
        assert held_targets(cand, targets) == [None if t is None else label_cells(cand, t) for t in targets]
    empty = Candidates(points=np.zeros((0, 2)), cells=(), cost=np.zeros((1, 0)), positions=np.zeros((1, 2)))
    assert held_targets(empty, [np.ones((1, 2), np.int64)]) == [None]


class Hold(Explorer):
    """Stands still and tells the team its frontier: the 4 x 4-cell patches of `phases` (patch names per phase),
    the phase changing after the steps of `after`; records the targets it is given."""

    takes_targets = True

    def __init__(self, patches, phases, after=(15, 35)) -> None:
        self.patches, self.phases, self.after = patches, phases, after
        self.steps = 0
        self.given: list[tuple[int, str | None]] = []

    def step(self, state, grid):
        self.steps += 1
        return Twist(0.0, 0.0)

    def target_frontier(self, grid):
        mask = np.zeros(grid.shape, bool)
        for name in self.phases[sum(self.steps >= a for a in self.after)]:
            cells = self.patches[name]
            mask[cells[:, 0], cells[:, 1]] = True
        return mask, (0, 0)

    def assign_targets(self, cells):
        name = None if cells is None else next(k for k, v in self.patches.items()
                                               if {tuple(c) for c in v} == {tuple(c) for c in cells})
        self.given.append((self.steps, name))


def _patch(geo, x, y):
    """4 x 4 cells by (x, y) [m], within one 1 m square of the team's targets."""
    r, c = geo.cell_of(x, y)
    r, c = r // 10 * 10 + 3, c // 10 * 10 + 3
    return np.array([(r + i, c + j) for i in range(4) for j in range(4)], np.int64)


def run_held(coordinator, phases0, phases1):
    world = hall()
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5)
    grid = OccupancyGrid(geo, range_max=4.0)
    patches = {"A": _patch(geo, 3.5, 1.0), "B": _patch(geo, 6.5, 1.0)}
    explorers = [Hold(patches, phases0), Hold(patches, phases1)]
    # robot 0 faces east and maps the hall from 2 m to 6 m (A), robot 1 faces west and maps it from 8.6 m to
    # 4.6 m (B); at the start neither stands within reach of a target (the floor under a robot is known free
    # from the start: A's cells are reached from 2.6 to 5.1 m, B's from 5.6 to 8.1 m)
    laser = LaserConfig(range_max=4.0)
    robots = [SimRobot(world, pose=Pose(2.0, 1.0, 0.0), laser=laser, sonar=False),
              SimRobot(world, pose=Pose(8.6, 1.0, math.pi), laser=laser, sonar=False)]
    with SimTeam(robots) as team:
        TeamRun(robots, explorers, [grid, grid], team.make_clock(0.1), coordinator=coordinator, max_time=4.55).run()
    return [e.given for e in explorers]


class Sides(Coordinator):
    """Robot 0 the reachable target farthest west (east with `east`), robot 1 the other way; records the kept
    targets and costs it was asked with."""

    def __init__(self, *, east: bool = False) -> None:
        self.east = east
        self.asked: list[tuple[list[int | None], np.ndarray]] = []

    def assign(self, candidates, kept):
        self.asked.append((list(kept), candidates.cost.copy()))
        west = list(np.argsort(candidates.points[:, 0], kind="stable"))
        out = list(kept)
        for i, order in enumerate((west[::-1], west) if self.east else (west, west[::-1])):
            if out[i] is None:
                out[i] = next((int(k) for k in order if math.isfinite(candidates.cost[i, k])), None)
        return out


def test_a_target_leaves_the_robot_when_its_cells_leave_its_own_frontier():
    c = Sides()
    # target A at 3.5 m, B at 6.5 m. After 1.5 s robot 1's own frontier lacks B (it gave B up), after 3.5 s
    # A is resolved on both maps
    given = run_held(c, [("A", "B"), ("A", "B"), ("B",)], [("A", "B"), ("A",), ()])
    # t 0: nothing mapped, nothing reachable; t 1: robot 0 takes A, robot 1 B; t 2: B left robot 1's own
    # frontier: robot 1 is free and B costs it inf (robot 0 keeps A); t 3: both hold A, no round; t 4: A
    # is gone, robot 0 gets B, robot 1 (its frontier empty) none
    assert [k for k, _ in c.asked] == [[None, None], [None, None], [0, None], [None, None]]
    assert np.isfinite(c.asked[1][1]).all()
    assert math.isinf(c.asked[2][1][1, 1]) and math.isfinite(c.asked[2][1][0, 1])
    assert c.asked[3][1].shape == (2, 1) and math.isinf(c.asked[3][1][1, 0]) and math.isfinite(c.asked[3][1][0, 0])
    assert given == [[(10, "A"), (40, "B")], [(10, "B"), (20, "A"), (40, None)]]


def test_a_coordinator_that_reassigns_is_asked_for_every_robot_at_every_round():
    class Anew(Sides):
        reassigns = True

    c = Anew(east=True)
    given = run_held(c, [("A", "B")] * 2 + [("A",)], [("A", "B")] * 2 + [("A",)])
    # a round every second (t 0 .. 4), every robot free in each; a robot given its target again is not told anew
    assert [k for k, _ in c.asked] == [[None, None]] * 5
    assert given == [[(10, "B"), (40, "A")], [(10, "A")]]



def test_robots_side_by_side_do_not_wait_for_each_other_at_the_start():
    """Four P3-DX in a row in dense's corridor (start 1), each robot's explorer alone: the floor under each
    robot is free on the team's map from the start, so no robot takes a teammate's feet for frontier and
    waits behind it (they had stood still for about 40 s, coverage 0.093 at 30 s)."""
    spec = RunSpec(world="dense", method="frontier", pose="1", max_time=30.0)
    r = run_team(spec, TeamSpec(robots=("p3dx",) * 4, coordinator="none"), None, image=False).record
    assert r.coverage > 0.25, r.coverage
    assert r.collisions == 0 and max(x["idle_time_s"] for x in r.robots) < 15.0


def test_where_a_robot_stands_is_marked_free_once():
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 30, 40))
    wall = np.zeros(grid.shape, bool)
    wall[10, 5:15] = True
    grid.mark_occupied(wall)
    scans = grid.scans
    # a disc of 0.36 m about (1.0, 1.0): the cells whose centres lie within it, 44 of them; the wall row
    # (centres y 1.05 m, x 0.65..1.35 m within the disc: 8 cells) is occupied, not unknown, and stays so
    assert grid.mark_free_disc(1.0, 1.0, 0.36) == 44 - 8
    assert grid.scans == scans + 1 and grid.changed_box(grid.scans - 1) == (6, 14, 6, 14)
    assert grid.occupied()[10, 6:14].all()
    assert np.count_nonzero(grid.free()) == 36
    assert grid.mark_free_disc(1.0, 1.0, 0.36) == 0 and grid.scans == scans + 1      # nothing unknown left: no mark
    assert grid.mark_free_disc(math.nan, 1.0, 0.36) == 0 and grid.mark_free_disc(-5.0, -5.0, 0.36) == 0


class _Hold(Explorer):
    """Holds the robot where it stands with a command of rounding noise, as a controller waiting may."""

    def step(self, state, grid):
        return Twist(0.0, 1e-9)


def test_a_robot_held_with_rounding_noise_counts_idle():
    world = hall()
    grid = OccupancyGrid(GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5), range_max=3.0)
    robots = [SimRobot(world, pose=Pose(1.0, 1.0, 0.0), sonar=False),
              SimRobot(world, pose=Pose(4.0, 1.0, 0.0), sonar=False)]
    with SimTeam(robots) as team:
        run = TeamRun(robots, [_Hold(), Drive(9.0)], [grid, grid], team.make_clock(0.1), max_time=6.0)
        run.run()
    idle = [x["idle_time_s"] for x in run.record.robots]
    assert idle[0] == pytest.approx(6.0, abs=0.15) and idle[1] < 0.5, idle


def test_robots_held_for_each_other_plan_around_their_teammates():
    """Four P3-DX on dense from start 7, burgard with beta 0.5: by 60 s three robots stand by the door of the
    south-west room, each one's laser guard holding it for the others. Held 20 s beside teammates held too,
    a robot plans around them (`Explorer.plan_around`) and the team explores on; without that rule the three
    stood there to the end (8-9 m driven each in 536 s), the fourth explored alone and reached 95 % at 480 s."""
    spec = RunSpec(world="dense", method="frontier", pose="7", max_time=300.0)
    r = run_team(spec, TeamSpec(robots=("p3dx",) * 4, coordinator="burgard", coordinator_params={"beta": 0.5}),
                 None, image=False).record
    assert r.time_to_coverage_95_s is not None and r.time_to_coverage_95_s < 300.0
    assert min(x["path_length_m"] for x in r.robots) > 30.0, [x["path_length_m"] for x in r.robots]
    assert sum(x["planned_around"] for x in r.robots) >= 1 and r.collisions == 0


def test_a_robot_the_team_rules_stop_counts_as_held():
    """Eight P3-DX from dense's start 4 (a room in the north-west), each robot's explorer alone: by 60 s six
    of them queue towards the door, the first one's command cut by the team's keep-clear rule (a teammate
    beside it), the others' laser guards waiting behind. The one the rule stops counts as held and plans
    around its teammates, and the queue moves; when only the explorers' own holds counted, the six drove
    3-8 m each to the end and the team reached 95 % at 255 s."""
    spec = RunSpec(world="dense", method="frontier", pose="4", max_time=240.0)
    r = run_team(spec, TeamSpec(robots=("p3dx",) * 8, coordinator="none"), None, image=False).record
    paths = [x["path_length_m"] for x in r.robots]
    assert r.time_to_coverage_95_s is not None and min(paths) > 20.0, (r.time_to_coverage_95_s, paths)
    assert r.collisions == 0


def test_a_robot_that_is_done_stands_for_its_teammates():
    """Robot 1 stops at x 3 m (done) while driving at 0.5 m/s; robot 2 passes it 0.8 m to the side (0.3 m
    between the bodies). A teammate that drives keeps its stopping distance (0.35 m at 0.5 m/s) around it for
    the others; one that is done stands, and robot 2 drives past. With the last speed kept, robot 2 was cut to
    a stop beside it to the end."""
    world = hall()
    grid = OccupancyGrid(GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5), range_max=3.0)
    robots = [SimRobot(world, pose=Pose(1.0, 0.6, 0.0), sonar=False),
              SimRobot(world, pose=Pose(8.0, 1.4, math.pi), sonar=False)]
    with SimTeam(robots) as team:
        run = TeamRun(robots, [Drive(3.0), Drive(1.0)], [grid, grid], team.make_clock(0.1), max_time=40.0)
        run.run()
    r = run.record
    assert [x["end"] for x in r.robots] == ["explored", "explored"], [x["reason"] for x in r.robots]
    assert r.robots[1]["path_length_m"] > 6.9 and r.collisions == 0


def test_a_team_steering_by_its_scans_stays_in_the_exploration_area(tmp_path) -> None:
    # SRT steers by its scans: each robot's explorer sees the area's edge as a wall (as one robot's does),
    # or it drives out of the area (dense's west half here) and the team's guard stops the run
    area = (-10.0, 0.0, 0.0, 10.0)
    spec = RunSpec(world="dense", method="srt-laser", pose="-5000,7500,0", map_bounds=area, max_time=150.0)
    out = run_team(spec, TeamSpec(robots=("p3dx", "p3dx")), tmp_path, image=False)
    r = out.record
    assert "left the exploration area" not in r.reason and r.collisions == 0
    assert r.total_path_m > 20.0
    for path in out.run.paths:
        xy = np.asarray(path)
        assert xy[:, 0].min() >= area[0] - 0.3 and xy[:, 0].max() <= area[2] + 0.3
        assert xy[:, 1].min() >= area[1] - 0.3 and xy[:, 1].max() <= area[3] + 0.3

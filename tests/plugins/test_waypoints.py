"""The waypoints (UFMG potential-field) explorer: its forces, its goal choice, and whole runs on the
UFMG scenes with the Kobuki preset, log-odds mapping at 5 cm and uniform +-10 cm laser noise.

The four whole runs (two scenes x two paths) are made once per module at 0.5 m/s without ground
truth (no coverage sampling) to keep the file fast.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from PIL import Image

from robotexp.errors import ConfigError, ScriptError
from robotexp.run.spec import RunSpec
from robotexp.registry import make_explorer
from robotexp.experiment import run_experiment
from robotexp.explorer import Done, ExplorerContext
from robotexp.run.loop import ExplorationRun
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.world.groundtruth import occupancy
from robotexp.robot import LaserScan, Limits, Pose, RobotState, Twist
from robotexp.sim import LaserConfig, SimRobot, preset
from robotexp.world.builtin import builtin_world
from robotexp.world.model import World
from robotexp_plugins.waypoints import SECTORS, WaypointsExplorer, attractive_force, repulsive_force, scan_points

CELL = 0.05
RANGE = 5.0
NOISE = 0.10        # [m] uniform laser noise half-width (the UFMG study)
SPEED = 0.5


def ctx(goals: dict[str, list[tuple[float, float]]] | None = None, start_name: str | None = None) -> ExplorerContext:
    return ExplorerContext(radius=0.175, limits=Limits(v_max=0.5, w_max=math.pi, a_max=0.5, alpha_max=math.pi),
                           period=0.1, start=Pose(0, 0, 0), laser_range=RANGE, rng=np.random.default_rng(0),
                           goals=goals or {}, start_name=start_name)


# -- forces ---------------------------------------------------------------------------------------

def test_attractive_force_is_linear_inside_a_metre_and_unit_beyond() -> None:
    np.testing.assert_allclose(attractive_force(Pose(1, 1, 0.3), (1.3, 0.6), 2.0), [0.6, -0.8])
    np.testing.assert_allclose(attractive_force(Pose(0, 0, 0), (3.0, 4.0), 2.0), [1.2, 1.6])


def test_repulsive_force_of_one_point_matches_khatib() -> None:
    # a point 0.3 m left of a robot of radius 0.1 at (1, 2): clearance 0.2 m
    f, c = repulsive_force(1.0, 2.0, np.array([[0.7, 2.0]]), 0.1, 0.5, 0.02)
    mag = 0.02 * (1 / 0.2 - 1 / 0.5) / 0.2**2      # 1.5
    np.testing.assert_allclose(f, [mag, 0.0])
    assert c == pytest.approx(0.2)
    # beyond the influence distance: nothing
    f, c = repulsive_force(1.0, 2.0, np.array([[0.3, 2.0]]), 0.1, 0.5, 0.02)
    np.testing.assert_array_equal(f, [0.0, 0.0])
    assert c == pytest.approx(0.6)
    f, c = repulsive_force(0.0, 0.0, np.zeros((0, 2)), 0.1, 0.5, 0.02)
    assert c == math.inf and not f.any()


def test_repulsive_force_counts_the_nearest_point_of_each_sector() -> None:
    # many points of one sector (16 sectors of 22.5 deg from bearing -180) push as the nearest alone;
    # the mirror point in the opposite sector cancels it
    def polar(r: float, deg: float) -> list[float]:
        return [r * math.cos(math.radians(deg)), r * math.sin(math.radians(deg))]
    one, _ = repulsive_force(0.0, 0.0, np.array([polar(0.4, 10)]), 0.1, 0.5, 0.02)
    np.testing.assert_allclose(one, polar(-0.02 * (1 / 0.3 - 2) / 0.09, 10))
    many, _ = repulsive_force(0.0, 0.0, np.array([polar(0.4, 10), polar(0.45, 3), polar(0.42, 20)]), 0.1, 0.5, 0.02)
    np.testing.assert_allclose(many, one)
    both, _ = repulsive_force(0.0, 0.0, np.array([polar(0.4, 10), polar(0.4, 190)]), 0.1, 0.5, 0.02)
    np.testing.assert_allclose(both, [0.0, 0.0], atol=1e-12)
    # points of two neighbouring sectors both push
    two, _ = repulsive_force(0.0, 0.0, np.array([polar(0.4, 10), polar(0.4, 30)]), 0.1, 0.5, 0.02)
    np.testing.assert_allclose(two, np.add(one, polar(-0.02 * (1 / 0.3 - 2) / 0.09, 30)))
    assert SECTORS >= 8


def test_scan_points_in_the_world_frame() -> None:
    scan = LaserScan(np.array([0.0, math.pi / 2, 0.1]), np.array([1.0, 2.0, 5.0]), 5.0, 0.1)
    pts = scan_points(Pose(1.0, 1.0, math.pi / 2), scan, reach=3.0)
    # sensor at (1, 1.1); beam 0 ahead (+y) 1 m, beam 1 to the left (-x) 2 m; beam 2 is no hit
    np.testing.assert_allclose(pts, [[1.0, 2.1], [-1.0, 1.1]], atol=1e-12)
    assert len(scan_points(Pose(0, 0, 0), scan, reach=1.05)) == 0


# -- parameters and goal choice ---------------------------------------------------------------------

@pytest.mark.parametrize("params", [{"k_att": 0}, {"influence": -1}, {"tolerance": math.nan},
                                    {"goals": []}, {"goals": [[1, 2, 3]]}, {"goals": [[1, 2]], "path": "p"}])
def test_bad_parameters(params: dict[str, object]) -> None:
    with pytest.raises(ConfigError, match="waypoints"):
        WaypointsExplorer(**params)  # type: ignore[arg-type]


def test_goal_list_named_like_the_start_pose_then_path_then_given() -> None:
    lists = {"path1": [(1.0, 2.0)], "path2": [(3.0, 4.0), (5.0, 6.0)]}
    ex = WaypointsExplorer()
    ex.reset(ctx(lists, "path2"))
    assert ex.goals == [(3.0, 4.0), (5.0, 6.0)]
    ex = WaypointsExplorer(path="path1")
    ex.reset(ctx(lists, "path2"))
    assert ex.goals == [(1.0, 2.0)]
    ex = WaypointsExplorer(goals=[[7, 8]])
    ex.reset(ctx(lists, "path2"))
    assert ex.goals == [(7.0, 8.0)]
    with pytest.raises(ConfigError, match="it has: path1, path2"):
        WaypointsExplorer().reset(ctx(lists, None))
    with pytest.raises(ConfigError, match="no goal list named 'x'"):
        WaypointsExplorer(path="x").reset(ctx(lists))


def test_goals_are_visited_in_order_and_done_after_the_last() -> None:
    ex = WaypointsExplorer(goals=[[1.0, 0.0], [1.0, 1.0]], tolerance=0.2)
    ex.reset(ctx())
    geo = GridGeometry(-2, -2, 0.1, 40, 40)
    grid = OccupancyGrid(geo)

    def at(x: float, y: float, th: float, t: float) -> Twist | Done:
        return ex.step(RobotState(time=t, pose=Pose(x, y, th), velocity=Twist.ZERO), grid)

    tw = at(0.0, 0.0, 0.0, 0.0)
    assert isinstance(tw, Twist) and tw.v > 0 and tw.w == pytest.approx(0.0)
    tw = at(0.0, 0.0, math.pi, 0.1)      # goal behind: turn in place, towards the goal's side
    assert isinstance(tw, Twist) and tw.v == 0 and abs(tw.w) > 0
    tw = at(0.9, 0.0, 0.0, 1.0)          # first goal reached: now the goal is to the left
    assert isinstance(tw, Twist) and ex.index == 1 and tw.w > 0
    assert isinstance(at(1.0, 0.95, 0.0, 2.0), Done)
    assert ex.result_fields()["goals_reached"] == 2


def test_registered_and_made_by_name() -> None:
    assert isinstance(make_explorer("waypoints", {"path": "path1"}), WaypointsExplorer)


# -- whole runs on the UFMG scenes --------------------------------------------------------------------

@dataclass
class Outcome:
    run: ExplorationRun
    world: World
    band: np.ndarray | None         # cells the person's disc swept at some time of the run
    occupied_band_max: int          # the most band cells marked occupied at once during the run
    passes_since: np.ndarray | None     # per cell: scans that touched it since the person last covered it


def centres(geo: GridGeometry) -> tuple[np.ndarray, np.ndarray]:
    """World x and y [m] of every cell centre, each (rows, cols)."""
    rows, cols = np.mgrid[0:geo.rows, 0:geo.cols]
    return geo.origin_x + (cols + 0.5) * geo.cell, geo.origin_y + (rows + 0.5) * geo.cell


_RUNS: dict[tuple[str, str], Outcome] = {}


def ufmg_run(world_name: str, path: str) -> Outcome:
    """One run of the waypoints explorer; with a person, watch after every scan which cells it covers."""
    if (world_name, path) in _RUNS:
        return _RUNS[(world_name, path)]
    world = builtin_world(world_name)
    geo = GridGeometry.covering(*world.bounds, cell=CELL, margin=1.0)
    grid = OccupancyGrid(geo, range_max=RANGE)
    kobuki = preset("kobuki")
    laser = LaserConfig(range_max=RANGE, uniform=NOISE, height=kobuki.laser.height)
    dynamic = bool(world.movers)
    shape = (geo.rows, geo.cols)
    band = np.zeros(shape, bool)
    since = np.zeros(shape, np.int64)
    most = 0
    cx, cy = centres(geo)
    # a cell counts as covered by the person within its radius plus the laser noise and half a cell diagonal
    reach = world.movers[0].radius + NOISE + CELL * 0.71 if dynamic else 0.0
    with SimRobot(world, robot=kobuki, pose=world.poses[path], seed=0, laser=laser, max_speed=SPEED,
                  sonar=False) as robot:
        def after_scan(t: float, cov: float | None) -> None:
            nonlocal most
            (px, py), = robot.mover_positions()
            d = np.hypot(cx - px, cy - py)
            body, covered = d <= world.movers[0].radius, d <= reach
            band[body] = True
            touched = grid.stamp == grid.scans
            since[touched & ~covered] += 1
            since[covered] = 0
            most = max(most, int(np.count_nonzero(grid.occupied() & band)))
        run = ExplorationRun(robot, WaypointsExplorer(), grid, max_time=400.0, sample_period=0.1,
                             on_sample=after_scan if dynamic else None, goals=world.goals, start_name=path).run()
    out = Outcome(run, world, band if dynamic else None, most, since if dynamic else None)
    _RUNS[(world_name, path)] = out
    return out


@pytest.mark.parametrize("world_name", ["ufmg-static", "ufmg-dynamic"])
@pytest.mark.parametrize("path", ["path1", "path2"])
def test_completes_both_paths_of_both_scenes_without_collisions(world_name: str, path: str) -> None:
    out = ufmg_run(world_name, path)
    run = out.run
    assert run.completed and run.reason == f"all 7 goals of path {path!r} reached"
    assert run.metrics.collisions == 0
    ex = run.explorer
    assert isinstance(ex, WaypointsExplorer) and ex.goals == out.world.goals[path]
    # the robot went through every goal: its path passes within the tolerance of each
    pts = np.array(run.metrics.path)
    for gx, gy in ex.goals:
        assert np.hypot(pts[:, 0] - gx, pts[:, 1] - gy).min() <= ex.tolerance + 0.05
    assert 20.0 < run.metrics.path_length < 45.0


def test_the_walking_person_is_seen_then_erased_while_walls_stay() -> None:
    out = ufmg_run("ufmg-dynamic", "path1")
    run, world = out.run, out.world
    grid = run.grid
    assert out.band is not None and out.passes_since is not None
    band = out.band
    assert np.count_nonzero(band) > 1000            # the person crossed the room at least once
    # the person was mapped as an obstacle during the run...
    assert out.occupied_band_max >= 20
    # ...and every cell it walked through that the laser crossed twice since the person last
    # covered it is free: two passes (2 x -2.197) outweigh a clamped hit (+3.5). The person walks
    # to and fro until the end, so that is only the part of the band seen after its last visit
    # (measured: 680 of 1608 cells)...
    rescanned = band & (out.passes_since >= 2)
    assert np.count_nonzero(rescanned) >= 0.3 * np.count_nonzero(band)
    assert np.count_nonzero(grid.free() & rescanned) == np.count_nonzero(rescanned)
    # ...but nearly all the band ends free: what is left of the person (measured: 11 cells, where it
    # was last seen) lies where the robot did not look again
    assert np.count_nonzero(grid.free() & band) >= 0.98 * np.count_nonzero(band)
    assert np.count_nonzero(grid.occupied() & band) <= 0.02 * np.count_nonzero(band)
    # the walls stay occupied: nearly every outer-wall cell facing the room has an occupied cell
    # within one cell (noise of +-10 cm spreads the hits over 4 cells across the wall's face)
    truth = occupancy(world, grid.geo)
    cx, cy = centres(grid.geo)
    inside = ~truth & (np.abs(cx) < 4.95) & (np.abs(cy) < 4.95)
    beside = np.roll(inside, 1, 0) | np.roll(inside, -1, 0) | np.roll(inside, 1, 1) | np.roll(inside, -1, 1)
    face = truth & beside & (np.maximum(np.abs(cx), np.abs(cy)) > 4.8)     # the outer walls' inner faces
    occ = grid.occupied()
    near = occ.copy()
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            near |= np.roll(np.roll(occ, dr, 0), dc, 1)
    assert np.count_nonzero(face) > 700
    assert np.count_nonzero(near & face) / np.count_nonzero(face) >= 0.97     # measured 793 / 796


def test_static_scene_has_no_person_to_erase() -> None:
    assert builtin_world("ufmg-static").movers == []
    assert len(builtin_world("ufmg-dynamic").movers) == 1


def test_run_experiment_picks_the_goal_list_of_the_start_pose() -> None:
    spec = RunSpec(world="ufmg-static", method="waypoints", pose="path2", robot="kobuki", speed=0.5,
                   laser_range=3.0, laser_uniform=NOISE, max_time=2.0)
    run = run_experiment(spec, None).run
    assert isinstance(run.explorer, WaypointsExplorer)
    assert run.explorer.path_name == "path2" and run.grid.geo.cell == pytest.approx(0.05)
    assert not run.completed and run.reason.startswith("time limit")


# -- Lua: robot.setLaserNoise (the study's noise from a script) -----------------------------------------

def _lua(tmp_path: Path, code: str) -> list[str]:
    from robotexp.lua import run_script
    lines: list[str] = []
    script = tmp_path / "s.lua"
    script.write_text(code)
    run_script(script, out=tmp_path / "out", emit=lines.append, notice=lambda _: None)
    return lines


@pytest.mark.parametrize("call", ["robot.setLaserNoise(-1)", "robot.setLaserNoise()",
                                  "robot.setLaserNoise(100, 1, 2)", "robot.setLaserNoise('a')"])
def test_lua_set_laser_noise_checks_its_arguments(tmp_path: Path, call: str) -> None:
    with pytest.raises(ScriptError, match=r"robot\.setLaserNoise"):
        _lua(tmp_path, call)


def test_lua_set_laser_noise_reaches_the_laser(tmp_path: Path) -> None:
    run = """robot.setModel("kobuki")
exploration.setWorld("ufmg-static")
exploration.setMethod(ExplorationMethod.WAYPOINTS)
exploration.setParameter("path", "path1")
robot.moveMobileSim(-4200, -4200, 45)
exploration.setMaxTime(300)
robot.setLaserNoise(%s)
exploration.start()
exploration.wait()
mapView.saveMapImage("%s.png")
"""
    _lua(tmp_path, run % ("0", "a") + run % ("100", "b") + run % ("0, 0", "c"))
    assert len(list((tmp_path / "out").glob("*.map.pgm"))) == 3
    with Image.open(tmp_path / "out" / "a.png") as a, Image.open(tmp_path / "out" / "b.png") as b, \
            Image.open(tmp_path / "out" / "c.png") as c:
        assert np.asarray(a).tobytes() == np.asarray(c).tobytes()     # same seed, no noise: same map
        assert np.asarray(a).tobytes() != np.asarray(b).tobytes()     # noise changes the map

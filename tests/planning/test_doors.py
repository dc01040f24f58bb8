"""Five 4 x 4 m rooms in a row joined by off-centre doors: explorers leave the first room through doors
a little wider than the robot (0.65 m for the P3-DX's 0.5 m disc, 0.50 m for the Kobuki's 0.35 m), on a
10 cm map, at the CLI's default speed, without a collision. The walls' faces lie off the cell borders.

The planners block only what the robot's disc (plus 1 cm) touches, measured to where the laser hits
landed in a wall's cell (`robotexp.planning.targets.plan_costs`); a hard margin of 5 cm plus half a cell
closed every one of these doors."""

from __future__ import annotations

import numpy as np
import pytest

from robotexp.experiment import make_explorer
from robotexp.explorer import ExplorationRun
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.mapping.groundtruth import ground_truth
from robotexp.robot import Pose
from robotexp.sim import SimRobot
from robotexp.world.model import World, segment_box

T = 0.1             # [m] wall thickness
SIDE = 4.0          # [m] room side
START = Pose(2.0, 2.0, 0.0)
DOORS = {"p3dx": 0.65, "kobuki": 0.50}


def rooms(door: float, n: int = 5) -> World:
    """`n` rooms of SIDE x SIDE m in a row along x; the wall at x = i SIDE has a door `door` [m] wide 0.7 m
    from the bottom (odd i) or the top (even i), moved up by 13 mm per wall (faces off the cell borders)."""
    boxes = [segment_box(0, 0, n * SIDE, 0, T), segment_box(0, SIDE, n * SIDE, SIDE, T),
             segment_box(0, 0, 0, SIDE, T), segment_box(n * SIDE, 0, n * SIDE, SIDE, T)]
    for i in range(1, n):
        x = i * SIDE
        lo = (0.7 if i % 2 else SIDE - 0.7 - door) + 0.013 * i
        boxes += [segment_box(x, 0, x, lo - T / 2, T), segment_box(x, lo + door + T / 2, x, SIDE, T)]
    return World(f"rooms-{door:g}", np.array(boxes))


def explore(method: str, robot: str, max_time: float = 600.0) -> tuple[ExplorationRun, float]:
    world = rooms(DOORS[robot])
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5)
    with SimRobot(world, robot=robot, pose=START, max_speed=0.3, sonar=False) as sim:
        truth = ground_truth(world, geo, robot_radius=sim.radius, laser_range=3.0, start=START)
        # every room is reachable: the doors are wider than the robot
        assert all(truth.reachable[geo.cell_of(SIDE * (i + 0.5), SIDE / 2)] for i in range(5))
        run = ExplorationRun(sim, make_explorer(method, {}), OccupancyGrid(geo), truth=truth,
                             max_time=max_time).run()
    return run, max(x for x, _ in run.metrics.path)


def _check(method: str, robot: str) -> None:
    run, reached = explore(method, robot)
    # through the fourth door at least (the last room can be seen whole from its door)
    assert reached > 3 * SIDE + 0.5, f"{method} with the {robot} got to x = {reached:.1f} m: {run.reason}"
    assert run.coverage() is not None and run.coverage() >= 0.95, run.coverage()
    assert run.metrics.collisions == 0
    assert run.completed, run.reason


@pytest.mark.parametrize("method,robot", [("frontier", "p3dx"), ("bvp", "p3dx")])
def test_explorers_pass_doors_a_little_wider_than_the_robot(method: str, robot: str) -> None:
    _check(method, robot)


# Not yet everywhere: the frontier explorer with the Kobuki and meta-ga / meta-firefly with the P3-DX reach
# the last room's door and end there (coverage 0.88-0.90), the metaheuristics with the Kobuki and bvp with
# the Kobuki stop at the second or third door, srt-laser never leaves the first room (its safe region is
# the laser's star, not the planners' costs).
NOT_YET = pytest.mark.xfail(strict=False, reason="stops at a door (see above)")


@pytest.mark.slow
@pytest.mark.parametrize("method,robot", [
    pytest.param("frontier", "kobuki", marks=NOT_YET),
    pytest.param("meta-ga", "p3dx", marks=NOT_YET),
    pytest.param("meta-firefly", "p3dx", marks=NOT_YET),
    pytest.param("meta-ga", "kobuki", marks=NOT_YET),
    pytest.param("meta-firefly", "kobuki", marks=NOT_YET),
    pytest.param("bvp", "kobuki", marks=NOT_YET),
    pytest.param("srt-laser", "p3dx", marks=NOT_YET),
    pytest.param("srt-laser", "kobuki", marks=NOT_YET),
])
def test_every_explorer_passes_the_doors(method: str, robot: str) -> None:
    _check(method, robot)

"""A robot that sends nothing to sense with (a Kobuki or a P3-DX with no laser mounted): the run holds it and
ends as a robot error after RANGE_WAIT s of robot time, instead of an explorer driving it blind or calling
its empty map explored; a laser that starts late is waited for."""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import pytest

from robotexp.explorer import Done, Explorer
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import Pose, RobotState, Twist
from robotexp.run.loop import RANGE_WAIT, ExplorationRun
from robotexp.run.observers import RunObserver
from robotexp.run.record import EndReason
from robotexp.sim import LaserConfig, SimRobot
from robotexp.world.groundtruth import ground_truth
from robotexp.world.model import World, segment_box
from robotexp_plugins.frontier import FrontierExplorer

T = 0.1
ROOM = World("room", np.array([segment_box(0, 0, 6, 0, T), segment_box(6, 0, 6, 4, T), segment_box(6, 4, 0, 4, T),
                               segment_box(0, 4, 0, 0, T)]))
GEO = GridGeometry.covering(*ROOM.bounds, cell=0.1, margin=0.5)
LASER = LaserConfig(beams=360, fov=2 * math.pi, range_max=3.0)
START = Pose(1.5, 2.0, 0.0)


class Ahead(Explorer):
    """Drives ahead at 0.2 m/s, turning while anything is within 0.8 m in front when it has a scan."""

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        scan = state.laser
        if scan is not None:
            front = scan.ranges[np.abs(scan.angles) < 0.5]
            if np.any(front < 0.8):
                return Twist(0.0, 0.6)
        return Twist(0.2, 0.0)


class Route(Ahead):
    """Ahead, declared as a method that drives without range readings."""

    needs_range = False


class SonarSpin(Explorer):
    """Turns on the spot, sensing with the sonar ring."""

    uses_sonar = True

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        return Twist(0.0, 0.5)


class LaserOnAt(RunObserver):
    """Switches the simulated laser on at `at` s of robot time (a laser still starting), and notes when the
    robot first moved."""

    def __init__(self, at: float) -> None:
        self.at = at
        self.moved: float | None = None

    def on_step(self, run: ExplorationRun, step: object) -> None:
        if run.robot_time >= self.at:
            run.robot.laser_in_state = True     # type: ignore[attr-defined]
        p = run.state.true_pose
        if self.moved is None and p is not None and math.hypot(p.x - START.x, p.y - START.y) > 1e-6:
            self.moved = run.robot_time


def run(explorer: Explorer, *, laser: bool, sonar: bool = False, max_time: float = 30.0,
        observers: Iterable[RunObserver] = ()) -> ExplorationRun:
    with SimRobot(ROOM, pose=START, laser=LASER, max_speed=0.3, sonar=sonar, laser_in_state=laser) as robot:
        truth = ground_truth(ROOM, GEO, robot_radius=robot.radius, laser_range=3.0, start=START)
        return ExplorationRun(robot, explorer, OccupancyGrid(GEO), truth=truth, max_time=max_time,
                              observers=observers).run()


@pytest.mark.parametrize("explorer", [FrontierExplorer(), Ahead()], ids=["frontier", "ahead"])
def test_a_robot_without_a_laser_stands_and_the_run_ends_as_a_robot_error(explorer):
    # frontier used to call the empty map explored at its first step; Ahead drove blind into the wall
    r = run(explorer, laser=False)
    assert r.end is EndReason.ROBOT_ERROR and not r.completed
    name = type(explorer).__name__
    assert r.reason == (f"robot error: the robot sent no laser scan in the first 5 s: {name} has nothing to map "
                        "with; mount a laser (robotexp explore --laser NAME:ADDRESS, laser in a campaign set, "
                        "robot.setLaser in Lua, +LASER:ADDRESS in a --team list)")
    assert r.robot_time == pytest.approx(RANGE_WAIT, abs=0.11)
    assert r.metrics.path_length == 0.0 and r.metrics.collisions == 0
    assert r.record is not None and r.record.coverage == 0.0


def test_a_laser_that_starts_late_is_waited_for():
    watch = LaserOnAt(1.5)
    r = run(Ahead(), laser=False, max_time=20.0, observers=[watch])
    assert r.end is EndReason.TIME_LIMIT, r.reason
    assert watch.moved is not None and 1.5 <= watch.moved <= 1.5 + 0.25       # it stood until the first scan
    assert r.metrics.path_length > 1.0 and r.metrics.collisions == 0


def test_a_method_that_needs_no_range_and_one_that_senses_with_sonar_are_not_held():
    r = run(Route(), laser=False, max_time=3.0)
    assert r.end is EndReason.TIME_LIMIT and r.metrics.path_length == pytest.approx(0.2 * 3.0, abs=0.1)
    r = run(SonarSpin(), laser=False, sonar=True, max_time=8.0)
    assert r.end is EndReason.TIME_LIMIT, r.reason
    r = run(SonarSpin(), laser=False, sonar=False, max_time=8.0)
    assert r.end is EndReason.ROBOT_ERROR and "no laser scan or sonar reading in the first 5 s" in r.reason


def test_a_robot_whose_clock_stands_still_is_not_waited_for_ever():
    # a recording's last tick read again and again: its time stops, the wait counts control periods instead
    from robotexp.bag.replay import ReplayRobot, Tick

    robot = ReplayRobot([Tick(0.1 * i, Pose(0.0, 0.0, 0.0), Twist(0.0, 0.0)) for i in range(5)])    # no laser
    with robot:
        r = ExplorationRun(robot, Ahead(), OccupancyGrid(GridGeometry(-1.0, -1.0, 0.1, 20, 20)), max_time=60.0).run()
    assert r.end is EndReason.ROBOT_ERROR and "no laser scan in the first 5 s" in r.reason
    assert r.robot_time == pytest.approx(0.4)

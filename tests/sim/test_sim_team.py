"""SimTeam: robots of one world see each other, collide with each other, step on one clock; spread_starts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError, WorldError
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import Pose, Twist
from robotexp.sim import SharedWorld, SimRobot, SimTeam, preset, spread_starts
from robotexp.world.groundtruth import ground_truth
from robotexp.world.model import World, segment_box


def hall(length: float = 10.0, width: float = 3.0) -> World:
    wall = 0.1
    boxes = [segment_box(0, 0, length, 0, wall), segment_box(length, 0, length, width, wall),
             segment_box(length, width, 0, width, wall), segment_box(0, width, 0, 0, wall)]
    return World("hall", np.array(boxes, dtype=np.float64), bounds=(-0.1, -0.1, length + 0.1, width + 0.1),
                 poses={"west": Pose(1.0, 1.5, 0.0)})


def team_of(world: World, *poses: Pose) -> SimTeam:
    return SimTeam([SimRobot(world, pose=p, sonar=False) for p in poses])


def test_a_robot_sees_another_in_its_laser_where_the_wall_was():
    world = hall()
    with team_of(world, Pose(2.0, 1.5, 0.0), Pose(5.0, 1.5, math.pi)) as team:
        a, b = team.robots
        scan = a.read().laser
        ahead = int(np.argmin(np.abs(scan.angles)))
        # the beam straight ahead ends on the other robot's cylinder (the disc its body turns in): 3 m between
        # centres, minus its radius
        assert scan.ranges[ahead] == pytest.approx(3.0 - b.footprint.swing, abs=1e-6)
    with SimRobot(world, pose=Pose(2.0, 1.5, 0.0), sonar=False) as alone:
        assert alone.read().laser.ranges[ahead] == math.inf      # 3 m laser, the far wall 8 m away


def test_robots_that_drive_into_each_other_stop_and_count_one_collision_each():
    world = hall()
    body = preset("p3dx").outline
    touch = body.length / 2 + body.swing     # each robot's body against the disc the other turns in
    with team_of(world, Pose(3.0, 1.5, 0.0), Pose(4.0, 1.5, math.pi)) as team:
        a, b = team.robots
        a.command(Twist(0.3, 0.0))
        b.command(Twist(0.3, 0.0))
        clock = team.make_clock(0.1)
        for _ in range(40):
            clock.tick()
        gap = math.hypot(a.true_pose.x - b.true_pose.x, a.true_pose.y - b.true_pose.y)
        assert touch - 1e-9 <= gap <= touch + 0.02          # stopped where they touch, not through each other
        assert (a.collisions, b.collisions) == (1, 1)
        assert (a.robot_collisions, b.robot_collisions) == (1, 1)
        assert a.read().stalled and b.read().stalled
        assert team.time == pytest.approx(4.0)


def test_one_clock_advances_every_robot_alike_and_repeats():
    def drive() -> list[tuple[float, float, float]]:
        with team_of(hall(), Pose(1.0, 1.0, 0.0), Pose(1.0, 2.2, 0.0)) as team:
            for i, robot in enumerate(team.robots):
                robot.command(Twist(0.2 + 0.1 * i, 0.1))
            clock = team.make_clock(0.1)
            for _ in range(30):
                clock.tick()
            return [(r.time, r.true_pose.x, r.true_pose.y) for r in team.robots]
    first = drive()
    assert [t for t, _, _ in first] == pytest.approx([3.0, 3.0])
    assert first == drive()


def test_a_team_refuses_a_world_with_movers_and_robots_of_two_worlds():
    from robotexp.world.loader import load_world

    dynamic = load_world("ufmg-dynamic")
    with SimRobot(dynamic, sonar=False) as robot, pytest.raises(ConfigError, match="moving obstacles"):
        SimTeam([robot])
    with SimRobot(hall(), sonar=False) as a, SimRobot(hall(), sonar=False) as b, \
            pytest.raises(ConfigError, match="same world"):
        SimTeam([a, b])


def test_spread_starts_keep_apart_off_the_walls_in_the_start_region():
    world = hall()
    radius = preset("p3dx").radius
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5)
    truth = ground_truth(world, geo, robot_radius=radius, laser_range=3.0, start=Pose(1.0, 1.5, 0.0))
    with SimRobot(world, pose=Pose(1.0, 1.5, 0.3), sonar=False) as first:
        starts = spread_starts(truth, Pose(1.0, 1.5, 0.3), [radius] * 4, free=first)
        assert starts[0] == Pose(1.0, 1.5, 0.3)
        assert all(p.theta == 0.3 for p in starts)
        for i, p in enumerate(starts):
            assert truth.reachable[geo.cell_of(p.x, p.y)]
            assert radius + 0.1 <= p.x <= 10 - radius - 0.1 and radius + 0.1 <= p.y <= 3 - radius - 0.1
            for q in starts[:i]:
                assert math.hypot(p.x - q.x, p.y - q.y) >= 2 * radius + 0.3 - 1e-9
        # nearest first: the team stays by the start, not spread over the hall
        assert max(math.hypot(p.x - 1.0, p.y - 1.5) for p in starts) < 2.0
        with pytest.raises(WorldError, match="room for"):
            spread_starts(truth, Pose(1.0, 1.5, 0.0), [radius] * 200, free=first)


def test_robots_of_a_shared_world_advanced_apart_see_and_stop_at_each_other():
    # what `robotexp emulate p3dx,p3dx` serves: each robot advanced on its own (here: in turn, by hand)
    world = hall()
    a = SimRobot(world, pose=Pose(2.0, 1.5, 0.0), sonar=False)
    b = SimRobot(world, pose=Pose(5.0, 1.5, math.pi), sonar=False)
    shared = SharedWorld()
    try:
        shared.join(a)
        shared.join(b)
        scan = a.read().laser
        ahead = int(np.argmin(np.abs(scan.angles)))
        assert scan.ranges[ahead] == pytest.approx(3.0 - b.radius, abs=1e-6)
        b.command(Twist(0.3, 0.0))
        for _ in range(20):          # b drives towards a (0.47 m in 2 s from standstill); a sees it there
            b.advance(0.1)
        assert 4.4 < b.true_pose.x < 4.6
        assert a.scan().ranges[ahead] == pytest.approx(b.true_pose.x - 2.0 - b.radius, abs=1e-6)  # a's time: 0 s
        for _ in range(100):         # on until it touches a: it stops there, one collision with a robot
            b.advance(0.1)
        gap = b.true_pose.x - a.true_pose.x - a.radius - b.radius
        assert 0.0 <= gap < 0.01 and b.collisions == b.robot_collisions == 1 and b.read().stalled
        with SimRobot(hall(), pose=Pose(8.0, 1.5, 0.0), sonar=False) as elsewhere, \
                pytest.raises(ConfigError, match="same world"):
            shared.join(elsewhere)
    finally:
        a.close()
        b.close()

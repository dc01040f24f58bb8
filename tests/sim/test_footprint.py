"""A rectangular robot (the `p3dx-body` preset: the P3-DX's 455 x 381 mm body): the simulator collides with
the rectangle, turning included; the guard sweeps it; the ground truth opens passages wider than its width."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from robotexp.errors import ConfigError, WorldError
from robotexp.mapping.geometry import GridGeometry
from robotexp.planning.follower import ScanMemory, footprint_blocked
from robotexp.robot import Footprint, Pose, Twist
from robotexp.sim import SimRobot, preset
from robotexp.world.builtin import rooms_in_a_row
from robotexp.world.groundtruth import ground_truth
from robotexp.world.model import World
from robotexp.world.raycast import box_distance

L, W = 0.455, 0.381         # [m] the P3-DX body
WALL_X = 2.0                # [m] the near face of the wall


def wall_world() -> World:
    return World("wall", np.array([[WALL_X + 0.05, 0.0, 0.05, 5.0, 0.0]]), bounds=(-3.0, -5.0, 2.1, 5.0))


def test_the_p3dx_body_preset_is_its_body() -> None:
    assert preset("p3dx").outline == Footprint.disc(0.25)
    p = preset("p3dx-body")
    assert (p.outline.length, p.outline.width, p.outline.round) == (L, W, False)
    assert p.radius == pytest.approx(W / 2)
    assert p.outline.swing == pytest.approx(math.hypot(L / 2, W / 2))       # 0.2967 m
    assert preset("kobuki").outline == Footprint.disc(0.175)
    with pytest.raises(ConfigError):
        Footprint(0.4, 0.0)
    with pytest.raises(ConfigError):
        Footprint(0.4, 0.3, round=True)


def test_footprint_distance_by_hand() -> None:
    f = Footprint.rectangle(L, W)
    d = f.distance(np.array([0.3, 0.0, 0.0, 0.3, 0.1]), np.array([0.0, 0.3, 0.0, 0.3, 0.1]))
    assert d == pytest.approx([0.3 - L / 2, 0.3 - W / 2, 0.0, math.hypot(0.3 - L / 2, 0.3 - W / 2), 0.0])
    assert Footprint.disc(0.2).distance(np.array([0.5]), np.array([0.0])) == pytest.approx([0.3])


def test_box_distance_by_hand() -> None:
    # side by side, 0.1 m apart
    assert box_distance(0.0, 0.0, 0.5, 0.5, 1.0, 0.0, 1.1, 0.0, 0.5, 0.5, 1.0, 0.0) == pytest.approx(0.1)
    # a unit square turned 45 deg, its corner sqrt(0.5) from its centre, 0.2 m from the other's face
    c = math.cos(math.pi / 4)
    x = 0.5 + 0.2 + math.sqrt(0.5)
    assert box_distance(0.0, 0.0, 0.5, 0.5, 1.0, 0.0, x, 0.0, 0.5, 0.5, c, c) == pytest.approx(0.2)
    # corner to corner, diagonally apart
    apart = box_distance(0.0, 0.0, 0.5, 0.5, 1.0, 0.0, 1.3, 1.4, 0.5, 0.5, 1.0, 0.0)
    assert apart == pytest.approx(math.hypot(0.3, 0.4))
    # overlapping
    assert box_distance(0.0, 0.0, 0.5, 0.5, 1.0, 0.0, 0.9, 0.2, 0.5, 0.5, c, c) == 0.0


@pytest.mark.parametrize("world", ["index", "bodies"])
def test_the_simulator_collides_with_the_rectangle(world: str) -> None:
    w = wall_world()
    if world == "index":
        w = World("wall", w.boxes, bounds=w.bounds, collision="index")
    gap = 0.20      # [m] from the centre to the wall: more than half the width, less than half the length
    with pytest.raises(WorldError, match="0.455 x 0.381"):
        SimRobot(w, robot="p3dx-body", pose=Pose(WALL_X - gap, 0.0, 0.0))
    with SimRobot(w, robot="p3dx-body", pose=Pose(WALL_X - gap, 0.0, math.pi / 2)) as robot:
        robot.command(Twist(0.0, -0.5))       # turning towards the wall: a corner reaches it
        for _ in range(40):
            robot.advance(0.1)
        # the heading phi (from the wall's normal) where the body's reach towards the wall,
        # L/2 cos(phi) + W/2 sin(phi), equals the gap
        phi = brentq(lambda a: L / 2 * math.cos(a) + W / 2 * math.sin(a) - gap, 0.9, math.pi / 2)
        assert robot.collisions == 1
        assert robot.true_pose.theta == pytest.approx(phi, abs=math.radians(1.0))
        robot.command(Twist(0.0, 0.5))        # turning back is free until the other corner reaches it
        for _ in range(40):
            robot.advance(0.1)
        assert robot.collisions == 1        # one contact: the body never left the wall's 2 cm
        assert robot.true_pose.theta == pytest.approx(math.pi - phi, abs=math.radians(1.0))


def test_a_round_robot_turns_anywhere() -> None:
    with SimRobot(wall_world(), robot="kobuki", pose=Pose(WALL_X - 0.18, 0.0, math.pi / 2)) as robot:
        robot.command(Twist(0.0, 1.0))
        for _ in range(40):
            robot.advance(0.1)
        assert robot.collisions == 0


def test_the_guard_sweeps_the_rectangle_turning() -> None:
    f = Footprint.rectangle(L, W)
    corner = math.atan2(W, L)              # the front-left corner's bearing, 40 deg
    a = corner + math.radians(8)
    beside = np.array([[0.29 * math.cos(a), 0.29 * math.sin(a)]])     # 8 deg past it, inside the swing (0.297 m)
    assert f.distance(beside[:, 0], beside[:, 1])[0] > 0.02
    assert not footprint_blocked(beside, f, 0.01, 0.3, 0.0)            # driving past it
    assert footprint_blocked(beside, f, 0.01, 0.0, 1.0)                # turning left: the corner swings onto it
    assert not footprint_blocked(beside, f, 0.01, 0.0, -1.0)           # turning right: every corner moves away
    assert footprint_blocked(beside, f, 0.01, 0.1, 2.0)                # an arc to the left
    far = beside * 0.31 / 0.29             # beyond the swing radius
    assert not footprint_blocked(far, f, 0.01, 0.0, 1.0)
    ahead = np.array([[0.26, 0.0]])
    assert footprint_blocked(ahead, f, 0.01, 0.3, 0.0)
    assert not footprint_blocked(ahead, f, 0.01, 0.0, 0.0)            # standing still never blocks


def test_scan_memory_keeps_what_the_laser_no_longer_sees() -> None:
    from robotexp.robot import LaserScan
    memory = ScanMemory(reach=1.0, scans=3)
    angles = np.array([-math.pi / 2, 0.0])
    memory.note(Pose(0.0, 0.0, 0.0), LaserScan(angles, np.array([0.4, np.inf]), 4.0))    # a wall point at (0, -0.4)
    memory.note(Pose(0.0, 0.0, math.pi), LaserScan(angles, np.array([np.inf, np.inf]), 4.0))
    pts = memory.points(Pose(0.0, 0.0, math.pi))           # turned round: the point is now on its left
    assert pts == pytest.approx(np.array([[0.0, 0.4]]))
    for _ in range(3):
        memory.note(Pose(0.0, 0.0, 0.0), LaserScan(angles, np.array([np.inf, np.inf]), 4.0))
    assert len(memory.points(Pose(0.0, 0.0, 0.0))) == 0        # older than the last 3 scans


def test_a_door_two_cm_wider_than_the_body_is_reachable() -> None:
    radius = preset("p3dx-body").radius
    for door, open_ in ((W + 0.02, True), (W - 0.02, False)):
        world = rooms_in_a_row(door, rooms=2)
        geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5)
        truth = ground_truth(world, geo, robot_radius=radius, laser_range=3.0, start=world.poses["first room"])
        assert bool(truth.reachable[geo.cell_of(6.0, 2.0)]) is open_, door

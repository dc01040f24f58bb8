"""`LocalizedRobot` on the simulator: the P3-DX's curving odometry corrected by scan matching."""

from __future__ import annotations

import math

from robotexp.localization.robot import LocalizedRobot
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import Twist
from robotexp.sim import SimRobot, odometry_error
from robotexp.world.builtin import builtin_world


def test_corrected_pose_follows_the_truth_while_odometry_curves_away() -> None:
    world = builtin_world("dense")
    assert world.bounds is not None
    sim = SimRobot(world, pose=world.poses["1"], odometry=odometry_error("p3dx"), seed=1, sonar=False)
    robot = LocalizedRobot(sim, GridGeometry.covering(*world.bounds, cell=0.05, margin=1.0), range_max=3.0)
    with robot:
        odometry: list = []
        for k in range(160):                      # 14 s at 0.25 m/s "straight" along the corridor, 2 s turning
            state = robot.read()
            odometry.append(sim.read().pose)
            robot.command(Twist(0.25, 0.0) if k < 140 else Twist(0.0, 0.5))
            sim.advance(0.1)
        state = robot.read()
        truth, raw = state.true_pose, sim.read().pose
        assert truth is not None
        # the wheels bend the true path by m s / b; odometry believes it went straight
        assert math.hypot(raw.x - truth.x, raw.y - truth.y) > 0.1
        assert abs(math.degrees(raw.theta - truth.theta)) > 3.0
        assert state.extra["collisions"] == 0.0
        # the explorer's pose: corrected, not the truth itself, and close to it
        assert state.pose is not truth and state.pose != truth
        assert math.hypot(state.pose.x - truth.x, state.pose.y - truth.y) < 0.08
        assert abs(math.degrees(math.remainder(state.pose.theta - truth.theta, 2 * math.pi))) < 1.0
        assert robot.localizer.counts.get("matched", 0) > 10
        ate = robot.ate_m()
        assert ate is not None and ate < 0.06
        assert len(robot.track) == 161         # one entry per new instant (reads at the same time: one match)

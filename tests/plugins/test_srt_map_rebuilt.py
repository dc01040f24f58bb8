"""SRT under loop closure: when the run's map is rebuilt and the frame of the poses moves
(`Explorer.map_rebuilt` with a `FrameCorrection`), the tree, its regions and the way home move with it."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from test_srt import room_world

from robotexp.localization import FrameCorrection
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import LaserScan, Pose, RobotState
from robotexp.run.loop import ExplorationRun
from robotexp.run.observers import RunObserver, StepEvent
from robotexp.sim import SimRobot
from robotexp_plugins.srt import PolygonRegion, SRTLaserExplorer

SHIFT = (0.3, -0.2, math.radians(8.0))     # the correction: p -> R(8 deg) p + (0.3, -0.2) m


def shifted(pose: Pose) -> Pose:
    dx, dy, dth = SHIFT
    c, s = math.cos(dth), math.sin(dth)
    return Pose(c * pose.x - s * pose.y + dx, s * pose.x + c * pose.y + dy, pose.theta + dth)


class LoopCloses(RunObserver):
    """At robot time `at` the frame moves by SHIFT (from then on the robot reports shifted poses), the map is
    rebuilt from every scan at its shifted pose and the explorer is told, as `LoopClosureTracker` does."""

    def __init__(self, at: float) -> None:
        self.at, self.done = at, False
        self.scans: list[tuple[Pose, LaserScan]] = []
        self.before: list[tuple[float, float]] = []

    def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
        if step.map_updated and step.state.laser is not None:
            self.scans.append((step.state.pose, step.state.laser))
        if self.done or step.state.time < self.at:
            return
        self.done = True
        grid = run.grid
        grid.values[...] = 0
        grid.stamp[...] = 0
        for pose, scan in self.scans[:-1]:           # the last was taken in the new frame already
            grid.update(shifted(pose), scan)
        grid.update(*self.scans[-1])
        self.before = [(n.x, n.y) for n in run.explorer.tree.nodes]
        run.explorer.map_rebuilt(grid, FrameCorrection([0.0, step.state.time], [SHIFT, (0.0, 0.0, 0.0)]))


def test_a_rebuilt_map_in_a_moved_frame_moves_the_tree_and_the_robot_still_gets_home() -> None:
    world = room_world()
    start = Pose(-1.5, 0.0, 0.0)
    geo = GridGeometry.covering(-6, -5, 6, 5, cell=0.1)
    explorer = SRTLaserExplorer()
    grid = OccupancyGrid(geo)
    loop = LoopCloses(at=40.0)
    with SimRobot(world, pose=start, seed=1, max_speed=0.5) as robot:
        read = robot.read

        def read_shifted() -> RobotState:
            state = read()
            return state if state.time < loop.at else replace(state, pose=shifted(state.pose))

        robot.read = read_shifted  # type: ignore[method-assign]
        run = ExplorationRun(robot, explorer, grid, max_time=1500.0, seed=3, observers=[loop]).run()
        end = read().true_pose
    assert loop.done and len(loop.before) >= 2, "the frame moved while the tree had nodes"
    assert run.completed, run.reason
    assert run.metrics.collisions == 0
    # every node that was in the tree moved exactly with the frame ...
    for (x, y), node in zip(loop.before, explorer.tree.nodes, strict=False):
        q = shifted(Pose(x, y, 0.0))
        assert math.hypot(node.x - q.x, node.y - q.y) < 1e-9
    # ... its region with it (each node lies inside its own region, and the boundary's points moved rigidly)
    for node in explorer.tree.nodes:
        assert node.region.contains(np.array([[node.x, node.y]]))[0]
    # the root moved with the frame, so the robot drove home to the true start (not to the stale root,
    # which is the true start moved by the inverse shift: 0.36 m away)
    assert end is not None and math.hypot(end.x - start.x, end.y - start.y) < 0.2


def test_a_polygon_region_moved_contains_the_moved_points() -> None:
    angles = np.linspace(-math.pi, math.pi, 24, endpoint=False)
    ranges = 1.0 + 0.5 * np.abs(np.sin(2 * angles))
    region = PolygonRegion(0.4, -0.3, angles, ranges, np.zeros(24, bool))
    moved = region.moved(*SHIFT)
    rng = np.random.default_rng(0)
    pts = rng.uniform(-2.5, 2.5, (400, 2))
    q = np.array([[p.x, p.y] for p in (shifted(Pose(x, y)) for x, y in pts)])
    np.testing.assert_array_equal(moved.contains(q), region.contains(pts))
    want = [[p.x, p.y] for p in (shifted(Pose(x, y)) for x, y in region.vertices())]
    np.testing.assert_allclose(moved.vertices(), want, atol=1e-12)

"""A team of simulated robots in one world (`SimTeam`): one stepped clock for all, robots that see each
other in their laser and sonar and collide with each other, and start poses spread around a start
(`spread_starts`). `SharedWorld` puts robots that are advanced each by a thread of its own (the emulators
of `robotexp emulate p3dx,p3dx,kobuki`) in one world the same way."""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robotexp.clock import Clock, SimClock
from robotexp.errors import ConfigError, WorldError
from robotexp.robot import Pose
from robotexp.sim.robot import SimRobot
from robotexp.world.groundtruth import GroundTruth

__all__ = ["SimTeam", "SharedWorld", "spread_starts", "START_GAP", "MAX_TEAM"]

START_GAP = 0.3         # [m] kept between two robots' footprints at the start
START_CLEARANCE = 0.1   # [m] kept between a robot's footprint and the walls at the start
MAX_TEAM = 64           # robots in one team at most


class SimTeam:
    """Robots of one world stepped by one clock.

    Each tick advances the robots one after the other, in their order, each against the others where
    they stand at that moment; then every robot's rays are set to see the others where the tick left
    them. The same seed, order and commands give the same run. A robot that would touch another stops
    as at a wall (a collision, also counted in its `robot_collisions`).

    Args:
        robots: the open robots, all in the same world (the team closes them with `close`).

    Raises:
        ConfigError: no robot, robots of different worlds, or a world with moving obstacles (each
            robot would walk its own copy of them).
    """

    def __init__(self, robots: Sequence[SimRobot]) -> None:
        if not robots:
            raise ConfigError("team: no robot")
        world = robots[0].world
        if any(r.world is not world for r in robots):
            raise ConfigError("team: every robot must stand in the same world")
        if world.movers:
            raise ConfigError(f"team: world {world.name!r} has moving obstacles, which teams do not support yet; "
                              "choose a world without them")
        self.robots = list(robots)
        self.time = 0.0
        n = len(self.robots)
        self._others = [np.array([j for j in range(n) if j != i], np.intp) for i in range(n)]   # rows of the peers
        self._sync()

    def _discs(self) -> npt.NDArray[np.float64]:
        return np.array([[r.true_pose.x, r.true_pose.y, r.footprint.swing, r.preset.height] for r in self.robots],
                        np.float64).reshape(-1, 4)

    def _sync(self) -> None:
        """Tell every robot where the others stand."""
        discs = self._discs()
        for i, robot in enumerate(self.robots):
            robot.engine.set_peers(discs[self._others[i]])

    def advance(self, dt: float) -> None:
        """Advance every robot by `dt` [s], in order, each against the others where they stand."""
        discs = self._discs()
        others = self._others
        for i, robot in enumerate(self.robots):
            if i:           # robot 0's peers are where the last tick left them (set at its end)
                robot.engine.set_peers(discs[others[i]])
            robot.advance(dt)
            p = robot.true_pose
            discs[i, 0], discs[i, 1] = p.x, p.y
        for i, robot in enumerate(self.robots):
            robot.engine.set_peers(discs[others[i]])
        self.time += dt

    def make_clock(self, period: float) -> Clock:
        """A stepped clock: each tick advances the whole team by `period`."""
        return SimClock(period, self.advance)

    def close(self) -> None:
        """Close every robot."""
        for robot in self.robots:
            robot.close()

    def __enter__(self) -> SimTeam:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SharedWorld:
    """Simulated robots of one world, each advanced by its own caller (an emulator's serving thread, on its own
    clock), that see and touch each other as a `SimTeam`'s do.

    A robot that joined (`join`) is told where the others stand (`sync`) each time it moves or casts rays;
    its moves hold `lock`, so one robot moves at a time, against the others where they stand then.

    Raises (from `join`):
        ConfigError: a robot of another world, one that joined already, a world with moving obstacles, or
            more than MAX_TEAM robots.
    """

    def __init__(self) -> None:
        self.robots: list[SimRobot] = []
        self.lock = threading.Lock()
        self.moves = 0          # the robots' steps so far (a scan cast before the last one is out of date)

    def join(self, robot: SimRobot) -> None:
        """Put `robot` in the shared world (it stands where it stands; the others now see it)."""
        if robot.shared is not None:
            raise ConfigError("shared world: the robot is in a shared world already")
        if self.robots and robot.world is not self.robots[0].world:
            raise ConfigError("shared world: every robot must stand in the same world")
        if robot.world.movers:
            raise ConfigError(f"shared world: world {robot.world.name!r} has moving obstacles, which teams do not "
                              "support yet; choose a world without them")
        if len(self.robots) >= MAX_TEAM:
            raise ConfigError(f"shared world: {MAX_TEAM} robots at most")
        with self.lock:
            self.robots.append(robot)
            robot.shared = self

    def sync(self, robot: SimRobot) -> None:
        """Tell `robot` where the others stand now."""
        discs = [(p.x, p.y, r.footprint.swing, r.preset.height) for r in self.robots if r is not robot
                 for p in (r.true_pose,)]
        robot.engine.set_peers(np.array(discs, np.float64).reshape(-1, 4))


def spread_starts(truth: GroundTruth, start: Pose, radii: Sequence[float], free: SimRobot | None = None,
                  gap: float = START_GAP) -> list[Pose]:
    """Start poses for a team of robots of `radii` [m]: the first at `start`, the others on the nearest
    cells (by steps through the reachable cells of `truth`, the region of the start) whose footprints keep
    `gap` from every other robot's and, when `free` is given, START_CLEARANCE from every obstacle (asked of
    `free`'s simulator), all facing as `start` does.

    Raises:
        WorldError: the start's region has no room for the whole team.
    """
    geo = truth.geo
    rmax = max(radii)
    chosen = [start]
    row, col = geo.cell_of(start.x, start.y)
    reach = truth.reachable
    rows, cols = reach.shape
    if not (0 <= row < rows and 0 <= col < cols and reach[row, col]):
        row, col = _nearest_true(reach, row, col)
    seen = np.zeros_like(reach)
    seen[row, col] = True
    todo: deque[tuple[int, int]] = deque([(row, col)])
    spacing = 2 * rmax + gap
    while todo and len(chosen) < len(radii):
        r, c = todo.popleft()
        x, y = geo.center_of(r, c)
        if all(math.hypot(x - p.x, y - p.y) >= spacing for p in chosen) and _clear(free, x, y, rmax):
            chosen.append(Pose(x, y, start.theta))
        for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            nr, nc = r + dr, c + dc
            if 0 <= nr < rows and 0 <= nc < cols and reach[nr, nc] and not seen[nr, nc]:
                seen[nr, nc] = True
                todo.append((nr, nc))
    if len(chosen) < len(radii):
        raise WorldError(f"team: the region of the start ({start.x * 1000:.0f}, {start.y * 1000:.0f}) mm has room "
                         f"for {len(chosen)} robots {spacing * 1000:.0f} mm apart, not {len(radii)}: give fewer "
                         "robots or their start poses")
    return chosen


def _nearest_true(mask: npt.NDArray[np.bool_], row: int, col: int) -> tuple[int, int]:
    cells = np.argwhere(mask)
    if len(cells) == 0:
        raise WorldError("team: the start has no reachable cell around it")
    best = int(np.argmin((cells[:, 0] - row) ** 2 + (cells[:, 1] - col) ** 2))
    return int(cells[best, 0]), int(cells[best, 1])


def _clear(free: SimRobot | None, x: float, y: float, radius: float) -> bool:
    """No obstacle within radius + START_CLEARANCE of (x, y), asked of `free`'s simulator."""
    if free is None:
        return True
    engine = free.engine
    here = free.true_pose
    engine.place_robot(x, y)
    try:
        return not engine.robot_near_obstacle(START_CLEARANCE + radius - free.radius, include_movers=False)
    finally:
        engine.place_robot(here.x, here.y, here.theta)

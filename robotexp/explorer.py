"""The explorer plugin contract (`Explorer`) and the control loop that runs one (`ExplorationRun`).

An explorer only decides: given the robot's state and the map it returns a `Twist`, or `Done`.
It never sleeps, reads clocks, does I/O or holds a robot handle; its randomness comes from the
generator in its `ExplorerContext`. `ExplorationRun` owns the loop of DESIGN.md:

    clock tick -> robot.read() -> grid.update() -> explorer.step() -> robot.command() -> metrics
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError, RobotError
from robotexp.robot import Limits, Pose, Robot, RobotState, Twist
from robotexp.world.bounds import clip_scan

if TYPE_CHECKING:
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.mapping.groundtruth import GroundTruth

__all__ = ["Done", "ExplorerContext", "Explorer", "ExplorationRun", "RunMetrics", "COVERAGE_MILESTONES"]

COVERAGE_MILESTONES = (0.90, 0.95, 0.99)


@dataclass(frozen=True)
class Done:
    """What `Explorer.step` returns when exploration is over, with the reason."""

    reason: str = "explored"


@dataclass
class ExplorerContext:
    """What an explorer may know before it starts."""

    radius: float                  # [m] robot footprint
    limits: Limits                 # velocity limits of the robot
    period: float                  # [s] control period
    start: Pose                    # the pose the run starts from
    laser_range: float             # [m]
    rng: np.random.Generator
    sonar: bool = False            # the robot has a sonar ring
    goals: dict[str, list[tuple[float, float]]] = field(default_factory=dict)   # [m] the world's waypoint lists
    start_name: str | None = None  # the name of the start pose in the world, when it has one


class Explorer(ABC):
    """An exploration strategy (a plugin in the `robotexp.explorers` entry-point group).

    Subclasses take keyword-only parameters in `__init__`, validated there (ConfigError), and
    implement `step`. Class attributes tell the run which map they want.
    """

    grid_model: ClassVar[Literal["logodds", "himm"]] = "logodds"
    preferred_cell: ClassVar[float | None] = None   # [m] a cell size the method is defined for
    uses_sonar: ClassVar[bool] = False      # the method reads RobotState.sonar

    def reset(self, ctx: ExplorerContext) -> None:
        """Called once before the first step of a run."""
        self.ctx = ctx

    @abstractmethod
    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        """Decide the next velocity command from the state and the map (updated with this state)."""

    def result_fields(self) -> dict[str, object]:
        """Extra result fields of this method (e.g. `nodes` of a tree)."""
        return {}

    def overlays(self) -> dict[str, npt.NDArray[np.float64]]:
        """Arrays to draw over the map image (e.g. `potential`, `vectors`), on the run's grid."""
        return {}


@dataclass
class RunMetrics:
    """What a run measures as it goes."""

    path_length: float = 0.0                # [m] along the true path where known, else odometry
    path: list[tuple[float, float]] = field(default_factory=list)
    visited: set[tuple[int, int]] = field(default_factory=set)
    curve: list[tuple[float, float, float]] = field(default_factory=list)  # (robot time, path, coverage)
    milestones: dict[float, tuple[float, float] | None] = field(
        default_factory=lambda: dict.fromkeys(COVERAGE_MILESTONES))
    collisions: int = 0


class ExplorationRun:
    """Runs one explorer on one robot until it is done, times out, fails or is interrupted.

    Args:
        robot: an open robot (the run does not close it; it stops it when the run ends).
        explorer: the strategy.
        grid: the map the robot builds (its geometry bounds the exploration).
        truth: ground truth of the world for coverage (None on a real robot without a world).
        period: control period [s] (10 Hz by default).
        max_time: robot time [s] after which the run ends incomplete.
        sample_period: robot time [s] between coverage samples.
        on_sample: called after each coverage sample with (robot time, coverage or None).
        watch: the honest-endings observer (`robotexp.watch.RunWatch`: stall watch, area guard, Done check).
        area: [m] the exploration area: the explorer's scans end at its edge (`clip_scan`).
        goals: the world's named waypoint lists [m], for goal-following explorers (ExplorerContext.goals).
        start_name: the name of the start pose in the world, if any (ExplorerContext.start_name).
    """

    def __init__(self, robot: Robot, explorer: Explorer, grid: OccupancyGrid, *,
                 truth: GroundTruth | None = None, period: float = 0.1, max_time: float = 4 * 3600,
                 sample_period: float = 1.0, seed: int = 0,
                 on_sample: Callable[[float, float | None], None] | None = None,
                 goals: dict[str, list[tuple[float, float]]] | None = None, start_name: str | None = None,
                 watch: Any = None, area: tuple[float, float, float, float] | None = None) -> None:
        if not period > 0 or not max_time > 0 or not sample_period > 0:
            raise ConfigError(f"run: period, max_time and sample_period must be > 0 s, got "
                              f"{period}, {max_time}, {sample_period}")
        self.robot, self.explorer, self.grid, self.truth = robot, explorer, grid, truth
        self.period, self.max_time, self.sample_period = period, max_time, sample_period
        self.seed = seed
        self.on_sample = on_sample
        self.goals = dict(goals or {})
        self.start_name = start_name
        self.metrics = RunMetrics()
        self.state: RobotState | None = None
        self.start_pose: Pose | None = None
        self.reason = "not started"
        self.completed = False
        self.robot_time = 0.0
        self.wall_time = 0.0
        self._stop_reason: str | None = None
        self.watch, self.area = watch, area

    def request_stop(self, reason: str, end: Any = None) -> None:
        """End the run at its next step with `reason` (`completed` stays False; the robot is stopped).

        Meant for observers such as `on_sample` (a script's --timeout, a supervisor).
        """
        self._stop_reason = reason

    def coverage(self) -> float | None:
        """Share of the explorable free space the map marks free now (None without ground truth)."""
        if self.truth is None:
            return None
        from robotexp.mapping.groundtruth import coverage
        return coverage(self.grid.free(), self.truth)

    def run(self) -> ExplorationRun:
        """Run to the end. Ctrl-C and robot errors end the run with `completed` False; the robot is
        stopped in every case. Returns self (read `metrics`, `reason`, `completed`)."""
        robot = self.robot
        clock = robot.make_clock(self.period)
        wall0 = time.perf_counter()
        next_sample = 0.0
        slack = self.period / 2
        try:
            state = robot.read()
            self.start_pose = state.true_pose or state.pose
            t0 = state.time
            self.explorer.reset(ExplorerContext(
                radius=robot.radius, limits=robot.limits, period=self.period, start=state.pose,
                laser_range=state.laser.range_max if state.laser else 0.0,
                rng=np.random.default_rng(self.seed), sonar=state.sonar is not None,
                goals=self.goals, start_name=self.start_name))
            collisions0 = int(state.extra.get("collisions", 0))
            if self.watch is not None:
                self.watch.on_start(self)
            while True:
                self.state = state
                self.robot_time = state.time - t0
                self._track(state, collisions0)
                if state.laser is not None:
                    self.grid.update(state.pose, state.laser)
                # half a period of slack: robot time summed from float periods reads 0.99999 s at
                # the tick meant for 1 s, and the sample (or the time limit) belongs to that tick
                if self.robot_time >= next_sample - slack:
                    self._sample()
                    while next_sample <= self.robot_time + slack:   # a late robot: no burst of samples
                        next_sample += self.sample_period
                if self._stop_reason is not None:
                    self.reason = self._stop_reason
                    break
                if self.robot_time >= self.max_time - slack:
                    self.reason = f"time limit of {self.max_time:.0f} s reached"
                    break
                # the explorer sees the exploration area's edge as a wall (the map takes the real scan)
                view = state if self.area is None or state.laser is None else \
                    replace(state, laser=clip_scan(state.laser, state.pose, self.area))
                decision = self.explorer.step(view, self.grid)
                if isinstance(decision, Done):
                    self.reason = decision.reason
                    self.completed = True
                if self.watch is not None:
                    self.watch.on_step(self, SimpleNamespace(state=state, decision=decision))
                if isinstance(decision, Done):
                    break
                robot.command(decision)
                clock.tick()
                state = robot.read()
        except KeyboardInterrupt:
            self.reason = "interrupted (Ctrl-C)"
        except RobotError as exc:
            self.reason = f"robot error: {exc}"
        finally:
            self._safe_stop()
            self.wall_time = time.perf_counter() - wall0
        self._sample()
        return self

    def _track(self, state: RobotState, collisions0: int) -> None:
        m = self.metrics
        p = state.true_pose or state.pose
        if m.path:
            x0, y0 = m.path[-1]
            m.path_length += math.hypot(p.x - x0, p.y - y0)
        m.path.append((p.x, p.y))
        row, col = self.grid.geo.cell_of(p.x, p.y)
        m.visited.add((row, col))
        m.collisions = int(state.extra.get("collisions", 0)) - collisions0

    def _sample(self) -> None:
        cov = self.coverage()
        m = self.metrics
        if m.curve and m.curve[-1][0] == self.robot_time:
            m.curve.pop()
        m.curve.append((self.robot_time, m.path_length, -1.0 if cov is None else cov))
        if cov is not None:
            for level, hit in m.milestones.items():
                if hit is None and cov >= level:
                    m.milestones[level] = (self.robot_time, m.path_length)
        if self.on_sample is not None:
            self.on_sample(self.robot_time, cov)
        if self.watch is not None:
            self.watch.on_sample(self, self.robot_time, cov)

    def _safe_stop(self) -> None:
        """Stop the robot; a robot that cannot be reached any more cannot be stopped either."""
        try:
            if not self.robot.closed:
                self.robot.command(Twist.ZERO)
        except (RobotError, OSError):
            pass

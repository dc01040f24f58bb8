"""The explorer plugin contract: `Explorer`, what it is given (`ExplorerContext`) and `Done`.

An explorer only decides: given the robot's state and the map it returns a `Twist`, or `Done`.
It never sleeps, reads clocks, does I/O or holds a robot handle; its randomness comes from the
generator in its `ExplorerContext`. The loop that runs one is `robotexp.run.loop.ExplorationRun`.
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from robotexp.robot import Footprint, Limits, Pose, RobotState, Twist

if TYPE_CHECKING:
    from robotexp.localization.correction import FrameCorrection
    from robotexp.mapping.grid import OccupancyGrid

__all__ = ["Done", "ExplorerContext", "Explorer"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Done:
    """What `Explorer.step` returns when exploration is over, with the reason.

    `explored` False says the explorer stops for a reason of its own (a budget, a node limit), not
    because it believes the place explored; the run loop checks a claim of exploration against the
    frontier the robot could still reach (`robotexp.run.endings.RunWatch`), not a stop.
    """

    reason: str = "explored"
    explored: bool = True


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
    footprint: Footprint | None = None   # the robot's outline (None: a disc of `radius`)

    def __post_init__(self) -> None:
        if self.footprint is None:
            self.footprint = Footprint.disc(self.radius)

    @property
    def outline(self) -> Footprint:
        """The robot's outline (`footprint`, never None once built)."""
        assert self.footprint is not None
        return self.footprint


class Explorer(ABC):
    """An exploration strategy (a plugin in the `robotexp.explorers` entry-point group).

    Subclasses take keyword-only parameters in `__init__`, validated there (ConfigError), and
    implement `step`. Class attributes tell the run which map they want.
    """

    grid_model: ClassVar[Literal["logodds", "himm"]] = "logodds"
    preferred_cell: ClassVar[float | None] = None   # [m] a cell size the method is defined for
    uses_sonar: ClassVar[bool] = False      # the method reads RobotState.sonar
    # the method senses through the robot's laser (or its sonar, with `uses_sonar`): the run holds the robot
    # until the first reading and ends as a robot error when none comes (`robotexp.run.loop.RANGE_WAIT`);
    # False for a method that drives without them (a route)
    needs_range: ClassVar[bool] = True
    # the inclusive range of each numeric parameter, {name: (low, high)} (None: open on that side); a
    # class's entries add to its bases'; checked before the explorer is built, shown by `-p help`
    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {}
    # the explorer chooses its goals among frontier cells and follows a team coordinator's targets
    # (`assign_targets`); teams with a coordinator that assigns targets need it
    takes_targets: ClassVar[bool] = False

    def reset(self, ctx: ExplorerContext) -> None:
        """Called once before the first step of a run."""
        self.ctx = ctx

    @abstractmethod
    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        """Decide the next velocity command from the state and the map (updated with this state)."""

    def assign_targets(self, cells: npt.NDArray[np.int64] | None) -> None:
        """A team's coordinator (`robotexp.coordinator`) gives this robot a target: the frontier cells, (m, 2)
        (row, col) of the run's grid, to choose the next goal among; None: choose alone. Called between
        steps, on explorers whose `takes_targets` is True, when the target changes. When none of the cells
        is among the explorer's own candidates any more, it chooses alone. Default: ignored."""
        return None

    def plan_around(self, discs: npt.NDArray[np.float64] | None) -> None:
        """A team tells this robot that teammates stand still in its way: plan around the discs (k, 3)
        (x, y, radius) [m] its centre must keep out of (drop the goal and plan anew without them), until told
        None. Called between steps, when the robot and teammates near it have been held for a while (robots
        whose laser guards wait for each other). A robot that finds no goal around them plans as usual again.
        Default: ignored (the robot's own rules are all it has)."""
        return None

    def target_frontier(self, grid: OccupancyGrid) -> tuple[npt.NDArray[np.bool_], tuple[int, int]] | None:
        """The frontier cells this explorer would choose a goal among on `grid` now, for a team's coordinator
        to share out: a bool mask of a window of the grid and the (row, col) of the window's cell (0, 0).
        Default None: the team takes `robotexp.planning.targets.frontier_targets` of the map."""
        return None

    def result_fields(self) -> dict[str, object]:
        """Extra result fields of this method (e.g. `nodes` of a tree)."""
        return {}

    def map_rebuilt(self, grid: OccupancyGrid, moved: FrameCorrection) -> None:
        """The run's map was rebuilt: loop closure (`robotexp explore --localize slam`) moved the poses its
        scans were mapped at, so any cell may have changed and what was derived from the old map (costs,
        a potential, a memory of walls) is stale; and every pose the explorer was given moved with it:
        a point derived from the pose of robot time t (`RobotState.time`; a tree node, a goal, a path) now
        lies at `moved.points(xy, t)` (`robotexp.localization.FrameCorrection`). Called between steps,
        before the next `step` sees `grid`; drop, move or recompute such state here. Default: nothing
        (for methods that keep none)."""
        return None

    def overlays(self) -> dict[str, npt.NDArray[np.float64]]:
        """Arrays to draw over the map image (e.g. `potential`, `vectors`), on the run's grid."""
        return {}

    def markers(self) -> dict[str, dict[str, Any]]:
        """Shapes to draw over the map in world coordinates [m] (a tree's nodes and edges, a target):
        {"points" | "circles" | "lines" | "polygons": {name: numbers}}, see `robotexp.markers`. The live
        view draws them and recordings hold them (visualization_msgs/MarkerArray). It is called between
        steps, at a bounded rate, and must not change what the explorer decides. Default: {} (none)."""
        return {}



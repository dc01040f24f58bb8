"""The coordinator plugin contract of a team of robots: `Coordinator`, what it is given (`TeamContext`,
`Candidates`).

A team run (`robotexp explore --team N`) runs one explorer per robot. A coordinator that assigns targets
(`assigns_targets`) is asked, whenever a robot of the team has no target, which frontier target each robot
without one should drive to (one that `reassigns`: at every round, for every robot); the explorers that
take targets (`Explorer.takes_targets`: frontier, the metaheuristics) then choose their goal among the
frontier cells of the target they were given. A coordinator only decides: it gets the candidate targets
with the path cost from every robot and returns an index per robot; it never plans, reads clocks or holds
a robot. Its randomness comes from `TeamContext.rng`. Coordinators are plugins of the
`robotexp.coordinators` entry-point group.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import numpy.typing as npt

__all__ = ["Candidates", "TeamContext", "Coordinator"]


@dataclass(frozen=True)
class Candidates:
    """The frontier targets of a team's map at one coordination round.

    Attributes:
        points: (k, 2) [m] where each target lies (a frontier cell of it).
        cells: k arrays (m_i, 2) of the grid cells (row, col) of the frontier each target stands for.
        cost: (n, k) [m] the length of the shortest path from each robot to each target (inf: unreachable).
        positions: (n, 2) [m] where each robot stands.
        held: for a coordinator that `reassigns`, the target each robot is on its way to (None: none; ():
            not told), for it to keep a robot on its way where another target is no better.
    """

    points: npt.NDArray[np.float64]
    cells: tuple[npt.NDArray[np.int64], ...]
    cost: npt.NDArray[np.float64]
    positions: npt.NDArray[np.float64]
    held: tuple[int | None, ...] = ()

    @property
    def robots(self) -> int:
        """n, the robots asked about."""
        return int(self.cost.shape[0])

    def __len__(self) -> int:
        return int(self.points.shape[0])


@dataclass
class TeamContext:
    """What a coordinator may know before the team starts."""

    size: int                       # robots in the team
    laser_range: float              # [m] the robots' laser range (the sensor range of utility models)
    radius: tuple[float, ...]       # [m] each robot's footprint radius
    rng: np.random.Generator


class Coordinator(ABC):
    """A way to share out frontier targets among a team (a plugin in the `robotexp.coordinators` group).

    Subclasses take keyword-only parameters in `__init__`, validated there (ConfigError), and implement
    `assign`. `assigns_targets` False (the `none` coordinator) means no targets are ever computed: each
    robot's explorer decides alone on the team's map.
    """

    assigns_targets: ClassVar[bool] = True
    # True: every round asks for the targets of all robots anew (`assign` gets no kept target), as MinPos
    # recomputes its allocation at every step; False: a robot keeps its target until its frontier is
    # resolved (or it gives it up), and rounds run only when some robot has none
    reassigns: ClassVar[bool] = False
    # the inclusive range of each numeric parameter, {name: (low, high)} (None: open on that side)
    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {}

    def reset(self, ctx: TeamContext) -> None:
        """Called once before the team's first step."""
        self.ctx = ctx

    @abstractmethod
    def assign(self, candidates: Candidates, kept: Sequence[int | None]) -> list[int | None]:
        """The target of every robot: for robot i, `kept[i]` when that is not None (the robot is on its way
        to that candidate and keeps it), else the index of the candidate it should go to, or None for none
        (the robot's explorer then chooses alone). A coordinator never gives a robot a target its cost marks
        unreachable."""

    def result_fields(self) -> dict[str, object]:
        """Extra result fields of this coordinator."""
        return {}

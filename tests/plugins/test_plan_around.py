"""`Explorer.plan_around`, which a team calls for a robot held beside teammates that are held too: the planning
explorers drop their goal and plan with the teammates' discs impassable, and plan as usual when no goal is left
around them."""

from __future__ import annotations

import numpy as np
import pytest

from robotexp.explorer import ExplorerContext
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import Limits, Pose, RobotState, Twist
from robotexp_plugins.frontier import FrontierExplorer
from robotexp_plugins.metaheuristic import ExhaustiveExplorer

HERE = Pose(1.0, 2.0, 0.0)


def open_corridor() -> OccupancyGrid:
    """A corridor 2 m wide (y 1..3 m) closed to the west at x 0.4 m, open to the east onto unknown space at
    x 5.5 m, on 10 cm cells."""
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 40, 60))
    free = np.zeros(grid.shape, bool)
    free[10:30, 5:55] = True
    wall = np.zeros(grid.shape, bool)
    wall[9, 4:55] = wall[30, 4:55] = wall[9:31, 4] = True
    grid.mark_free(free)
    grid.mark_occupied(wall)
    return grid


def every_cm(path: object) -> np.ndarray:
    """The points of a polyline (k, 2) [m], every centimetre along its segments."""
    p = np.asarray(path, np.float64)
    return np.concatenate([a + (b - a) * np.linspace(0, 1, 1 + int(np.hypot(*(b - a)) / 0.01))[:, None]
                           for a, b in zip(p[:-1], p[1:], strict=True)])


@pytest.mark.parametrize(("make", "goal"), [(FrontierExplorer, "goal"), (ExhaustiveExplorer, "target")])
def test_plan_around_keeps_the_path_out_of_the_discs_and_falls_back_when_boxed_in(make, goal) -> None:
    """The goal (frontier) or target (metaheuristics) is dropped, the next path keeps the robot's centre out of
    the discs; discs that leave no goal reachable are forgotten and the robot plans as usual, rather than
    ending its exploration."""
    grid = open_corridor()
    explorer = make()
    explorer.reset(ExplorerContext(radius=0.25, limits=Limits(v_max=0.3, w_max=1.0), period=0.1, start=HERE,
                                   laser_range=2.0, rng=np.random.default_rng(0)))

    def step(t: float) -> object:
        return explorer.step(RobotState(time=t, pose=HERE, velocity=Twist.ZERO), grid)

    assert isinstance(step(0.0), Twist)
    assert getattr(explorer, goal)[0] > 4.0           # towards the frontier at the corridor's east end
    assert np.abs(every_cm(explorer.follower.path)[:, 1] - 2.0).max() < 0.1      # straight along it
    explorer.plan_around(np.array([[3.0, 2.0, 0.45]]))      # a teammate held in the middle of the corridor
    assert getattr(explorer, goal) is None
    assert isinstance(step(0.1), Twist)
    assert getattr(explorer, goal)[0] > 4.0 and explorer.around is not None
    around = every_cm(explorer.follower.path)
    # the cells whose centres lie in the disc are out; a path passes a cell at one of its points (`cell_points`),
    # up to half a cell's diagonal from the centre
    assert np.hypot(around[:, 0] - 3.0, around[:, 1] - 2.0).min() > 0.45 - 0.071
    explorer.plan_around(np.array([[1.0, 2.0, 20.0]]))      # the whole map: no goal around it
    assert isinstance(step(0.2), Twist)
    assert explorer.around is None and getattr(explorer, goal)[0] > 4.0
    explorer.plan_around(None)
    assert explorer.around is None

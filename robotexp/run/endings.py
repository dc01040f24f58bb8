"""Honest endings: the run loop's stall watch and the check of an explorer's "explored".

`StallWatch` follows how many cells of the map are known. When a run gains less than `min_gain`
[m^2] of newly known space for `window` seconds of robot time, that is a strike: the explorer is
asked to give up its current target (`Explorer.give_up(grid)`, which blacklists it; an explorer
without targets has nothing to give up) and the window starts again; a gain clears the strikes.
After `strikes` strikes in a row the run ends as stalled (`completed` false). A window in which the
explorer's own count of the frontier it has left (an int attribute `frontier_left`, when it has one)
fell below its lowest since the last gain is no strike either: looking at the last specks of frontier
across a large floor resolves them a few cells a trip and maps less than `min_gain`, and the count
can fall only so often before the explorer's own end. The window grows with
the map, so that a long transit across a large building to a far frontier is not taken for a stall:
by default the time to drive `TRANSIT_FACTOR` times round the map's half perimeter at the robot's
top speed, within `MIN_WINDOW`..`MAX_WINDOW` (bounds stretched for a robot slower than `SLOW_SPEED`, so
that they span the same distance).

`frontier_left` counts the frontier a robot could still reach on its own map and never went near
(openings of groups at least a robot wide, wall faces left out - the faces of every wall the map
ever showed firmly occupied, which beams grazing it may have worn down since (`WallMemory`) -
within reach of the known-free space the robot can drive through from where it stands, farther
than `APPROACHED` from its path, bordering unknown space a robot's disc could enter if it were
free) and that unknown space: when an
explorer says it is done while some is left and what lies behind it is more than shadows
(`LEFT_AREA`, `LEFT_SHARE`), the run records that it stopped with reachable frontier left, not that
the building was explored.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robotexp.run.observers import RunObserver
from robotexp.run.record import EndReason
from robotexp.robot import Pose

if TYPE_CHECKING:
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.planning.targets import WallMemory

__all__ = ["MAX_WINDOW", "MIN_WINDOW", "RunWatch", "SLOW_SPEED", "STRIKES", "StallWatch", "TRANSIT_FACTOR",
           "frontier_left", "unexplored_left"]

MIN_WINDOW = 120.0          # [s] of robot time without a gain before a strike
MAX_WINDOW = 240.0          # [s] the longest window, however large the map ...
SLOW_SPEED = 0.1            # [m/s] ... for a robot this fast or faster; a slower one gets the bounds
                            # stretched to the same distance (40 mm/s: 300..600 s), as it needs that
                            # much longer to cross the same space
TRANSIT_FACTOR = 1.5        # the window covers this many half perimeters of the map at top speed
STRIKES = 3                 # strikes in a row that end a run as stalled
MIN_GAIN = 0.5              # [m^2] newly known space that counts as progress
APPROACHED = 1.5            # [m] frontier this near the robot's path was looked at from close by
LEFT_AREA = 2.0             # [m^2] unknown space behind the frontier left that makes a "done" premature
LEFT_SHARE = 0.05           # ... and as a share of the known free area
LEFT_REACH = 2.0            # [m] how far behind the frontier left the unknown space is counted


def frontier_left(grid: OccupancyGrid, pose: Pose, radius: float,
                  path: npt.NDArray[np.float64] | None = None,
                  walls: npt.NDArray[np.bool_] | None = None) -> tuple[int, float]:
    """The frontier a robot at `pose` could still go to and never went near, and the unknown space
    behind it.

    Frontier cells worth going to (`frontier_targets`, groups at least a robot wide) within a robot
    radius and a cell and a half of the known-free cells the robot can drive through from `pose`
    (`plan_costs` passable, 8-connected to its cell), leaving out those within `APPROACHED` of the
    robot's `path` (k, 2) [m] (the robot went there and looked: they stay frontier because no laser
    sees behind them from anywhere near, as inside a shelf). `walls` (rows, cols) bool, the cells the
    map ever showed firmly occupied (`WallMemory`), are walls too: a face that grazing beams wore
    down to free is still a face, not an opening, and the unknown behind it is the wall's inside. The
    unknown space counts where the planners would let the robot's disc go were it free (`plan_costs`'
    passability: its radius and `MARGIN` from the walls' surface).

    Returns:
        (cells, area): how many such frontier cells, and the area [m^2] of the unknown space
        within `LEFT_REACH` of them that they border (8-connected): what a laser would map from there.
    """
    from robotexp.mapping.kernels import flood8, label8
    from robotexp.planning.grid_planner import distance_transform
    from robotexp.planning.targets import (away_from, frontier_targets, passable_cell, passable_radius, plan_costs,
                                          surface_distance)

    geo = grid.geo
    passable = np.isfinite(plan_costs(grid, radius, 0.0))
    start = passable_cell(geo, passable, pose.x, pose.y)
    if start is None:
        return 0, 0.0
    occupied = grid.occupied()
    faces = None
    if walls is not None and walls.any():
        occupied = occupied | walls
        faces = distance_transform(walls) < 1.5      # the remembered walls' 8-neighbours
    targets = frontier_targets(grid, max(1, int(math.ceil(2 * radius / geo.cell))), faces)
    if not targets.any():
        return 0, 0.0
    reach = flood8(np.ascontiguousarray(passable), start[0], start[1])
    left = targets & (distance_transform(reach) <= radius / geo.cell + 1.5)
    # the unknown space a robot could drive into were it free: where a plan would let its disc go (clear of
    # every occupied cell's laser endpoints by the radius and the planners' margin: their passability,
    # unknown cells counted free), connected to the robot. A gap in a wall narrower than that (grazing
    # beams that freed or never reached a wall cell) opens no way to the unknown space beyond it, nor
    # does a shelf's inside.
    rr = passable_radius(geo.cell, radius)
    open_space = np.ascontiguousarray(surface_distance(occupied, grid.hit_box, rr) > rr)
    beyond = grid.unknown() & flood8(open_space, start[0], start[1]) if open_space[start] else None
    if beyond is None or not beyond.any():
        return 0, 0.0
    left &= distance_transform(beyond) <= 1.5
    if path is not None and len(path) and left.any():
        cells = geo.cells_of(path)
        cells = cells[geo.contains_cells(cells)]
        been = np.zeros(grid.shape, dtype=bool)
        been[cells[:, 0], cells[:, 1]] = True
        left = away_from(left, been, APPROACHED / geo.cell)
    n = int(np.count_nonzero(left))
    if n == 0:
        return 0, 0.0
    near = distance_transform(left) <= LEFT_REACH / geo.cell
    labels, _ = label8(np.ascontiguousarray(beyond & near))
    padded = np.pad(labels, 1)
    touched: set[int] = set()
    for r, c in np.argwhere(left):
        touched.update(int(v) for v in padded[r:r + 3, c:c + 3].ravel() if v)
    sizes = np.bincount(labels.ravel())
    return n, float(sum(int(sizes[k]) for k in touched)) * geo.cell ** 2


def unexplored_left(grid: OccupancyGrid, pose: Pose, radius: float, path: npt.NDArray[np.float64] | None = None,
                    walls: npt.NDArray[np.bool_] | None = None) -> tuple[int, float] | None:
    """`frontier_left` when what lies behind that frontier matters: at least `LEFT_AREA` [m^2] and
    `LEFT_SHARE` of the known free area (shadows behind furniture do not); else None."""
    n, area = frontier_left(grid, pose, radius, path, walls)
    free = float(np.count_nonzero(grid.free())) * grid.geo.cell ** 2
    if n and area >= max(LEFT_AREA, LEFT_SHARE * free):
        return n, area
    return None


class StallWatch:
    """Watches a run for lack of progress (see the module). Call `start` once, then `sample` at each
    coverage sample; `sample` returns the reason to end the run as stalled, else None.

    Args:
        window: [s] of robot time without a gain that makes a strike; None: from the map and the
            robot's top speed (see the module).
        strikes: strikes in a row that end the run.
        min_gain: [m^2] newly known space that counts as progress.
    """

    def __init__(self, window: float | None = None, strikes: int = STRIKES, min_gain: float = MIN_GAIN) -> None:
        if window is not None and not window > 0:
            raise ValueError(f"stall watch: window must be > 0 s, got {window}")
        if strikes < 1:
            raise ValueError(f"stall watch: strikes must be >= 1, got {strikes}")
        self.window_given = window
        self.window = window or MIN_WINDOW
        self.strikes_limit = strikes
        self.min_gain = min_gain
        self.strikes = 0
        self.given_up = 0           # targets the explorer gave up at a strike
        self.best = -1              # most known cells so far
        self.since = 0.0            # [s] robot time of the last gain (or strike)
        self._gain_cells = 1
        self.least_left: int | None = None     # the explorer's lowest `frontier_left` since the last gain

    def start(self, grid: OccupancyGrid, v_max: float) -> None:
        """Size the window for `grid` and a robot of top speed `v_max` [m/s]; reset the counts."""
        geo = grid.geo
        if self.window_given is None:
            transit = TRANSIT_FACTOR * (geo.width + geo.height) / v_max if v_max > 0 else 0.0
            slow = SLOW_SPEED / v_max if 0 < v_max < SLOW_SPEED else 1.0
            self.window = min(max(MIN_WINDOW * slow, transit), MAX_WINDOW * slow)
        self._gain_cells = max(1, int(math.ceil(self.min_gain / geo.cell ** 2)))
        self.strikes = self.given_up = 0
        self.best, self.since = -1, 0.0
        self.least_left = None

    def sample(self, time: float, grid: OccupancyGrid, explorer: Any) -> str | None:
        """Account the map at robot time `time` [s]; at a strike ask `explorer.give_up(grid)`.

        Returns:
            The reason to end the run (it starts with "stalled"), or None to go on.
        """
        box = grid.touched_box()            # every cell outside it is unknown
        view = grid.window(*box) if box is not None else None
        known = 0 if view is None else int(view.values.size - np.count_nonzero(view.unknown()))
        if getattr(explorer, "backtracking", False):
            # an explorer on a way back it bounds itself (SRT's drive to the parent node: each one
            # moves up a finite tree) gains nothing by design; the window starts when it is done
            self.since = time
            return None
        left = getattr(explorer, "frontier_left", None)
        left = left if isinstance(left, int) and not isinstance(left, bool) else None
        if known >= self.best + self._gain_cells or self.best < 0:
            self.best, self.since, self.strikes, self.least_left = known, time, 0, left
            return None
        if time - self.since < self.window:
            return None
        if left is not None and self.least_left is not None and left < self.least_left:
            # the explorer resolved frontier to a new low: progress that maps too little to count as a
            # gain, bounded (the count is a natural number and must fall each window)
            self.least_left, self.since, self.strikes = left, time, 0
            return None
        self.strikes += 1
        self.since = time
        give_up = getattr(explorer, "give_up", None)
        if callable(give_up) and give_up(grid):
            self.given_up += 1
        if self.strikes >= self.strikes_limit:
            return (f"stalled: no newly known space for {self.strikes} x {self.window:.0f} s of robot time "
                    f"({self.given_up} targets given up)")
        return None


LEAVE_TOL = 0.3             # [m] how far the robot's centre may stray past the exploration area


class RunWatch(RunObserver):
    """The run observer of honest endings (see the module): the stall watch at every coverage sample,
    the exploration area at every step (a robot centre more than LEAVE_TOL outside it ends the run),
    and the frontier left when the explorer says it is done (the run is then not completed: its
    reason says the explorer stopped with reachable frontier left).

    Args:
        stall: the stall watch, or None for none.
        area: [m] the exploration area, or None.
        check_done: check an explorer's Done against the frontier left.
    """

    def __init__(self, stall: StallWatch | None = None, area: tuple[float, float, float, float] | None = None,
                 check_done: bool = True) -> None:
        self.stall, self.area, self.check_done = stall, area, check_done
        self.walls: WallMemory | None = None

    def on_start(self, run: Any) -> None:
        """Size the stall window for the run's grid and robot; start the memory of walls."""
        from robotexp.planning.targets import shared_wall_memory

        if self.stall is not None:
            self.stall.start(run.grid, run.robot.limits.v_max)
        self.walls = shared_wall_memory(run.grid, 1.5) if self.check_done else None

    def on_step(self, run: Any, step: Any) -> None:
        """Bounds and Done checks."""
        from robotexp.explorer import Done
        from robotexp.world.bounds import inside


        p = step.state.true_pose or step.state.pose
        if self.area is not None and not inside(self.area, p.x, p.y, LEAVE_TOL):
            x0, y0, x1, y1 = self.area
            run.request_stop(f"the robot left the exploration area at ({p.x:.2f}, {p.y:.2f}) m "
                             f"(x {x0:g}..{x1:g}, y {y0:g}..{y1:g} m)", EndReason.STOPPED)
        if self.walls is not None:
            self.walls.note(run.grid)
        if self.check_done and isinstance(step.decision, Done) and step.decision.explored:
            walls = self.walls.ever if self.walls is not None else None
            left = unexplored_left(run.grid, step.state.pose, run.robot.radius, np.asarray(run.metrics.path),
                                   walls)
            if left is not None:
                run.completed = False
                run.end = EndReason.STOPPED
                run.reason = (f"stopped: the explorer ended ({step.decision.reason}) with {left[0]} frontier cells "
                              f"left that the robot can reach, {left[1]:.1f} m2 of unknown space behind them")

    def on_sample(self, run: Any, time: float, coverage: float | None) -> None:
        """The stall watch."""
        if self.stall is None:
            return
        reason = self.stall.sample(time, run.grid, run.explorer)
        if reason is not None:
            run.request_stop(reason, EndReason.STALLED)


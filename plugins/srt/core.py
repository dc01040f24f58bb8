"""The Sensor-based Random Tree (Oriolo et al. 2004; thesis §3.2, Fig. 3.5): tree and algorithm.

`SRTTree` holds the nodes (pose, local safe region, parent). `SRTExplorer` runs Fig. 3.5 as a
robotexp explorer: perceive at the current node, add it to the tree, look for a valid candidate
(`_candidate`, per perception) and drive to it in a straight line inside the current safe region,
or drive back along the tree edge to the parent; at the root with nothing valid the robot is back
at its start pose and the run is done. The perceptions are in `explorers.py`.

Two safeguards keep the motion on the tree's edges (both beyond the thesis's idealised robot):

- Re-centring: the follower stops within its goal tolerance (0.15 m) of a target, so a robot that
  comes back to a node stands up to 0.15 m beside it, and a straight line from there to the parent
  is not the edge whose clearance the region guaranteed: in the dense world such a line passed
  0.25 m from a wall corner that the edge cleared by 0.34 m, the follower's laser guard stopped the
  robot and the run stalled. Before every move away from a node the robot therefore first drives
  back onto the node's position (within `settle_tolerance`), so it follows the recorded edge.
- Detour (an extension of the thesis): when the way back to the parent still makes no progress for
  `detour_after` [s] (e.g. something moved into it), the robot plans a path to the parent with A*
  on the run's occupancy grid (`robotexp.planning.targets.plan_costs`: known-free cells, the robot
  inflated) restricted to the union of the safe regions, the space SRT has perceived as free; a
  detour that stalls in turn is planned again on the updated grid, up to 3 times.

The map of SRT is the union of the safe regions: each new region is rasterised into the run's
grid (`mark_free`, cells the map already holds as occupied are kept) and the obstacle points it
knows are marked occupied. The run loop integrates the laser scans into the same grid too.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import numpy.typing as npt

from robotexp import ConfigError, Done, Explorer, ExplorerContext, Pose, RobotState, Twist
from robotexp.mapping.grid import OccupancyGrid
from robotexp.planning.follower import GRAIN, FollowerConfig, PathFollower, ScanMemory, footprint_blocked, path_points
from robotexp.planning.grid_planner import astar
from robotexp.planning.targets import passable_cell, plan_costs

from .regions import SafeRegion

if TYPE_CHECKING:
    from robotexp.localization import FrameCorrection

__all__ = ["Node", "SRTTree", "SRTExplorer", "Phase"]

TURN_MARGIN = 0.03      # [m] kept between a rectangular robot turning at a node and the mapped walls
TURN_STEP_BACK = 0.05   # [m] a target where it cannot turn moves back towards its node by this much at a time
TURN_AHEAD = 1.0        # [m] how far beyond a target in a door its node may move to where the robot can turn


@dataclass
class Node:
    """One tree node: where the robot perceived, what it found safe, and its parent (None: root)."""

    x: float                   # [m]
    y: float                   # [m]
    region: SafeRegion
    parent: int | None
    children: list[int] = field(default_factory=list)
    failed: list[tuple[float, float]] = field(default_factory=list)   # candidates the robot could not reach
    t: float = 0.0             # [s] the robot time of the pose it was perceived from (`map_rebuilt` moves it)


class SRTTree:
    """The SRT tree T: nodes in insertion order, index 0 the root."""

    def __init__(self) -> None:
        self.nodes: list[Node] = []

    def __len__(self) -> int:
        return len(self.nodes)

    def add(self, x: float, y: float, region: SafeRegion, parent: int | None, t: float = 0.0) -> int:
        """ADD(T, (q, S(q))) as a child of `parent` (None only for the first node), perceived from the pose
        of robot time `t` [s]; returns its index.

        Raises:
            ConfigError: a parent that is not in the tree, or a second root.
        """
        if parent is None and self.nodes:
            raise ConfigError("srt tree: only the first node may be the root")
        if parent is not None and not 0 <= parent < len(self.nodes):
            raise ConfigError(f"srt tree: parent {parent} is not a node (tree has {len(self.nodes)})")
        self.nodes.append(Node(x, y, region, parent, t=t))
        index = len(self.nodes) - 1
        if parent is not None:
            self.nodes[parent].children.append(index)
        return index

    def path_to_root(self, index: int) -> list[int]:
        """The backtracking order from node `index`: itself, its parent, ..., the root."""
        out = [index]
        while (parent := self.nodes[out[-1]].parent) is not None:
            out.append(parent)
        return out

    def inside_other(self, points: npt.NDArray[np.float64], exclude: int | None = None,
                     margin: float = 0.0) -> npt.NDArray[np.bool_]:
        """Bool (k,): which of the (k, 2) points [m] lie in the safe region (radius grown by `margin`
        [m]) of a node other than `exclude`."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        inside = np.zeros(len(p), dtype=bool)
        for i, node in enumerate(self.nodes):
            if i != exclude:
                inside |= node.region.contains(p, margin)
        return inside

    def near_node(self, points: npt.NDArray[np.float64], gap: float) -> npt.NDArray[np.bool_]:
        """Bool (k,): which of the (k, 2) points [m] lie within `gap` [m] of a node's position."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if not self.nodes or gap <= 0:
            return np.zeros(len(p), dtype=bool)
        q = np.array([(n.x, n.y) for n in self.nodes])
        d = np.hypot(p[:, None, 0] - q[None, :, 0], p[:, None, 1] - q[None, :, 1])
        return np.asarray((d < gap).any(axis=1))

    def union_mask(self, grid: OccupancyGrid) -> npt.NDArray[np.bool_]:
        """Bool (rows, cols) of `grid`: the cells inside any node's safe region (SRT's own map)."""
        out = np.zeros(grid.shape, dtype=bool)
        for node in self.nodes:
            out |= node.region.mask(grid.geo)
        return out


class Phase(Enum):
    """What the explorer is doing."""

    SENSE = "sense"        # taking the perception of a new node
    SETTLE = "settle"      # driving back onto the current node's position before leaving it
    TURN = "turn"          # turning on the spot towards the next target
    MOVE = "move"          # driving straight to the target
    HOME = "home"          # back at the root: turning to the start heading


class SRTExplorer(Explorer):
    """The SRT algorithm of thesis Fig. 3.5 for a differential robot; subclasses define the perception.

    Motion: the robot turns on the spot to face the target, then drives the straight segment with
    the shared `PathFollower` (which also stops it before an obstacle the laser sees in its way).
    A move that makes no progress for `stuck_timeout` [s] is abandoned: the robot goes back to the
    node it left and never tries a candidate within `failed_radius` of that one again from there.
    Before leaving a node the robot re-centres on it; a way back to the parent without progress
    for `detour_after` [s] is replaced by a detour through the union of the safe regions (see the
    module docstring); only when no detour exists, or the detour itself stalls, does the run end,
    unless it stalled within `arrive_tolerance` of the node: then the node counts as reached.

    Args:
        max_nodes: K_max, the largest number of nodes (the run ends when it is reached).
        stuck_timeout: [s] without progress before a move is abandoned.
        failed_radius: [m] around an abandoned candidate where no candidate is tried again.
        settle_tolerance: [m] how close to a node's position the robot re-centres before leaving it.
        detour_after: [s] without progress on the way back to the parent before a detour is planned.
    """

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "max_nodes": (1, 100_000), "stuck_timeout": (None, 86400.0), "failed_radius": (0.0, 10.0)}

    def __init__(self, *, max_nodes: int = 1000, stuck_timeout: float = 8.0, failed_radius: float = 0.3,
                 settle_tolerance: float = 0.03, detour_after: float = 3.0) -> None:
        if max_nodes < 1:
            raise ConfigError(f"{self.name}: max_nodes must be >= 1, got {max_nodes}")
        if not stuck_timeout > 0 or not failed_radius >= 0:
            raise ConfigError(f"{self.name}: stuck_timeout must be > 0 s and failed_radius >= 0 m, "
                              f"got {stuck_timeout} and {failed_radius}")
        if not 0 < settle_tolerance <= 0.15 or not detour_after > 0:
            raise ConfigError(f"{self.name}: settle_tolerance must be in (0, 0.15] m and detour_after > 0 s, "
                              f"got {settle_tolerance} and {detour_after}")
        self.max_nodes, self.stuck_timeout, self.failed_radius = max_nodes, stuck_timeout, failed_radius
        self.settle_tolerance, self.detour_after = settle_tolerance, detour_after
        self.skip_back = False      # a variant's extension: back to the nearest ancestor with a candidate (`_skip_up`)

    name = "srt"
    arrive_tolerance = 0.3   # [m] a way back that stalls this close to its node counts as arrived

    def reset(self, ctx: ExplorerContext) -> None:
        """Start a new run: an empty tree, perceiving at the start pose. On a sonar map (`_laser_rectangle`
        False) a rectangular robot is grown the disc it sweeps turning (`Footprint.swing`): its nodes and
        straight ways then fit it at any heading."""
        if self.uses_sonar and not ctx.outline.round:
            ctx = replace(ctx, radius=ctx.outline.swing)
        super().reset(ctx)
        self._memory = ScanMemory(reach=ctx.outline.swing + 0.6)
        self.tree = SRTTree()
        self.follower = PathFollower(ctx.limits, ctx.radius, footprint=ctx.footprint, memory=self._memory)
        self.settler = PathFollower(ctx.limits, ctx.radius, footprint=ctx.footprint, memory=self._memory,
                                    config=FollowerConfig(goal_tolerance=self.settle_tolerance, lookahead=0.05))
        self.current: int | None = None       # the node the robot is at (or left from)
        self.target: tuple[float, float] | None = None
        self.target_node: int | None = None   # node the target is (None: a new candidate)
        self.phase = Phase.SENSE
        self.backtracks = 0
        self.abandoned = 0
        self.detours = 0
        self._detoured = 0
        self._grid: OccupancyGrid | None = None
        self._best = math.inf
        self._progress_t = 0.0
        self._now = 0.0                      # [s] the robot time of the step
        self._planned_move = False           # the move at hand drives the planner's path (`_drives_map_path`)
        self.passed = np.zeros((0, 0), dtype=bool)      # the cells the robot's centre has been in
        self._planned_nodes: set[int] = set()    # nodes reached on the planner's path from their parent
        self._pending: tuple[int, tuple[float, float], bool] | None = None   # (node, its candidate, planned)
        self._skipping = False               # the move at hand goes back past the parent (`_skip_up`)
        self._rescue_from: int | None = None     # the node a rescue through the map is planned from (`_skip_up`)
        self.skipped = 0                     # nodes passed on the way back without stopping
        self._skip_count = 0                 # those of the way back at hand (`_skip_up`; undone by `_back_to_parent`)
        self._begin_sense()

    def result_fields(self) -> dict[str, object]:
        """`nodes`: the size of the tree; `backtracks`: moves back up the tree; `detours`: planned
        detours on the way back; `abandoned`: candidates given up; `skipped`: nodes passed on the way back
        without stopping (`skip_back`)."""
        return {"nodes": len(self.tree), "backtracks": self.backtracks, "detours": self.detours,
                "abandoned": self.abandoned, "skipped": self.skipped}

    @property
    def backtracking(self) -> bool:
        """True while the robot drives back to a node of the tree (to the parent or an ancestor, or re-centres on
        its node before leaving it) or across the map to a variant's rescue through the map: the run's stall
        watch (`robotexp.run.endings.StallWatch`) does not count this time, in which SRT maps nothing by design.
        Both are bounded (each move goes up the finite tree; each rescue through the map aims at frontier no
        earlier one aimed at; a move without progress is abandoned after `stuck_timeout`)."""
        moving = self.phase in (Phase.TURN, Phase.MOVE)
        return self.phase is Phase.SETTLE or (moving and (self.target_node is not None or self._planned_move))

    def markers(self) -> dict[str, dict[str, object]]:
        """What the live view draws (robotexp.view): the tree's nodes and edges, each node's safe region
        (its boundary, at most 90 vertices) and the current target, in world coordinates [m]."""
        nodes = self.tree.nodes
        regions = []
        for node in nodes:
            b = node.region.boundary()
            b = b[:: max(1, math.ceil(len(b) / 90))]
            regions.append([round(float(v), 3) for v in b.ravel()])
        edges = [round(float(v), 3) for n in nodes if n.parent is not None
                 for v in (nodes[n.parent].x, nodes[n.parent].y, n.x, n.y)]
        points: dict[str, object] = {"SRT nodes": [round(float(v), 3) for n in nodes for v in (n.x, n.y)]}
        if self.target is not None:
            points["target"] = [round(float(v), 3) for v in self.target]
        return {"polygons": {"safe regions": regions}, "lines": {"SRT tree": edges}, "points": points}

    # -- the perception, per variant --------------------------------------------------
    @abstractmethod
    def _begin_sense(self) -> None:
        """Prepare to perceive at a new node."""

    @abstractmethod
    def _sense(self, state: RobotState) -> tuple[Twist, SafeRegion | None]:
        """One step of PERCEPTION: the command meanwhile, and the region once it is complete."""

    @abstractmethod
    def _candidate(self, index: int) -> tuple[float, float] | None:
        """A valid candidate [m] from node `index`, or None (then the robot backtracks)."""

    # -- the algorithm --------------------------------------------------------------
    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        """One control step of Fig. 3.5."""
        pose = state.pose
        self._grid = grid
        self._now = state.time
        if self.passed.shape != grid.shape:
            self.passed = np.zeros(grid.shape, dtype=bool)
        r, c = grid.geo.cell_of(pose.x, pose.y)
        if grid.geo.contains(r, c):
            self.passed[r, c] = True
        if not self.ctx.outline.round:
            self._memory.see_map(grid)
            self._memory.note(pose, state.laser)
        if self.phase is Phase.SENSE:
            twist, region = self._sense(state)
            if region is None:
                return twist
            self._add_node(pose, region, grid)
            if len(self.tree) >= self.max_nodes:
                return Done(f"node limit of {self.max_nodes} reached", explored=False)
            return self._choose(pose, state)
        if self.phase is Phase.SETTLE:
            return self._settle(pose, state)
        if self.phase is Phase.TURN:
            return self._turn(pose, state)
        if self.phase is Phase.MOVE:
            return self._move(pose, state)
        # HOME: at the root, nothing left to explore
        twist, facing = self.follower.turn_to(pose, self.ctx.start.theta, state.laser)
        return Done("explored; back at the start") if facing else twist

    def _laser_rectangle(self) -> bool:
        """A rectangular robot whose map is the laser's: its nodes go where it can turn (`_turnable_target`)
        and it drives between them on the planner's path (`rectangle_path`). A sonar map (SRT-Star's) is
        too sparse to say where the robot can turn: there the robot keeps the straight ways and its
        guard."""
        return not self.ctx.outline.round and not self.uses_sonar

    def _drives_map_path(self) -> bool:
        """True when the move at hand follows the planner's path on the map (`rectangle_path`) rather than a
        straight way: always for a rectangular robot (`_laser_rectangle`); for a move to a candidate that
        the tree's regions do not lead to (a variant's rescue through the map, `_planned_move`), the way
        back from it to its node, and the way back up to the parent from a node reached so."""
        if self._laser_rectangle() or self._planned_move or self._skipping:
            return True
        current, back = self.current, self.target_node
        return (back is not None and current is not None and current in self._planned_nodes
                and self.tree.nodes[current].parent == back)

    def _turnable(self, x: float, y: float, reach: float | None = None) -> bool:
        """True when no cell the map holds occupied lies within `reach` [m] (default: the disc a rectangular
        robot sweeps turning, `Footprint.swing` + `TURN_MARGIN`) of (x, y) [m], each cell taken as its whole
        square, and (x, y) lies in a free cell."""
        grid = self._grid
        if grid is None:
            return False
        geo = grid.geo
        reach = self.ctx.outline.swing + TURN_MARGIN if reach is None else reach
        r, c = geo.cell_of(x, y)
        if not geo.contains(r, c) or not grid.window(r, r + 1, c, c + 1).free()[0, 0]:
            return False
        k = int(math.ceil(reach / geo.cell)) + 1
        r0, c0 = max(r - k, 0), max(c - k, 0)
        if r + k + 1 <= r0 or c + k + 1 <= c0 or r0 >= geo.rows or c0 >= geo.cols:
            return False
        rr, cc = np.nonzero(grid.window(r0, r + k + 1, c0, c + k + 1).occupied())
        dx = np.maximum(np.abs(geo.origin_x + (c0 + cc + 0.5) * geo.cell - x) - geo.cell / 2, 0.0)
        dy = np.maximum(np.abs(geo.origin_y + (r0 + rr + 0.5) * geo.cell - y) - geo.cell / 2, 0.0)
        return not bool((dx * dx + dy * dy < reach * reach).any())

    def _turnable_target(self, node: Node, cand: tuple[float, float]) -> tuple[float, float] | None:
        """A rectangular robot senses by turning in place at its next node: the candidate; else, when the
        candidate lies in a passage (a door), the nearest point up to `TURN_AHEAD` beyond it on the same
        line, over mapped free cells as wide as the robot, where it can turn (`_turnable`); else the
        point nearest it on the way back to `node` where it can; None when there is none beyond
        `TURN_STEP_BACK` of the node."""
        dx, dy = cand[0] - node.x, cand[1] - node.y
        length = math.hypot(dx, dy)
        if length < 1e-9:
            return None
        assert self._grid is not None
        width = self.ctx.outline.half_width - self._grid.geo.cell      # the cells' squares are conservative
        s = length
        while s <= length + TURN_AHEAD:
            x, y = node.x + dx * s / length, node.y + dy * s / length
            if not self._turnable(x, y, width):     # (a free cell, nothing mapped as wide as the robot)
                break
            if self._turnable(x, y):
                return x, y
            s += TURN_STEP_BACK
        s = length
        while s >= TURN_STEP_BACK:
            x, y = node.x + dx * s / length, node.y + dy * s / length
            if self._turnable(x, y):
                return x, y
            s -= TURN_STEP_BACK
        return None

    def _turn_blocked(self, state: RobotState, rate: float) -> bool:
        """True when turning in place at `rate` [rad/s] would bring a corner of a rectangular robot onto a
        return of its recent scans (a round robot never is): its sweep then ends with what it saw."""
        foot = self.ctx.outline
        if foot.round:
            return False
        lim = self.ctx.limits
        return footprint_blocked(self._memory.points(state.pose), foot, 0.01 + GRAIN, 0.0, rate, lim.a_max,
                                 lim.alpha_max)

    def _turn(self, pose: Pose, state: RobotState) -> Twist | Done:
        """Turn on the spot to face the target, then drive. A rectangular robot drives the planner's path
        instead (`rectangle_path`), which crosses a door square to it: its straight way may not fit."""
        assert self.target is not None
        if self._drives_map_path() and self._grid is not None:
            # a way back past the parent: inside the union of the safe regions, the ways the tree drove
            path = self.detour(pose, self.target, self._grid) if self._skipping else None
            if path is None:
                path = self.rectangle_path(pose, self.target, self._grid)
            if path is None and self._skipping and self.current is not None:
                self._back_to_parent()          # no way there on the map: up one node, as the thesis
                return self._turn(pose, state)
            if path is not None:
                self.follower.set_path(path)
                self.phase = Phase.MOVE
                self._best, self._progress_t = math.inf, state.time
                return self._move(pose, state)
        twist, facing = self.follower.turn_to(pose, math.atan2(self.target[1] - pose.y, self.target[0] - pose.x),
                                              state.laser)
        if not facing:
            return twist
        self.follower.set_path(np.array([[pose.x, pose.y], self.target]))
        self.phase = Phase.MOVE
        self._best, self._progress_t = math.inf, state.time
        return self._move(pose, state)

    def _move(self, pose: Pose, state: RobotState) -> Twist | Done:
        """Drive the straight segment to the target."""
        twist = self.follower.twist(pose, state.laser, state.velocity)
        if not self.follower.done:
            return self._watch(pose, state, twist)
        self._detoured = 0
        if self.target_node is None:         # a new candidate: perceive there (line 4)
            self.phase = Phase.SENSE
            self._begin_sense()
            return Twist.ZERO
        self.current = self.target_node      # back at a known node: choose again (no new node)
        return self._choose(pose, state)

    def map_rebuilt(self, grid: OccupancyGrid, moved: FrameCorrection) -> None:
        """Loop closure moved the poses: every node moves (position, safe region, abandoned candidates) with the
        pose it was perceived from, the target and the path being driven with the node they lead from or to,
        and the regions are marked into the rebuilt map again (it holds the scans only). A perception under way
        starts over (its beams were taken in the old frame)."""
        for node in self.tree.nodes:
            dx, dy, dth = moved.move(node.t)
            node.x, node.y = moved.point(node.x, node.y, node.t)
            node.region = node.region.moved(dx, dy, dth)
            node.failed = [moved.point(fx, fy, node.t) for fx, fy in node.failed]
            self._mark(node.region, grid)
        if self.current is not None:
            here = self.tree.nodes[self.current]
            if self.target_node is not None:
                node = self.tree.nodes[self.target_node]
                self.target = (node.x, node.y)
            elif self.target is not None:
                self.target = moved.point(*self.target, here.t)
            for follower, end in ((self.follower, self.target), (self.settler, (here.x, here.y))):
                if not follower.done:         # the path from here, its end where its node or target now is
                    index = follower._index
                    path = moved.points(follower.path, here.t)
                    if end is not None:
                        path[-1] = end
                    follower.set_path(path)
                    follower._index = index
        if self.phase is Phase.SENSE and self.tree.nodes:
            self._begin_sense()
        self._pending = None        # the candidate found on the way back is looked for again on arrival
        self._best = math.inf

    def _add_node(self, pose: Pose, region: SafeRegion, grid: OccupancyGrid) -> None:
        self.current = self.tree.add(pose.x, pose.y, region, self.current, t=self._now)
        if self._planned_move:
            self._planned_nodes.add(self.current)
        self._mark(region, grid)

    def _mark(self, region: SafeRegion, grid: OccupancyGrid) -> None:
        """Mark a safe region into the map: its cells free (unless occupied), and with the sonar ring (whose
        map holds nothing else of them) its obstacle points occupied. A laser's scans map the obstacles
        themselves, finer than its sweep: a sweep's obstacle points (the shortest reading of each bin) stand
        in front of surfaces seen aslant, and marked as certain walls they had closed the 0.6 m way out of
        a cluttered room to the 0.5 m disc (ipa_lab_a)."""
        free = region.mask(grid.geo) & ~grid.occupied()
        grid.mark_free(free)
        obstacles = region.obstacle_points() if self.uses_sonar else np.zeros((0, 2))
        if len(obstacles):
            occ = np.zeros(grid.shape, dtype=bool)
            geo = grid.geo
            # a hit lies on the obstacle's face: a hair further along the ray is inside it
            d = obstacles - (region.x, region.y)
            n = np.hypot(d[:, 0], d[:, 1])[:, None]
            inner = obstacles + 1e-4 * d / np.maximum(n, 1e-12)
            rc = geo.cells_of(inner)
            rc = rc[geo.contains_cells(rc)]
            occ[rc[:, 0], rc[:, 1]] = True
            grid.mark_occupied(occ)

    def _choose(self, pose: Pose, state: RobotState) -> Twist | Done:
        """Lines 7-19: a valid candidate, else back to the parent (with `skip_back`, to the nearest ancestor
        that has one), else (root) done."""
        assert self.current is not None
        pending, self._pending, self._skipping = self._pending, None, False
        cand: tuple[float, float] | None
        if pending is not None and pending[0] == self.current:     # found on the way back (`_skip_up`)
            cand, self._planned_move = pending[1], pending[2]
        else:
            cand = self._node_candidate(self.current)
        if cand is not None:
            self.target, self.target_node = cand, None
        else:
            parent = self.tree.nodes[self.current].parent
            if parent is None:
                self.target, self.target_node = None, None
            else:
                self.backtracks += 1
                up = self._skip_up(parent) if self.skip_back else parent
                if self._pending is not None and self._pending[2]:
                    # a candidate on the planner's path (srt-laser's map rescue at the root): driven to from
                    # here on that path, as from its node, and the new node hangs from that node
                    (_, cand, self._planned_move), self._pending = self._pending, None
                    self.current, self.target, self.target_node = up, cand, None
                else:
                    node = self.tree.nodes[up]
                    self.target, self.target_node = (node.x, node.y), up
                    self._skipping = up != parent
        self._detoured = 0
        here = self.tree.nodes[self.current]
        straight = not (self._skipping or (self.skip_back and self._planned_move))
        if straight and math.hypot(here.x - pose.x, here.y - pose.y) > self.settle_tolerance:
            self.phase = Phase.SETTLE
            self.settler.set_path(np.array([[pose.x, pose.y], [here.x, here.y]]))
            self._progress_t = state.time
            return self._settle(pose, state)
        return self._leave(pose, state)

    def _node_candidate(self, index: int) -> tuple[float, float] | None:
        """VALIDATE at node `index`: a candidate (for a rectangular robot on a laser map, where it can turn),
        or None; `_planned_move` says whether the move to it drives the planner's path."""
        self._planned_move = False
        cand = self._candidate(index)
        if cand is not None and self._laser_rectangle():
            cand = self._turnable_target(self.tree.nodes[index], cand)
        return cand

    def _skip_up(self, parent: int) -> int:
        """`skip_back` (an extension): the nearest of `parent` and its ancestors with a candidate (VALIDATE at
        each, as the robot would on arriving there), else the root. The robot drives there on a path through
        the union of the safe regions (`detour`) instead of up the tree edge by edge, turning and re-centring
        at every node: those were two fifths of srt-laser's time on a large floor. The candidate found is
        kept for the arrival."""
        index = parent
        self._rescue_from = self.current    # a rescue through the map: the nearest to the robot, not to its node
        self._skip_count = 0
        try:
            while True:
                cand = self._node_candidate(index)
                if cand is not None:
                    self._pending = (index, cand, self._planned_move)
                    self._planned_move = False
                    return index
                up = self.tree.nodes[index].parent
                if up is None:
                    return index
                self._skip_count += 1
                index = up
        finally:
            self._rescue_from = None
            self.skipped += self._skip_count

    def _back_to_parent(self) -> None:
        """A way back past the parent has no path: go back to the parent instead (what was found on the way
        is found again there)."""
        assert self.current is not None
        parent = self.tree.nodes[self.current].parent
        if parent is not None:
            node = self.tree.nodes[parent]
            self.target, self.target_node = (node.x, node.y), parent
        self._pending, self._skipping = None, False
        self.skipped -= self._skip_count         # the nodes of that way are not passed: they are gone up to again
        self._skip_count = 0

    def _leave(self, pose: Pose, state: RobotState) -> Twist | Done:
        """At the node: turn towards the target, or (no target) to the start heading at the root."""
        if self.target is None:
            self.phase = Phase.HOME
            self.follower.clear()
            twist, facing = self.follower.turn_to(pose, self.ctx.start.theta, state.laser)
            return Done("explored; back at the start") if facing else twist
        self.phase = Phase.TURN
        return self._turn(pose, state)

    def _settle(self, pose: Pose, state: RobotState) -> Twist | Done:
        """Drive onto the current node's position (it was reached within the follower's tolerance),
        so the next move starts where its straight way was validated; give up after `stuck_timeout`."""
        twist = self.settler.twist(pose, state.laser, state.velocity)
        if self.settler.done or state.time - self._progress_t > self.stuck_timeout:
            self.settler.clear()
            return self._leave(pose, state)
        return twist

    def _watch(self, pose: Pose, state: RobotState, twist: Twist) -> Twist | Done:
        """Abandon a move without progress: back to the node it started from."""
        remaining = self.follower.remaining(pose)
        if remaining < self._best - 0.05:
            self._best, self._progress_t = remaining, state.time
            return twist
        waited = state.time - self._progress_t
        assert self.current is not None
        if self.target_node is not None and self._detoured < 3:
            if waited < self.detour_after:
                return twist
            self._detoured += 1
            path = self._detour(pose)
            if path is not None:
                self.detours += 1
                self.follower.set_path(path)
                self._best, self._progress_t = math.inf, state.time
                self.phase = Phase.MOVE
                return Twist.ZERO
        if waited < self.stuck_timeout:
            return twist
        if self.target_node is not None and remaining <= self.arrive_tolerance:
            # the last few centimetres to a node the robot already stood on: the follower's laser
            # guard (a corridor a little wider than the robot) can refuse them beside a wall; the
            # node counts as reached and the next move leaves from here
            self.follower.clear()
            self._detoured = 0
            self.current = self.target_node
            return self._choose(pose, state)
        if self._skipping:                  # a way back past the parent that stalled: up one node instead
            self._back_to_parent()
            self.phase = Phase.TURN
            self._best, self._progress_t = math.inf, state.time
            return Twist.ZERO
        if self.target_node is not None or self.target is None:
            return Done(f"stuck on the way back to node {self.target_node} (no progress for "
                        f"{self.stuck_timeout:g} s; no detour through the safe regions)")
        node = self.tree.nodes[self.current]
        node.failed.append(self.target)
        self.abandoned += 1
        self.target, self.target_node = (node.x, node.y), self.current
        self.phase = Phase.TURN
        self._best, self._progress_t = math.inf, state.time
        return Twist.ZERO

    def _near_failed(self, index: int, points: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
        """Bool (k,): points within `failed_radius` of a candidate abandoned from node `index`."""
        failed = self.tree.nodes[index].failed
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if not failed:
            return np.zeros(len(p), dtype=bool)
        f = np.asarray(failed)
        d = np.hypot(p[:, None, 0] - f[None, :, 0], p[:, None, 1] - f[None, :, 1])
        return np.asarray((d < self.failed_radius).any(axis=1))

    def detour(self, pose: Pose, goal: tuple[float, float], grid: OccupancyGrid) -> npt.NDArray[np.float64] | None:
        """A path (k, 2) [m] from `pose` to `goal` [m] inside the union of the safe regions, or None.

        A* on `plan_costs` of `grid` (known-free cells, the robot radius plus a margin inflated
        around occupied cells) with every cell outside the union of the tree's safe regions blocked,
        string-pulled; the ends are the exact pose and goal. An extension of the thesis, whose
        robot always retraces the tree edge.
        """
        return self.rectangle_path(pose, goal, grid, within_tree=True)

    def rectangle_path(self, pose: Pose, goal: tuple[float, float], grid: OccupancyGrid,
                       within_tree: bool = False) -> npt.NDArray[np.float64] | None:
        """A path (k, 2) [m] from `pose` to `goal` [m] over the mapped free space (A* on `plan_costs` of
        `grid` for half the robot's width, clearance a cost; `within_tree`: inside the union of the safe
        regions), string-pulled; None when there is none."""
        points = np.zeros(grid.shape, np.uint8)
        cost = plan_costs(grid, self.ctx.radius, 0.3, points)
        if within_tree:
            cost[~self.tree.union_mask(grid)] = np.inf
        passable = np.isfinite(cost)
        geo = grid.geo
        begin = passable_cell(geo, passable, pose.x, pose.y)
        end = passable_cell(geo, passable, *goal)
        if begin is None or end is None:
            return None
        cells = astar(cost, begin, end)
        if cells is None:
            return None
        return np.vstack([[pose.x, pose.y], path_points(cells, passable, geo, points=points), [goal]])

    def _detour(self, pose: Pose) -> npt.NDArray[np.float64] | None:
        if self._grid is None or self.target is None:
            return None
        if self._drives_map_path():
            return self.rectangle_path(pose, self.target, self._grid)
        return self.detour(pose, self.target, self._grid)

"""The three SRT perceptions as robotexp explorers: `srt-ball`, `srt-star`, `srt-laser`.

Perception with a 180-degree laser (SRT-Ball, SRT-Laser): SRT assumes the sensors give the free
space all around the robot (thesis §3.2.1, assumption IV), and the P3-DX's laser covers only
the front half. At every new node the robot therefore turns on the spot and collects the scans
of the turn into 1-degree world-angle bins (smallest range per bin) until every bin has a beam:
about half a turn with a 180-degree laser, none with a 360-degree one. Turning does not add to the
path length; it costs robot time. SRT-Star reads the sonar ring, which already covers 360 degrees.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from typing import ClassVar

import numpy as np

from robotexp import ConfigError, ExplorerContext, Pose, RobotState, Twist, wrap_angle
from robotexp.mapping.grid import OccupancyGrid
from robotexp.world.groundtruth import ray_tree
from robotexp.mapping.kernels import flood8, view_free
from robotexp.planning.grid_planner import distance_transform, line_of_sight, nearest_goal
from robotexp.planning.reach import near_cells
from robotexp.planning.targets import (MARGIN, away_from, beside_large_unknown, cell_points, frontier_targets,
                                       passable_cell, plan_costs)

from .core import SRTExplorer
from .regions import (
    BallRegion,
    PolygonRegion,
    SafeRegion,
    StarRegion,
    SweepBuffer,
    in_sight,
    ray_reach,
    reachable_points,
    star_from_sonar,
    star_from_sweep,
)

__all__ = ["SRTBallExplorer", "SRTStarExplorer", "SRTLaserExplorer", "displace", "largest_gap"]

TAU = 2.0 * math.pi
ESCAPE = 0.5     # srt-star: a way that starts near the star's edge must leave it at >= 0.5 m per m (ray_reach)
RESCUE_RAYS = 360  # rays from a frontier cell when the rescue looks for the points that see it


def displace(x: float, y: float, theta: float, distance: float) -> tuple[float, float]:
    """DISPLACE(q, theta, d): the point `distance` [m] from (x, y) [m] along world angle `theta` [rad]."""
    return x + distance * math.cos(theta), y + distance * math.sin(theta)


class _FrontierRescue(SRTExplorer):
    """The frontier rescue of srt-star and srt-laser (an extension of the thesis, switch `frontier`).

    When VALIDATE finds no candidate at a node, before the robot goes back to the parent, the node
    looks at the frontier of the run's map (`frontier_targets`: free cells next to unknown ones,
    openings only, within the rescue view of the region), nearest first, and takes the point of its
    region the robot reaches in a straight line (`_rescue_points`), at least `node_gap` from every
    node, from which that cell is in sight through known-free cells within the rescue view. There the
    robot perceives as at any new node; the frontier cells the rescue was for that are still frontier
    then are given up (seen from beside them, they stay next to space the sensor cannot reach), so
    every rescue opens new ground or retires frontier cells, and the node gap bounds the nodes.
    A rescue that made less than `RESCUE_GAIN` of the map known (beyond the most it ever knew before
    the rescue was chosen, to the end of its perception) gives up every cell within `RESCUE_RADIUS`
    of its aim as a frontier: along a wall whose cells the grazing beams leave unknown, each
    perception moved the frontier a cell and the next rescue chased it (a generated office: 30
    rescues in one corridor, 720 s without new space, run stalled at 0.48). After `RESCUE_MISSES`
    unproductive rescues in a row no rescue is tried until a node makes the map grow by
    `RESCUE_GAIN`: in the sparse hall, rescues at the outer walls (wall cells left unknown) one after
    another kept the map from growing for 720 s and the run stalled at 0.88, where the thesis's
    tree alone completes. When the run's stall watch strikes (`give_up`), the frontier within the
    rescue view of the robot is given up.
    Subclasses set `frontier`, `node_gap`, `tries`, `bins` and define the view and the points.
    """

    RESCUE_GAIN = 0.5       # [m2] newly known by a rescue for it to count as productive
    RESCUE_RADIUS = 1.0     # [m] around an unproductive rescue's aim, the frontier given up
    RESCUE_MISSES = 4       # unproductive rescues in a row before rescues pause until the map grows
    RESCUE_SIGHT = False    # when no nearest point sees a cell, look for the points the cell sees (srt-laser)

    frontier: bool
    node_gap: float
    tries: int
    bins: int

    def reset(self, ctx: ExplorerContext) -> None:
        """Start a new run: no rescue yet, nothing given up."""
        super().reset(ctx)
        self.rescues = 0
        self._given_up = np.zeros((0, 0), dtype=bool)          # frontier cells a rescue did not resolve
        self._aim = np.zeros((0, 2), dtype=np.intp)             # frontier cells the pending rescue is for
        self._face: tuple[float, float] | None = None          # where the pending rescue looks on arrival
        self._known_at_rescue = 0                               # known cells when the pending rescue was chosen
        self._known_best = 0                                    # the most cells the map has known (high water)
        self._misses = 0                                        # unproductive rescues since the map last grew

    def result_fields(self) -> dict[str, object]:
        """As `SRTExplorer`, plus `rescues`: candidates taken from the map's frontier (VALIDATE found none)."""
        return {**super().result_fields(), "rescues": self.rescues}

    @abstractmethod
    def _rescue_view(self) -> float:
        """[m] the farthest a frontier cell may be from a rescue candidate (and from the region)."""

    @abstractmethod
    def _rescue_points(self, index: int) -> np.ndarray:
        """The (k, 2) points [m] of node `index`'s region the robot may drive to in a straight line."""

    def _skip_frontier(self, centres: np.ndarray, cell: float) -> np.ndarray:
        """Bool (k,): frontier cells (centres [m]) that are no openings for this sensor (default: none)."""
        return np.zeros(len(centres), dtype=bool)

    def _rescue_allowed(self) -> bool:
        """False after `RESCUE_MISSES` unproductive rescues in a row, until a node makes the map grow."""
        return self.frontier and self._misses < self.RESCUE_MISSES

    def frontier_cells(self, index: int) -> np.ndarray:
        """The map's frontier cells (int (k, 2) rows and columns) within the rescue view of node `index`'s
        region, nearest to the node first: `frontier_targets` of the run's grid (openings, not wall faces),
        less the cells a rescue already failed to resolve and those `_skip_frontier` leaves out."""
        grid = self._grid
        if grid is None:
            return np.zeros((0, 2), dtype=np.intp)
        geo = grid.geo
        min_cells = max(1, int(math.ceil(2 * self.ctx.radius / geo.cell)))
        cells = np.argwhere(frontier_targets(grid, min_cells, self._given_up_on(grid)))
        node = self.tree.nodes[index]
        centres = geo.centers_of(cells)
        d = np.hypot(centres[:, 0] - node.x, centres[:, 1] - node.y)
        near = d <= node.region.reach + self._rescue_view()
        cells, centres, d = cells[near], centres[near], d[near]
        if len(cells):
            keep = self._open_beyond(grid, node.x, node.y)[cells[:, 0], cells[:, 1]]
            cells, centres, d = cells[keep], centres[keep], d[keep]
        if len(cells):
            keep = ~self._skip_frontier(centres, geo.cell)
            cells, d = cells[keep], d[keep]
        return cells[np.argsort(d, kind="stable")]

    def _open_beyond(self, grid: OccupancyGrid, x: float, y: float) -> np.ndarray:
        """Bool (rows, cols): the cells within 1.5 cells of unknown space a robot disc could drive into were
        it free, from (x, y) [m] (the disc clear of every occupied cell; as the run's honest ending counts
        frontier, `robotexp.run.endings.frontier_left`). The inside of a shelf whose outline the laser drew with
        gaps, or a wall's cells that grazing beams left unknown, is no such space: chasing them cost a
        rescue each (nav2's depot: 44 rescues among its shelves, then a stall at 0.95). The map's edge
        counts as a wall: through a wall's unmarked cells the unknown strip outside a building (the
        run's map has 0.5 m around the world) is no space a robot fits in (the sparse hall's walls)."""
        beyond = self._space_beyond(grid, x, y)
        if beyond is None:
            return np.ones(grid.shape, dtype=bool)       # the node itself is too near an obstacle: no filter
        return np.asarray(distance_transform(beyond) <= 1.5)

    def _space_beyond(self, grid: OccupancyGrid, x: float, y: float) -> np.ndarray | None:
        """Bool (rows, cols): the unknown cells a robot disc could drive into from (x, y) [m] were they free
        (`_open_beyond`); None when (x, y) is too near an obstacle to say."""
        geo = grid.geo
        occ = grid.occupied().copy()
        occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True     # the map's edge is a wall to the robot too
        open_space = np.ascontiguousarray(distance_transform(occ) > self.ctx.radius / geo.cell)
        r, c = geo.cell_of(x, y)
        if not geo.contains(r, c) or not open_space[r, c]:
            return None
        return np.asarray(grid.unknown() & flood8(open_space, r, c))

    def _frontier_candidate(self, index: int) -> tuple[float, float] | None:
        """The rescue: a point of the region, reachable in a straight line, from which a frontier cell of
        the map is in sight (through known-free cells) within the rescue view."""
        grid = self._grid
        cells = self.frontier_cells(index)
        if grid is None or len(cells) == 0:
            return None
        geo = grid.geo
        view = self._rescue_view()
        reach = self._rescue_points(index)
        reach = reach[~self._near_failed(index, reach) & ~self.tree.near_node(reach, self.node_gap)]
        rc = geo.cells_of(reach)
        inside = geo.contains_cells(rc)
        _, first = np.unique(rc[inside, 0] * geo.cols + rc[inside, 1], return_index=True)
        reach, rc = reach[inside][first], rc[inside][first]       # one reachable point per cell
        if len(reach) == 0:
            return None
        free = grid.free()
        centres = geo.centers_of(cells)
        for (r, c), f in zip(cells, centres, strict=True):
            d = np.hypot(reach[:, 0] - f[0], reach[:, 1] - f[1])
            order = np.argsort(d, kind="stable")[:self.tries]
            j = self._in_sight(free, rc, order[d[order] <= view], (int(r), int(c)))
            if j is not None:
                return self._take_rescue(grid, cells, (int(r), int(c)), f, reach[j])
        # None of the nearest points sees its cell: a frontier inside a room, seen through its door from
        # the corridor, has its nearest points beside the door, behind the wall (a generated office: two
        # rooms never entered, "explored; back at the start" at 0.904). Then the points each cell sees:
        # rays from it through known-free cells within the view, nearest first. srt-laser only: srt-star's
        # sonar cones reach through a door only from near it, and such far looks cost it coverage
        # (campaigns/srt_star.toml, dense pose 4 at 40 mm/s: 0.922 against 0.995).
        if not self.RESCUE_SIGHT:
            return None
        offsets, skip = ray_tree(RESCUE_RAYS, view / geo.cell)
        span = int(math.ceil(view / geo.cell)) + 2
        for (r, c), f in zip(cells, centres, strict=True):
            r0, c0 = max(int(r) - span, 0), max(int(c) - span, 0)
            window = np.ascontiguousarray(~free[r0:int(r) + span + 1, c0:int(c) + span + 1])
            seen = view_free(window, np.array([[r - r0, c - c0]], np.int64), offsets, skip)
            local = rc - (r0, c0)
            cand = np.flatnonzero(((local >= 0) & (local < window.shape)).all(axis=1))
            cand = cand[seen[local[cand, 0], local[cand, 1]]]
            d = np.hypot(reach[cand, 0] - f[0], reach[cand, 1] - f[1])
            order = np.argsort(d, kind="stable")[:self.tries]
            j = self._in_sight(free, rc, cand[order[d[order] <= view]], (int(r), int(c)))
            if j is not None:
                return self._take_rescue(grid, cells, (int(r), int(c)), f, reach[j])
        return None

    @staticmethod
    def _in_sight(free: np.ndarray, rc: np.ndarray, order: np.ndarray, cell: tuple[int, int]) -> int | None:
        """The first of the points `order` (indices into `rc`, cells) with `cell` in sight through
        known-free cells (`line_of_sight`: False also when either end is not free), or None."""
        for j in order:
            if line_of_sight(free, (int(rc[j, 0]), int(rc[j, 1])), cell):
                return int(j)
        return None

    def _take_rescue(self, grid: OccupancyGrid, cells: np.ndarray, cell: tuple[int, int], face: np.ndarray,
                     point: np.ndarray) -> tuple[float, float]:
        """Choose `point` [m] as the rescue for frontier `cell` (centre `face`) and its neighbours in `cells`."""
        near = np.hypot(cells[:, 0] - cell[0], cells[:, 1] - cell[1]) * grid.geo.cell <= self.ctx.radius + grid.geo.cell
        self._aim, self._face = cells[near], (float(face[0]), float(face[1]))
        self._known_best = max(self._known_best, int(np.count_nonzero(~grid.unknown())))
        self._known_at_rescue = self._known_best
        self.rescues += 1
        return float(point[0]), float(point[1])

    def _given_up_on(self, grid: OccupancyGrid) -> np.ndarray:
        """The bool (rows, cols) mask of the frontier cells given up, sized to `grid`."""
        if self._given_up.shape != grid.shape:
            self._given_up = np.zeros(grid.shape, dtype=bool)
        return self._given_up

    def _add_node(self, pose: Pose, region: SafeRegion, grid: OccupancyGrid) -> None:
        """As `SRTExplorer`; after a rescue, the frontier cells it was for that are still frontier are
        given up (perceived from beside them, they stay next to unknown space the sensor cannot reach)."""
        super()._add_node(pose, region, grid)
        known = int(np.count_nonzero(~grid.unknown()))
        if (known - self._known_best) * grid.geo.cell ** 2 >= self.RESCUE_GAIN:
            self._misses = 0                    # the map grew: rescues may be tried again
        if len(self._aim) == 0:
            self._known_best = max(self._known_best, known)
            return
        front = frontier_targets(grid, 1)
        still = front[self._aim[:, 0], self._aim[:, 1]]
        given_up = self._given_up_on(grid)
        given_up[self._aim[still, 0], self._aim[still, 1]] = True
        # against the most the map ever knew (as the stall watch counts): cells that flicker between
        # free and unknown under grazing beams are no gain
        gained = (known - self._known_at_rescue) * grid.geo.cell ** 2
        self._known_best = max(self._known_best, known)
        if gained < self.RESCUE_GAIN:
            self._misses += 1
            # every cell near the aim, frontier now or not: cells beside a wall flicker between free,
            # unknown and wall face as beams graze them, and came back as frontier for the next rescue
            centre = grid.geo.centers_of(self._aim).mean(axis=0)
            self._give_up_near(grid, np.ones(grid.shape, dtype=bool), float(centre[0]), float(centre[1]),
                               self.RESCUE_RADIUS)
        self._aim = np.zeros((0, 2), dtype=np.intp)

    def _give_up_near(self, grid: OccupancyGrid, front: np.ndarray, x: float, y: float, radius: float) -> int:
        """Give up the cells of `front` (bool (rows, cols)) within `radius` [m] of (x, y) [m]; how many."""
        cells = np.argwhere(front)
        if len(cells) == 0:
            return 0
        c = grid.geo.centers_of(cells)
        near = cells[np.hypot(c[:, 0] - x, c[:, 1] - y) <= radius]
        self._given_up_on(grid)[near[:, 0], near[:, 1]] = True
        return len(near)

    def give_up(self, grid: OccupancyGrid) -> bool:
        """The run's stall watch struck (no new space for a while): give up the frontier within the rescue
        view of the robot's node. False when there was none to give up."""
        if self.current is None or not self.frontier:
            return False
        node = self.tree.nodes[self.current]
        front = frontier_targets(grid, 1, self._given_up_on(grid))
        return self._give_up_near(grid, front, node.x, node.y, node.region.reach + self._rescue_view()) > 0


class _SweepingSRT(SRTExplorer):
    """SRT whose perception is a turn on the spot with the laser (see the module docstring)."""

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "sweep_rate": (None, 10.0), "bins": (3, 36_000)}

    def __init__(self, *, sweep_rate: float = 0.8, bins: int = 360, max_nodes: int = 1000,
                 stuck_timeout: float = 8.0, failed_radius: float = 0.3) -> None:
        super().__init__(max_nodes=max_nodes, stuck_timeout=stuck_timeout, failed_radius=failed_radius)
        if not sweep_rate > 0 or bins < 3:
            raise ConfigError(f"{self.name}: sweep_rate must be > 0 rad/s and bins >= 3, got {sweep_rate}, {bins}")
        self.sweep_rate, self.bins = sweep_rate, bins

    def reset(self, ctx: ExplorerContext) -> None:
        """Start a new run. Raises ConfigError when the robot has no laser."""
        if not ctx.laser_range > 0:
            raise ConfigError(f"{self.name}: needs a laser, and the robot reports none (laser range "
                              f"{ctx.laser_range} m); choose a robot with a laser")
        super().reset(ctx)

    def _begin_sense(self) -> None:
        self.sweep = SweepBuffer(self.bins)
        self._turned = 0.0
        self._last_heading: float | None = None

    def _sense(self, state: RobotState) -> tuple[Twist, SafeRegion | None]:
        pose = state.pose
        if state.laser is not None:
            scan = state.laser
            self.sweep.add(pose.theta, scan.angles, scan.ranges, scan.range_max, scan.offset_x)
        if self._last_heading is not None:
            self._turned += abs(wrap_angle(pose.theta - self._last_heading))
        self._last_heading = pose.theta
        rate = min(self.ctx.limits.w_max, self.sweep_rate)
        if self.sweep.complete() or self._turned > 2 * math.pi + 0.2 or self._turn_blocked(state, rate):
            return Twist.ZERO, self._region(pose.x, pose.y)
        return Twist(0.0, rate), None

    @abstractmethod
    def _region(self, x: float, y: float) -> SafeRegion:
        """The region perceived at (x, y) [m] from the sweep."""


class SRTBallExplorer(_SweepingSRT):
    """SRT-Ball: the safe region is the disc of the smallest laser range (thesis §3.2, §4.1.1).

    A candidate lies at alpha RADIUS in a direction drawn uniformly; it is valid when it is at
    least `d_min` from the node and outside every other node's disc (Fig. 3.5 VALIDATE); after
    `i_max` invalid tries the robot drives back to the parent. With d_min (1/alpha - 1) >= the
    robot radius, the robot's disc never leaves the safe disc on the straight way (Fig. 4.1).

    Args:
        alpha: fraction of RADIUS at which candidates are placed, in (0, 1).
        d_min: [m] shortest move (None: r_robot / (1/alpha - 1), 1.0 m for the P3-DX).
        i_max: tries per visit of a node.
        margin: [m] the disc's radius is the smallest range less this: the thesis's d_min leaves no
            room between robot and obstacle at alpha RADIUS, and a real stop overshoots a little.
        sweep_rate: [rad/s] turn rate while perceiving.
        bins: world-angle bins of the perception.
        max_nodes, stuck_timeout, failed_radius: see `SRTExplorer`.

    Raises:
        ConfigError: a parameter out of range, or d_min too small for the robot (in `reset`).
    """

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "alpha": (None, 1.0), "d_min": (None, 100.0), "i_max": (1, 100_000), "margin": (0.0, 10.0)}

    name = "srt-ball"

    def __init__(self, *, alpha: float = 0.8, d_min: float | None = None, i_max: int = 200, margin: float = 0.05,
                 sweep_rate: float = 0.8, bins: int = 360, max_nodes: int = 1000, stuck_timeout: float = 8.0,
                 failed_radius: float = 0.3) -> None:
        super().__init__(sweep_rate=sweep_rate, bins=bins, max_nodes=max_nodes, stuck_timeout=stuck_timeout,
                         failed_radius=failed_radius)
        _check_alpha(self.name, alpha, d_min, i_max, margin)
        self.alpha, self.d_min_param, self.i_max, self.margin = alpha, d_min, i_max, margin

    def reset(self, ctx: ExplorerContext) -> None:
        """Start a new run; d_min follows from the robot radius unless given."""
        super().reset(ctx)
        self.d_min = _d_min(self.name, self.alpha, self.d_min_param, self.ctx.radius)

    def _region(self, x: float, y: float) -> SafeRegion:
        ball = self.sweep.ball(x, y)
        hit = ball.obstacle_points()
        return BallRegion(x, y, max(ball.r - self.margin, 0.0), tuple(hit[0]) if len(hit) else None)

    def _candidate(self, index: int) -> tuple[float, float] | None:
        node = self.tree.nodes[index]
        assert isinstance(node.region, BallRegion)
        theta = self.ctx.rng.uniform(-math.pi, math.pi, self.i_max)
        dist = self.alpha * node.region.r
        if dist < self.d_min:              # every try is closer than d_min: none can be valid
            return None
        pts = np.column_stack([node.x + dist * np.cos(theta), node.y + dist * np.sin(theta)])
        ok = ~self.tree.inside_other(pts, index) & ~self._near_failed(index, pts)
        if not ok.any():
            return None
        k = int(np.argmax(ok))
        return float(pts[k, 0]), float(pts[k, 1])


class SRTLaserExplorer(_FrontierRescue, _SweepingSRT):
    """SRT-Laser: the safe region is the polygon of the laser end points (thesis §3.2, §4.1.1).

    The boundary is split into frontier vertices (beams at the maximum range, not inside another
    node's region) and obstacle vertices (Freda & Oriolo 2005); vertices inside another node's
    region are free, already explored. Frontier vertices are taken in random order and each is
    mapped onto the region shrunk by `offset` (thesis Fig. 4.2): the shrunk region is sampled as
    the points the robot reaches from the node in a straight line keeping `offset` from the
    boundary (`reachable_points`, every `step` along the 360 bin directions), and the vertex maps to
    the nearest of them from which it is in sight inside the region, if that is within `view` x
    the laser range (the new node will see it). A vertex that cannot be mapped lies behind a
    passage narrower than 2 `offset`. With frontiers VALIDATE needs neither alpha nor d_min
    (thesis §4.1.1): the frontier vertex, not the candidate, must lie outside every other node's
    region (the candidate, at least `offset` short of it, often lies inside the previous node's
    region). No mapped vertex (no frontier) -> back to the parent.

    Args:
        offset: [m] the shrinking (None: the robot radius + `margin`).
        margin: [m] added to the robot radius when `offset` is None (the planners' hard `MARGIN`: a door the
            robot fits with it is a passage; more closes doors the robot drives through).
        view: the farthest a candidate may be from its frontier vertex, as a share of the laser range.
        tries: nearest reachable points tried per frontier vertex for the line of sight.
        tolerance: [m] a frontier vertex this close to another node's region counts as explored
            (polygon chords and grazing beams leave slivers that would otherwise never close).
        node_gap: [m] no candidate this close to an existing node (every move opens new ground).
        frontier: when no frontier vertex maps to a candidate, look at the map's frontier before going
            back to the parent (False: the thesis's tree alone).
        map_rescue: with `frontier`, at the root with no candidate left (where the run would end), drive
            on the planner's path over the map (`rectangle_path`) to the nearest place within a robot radius
            and a cell and a half of a frontier cell the map shows open beyond, and go on from a node there
            (False: end). A passage the robot fits with a few centimetres to spare (a 0.6 m gap for the 0.5 m
            disc) holds no ray of the shrunk polygon unless a node stands right before it.
        skip_back: with no candidate at a node, drive straight to the nearest ancestor that has one (or to the
            root) on a path through the union of the safe regions, not up the tree edge by edge with a turn and a
            re-centring at each node (False: the thesis's way back). On stage_hospital the way back was two
            fifths of the robot's time.
        d_min: [m] shortest move (the thesis needs none: 0; at least `step` is used).
        step: [m] sampling step of the shrunk region along each direction.
        sweep_rate, bins, max_nodes, stuck_timeout, failed_radius: see `SRTBallExplorer`.
    """

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "offset": (None, 10.0), "margin": (0.0, 10.0), "view": (None, 1.0), "tries": (1, 10_000),
        "tolerance": (0.0, 10.0), "node_gap": (0.0, 100.0), "d_min": (0.0, 100.0),
        "step": (0.001, 10.0)}     # a finer step samples the shrunk region too densely

    name = "srt-laser"
    RESCUE_SIGHT = True
    MAP_RESCUE_AREA = 2.0   # [m2] the least piece of unknown space a map rescue goes to (`map_rescue`) ...
    MAP_RESCUE_SHARE = 0.05     # ... and as a share of the known free area (as the run's LEFT_AREA, LEFT_SHARE)
    MAP_RESCUE_LOOKED = 1.5     # [m] frontier this near the robot's way was looked at (as the run's APPROACHED)

    def __init__(self, *, offset: float | None = None, margin: float = MARGIN, view: float = 0.8, tries: int = 20,  # noqa: PLR0913
                 tolerance: float = 0.1, node_gap: float = 0.3, frontier: bool = True, map_rescue: bool = True,
                 skip_back: bool = True, d_min: float = 0.0, step: float = 0.05, sweep_rate: float = 0.8,
                 bins: int = 360, max_nodes: int = 1000, stuck_timeout: float = 8.0,
                 failed_radius: float = 0.3) -> None:
        super().__init__(sweep_rate=sweep_rate, bins=bins, max_nodes=max_nodes, stuck_timeout=stuck_timeout,
                         failed_radius=failed_radius)
        if offset is not None and not offset > 0:
            raise ConfigError(f"srt-laser: offset must be > 0 m, got {offset}")
        if not 0 < view <= 1 or tries < 1:
            raise ConfigError(f"srt-laser: view must be in (0, 1] and tries >= 1, got {view} and {tries}")
        if margin < 0 or d_min < 0 or not step > 0:
            raise ConfigError(f"srt-laser: margin and d_min must be >= 0 m and step > 0 m, got {margin}, {d_min}, "
                              f"{step}")
        self.offset_param, self.margin, self.d_min, self.ray_step = offset, margin, d_min, step
        if tolerance < 0 or node_gap < 0:
            raise ConfigError(f"srt-laser: tolerance and node_gap must be >= 0 m, got {tolerance} and {node_gap}")
        self.view, self.tries, self.tolerance, self.node_gap = view, tries, tolerance, node_gap
        self.frontier = frontier
        self.map_rescue = map_rescue
        self.skip_back = bool(skip_back)

    def reset(self, ctx: ExplorerContext) -> None:
        """Start a new run."""
        super().reset(ctx)
        self.offset = self.offset_param if self.offset_param is not None else self.ctx.radius + self.margin
        self.map_rescues = 0
        self._map_tried = np.zeros((0, 0), dtype=bool)        # frontier cells a map rescue aimed near

    def _region(self, x: float, y: float) -> SafeRegion:
        return self.sweep.polygon(x, y)

    def frontier_vertices(self, index: int) -> np.ndarray:
        """Indices of the frontier vertices of node `index` that no other node's region holds."""
        region = self.tree.nodes[index].region
        assert isinstance(region, PolygonRegion)
        cand = np.flatnonzero(region.frontier)
        if cand.size == 0:
            return cand
        return cand[~self.tree.inside_other(region.vertices()[cand], index, self.tolerance)]

    def _candidate(self, index: int) -> tuple[float, float] | None:
        self._aim = np.zeros((0, 2), dtype=np.intp)
        cand = self._vertex_candidate(index)
        if cand is None and self._rescue_allowed():
            cand = self._frontier_candidate(index)
        if cand is None and self.frontier and self.map_rescue and self.tree.nodes[index].parent is None:
            cand = self._map_candidate(index)
        return cand

    def _map_candidate(self, index: int) -> tuple[float, float] | None:
        """`map_rescue`: the point [m] a plan passes through in the cell nearest node `index` (with `skip_back`,
        the node the robot is at when it finds nothing up the tree: `_skip_up`) by the planner's
        path (`plan_costs`, the cells' points: `cell_points`) within a robot radius and a cell and a half of
        a frontier cell (`frontier_cells`' kind, from anywhere on the map) beside a piece of unknown space of
        at least `MAP_RESCUE_AREA` and `MAP_RESCUE_SHARE` of the known free area that the map shows open to
        the robot (`_space_beyond`), farther than `MAP_RESCUE_LOOKED` from where the robot has been, and not
        within `RESCUE_RADIUS` of one an earlier map rescue aimed at; None when there is none. Cells near
        candidates abandoned from the node are left out."""
        grid = self._grid
        if grid is None:
            return None
        geo = grid.geo
        node = self.tree.nodes[index]
        # planned from where the robot is when it looks on its way back (`_skip_up`), else from the node
        here = node if self._rescue_from is None else self.tree.nodes[self._rescue_from]
        min_cells = max(1, int(math.ceil(2 * self.ctx.radius / geo.cell)))
        if self._map_tried.shape != grid.shape:
            self._map_tried = np.zeros(grid.shape, dtype=bool)
        beyond = self._space_beyond(grid, here.x, here.y)
        if beyond is None or not beyond.any():
            return None
        # only unknown space whose neglect would make the ending premature (as the run's check counts it): a
        # piece of at least MAP_RESCUE_AREA and MAP_RESCUE_SHARE of the known free area; smaller ones (the
        # inside of a shelf seen through its gaps, a wall's unseen cells) were chased for an hour
        least = max(self.MAP_RESCUE_AREA, self.MAP_RESCUE_SHARE * float(np.count_nonzero(grid.free())) * geo.cell ** 2)
        front = frontier_targets(grid, min_cells, self._map_tried) & beside_large_unknown(beyond, least, geo.cell)
        if self.passed.shape == grid.shape:      # not where the robot came near and looked
            front = away_from(front, self.passed, self.MAP_RESCUE_LOOKED / geo.cell)
        if not front.any():
            return None
        points = np.zeros(grid.shape, np.uint8)
        cost = plan_costs(grid, self.ctx.radius, 0.3, points)
        passable = np.isfinite(cost)
        start = passable_cell(geo, passable, here.x, here.y)
        if start is None:
            return None
        goals = near_cells(front, self.ctx.radius / geo.cell + 1.5) & passable
        if node.failed:
            cells = np.argwhere(goals)
            goals[tuple(cells[self._near_failed(index, cell_points(geo, cells, points))].T)] = False
        found = nearest_goal(cost, start, goals)
        if found is None:
            return None
        goal, _, _ = found
        point = cell_points(geo, [goal], points)[0]
        cells = np.argwhere(front)
        near = int(np.argmin(np.hypot(cells[:, 0] - goal[0], cells[:, 1] - goal[1])))
        self._planned_move = True
        self.map_rescues += 1
        # each map rescue is tried once: the frontier within RESCUE_RADIUS of its cell is not aimed at again
        c = geo.centers_of(cells)
        tried = cells[np.hypot(c[:, 0] - c[near, 0], c[:, 1] - c[near, 1]) <= self.RESCUE_RADIUS]
        self._map_tried[tried[:, 0], tried[:, 1]] = True
        return self._take_rescue(grid, cells, (int(cells[near, 0]), int(cells[near, 1])),
                                 geo.centers_of(cells[near:near + 1])[0], point)

    def result_fields(self) -> dict[str, object]:
        """As `_FrontierRescue`, plus `map_rescues`: rescues driven on the planner's path (`map_rescue`)."""
        return {**super().result_fields(), "map_rescues": self.map_rescues}

    def _rescue_view(self) -> float:
        return self.view * self.ctx.laser_range

    def _rescue_points(self, index: int) -> np.ndarray:
        directions = np.linspace(-math.pi, math.pi, self.bins, endpoint=False)
        return reachable_points(self.tree.nodes[index].region, directions, self.offset, step=self.ray_step,
                                min_step=max(self.d_min, self.ray_step))

    def _vertex_candidate(self, index: int) -> tuple[float, float] | None:
        """The thesis's candidate: a frontier vertex mapped onto the shrunk region (see the class)."""
        node = self.tree.nodes[index]
        region = node.region
        assert isinstance(region, PolygonRegion)
        front = self.frontier_vertices(index)
        if front.size == 0:
            return None
        directions = np.linspace(-math.pi, math.pi, self.bins, endpoint=False)
        reach = reachable_points(region, directions, self.offset, step=self.ray_step,
                                 min_step=max(self.d_min, self.ray_step))
        reach = reach[~self._near_failed(index, reach) & ~self.tree.near_node(reach, self.node_gap)]
        if len(reach) == 0:
            return None
        view = self.view * self.ctx.laser_range
        verts = region.vertices()
        for k in self.ctx.rng.permutation(front):
            f = verts[k]
            d = np.hypot(reach[:, 0] - f[0], reach[:, 1] - f[1])
            order = np.argsort(d, kind="stable")
            for j in order[:self.tries]:
                if d[j] > view:
                    break
                if in_sight(region, reach[j], f):
                    return float(reach[j, 0]), float(reach[j, 1])
        return None


class SRTStarExplorer(_FrontierRescue):
    """SRT-Star: the safe region is a star of cones from the sonar ring (thesis §3.2, Fig. 3.7b).

    Perception: the P3-DX ring has 16 transducers whose axes are 20-40 deg apart, each hearing a
    cone of about 15 deg, so one reading leaves blind gaps of up to 25 deg between the cones, and
    a pillar standing in one is not heard at all. At every node the robot therefore turns on the
    spot through the largest gap between adjacent axes (plus `extra_turn`), reading the ring at
    every control step. Each reading frees the sector of its transducer: apex at the transducer
    (`SonarScan.positions`; the robot centre when the robot does not say), axis its heading,
    opening `cone`, radius the reading. The region is the union of these sectors as seen from the
    robot centre (`star_from_sweep`): each of the `bins` world-angle cones reaches as far as the
    union covers it without a gap, from the robot's own disc outwards, less `margin` (never into
    the disc). A sector whose apex sits 0.2 m out holds the rays from the centre only within about
    +-1.5 deg of its axis near the robot, so the turn is slow (`sweep_rate` 0.3 rad/s: a reading
    every 1.7 deg at 10 Hz) for the union to close. `sweep=False` gives the thesis's single
    reading (`star_from_sonar`, cones between adjacent axes with the smaller of their two
    readings, from the centre), blind gaps and all.

    Candidates as in SRT-Ball (alpha RADIUS in a random direction, d_min, i_max); as cones differ
    in radius, VALIDATE also asks that the robot's disc, grown by `margin`, stays inside the star
    on the straight way there (`ray_reach`: the fundamental condition of thesis §4.1.1, checked
    rather than implied); a way that starts nearer the star's edge than that must move away from
    it at ESCAPE = 0.5 m per m (not slide along a wall at the starting clearance).

    d_min: the thesis derives d_min (1/alpha - 1) = r_robot (1 m on the P3-DX) for SRT-Ball only
    (§4.1.1): it is what keeps the robot's disc inside a *disc* region when the candidate lies at
    alpha R. Here the straight way is checked explicitly, so that bound protects nothing and
    d_min keeps only its role of §3.2 (moves worth a node, away from obstacles); the default is
    the value the thesis gives for dense places, 2 r_robot (0.5 m on the P3-DX: "the robot could
    cross corridors as narrow as its diameter"). Any d_min > 0 is accepted.

    Frontier rescue (`frontier`, an extension in the spirit of Freda & Oriolo's frontiers, which
    the thesis uses for SRT-Laser): a sonar cone reaches through a doorway only when the robot
    stands close to the door and faces it, and a random candidate rarely puts it there; the fans
    that the cones cast into the rooms beyond then make VALIDATE (b) call everything there
    explored, and the tree closes with rooms unseen (docs/explanation/srt-star.md gives the coverage without it). So
    when no random candidate is valid, before going back to the parent, the node looks at the
    frontier of the run's map (`frontier_targets`: free cells next to unknown ones, openings only,
    within `view` of the star), nearest first, and takes the point of its star nearest to a
    frontier cell - reachable in a straight line by the rule above, at least `node_gap` from every
    node - from which that cell is in sight through known-free cells, within `view`. There the
    robot first turns to face the cell, then perceives as at any new node; the frontier cells the
    rescue was for that are still frontier then are given up (seen from beside them, they stay
    next to space the sensors cannot reach), so every rescue either opens new ground or retires
    frontier cells, and the node gap bounds the number of nodes: the run ends.
    Frontier cells at the end of a wall cone (`wall_faces`; `StarRegion.walls`: the cone ends on
    the arc of a reading that heard an echo) are no openings: the sonar heard the obstacle there,
    and the unknown beyond is the inside of a wall that neither sensor can see; chasing them
    along the walls doubled the path in the sparse world. `frontier=False`: the thesis's
    VALIDATE alone.

    Args:
        alpha, i_max, max_nodes, stuck_timeout, failed_radius: see `SRTBallExplorer`.
        margin: [m] each cone's radius is its reading less this.
        d_min: [m] shortest move (None: twice the robot radius).
        ring_radius: [m] added to the readings of the single reading (`sweep=False`; 0: conservative).
        cone: [rad] opening of one transducer's cone (the P3-DX's: 15 deg).
        sweep: turn at each node to close the blind gaps between the transducers' cones.
        sweep_rate: [rad/s] turn rate while perceiving.
        extra_turn: [rad] turned beyond the largest gap between adjacent axes.
        bins: world-angle cones of a swept region.
        frontier: look at the map's frontier before going back to the parent (False: VALIDATE alone).
        view: [m] farthest a frontier cell may be from the rescue candidate (and from the star).
        node_gap: [m] no rescue candidate this close to an existing node.
        tries: nearest points of the star tried per frontier cell for the line of sight.
        wall_faces: leave out frontier cells at the end of a wall cone (no openings: the inside of a wall).
    """

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "alpha": (None, 1.0), "d_min": (None, 100.0), "i_max": (1, 100_000), "margin": (0.0, 10.0),
        "ring_radius": (0.0, 100.0), "cone": (None, math.pi), "sweep_rate": (None, 10.0),
        "extra_turn": (None, math.tau), "bins": (3, 36_000), "view": (None, 1000.0), "node_gap": (0.0, 100.0),
        "tries": (1, 10_000)}

    name = "srt-star"
    uses_sonar = True

    def __init__(self, *, alpha: float = 0.8, d_min: float | None = None, i_max: int = 200, margin: float = 0.05,  # noqa: PLR0913
                 ring_radius: float = 0.0, cone: float = math.radians(15.0), sweep: bool = True,
                 sweep_rate: float = 0.3, extra_turn: float = math.radians(10.0), bins: int = 360,
                 frontier: bool = True, view: float = 4.0, node_gap: float = 0.3, wall_faces: bool = True,
                 tries: int = 20, max_nodes: int = 1000, stuck_timeout: float = 8.0,
                 failed_radius: float = 0.3) -> None:
        super().__init__(max_nodes=max_nodes, stuck_timeout=stuck_timeout, failed_radius=failed_radius)
        _check_alpha(self.name, alpha, d_min, i_max, margin)
        self.margin = margin
        if ring_radius < 0:
            raise ConfigError(f"srt-star: ring_radius must be >= 0 m, got {ring_radius}")
        if not 0 < cone < math.pi or not sweep_rate > 0 or not 0 <= extra_turn < math.pi or bins < 3:
            raise ConfigError(f"srt-star: cone must be in (0, pi) rad, sweep_rate > 0 rad/s, extra_turn in "
                              f"[0, pi) rad and bins >= 3, got {cone}, {sweep_rate}, {extra_turn}, {bins}")
        self.alpha, self.d_min_param, self.i_max, self.ring_radius = alpha, d_min, i_max, ring_radius
        self.cone, self.sweep, self.sweep_rate, self.extra_turn, self.bins = cone, sweep, sweep_rate, extra_turn, bins
        if not view > 0 or node_gap < 0 or tries < 1:
            raise ConfigError(f"srt-star: view must be > 0 m, node_gap >= 0 m and tries >= 1, got {view}, "
                              f"{node_gap} and {tries}")
        self.frontier, self.view, self.node_gap, self.tries = frontier, view, node_gap, tries
        self.wall_faces = wall_faces

    def reset(self, ctx: ExplorerContext) -> None:
        """Start a new run. Raises ConfigError when the robot has no sonar ring."""
        if not ctx.sonar:
            raise ConfigError("srt-star: needs a sonar ring, and the robot reports none; use a robot with "
                              "sonar (e.g. --robot p3dx)")
        super().reset(ctx)
        self.d_min = self.d_min_param if self.d_min_param is not None else 2.0 * self.ctx.radius

    def _begin_sense(self) -> None:
        self._apexes: list[np.ndarray] = []
        self._axes: list[np.ndarray] = []
        self._ranges: list[np.ndarray] = []
        self._echo: list[np.ndarray] = []
        self._turned = 0.0
        self._last_heading: float | None = None

    def _sense(self, state: RobotState) -> tuple[Twist, SafeRegion | None]:
        sonar, p = state.sonar, state.pose
        if sonar is None:
            raise ConfigError("srt-star: the robot state carries no sonar reading; use a robot with sonar")
        if self._face is not None:        # a rescue: look at the frontier first (the laser maps it too)
            twist, facing = self.follower.turn_to(p, math.atan2(self._face[1] - p.y, self._face[0] - p.x), state.laser)
            if not facing:
                return twist, None
            self._face = None
        if not self.sweep:
            star = star_from_sonar(p.x, p.y, p.theta, sonar.angles, sonar.ranges, sonar.range_max, self.ring_radius)
            return Twist.ZERO, StarRegion(p.x, p.y, star.edges, np.maximum(star.radii - self.margin, 0.0),
                                          star.obstacle_points())
        heading = p.theta + np.asarray(sonar.angles, dtype=np.float64)
        at = np.zeros((heading.size, 2)) if sonar.positions is None else np.asarray(sonar.positions, dtype=np.float64)
        c, s = math.cos(p.theta), math.sin(p.theta)
        self._apexes.append(np.column_stack([p.x + c * at[:, 0] - s * at[:, 1], p.y + s * at[:, 0] + c * at[:, 1]]))
        self._axes.append(heading)
        self._ranges.append(np.where(np.isfinite(sonar.ranges), sonar.ranges, sonar.range_max))
        self._echo.append(np.isfinite(sonar.ranges) & (sonar.ranges < sonar.range_max))
        if self._last_heading is not None:
            self._turned += abs(wrap_angle(p.theta - self._last_heading))
        self._last_heading = p.theta
        rate = min(self.ctx.limits.w_max, self.sweep_rate)
        if self._turned < largest_gap(sonar.angles) + self.extra_turn and not self._turn_blocked(state, rate):
            return Twist(0.0, rate), None
        apexes, axes = np.vstack(self._apexes), np.concatenate(self._axes)
        ranges, echo = np.concatenate(self._ranges), np.concatenate(self._echo)
        star = star_from_sweep(p.x, p.y, apexes, axes, ranges, self.cone, self.bins, body=self.ctx.radius, echo=echo)
        echoes = apexes[echo] + ranges[echo, None] * np.column_stack([np.cos(axes[echo]), np.sin(axes[echo])])
        # the margin comes off every cone, but none is cut into the robot's own disc (free: it stands there)
        radii = np.maximum(star.radii - self.margin, self.ctx.radius)
        return Twist.ZERO, StarRegion(p.x, p.y, star.edges, radii, echoes, star.walls)

    def _candidate(self, index: int) -> tuple[float, float] | None:
        self._aim = np.zeros((0, 2), dtype=np.intp)
        self._face = None
        cand = self._random_candidate(index)
        if cand is None and self._rescue_allowed():
            cand = self._frontier_candidate(index)
        return cand

    def _random_candidate(self, index: int) -> tuple[float, float] | None:
        """Fig. 3.5 lines 7-12: alpha RADIUS in up to i_max random directions, VALIDATE (a), (b) and
        the straight way."""
        node = self.tree.nodes[index]
        region = node.region
        assert isinstance(region, StarRegion)
        theta = self.ctx.rng.uniform(-math.pi, math.pi, self.i_max)
        dist = self.alpha * region.radius(theta)
        pts = np.column_stack([node.x + dist * np.cos(theta), node.y + dist * np.sin(theta)])
        ok = (dist >= self.d_min) & ~self.tree.inside_other(pts, index) & ~self._near_failed(index, pts)
        for k in np.flatnonzero(ok):
            reach = ray_reach(region, float(theta[k]), self.ctx.radius + self.margin, length=float(dist[k]),
                              escape=ESCAPE)
            if reach is not None and reach >= dist[k] - 0.021:
                return float(pts[k, 0]), float(pts[k, 1])
        return None
    def _rescue_view(self) -> float:
        return self.view

    def _rescue_points(self, index: int) -> np.ndarray:
        directions = np.linspace(-math.pi, math.pi, self.bins, endpoint=False)
        return reachable_points(self.tree.nodes[index].region, directions, self.ctx.radius + self.margin,
                                step=0.05, min_step=0.05, escape=ESCAPE)

    def _skip_frontier(self, centres: np.ndarray, cell: float) -> np.ndarray:
        """With `wall_faces`: the cells at a heard wall (`heard_wall`)."""
        if not self.wall_faces:
            return super()._skip_frontier(centres, cell)
        return self.heard_wall(centres, cell)

    def heard_wall(self, points: np.ndarray, cell: float) -> np.ndarray:
        """Bool (k,): which of the (k, 2) world points [m] (cell centres of a grid of `cell` [m]) lie at
        the end of a wall cone of some node's star (between its radius less a cell and its radius plus
        `margin` and 1.5 cells): the sonar heard an obstacle right there, so the unknown beyond is that
        obstacle, not an opening."""
        out = np.zeros(len(points), dtype=bool)
        for node in self.tree.nodes:
            region = node.region
            if not isinstance(region, StarRegion) or not region.walls.any():
                continue
            dx, dy = points[:, 0] - node.x, points[:, 1] - node.y
            d = np.hypot(dx, dy)
            near = d <= region.reach + self.margin + 2 * cell
            if not near.any():
                continue
            k = region.cone_of(np.arctan2(dy[near], dx[near]))
            r = region.radii[k]
            out[np.flatnonzero(near)] |= region.walls[k] & (d[near] >= r - cell) & \
                (d[near] <= r + self.margin + 1.5 * cell)
        return out


def largest_gap(axes: np.ndarray) -> float:
    """The largest angle [rad] between adjacent transducer axes `axes` [rad] around the ring."""
    a = np.unique(np.round(np.mod(np.asarray(axes, dtype=np.float64), TAU), 9))
    if a.size < 2:
        return TAU
    return float(np.diff(np.append(a, a[0] + TAU)).max())


def _check_alpha(name: str, alpha: float, d_min: float | None, i_max: int, margin: float) -> None:
    if margin < 0:
        raise ConfigError(f"{name}: margin must be >= 0 m, got {margin}")
    if not 0 < alpha < 1:
        raise ConfigError(f"{name}: alpha must be in (0, 1), got {alpha}")
    if d_min is not None and not d_min > 0:
        raise ConfigError(f"{name}: d_min must be > 0 m, got {d_min}")
    if i_max < 1:
        raise ConfigError(f"{name}: i_max must be >= 1, got {i_max}")


def _d_min(name: str, alpha: float, d_min: float | None, radius: float) -> float:
    """d_min from d_min (1/alpha - 1) = r_robot (thesis §4.1.1), or the given one if large enough."""
    need = radius / (1.0 / alpha - 1.0)
    if d_min is None:
        return need
    if d_min < need - 1e-9:
        raise ConfigError(f"{name}: d_min = {d_min} m is below r_robot / (1/alpha - 1) = {need:.3f} m for "
                          f"alpha = {alpha}: the robot could leave its safe region; raise d_min or alpha")
    return d_min

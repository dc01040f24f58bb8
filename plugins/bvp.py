"""BVP ("PVC") exploration: follow the descent of a harmonic potential (Ribacki 2011 section 3.1, Prestes 2003).

Obstacles hold potential 1, unknown cells 0 (the goals); the free cells are relaxed by Gauss-Seidel
(eq. 3.1) and the robot follows the descent gradient (eq. 3.2) at its cell, with the heading and
speed laws of eqs. 3.3-3.5. Done when no reachable free cell touches an unknown cell.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import numpy.typing as npt

from robotexp import (ConfigError, Done, Explorer, ExplorerContext, Footprint, LaserScan, Pose, RobotState, Twist,
                      wrap_angle)
from robotexp.mapping.grid import OccupancyGrid
from robotexp.planning.follower import GRAIN, FollowerConfig, ScanMemory, blocked_ahead, footprint_blocked, free_heading
from robotexp.planning.targets import MARGIN, WallDistance
from robotexp.planning.harmonic import descent, descent_field, flood4, relax, touches

if TYPE_CHECKING:
    from robotexp.localization import FrameCorrection

__all__ = ["BVPExplorer", "speed_law", "edge_distance"]

RELATIVE_FLAT = 1e-12   # |v| at or below this times the largest neighbouring 1 - p: a vanished gradient
WINDOW_MARGIN = 2       # [cells] kept beyond the walls' inflation around the scanned and covered cells
TIGHT = FollowerConfig()    # where the path follower turns in place rather than drive round, bvp does too
INFLATE_MARGIN = MARGIN  # [m] the walls grow by the robot radius plus this (default inflate): the planners' margin
GIVE_UP_REACH = 2.0     # [m] goal cells given up around the robot when the run's stall watch strikes
TRAP_REACH = 1.0        # [m] a stale peak of the field this near the robot holds it (see `trap_time`)
TRAP_FLUSH = 1          # sweeps per cell of the free cells' rows + columns when a stale peak starts the flush
TRAP_SETTLE = 30.0      # [s] of robot time before a peak by the robot may count as stale (see `trap_time`)


def speed_law(v_prev: float, varphi: float, d: float, *, v_max: float, r_max: float, eta: float) -> float:
    """Forward speed [m/s] of eqs. 3.4 and 3.5.

    v_t = eta * vhat + (1 - eta) * v_prev, vhat = v_max * ((180 - |varphi|) / 180) * rho, with
    varphi in degrees on the short arc and rho = d / r_max when d <= r_max, else 1.

    Args:
        v_prev: the previous speed v_{t-1} [m/s].
        varphi: theta - phi [rad], wrapped to the short arc here.
        d: distance to the nearest obstacle [m] (clamped at 0).
        v_max: top speed [m/s].
        r_max: radius of the collision region [m].
        eta: smoothing factor in (0, 1].
    """
    deg = abs(math.degrees(wrap_angle(varphi)))
    rho = max(d, 0.0) / r_max if d <= r_max else 1.0
    vhat = v_max * ((180.0 - deg) / 180.0 * rho)
    return eta * vhat + (1.0 - eta) * v_prev


def edge_distance(scan: LaserScan | None, radius: float) -> float:
    """Distance [m] from the robot's edge (a disc of `radius` [m]) to the nearest laser return; inf if none."""
    if scan is None:
        return math.inf
    ok = np.isfinite(scan.ranges)
    if not ok.any():
        return math.inf
    r, a = scan.ranges[ok], scan.angles[ok]
    return float(np.hypot(scan.offset_x + r * np.cos(a), r * np.sin(a)).min()) - radius


class BVPExplorer(Explorer):
    """Harmonic-potential (boundary value problem) exploration of Prestes 2003 as in Ribacki 2011.

    What the thesis fixes is followed as written: HIMM map at 100 mm cells, occupied (certainty > 2)
    at potential 1, unknown at 0, Gauss-Seidel eq. 3.1 (in place, row-major, never SOR), `sweeps`
    (30) iterations every `update_period` (1 s of robot time), gradient eq. 3.2 at the robot's cell,
    heading phi = atan2(v_y, v_x) (eq. 3.3), speed eqs. 3.4-3.5 with r_max = 200 mm, and the stop test
    by region growing from the robot's cell. Where it is silent, these choices:

    - Warm start: the potential persists between updates; each update resets the boundary cells
      (obstacle 1, goal 0) and continues the sweeps from the previous field, so a free cell newly
      seen starts at 0, the value it held while unknown. The map's border is a ring of potential 1.
    - Precision: the field is stored and relaxed as q = 1 - p (eq. 3.1 is linear, so q obeys the
      same sweeps; eq. 3.2 gives v = ((q_E - q_W) / 2, (q_N - q_S) / 2)). Far from every goal p is
      within 1e-16 of 1 and rounds to a flat 1.0 in float64 (a robot in an explored room behind a
      door then had no gradient and stalled in our 40 mm/s runs); q keeps those tiny values down
      to 1e-308, so the gradient keeps its direction.
    - Configuration space (`inflate`, default the robot radius plus `INFLATE_MARGIN`, the 2 cm the
      planners keep): cells whose every point (the centre and eight more a third of a cell apart, as the
      planners judge a cell: `robotexp.planning.targets.cell_points`) lies within inflate of the walls'
      surface (the laser endpoints in the occupied cells: `wall_distance`) are obstacles (potential 1)
      too, as in Connolly & Grupen's planner, so the descent never leads into a gap the robot cannot
      pass and unknown cells right by walls (their unseen faces) are not goals. A door the robot fits
      with 2 cm to spare is a channel of the configuration space a cell or two wide: the guard (the
      swept disc, `blocked_ahead`) lets the robot in, and where the laser shows less than
      `FollowerConfig.tight` of room the robot turns in place to the descent before it drives on
      rather than drive round (through the five-room doors with both presets,
      benchmarks/studies/doors.py).
      `inflate=0` is the bare map; `campaigns/thesis.toml` sets the radius (the thesis's runs).
    - The robot's cell: cells the robot's footprint has covered count as free even if the laser
      (180 degrees, ahead) never saw them, so the robot is not drawn to the floor under itself.
      Eq. 3.2 does not use the cell's own value, so a robot cell on the inflated margin still has a
      gradient (out of it).
    - Stop test: 4-connected region growing (like the 5-point stencil) over the passable cells
      (free or covered, not inflated) from the robot's cell (or the nearest passable one within
      0.5 m); done when no cell of the region has a goal (unknown, not inflated) as 4-neighbour.
      Run at each potential update.
    - Cost: the boundary, the sweeps and the stop test are computed on the window of the map that
      holds every cell a scan touched or the robot covered, grown by the inflation and a margin
      (`OccupancyGrid.window`). Beyond it every cell is an unknown goal of fixed potential 0 in every
      update, so the field, the walls and the region are those of the whole map, bit for bit, at a cost
      that follows the explored part of the building rather than the map's size.
    - Turning: omega = -k_turn * varphi, clamped to the robot's limit; varphi = theta - phi on the
      short arc. The robot moves forward at the speed of eq. 3.5 while it turns.
    - rho of eq. 3.5: d is measured from the robot's edge (not its centre) to the nearest laser
      return, the safe reading for a 250 mm robot: with the centre it would always be > 200 mm.
    - Vanished gradient (|v| <= 1e-12 of the neighbours' q, i.e. flat to round-off): keep the last
      heading phi; before any heading is known, head for the nearest goal cell (a free region
      bounded only by unknown cells - no obstacle in view - has a constant potential), or turn in
      place while there is no goal yet (`flat_gradient_steps` counts these steps).
    - Guard beyond the thesis: no forward motion while a laser return lies in the corridor the
      robot would sweep (`blocked_ahead`, `clearance`); the smoothed speed restarts from 0 then.
    - Stalls (beyond the thesis): 30 sweeps a second carry a change about a cell per sweep against
      the sweep order, so on a large window the field under the robot still shows goals long gone
      (a room it has just explored keeps pulling it back while the unknown lies 20 m away). When the
      run's stall watch sees no progress (`give_up`), the next update starts the free cells over at
      p = 1 and runs `flush_sweeps` per cell of the rows + columns of the free cells' box (information
      crosses it a few times over): relaxed from below, the field has no stale bump, so the descent leads to the
      goals. Then the thesis's sweeps again. The goal cells within `GIVE_UP_REACH` of the robot at the
      strike are given up (walls from then on, potential 1): unknown space the robot was drawn to and could
      not resolve in the stall window, such as the inside of a rack seen through a gap in its outline
      whose channel the descent leads into and the guard never lets the robot through (a production hall:
      four such pockets held a run at 0.997 until it stalled).
    - Stale peaks (beyond the thesis): a harmonic field, and one relaxed from below, has no interior
      maximum of q (the discrete maximum principle: each free cell is the mean of its neighbours, or below
      it). When goals vanish (a pocket or a room resolved) the field relaxes from above, and the cells
      they pulled stay at a peak until the sweeps wear it down below the pull of the goals left; on a
      large floor that pull is 1e-5 to 1e-17 (tens of metres through the aisles), so the peak takes
      minutes of 30 sweeps a second to fall that far, and the robot circles on it. When a free cell within
      `TRAP_REACH` of the robot has stayed a peak (q above 0, no less than its four neighbours, above the
      least of them) for `trap_time` of robot time, after the first `TRAP_SETTLE` of the run (the first field,
      relaxing from q = 1 everywhere, is all peaks; a flush then had led the P3-DX body into a door's jamb),
      the field is relaxed anew from below as after a stall,
      with `TRAP_FLUSH` (1) sweep per cell of the free cells' rows + columns (at most `flush_sweeps`), and no
      goal given up: relaxed from below, the field has no peak, and the 30 sweeps a second that follow
      raise it towards the harmonic field without making one until goals vanish again. A run where that
      never happens and that never stalls is the thesis's, bit for bit (`trap_time=0` turns it off).
    - Perturbed fields (off by default, the thesis's runs are harmonic): eq. 3.6 with v = (cos
      `direction`, sin `direction`) and `epsilon`, eq. 3.7 with a constant eps(r) = `epsilon_grad`,
      discretised by central differences in cell units (see `robotexp.planning.harmonic`). With
      epsilon > 0 eq. 3.6 as written draws the robot towards goals on the -v side. In q = 1 - p,
      eq. 3.6 keeps its form and eq. 3.7 changes the sign of eps(r).

    Args:
        sweeps: Gauss-Seidel iterations per update (>= 1).
        update_period: [s] robot time between potential updates.
        r_max: [m] radius of the collision region of eq. 3.5.
        eta: smoothing factor of eq. 3.4, in (0, 1].
        k_turn: [1/s] turn rate per radian of heading error.
        inflate: [m] obstacle growth for the potential and the stop test (None: the robot radius
            plus INFLATE_MARGIN).
        clearance: [m] kept ahead of the robot by the guard.
        epsilon: eq. 3.6 strength [1/cell], within [-1, 1].
        direction: [rad] the preferred direction v of eq. 3.6.
        epsilon_grad: eq. 3.7 eps(r) [1/cell], within [-1, 1].
        flush_sweeps: after a stall or a trap, sweeps per cell of the free cells' rows + columns (>= 0; 0:
            none, and no relaxing anew at all).
        trap_time: [s] robot time the robot may stay by a stale peak of the field before it is relaxed
            anew (0: never).
    """

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "sweeps": (1, 10_000), "update_period": (None, 3600.0), "r_max": (None, 10.0), "eta": (None, 1.0),
        "k_turn": (None, 100.0), "inflate": (0.0, 10.0), "clearance": (0.0, 10.0), "epsilon": (-1.0, 1.0),
        "direction": (-math.tau, math.tau), "epsilon_grad": (-1.0, 1.0), "flush_sweeps": (0, 1000),
        "trap_time": (0.0, 3600.0)}

    grid_model = "himm"
    preferred_cell = 0.1

    def __init__(self, *, sweeps: int = 30, update_period: float = 1.0, r_max: float = 0.2, eta: float = 0.5,  # noqa: PLR0913
                 k_turn: float = 1.5, inflate: float | None = None, clearance: float = 0.01,
                 epsilon: float = 0.0, direction: float = 0.0, epsilon_grad: float = 0.0,
                 flush_sweeps: int = 4, trap_time: float = 5.0) -> None:
        if not (isinstance(sweeps, int) and sweeps >= 1):
            raise ConfigError(f"bvp: sweeps must be an integer >= 1, got {sweeps!r}")
        if not (isinstance(flush_sweeps, int) and flush_sweeps >= 0):
            raise ConfigError(f"bvp: flush_sweeps must be an integer >= 0, got {flush_sweeps!r}")
        for name, value in (("update_period", update_period), ("r_max", r_max), ("k_turn", k_turn)):
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"bvp: {name} must be > 0, got {value}")
        if not 0 < eta <= 1:
            raise ConfigError(f"bvp: eta must be within (0, 1], got {eta}")
        if inflate is not None and not (math.isfinite(inflate) and inflate >= 0):
            raise ConfigError(f"bvp: inflate must be >= 0 m or None, got {inflate}")
        if not (math.isfinite(trap_time) and trap_time >= 0):
            raise ConfigError(f"bvp: trap_time must be >= 0 s (0: never), got {trap_time}")
        if not clearance >= 0:
            raise ConfigError(f"bvp: clearance must be >= 0 m, got {clearance}")
        for name, value in (("epsilon", epsilon), ("epsilon_grad", epsilon_grad)):
            if not abs(value) <= 1:
                raise ConfigError(f"bvp: {name} must be within [-1, 1] (per cell; larger values break the "
                                  f"maximum principle of the discrete field), got {value}")
        if not math.isfinite(direction):
            raise ConfigError(f"bvp: direction must be a finite angle in rad, got {direction}")
        self.sweeps, self.update_period, self.r_max, self.eta = sweeps, update_period, r_max, eta
        self.k_turn, self.inflate, self.clearance = k_turn, inflate, clearance
        self.epsilon, self.direction, self.epsilon_grad = epsilon, direction, epsilon_grad
        self.flush_sweeps, self.trap_time = flush_sweeps, trap_time

    def reset(self, ctx: ExplorerContext) -> None:
        """Start a new run: empty potential, no heading, speed 0."""
        super().reset(ctx)
        self.q = np.zeros((0, 0), np.float64)             # 1 - potential, padded (rows + 2, cols + 2)
        self.fixed = np.zeros((0, 0), np.bool_)
        self.covered = np.zeros((0, 0), np.bool_)         # cells the robot's footprint has covered
        self.next_update = -math.inf
        self.updates = 0
        self.phi: float | None = None
        self.v = 0.0
        self.flat_steps = 0
        self.cover_box: tuple[int, int, int, int] | None = None    # rows, cols (half-open) of `covered`
        self.walls = WallDistance(0.0, surface=True)
        self._memory = ScanMemory(reach=ctx.outline.swing + 0.6)
        self._goal_off = (0, 0)
        self.flush = False          # the next update relaxes the field anew from below (`give_up`)
        self._flush_per_cell = self.flush_sweeps   # ... with this many sweeps per cell of its rows + cols
        self.flushes = 0
        self.traps = 0              # flushes started by a stale peak by the robot (`trap_time`)
        self._trapped_since: float | None = None
        self._trap_t0: float | None = None      # [s] robot time of the first update watched for a trap
        self.given_up = np.zeros((0, 0), np.bool_)        # goal cells given up at a stall (walls from then on)
        self._pose_xy = (ctx.start.x, ctx.start.y)

    def map_rebuilt(self, grid: OccupancyGrid, moved: FrameCorrection) -> None:
        """Loop closure rebuilt the map: the wall distances are recomputed and the field is relaxed anew from
        below at the next update (as after `give_up`), so that no goal or wall of the old map lingers in it."""
        if self.q.shape != (0, 0):
            self.walls = WallDistance(self._inflate_cells(grid), surface=True, points=True)
            self.given_up[:] = False        # cells of the old map
            self.flush, self._flush_per_cell = True, self.flush_sweeps
        self.next_update = -math.inf

    # -- the potential ---------------------------------------------------------------
    def _ensure(self, grid: OccupancyGrid) -> None:
        rows, cols = grid.shape
        if self.q.shape != (rows + 2, cols + 2):
            # q = 1 - p: unknown (goal) cells 1, walls and the map's border ring 0
            self.q = np.ones((rows + 2, cols + 2), np.float64)
            self.fixed = np.ones((rows + 2, cols + 2), np.bool_)
            self.q[0, :] = self.q[-1, :] = 0.0
            self.q[:, 0] = self.q[:, -1] = 0.0
            self.covered = np.zeros((rows, cols), np.bool_)
            self.given_up = np.zeros((rows, cols), np.bool_)
            self.cover_box = None
            self.walls = WallDistance(self._inflate_cells(grid), surface=True, points=True)

    def _cover(self, grid: OccupancyGrid, x: float, y: float) -> None:
        geo = grid.geo
        k = int(math.ceil(self.ctx.radius / geo.cell)) + 1
        r0, c0 = geo.cell_of(x, y)
        rs = np.arange(max(r0 - k, 0), min(r0 + k + 1, geo.rows))
        cs = np.arange(max(c0 - k, 0), min(c0 + k + 1, geo.cols))
        if rs.size == 0 or cs.size == 0:
            return
        cy = geo.origin_y + (rs + 0.5) * geo.cell
        cx = geo.origin_x + (cs + 0.5) * geo.cell
        inside = (cy[:, None] - y) ** 2 + (cx[None, :] - x) ** 2 <= self.ctx.radius ** 2
        self.covered[rs[0]:rs[-1] + 1, cs[0]:cs[-1] + 1] |= inside
        box = (int(rs[0]), int(rs[-1]) + 1, int(cs[0]), int(cs[-1]) + 1)
        b = self.cover_box
        self.cover_box = box if b is None else (min(b[0], box[0]), max(b[1], box[1]),
                                                min(b[2], box[2]), max(b[3], box[3]))

    def window(self, grid: OccupancyGrid) -> tuple[OccupancyGrid, tuple[int, int]]:
        """The part of `grid` every update works on, and the (row, col) of its cell (0, 0) in `grid`: the
        cells scans touched and the robot covered, grown by the inflation and `WINDOW_MARGIN`. Outside
        it every cell is unknown, uncovered and beyond any wall's inflation: a goal."""
        boxes = [b for b in (grid.touched_box(), self.cover_box) if b is not None]
        if not boxes:
            return grid, (0, 0)
        m = int(math.ceil(self._inflate_cells(grid))) + WINDOW_MARGIN
        r0 = min(b[0] for b in boxes) - m
        c0 = min(b[2] for b in boxes) - m
        r1 = max(b[1] for b in boxes) + m
        c1 = max(b[3] for b in boxes) + m
        r0, c0 = max(r0, 0), max(c0, 0)
        return grid.window(r0, r1, c0, c1), (r0, c0)

    def boundary(self, grid: OccupancyGrid, window: tuple[OccupancyGrid, tuple[int, int]] | None = None
                 ) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
        """The Dirichlet cells of the current map: (wall, goal), each (rows, cols) bool.

        wall: occupied (HIMM > 2) or within the inflation of an occupied cell (potential 1);
        goal: unknown, not covered by the robot and not a wall (potential 0).

        Args:
            grid: the map.
            window: (view, (row, col) of its cell (0, 0)) from `window`, or None for the whole map; the
                arrays returned are the window's.
        """
        self._ensure(grid)
        view, off = (grid, (0, 0)) if window is None else window
        rows, cols = view.shape
        self.walls.update(grid)         # distances to the walls, recomputed near what the scans changed
        dist = self.walls.dist[off[0]:off[0] + rows, off[1]:off[1] + cols]
        wall = (dist <= self._inflate_cells(grid)) | view.occupied()    # with no inflation: the occupied cells
        wall |= self.given_up[off[0]:off[0] + rows, off[1]:off[1] + cols]
        covered = self.covered[off[0]:off[0] + rows, off[1]:off[1] + cols]
        goal = view.unknown() & ~covered & ~wall
        return wall, goal

    def _inflate_cells(self, grid: OccupancyGrid) -> float:
        """[cells] a cell whose every point is this near the walls' surface (the laser endpoints in the occupied
        cells: `wall_distance`) is a wall."""
        inflate = self.ctx.radius + INFLATE_MARGIN if self.inflate is None else self.inflate
        return inflate / grid.geo.cell

    def update_potential(self, grid: OccupancyGrid
                         ) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_], tuple[int, int]]:
        """Set the boundary values from `grid` and run `sweeps` Gauss-Seidel sweeps from the last field,
        on the `window` of the map (every cell outside it is a goal, fixed at p = 0 from the start).

        Returns:
            (wall, goal, off): `boundary` of the window and the (row, col) of its cell (0, 0).
        """
        self._ensure(grid)
        view, off = self.window(grid)
        wall, goal = self.boundary(grid, (view, off))
        rows, cols = view.shape
        inner = self.q[1 + off[0]:1 + off[0] + rows, 1 + off[1]:1 + off[1] + cols]
        inner[wall] = 0.0           # p = 1
        inner[goal] = 1.0           # p = 0
        self.fixed[1 + off[0]:1 + off[0] + rows, 1 + off[1]:1 + off[1] + cols] = wall | goal
        e = self.epsilon
        # in q = 1 - p eq. 3.6 keeps its sign and eq. 3.7 flips it; the window with its ring of the
        # padded field (fixed cells or the map's border) is all the sweeps read
        sweeps = self.sweeps
        if self.flush:
            # start over from p = 1 on the free cells: relaxed from below, the field has no stale
            # bump (no interior extremum) anywhere, and every cell's value comes from the goals now
            free = ~(wall | goal)
            inner[free] = 0.0
            # the rows + columns of the box of the free cells: those of the window but for its margin, and
            # the same however far the map reaches beyond the window
            rs, cs = np.flatnonzero(free.any(axis=1)), np.flatnonzero(free.any(axis=0))
            if rs.size:
                sweeps += self._flush_per_cell * (int(rs[-1] - rs[0]) + 1 + int(cs[-1] - cs[0]) + 1)
            self.flush = False
            self.flushes += 1
        relax(self.q, self.fixed, sweeps,
              preferred=(e * math.cos(self.direction), e * math.sin(self.direction)), eps_abs=-self.epsilon_grad,
              window=(off[0], off[0] + rows + 2, off[1], off[1] + cols + 2))
        self.updates += 1
        return wall, goal, off

    def explored(self, grid: OccupancyGrid, wall: npt.NDArray[np.bool_], goal: npt.NDArray[np.bool_],
                 x: float, y: float, off: tuple[int, int] = (0, 0)) -> bool:
        """The stop test: True when no passable cell reachable from (x, y) [m] touches a goal cell.

        `wall` and `goal` are `boundary`'s, of the whole map or of a window of it whose cell (0, 0) is
        the map's `off`."""
        rows, cols = wall.shape
        view = grid if (rows, cols) == grid.shape else grid.window(off[0], off[0] + rows, off[1], off[1] + cols)
        covered = self.covered[off[0]:off[0] + rows, off[1]:off[1] + cols]
        passable = ~wall & ~goal & (view.free() | covered)
        geo = grid.geo
        r, c = geo.cell_of(x, y)
        r, c = r - off[0], c - off[1]
        if not (0 <= r < rows and 0 <= c < cols and passable[r, c]):
            reach = int(math.ceil(0.5 / geo.cell))
            r0, c0 = max(r - reach, 0), max(c - reach, 0)
            cand = np.argwhere(passable[r0:r + reach + 1, c0:c + reach + 1])
            if cand.size == 0:
                return False        # squeezed against a wall: keep going (the gradient leads out)
            cand += (r0, c0)
            best = int(np.argmin((cand[:, 0] - r) ** 2 + (cand[:, 1] - c) ** 2))
            r, c = int(cand[best, 0]), int(cand[best, 1])
        return not touches(flood4(passable, r, c), goal)

    # -- the decision ----------------------------------------------------------------
    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        """Update the potential when due, then steer along its descent (eqs. 3.2-3.5)."""
        pose = state.pose
        self._ensure(grid)
        self._pose_xy = (pose.x, pose.y)
        self._cover(grid, pose.x, pose.y)
        self._memory.see_map(grid)
        if state.time >= self.next_update:
            wall, goal, off = self.update_potential(grid)
            self._goal, self._goal_off = goal, off
            if self.explored(grid, wall, goal, pose.x, pose.y, off):
                return Done("explored: no reachable free cell touches an unknown cell")
            self.next_update = state.time + self.update_period - 1e-9
            self._watch_trap(grid, state.time)
        r, c = grid.geo.cell_of(pose.x, pose.y)
        if not grid.geo.contains(r, c):
            return Done("stopped: the robot left the map")
        q, rq, cq = self.q, r + 1, c + 1
        wx, wy = descent(q, rq, cq)
        vx, vy = -wx, -wy          # eq. 3.2 on p = 1 - q
        lim = self.ctx.limits
        scale = max(q[rq, cq - 1], q[rq, cq + 1], q[rq - 1, cq], q[rq + 1, cq])
        if math.hypot(vx, vy) > RELATIVE_FLAT * scale:
            self.phi = math.atan2(vy, vx)                                   # eq. 3.3
        else:
            self.flat_steps += 1
            if self.phi is None:
                self.phi = self._toward_nearest_goal(grid, r, c)
            if self.phi is None:
                self.v = 0.0
                return Twist(0.0, min(lim.w_max, 0.5))
        varphi = wrap_angle(pose.theta - self.phi)
        room = edge_distance(state.laser, self.ctx.radius)
        if room < TIGHT.tight:
            # the descent, taken at the robot's cell, may lead into an obstacle beside the robot (it stands
            # up to half a cell off the cell's centre): slide along it, in the free direction nearest the
            # descent (within 90 degrees of it: the potential still falls)
            free = free_heading(state.laser, self.ctx.radius, self.clearance, max(self.v, TIGHT.tight_speed),
                                -varphi, lim.a_max)
            if free is not None:
                varphi = -free
        w = max(-lim.w_max, min(lim.w_max, -self.k_turn * varphi))
        v = speed_law(self.v, varphi, room, v_max=lim.v_max, r_max=self.r_max, eta=self.eta)
        if room < TIGHT.tight and abs(varphi) > TIGHT.tight_turn:
            v = 0.0             # little room (a door the field leads through): face the descent first
        foot = self.ctx.outline
        if foot.round:
            if blocked_ahead(state.laser, self.ctx.radius, self.clearance, v, w, lim.a_max):
                v = 0.0
        else:
            v, w = self._guard_box(foot, pose, state, v, w)
        self.v = v
        return Twist(v, w)

    def _guard_box(self, foot: Footprint, pose: Pose, state: RobotState, v: float, w: float) -> tuple[float, float]:
        """The guard for a rectangular robot, against its recent scans (`ScanMemory`): the command, else
        the turn in place, else a turn while creeping forward, else creeping straight, else wait."""
        self._memory.note(pose, state.laser)
        pts = self._memory.points(pose)
        lim = self.ctx.limits
        creep = TIGHT.tight_speed
        for cv, cw in ((v, w), (0.0, w), (creep, w), (creep, 0.0)):
            if not footprint_blocked(pts, foot, self.clearance + GRAIN, cv, cw, lim.a_max, lim.alpha_max):
                return cv, cw
        return 0.0, 0.0

    def give_up(self, grid: OccupancyGrid) -> bool:
        """The run saw no progress for a while (its stall watch): the field under the robot may still
        show goals that are gone. Relax it anew at the next update (see the class); False when that
        cannot help (`flush_sweeps` 0, or no field yet). The goal cells near the robot are given up (see the
        class)."""
        if self.flush_sweeps == 0 or self.updates == 0:
            return False
        self._ensure(grid)
        geo = grid.geo
        k = int(math.ceil(GIVE_UP_REACH / geo.cell))
        r0, c0 = geo.cell_of(*self._pose_xy)
        rs = slice(max(r0 - k, 0), max(min(r0 + k + 1, geo.rows), 0))
        cs = slice(max(c0 - k, 0), max(min(c0 + k + 1, geo.cols), 0))
        goal = self.fixed[1:-1, 1:-1][rs, cs] & (self.q[1:-1, 1:-1][rs, cs] == 1.0)      # q = 1: a goal cell
        rr, cc = np.mgrid[rs, cs]
        x, y = self._pose_xy
        cx, cy = geo.origin_x + (cc + 0.5) * geo.cell, geo.origin_y + (rr + 0.5) * geo.cell
        near = np.hypot(cx - x, cy - y) <= GIVE_UP_REACH
        self.given_up[rs, cs] |= goal & near
        self.flush, self._flush_per_cell = True, self.flush_sweeps
        self.next_update = -math.inf
        return True

    def _watch_trap(self, grid: OccupancyGrid, time: float) -> None:
        """After an update: when a stale peak has stayed within `TRAP_REACH` of the robot for `trap_time`,
        relax the field anew from below at the next update (see the class)."""
        if self.trap_time <= 0 or self.flush_sweeps == 0:
            return
        if self._trap_t0 is None:
            self._trap_t0 = time
        if time - self._trap_t0 < TRAP_SETTLE:      # the first field, relaxing from q = 1, is all peaks: not stale
            return
        if not self._peak_near(grid):
            self._trapped_since = None
            return
        if self._trapped_since is None:
            self._trapped_since = time
        if time - self._trapped_since >= self.trap_time - 1e-9:
            self._trapped_since = None
            if not self.flush:
                self._flush_per_cell = min(TRAP_FLUSH, self.flush_sweeps)
            self.flush = True
            self.traps += 1
            self.next_update = -math.inf

    def _peak_near(self, grid: OccupancyGrid) -> bool:
        """True when a free cell within `TRAP_REACH` of the robot is a peak of q: above 0, no less than any
        of its 4 neighbours and above the least of them (impossible where each cell is the mean of its
        neighbours or below it)."""
        geo = grid.geo
        k = int(math.ceil(TRAP_REACH / geo.cell))
        r, c = geo.cell_of(*self._pose_xy)
        r0, r1 = max(r - k, 0), min(r + k + 1, geo.rows)
        c0, c1 = max(c - k, 0), min(c + k + 1, geo.cols)
        if r1 <= r0 or c1 <= c0:
            return False
        q = self.q
        mid = q[1 + r0:1 + r1, 1 + c0:1 + c1]
        near = np.stack([q[r0:r1, 1 + c0:1 + c1], q[2 + r0:2 + r1, 1 + c0:1 + c1],
                         q[1 + r0:1 + r1, c0:c1], q[1 + r0:1 + r1, 2 + c0:2 + c1]])
        peak = ~self.fixed[1 + r0:1 + r1, 1 + c0:1 + c1] & (mid > 0) & (mid >= near.max(axis=0)) \
            & (mid > near.min(axis=0))
        if not peak.any():
            return False
        rr, cc = np.nonzero(peak)
        dist = np.hypot(rr + r0 - r, cc + c0 - c) * geo.cell
        return bool((dist <= TRAP_REACH).any())

    def _toward_nearest_goal(self, grid: OccupancyGrid, r: int, c: int) -> float | None:
        """Heading [rad] to the nearest goal (unknown) cell, or None when there is none.

        A region bounded only by goals (no obstacle in view: the robot in the middle of a hall)
        has a constant harmonic potential, hence no gradient anywhere; the field's limit as the
        nearest boundary dominates is the way to the nearest goal.
        """
        goal = getattr(self, "_goal", None)
        if goal is None or not goal.any():
            return None
        cells = np.argwhere(goal) + self._goal_off
        k = int(np.argmin((cells[:, 0] - r) ** 2 + (cells[:, 1] - c) ** 2))
        return math.atan2(float(cells[k, 0] - r), float(cells[k, 1] - c))

    # -- what the run shows ----------------------------------------------------------
    def overlays(self) -> dict[str, npt.NDArray[np.float64]]:
        """{"potential": (rows, cols) in [0, 1], "vectors": (rows, cols, 2) unit descent directions}."""
        if self.q.size == 0:
            return {}
        vectors = -descent_field(self.q, 0.0)      # unit directions: only an exact tie has none
        vectors[self.fixed[1:-1, 1:-1]] = 0.0
        return {"potential": self.potential(), "vectors": vectors + 0.0}

    def potential(self) -> npt.NDArray[np.float64]:
        """The potential p = 1 - q, (rows, cols) float64 in [0, 1] (obstacles 1, goals 0)."""
        return 1.0 - self.q[1:-1, 1:-1]

    def result_fields(self) -> dict[str, object]:
        """`potential_updates` and `flat_gradient_steps` (steps with a vanished gradient)."""
        return {"potential_updates": self.updates, "flat_gradient_steps": self.flat_steps}

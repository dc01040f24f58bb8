"""A team of robots exploring together as one run (`TeamRun`), and its record.

Each robot is a member: an `ExplorationRun` of its robot and explorer whose steps the team takes in turn
(`ExplorationRun._begin` / `_tick`), one tick of one clock for all. The members map into one grid (perfect
communication), or each into its own grid, passing scans on to the robots within a communication range
(`robotexp.run.teamshare.ScanExchange`); the team's grid holds every scan and gives the coverage. A
coordinator (`robotexp.coordinator`) shares out frontier targets among the robots that have none. The team
samples coverage, watches for stalls, and makes one `RunRecord` with the team's keys (`team_size`, `robots`,
`overlap_ratio`, ...).
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np
import numpy.typing as npt

from robotexp.coordinator import Candidates, Coordinator, TeamContext
from robotexp.errors import ConfigError, RobotError
from robotexp.explorer import Explorer
from robotexp.planning.targets import shared_wall_memory
from robotexp.robot import LaserScan, Pose, RobotState, Twist, wrap_angle
from robotexp.run.endings import StallWatch, unexplored_left
from robotexp.run.loop import ExplorationRun, RunInfo, make_record
from robotexp.run.observers import RunObserver, StepEvent
from robotexp.run.record import EndReason, RunRecord
from robotexp.run.teamshare import ScanExchange, SeenCells, beams_on_teammates, groups_within, teammates_near

if TYPE_CHECKING:
    from robotexp.clock import Clock
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.planning.targets import PlanCosts
    from robotexp.robot import Robot
    from robotexp.world.groundtruth import GroundTruth

__all__ = ["TeamRun", "TeamExplorers", "TeamSpec", "parse_team", "COORDINATION_PERIOD"]

COORDINATION_PERIOD = 1.0       # [s] robot time between the coordinator's rounds
GIVE_WAY_GAP = 0.6              # [m] a robot gives way to a teammate ahead closer than this (footprints' gap)
GIVE_WAY_ANGLE = math.radians(75)   # [rad] "ahead": within this of the heading
GIVE_WAY_SPEED = 0.02           # [m/s] a teammate slower than this stands still
STAND_V = 1e-3                  # [m/s] a command below this and STAND_W [rad/s] stands still (idle time):
STAND_W = 1e-3                  # a controller holding a robot may command rounding noise (1e-9 rad/s)
TEAMMATE_MARGIN = 0.1           # [m] beams ending this close to a teammate's footprint are not mapped
TEAMMATE_CLEARANCE = 0.03       # [m] a robot's body swept along its command keeps this from a teammate's disc
_RING = np.linspace(-math.pi, math.pi, 24, endpoint=False)     # points on a teammate's disc for that check
# robots whose laser guards wait for each other (three by a door, each holding for the others) stand forever:
# a robot held JAM_HELD [s] (standing, under JAM_SPEED, while its explorer commands no translation or the
# team's rules stop it) with teammates within JAM_NEAR [m] held JAM_TEAMMATE_HELD [s] too, or done, plans
# around their discs (the two turning radii and JAM_MARGIN) until it has driven JAM_CLEAR [m]
# (Explorer.plan_around; TeamRun._unjam)
JAM_HELD = 20.0
JAM_TEAMMATE_HELD = 10.0
JAM_NEAR = 3.0
JAM_SPEED = 0.01
JAM_MARGIN = 0.05
JAM_CLEAR = 1.0
LEAVE_TOL = 0.3                 # [m] how far a robot's centre may stray past the exploration area
_END_ORDER = (EndReason.PLUGIN_ERROR, EndReason.ROBOT_ERROR, EndReason.INTERRUPTED, EndReason.STOPPED,
              EndReason.STALLED, EndReason.TIME_LIMIT, EndReason.EXPLORED)


class TeamExplorers(Explorer):
    """The explorers of a team seen as one, for what the team's observers ask of `run.explorer`: robot 0's
    overlays and markers, and `give_up` passed to every robot (the stall watch)."""

    def __init__(self, members: Sequence[ExplorationRun]) -> None:
        self.members = list(members)

    def step(self, state: Any, grid: OccupancyGrid) -> Twist:      # never called: the members step
        raise NotImplementedError("a team's explorers step one by one")

    def give_up(self, grid: OccupancyGrid) -> bool:
        """Every robot gives up its goal (on its own grid)."""
        given = False
        for m in self.members:
            give_up = getattr(m.explorer, "give_up", None)
            if callable(give_up) and m.end is EndReason.UNKNOWN:
                given = bool(give_up(m.grid)) or given
        return given

    def overlays(self) -> dict[str, npt.NDArray[np.float64]]:
        """Robot 0's overlays."""
        return self.members[0].explorer.overlays()

    def markers(self) -> dict[str, dict[str, Any]]:
        """Robot 0's markers."""
        return self.members[0].explorer.markers()


class TeamRun(ExplorationRun):
    """Robots exploring one world together, one record for the team.

    Args:
        robots: the open robots (the run stops them at its end, and does not close them).
        explorers: one explorer per robot (the same method).
        grids: one grid per robot: the same grid for all (perfect communication) or one each (`comm_range`).
        clock: the one clock of the team (`robotexp.sim.SimTeam.make_clock`).
        coordinator: shares out targets (None or one with `assigns_targets` False: none).
        comm_range: [m] robots share scans within this distance (None: all share one grid).
        grid: the team's grid, all scans (default: `grids[0]` when the robots share it).
        truth, period, max_time, sample_period, seed, info, observers, area: as `ExplorationRun`'s.

    Raises:
        ConfigError: the robots, explorers and grids do not match, or a coordinator that assigns targets
            with an explorer that takes none.
    """

    def __init__(self, robots: Sequence[Robot], explorers: Sequence[Explorer],  # noqa: PLR0913
                 grids: Sequence[OccupancyGrid], clock: Clock, *, coordinator: Coordinator | None = None,
                 comm_range: float | None = None, grid: OccupancyGrid | None = None,
                 truth: GroundTruth | None = None, period: float = 0.1, max_time: float = 4 * 3600,
                 seed: int = 0, info: RunInfo | None = None, observers: Iterable[RunObserver] = (),
                 area: tuple[float, float, float, float] | None = None, costs: Sequence[PlanCosts] = ()) -> None:
        n = len(robots)
        if n < 1 or len(explorers) != n or len(grids) != n:
            raise ConfigError(f"team: {n} robots, {len(explorers)} explorers and {len(grids)} grids; give one each")
        shared = all(g is grids[0] for g in grids)
        if comm_range is None and not shared:
            raise ConfigError("team: robots without a communication range share one grid")
        if comm_range is not None and not (math.isfinite(comm_range) and comm_range > 0):
            raise ConfigError(f"team: the communication range must be > 0 m, got {comm_range * 1000:g} mm")
        if coordinator is not None and coordinator.assigns_targets:
            refuse = [type(e).__name__ for e in explorers if not e.takes_targets]
            if refuse:
                raise ConfigError(f"team: coordinator {type(coordinator).__name__} assigns frontier targets, and the "
                                  f"explorer {refuse[0]} does not take them; use it with coordinator none")
        if grid is None:
            if not shared:
                raise ConfigError("team: robots with maps of their own need the team's grid for coverage")
            grid = grids[0]
        self.members = [ExplorationRun(r, e, g, truth=None, period=period, max_time=max_time, seed=seed,
                                       info=RunInfo(method=(info.method if info else "")), area=area)
                        for r, e, g in zip(robots, explorers, grids, strict=True)]
        for i, m in enumerate(self.members):
            m.sampling = False
            m.rng = np.random.default_rng(seed if i == 0 else (seed, i))
            m.scan_filter = functools.partial(self._without_teammates, i)
        info = info or RunInfo(method=type(explorers[0]).__name__)
        super().__init__(robots[0], TeamExplorers(self.members), grid, truth=truth, period=period,
                         max_time=max_time, seed=seed, info=info, observers=observers, area=area)
        self.clock = clock
        self.coordinator = coordinator if coordinator is not None and coordinator.assigns_targets else None
        self.coordinator_name = "none" if coordinator is None else getattr(coordinator, "name", "")
        self.comm_range = comm_range
        self.exchange = None if comm_range is None else ScanExchange(grids)
        self.seen = SeenCells(grid.shape, n)
        # the team grid's cells ever firmly occupied, for the end's check (noted once with the explorers on that grid)
        self.walls = shared_wall_memory(grid, 1.5)
        self.gave_way = [0] * n             # periods each robot gave way to a teammate
        self.held = np.zeros(n)             # [s] each robot held without a break, as `_unjam` counts it
        self.around = [0] * n               # times each robot was told to plan around held teammates
        self._around_from: list[tuple[float, float] | None] = [None] * n    # where it was told so
        self.idle = [0] * n                 # ticks each robot stood idle (done, or commanded to stand still)
        self.active: list[int] = []         # the robots still exploring, in the order they step at each tick
        self.targets: list[npt.NDArray[np.int64] | None] = [None] * n     # each robot's coordinator target
        self.rounds = 0                     # coordinator rounds that assigned targets
        self.stall = StallWatch()
        self.metrics.path = self.members[0].metrics.path        # robot 0's path (the others: `paths`)
        self.metrics.estimated = self.members[0].metrics.estimated
        self._costs = list(costs)
        self._next_round = 0.0
        # where each robot stands as the robots tell each other (its state's pose, NaN before it has one) and
        # how fast it drives: robot i's row is its latest step's, the rows of the robots after it last tick's
        self._xy = np.full((n, 2), np.nan)
        self._speed = np.zeros(n)
        self._swing = np.array([r.footprint.swing for r in robots], np.float64)
        self._brake = np.array([2.0 * max(r.limits.a_max, 1e-6) for r in robots], np.float64)

    @property
    def paths(self) -> list[list[tuple[float, float]]]:
        """Each robot's path [m] so far."""
        return [m.metrics.path for m in self.members]

    # -- the loop -----------------------------------------------------------------------------
    def _loop(self) -> None:
        n = len(self.members)
        states = []
        for m in self.members:
            state = m._begin()
            if state is None:
                self.reason, self.end, self.error = m.reason, m.end, m.error
                return
            states.append(state)
        for i in range(n):
            self._stand(i)
        self._mark_bodies()
        self.state = states[0]
        self.start_pose = self.members[0].start_pose
        self._t0 = states[0].time
        if self.coordinator is not None:
            lasers = [s.laser.range_max for s in states if s.laser is not None]
            self.coordinator.reset(TeamContext(size=n, laser_range=min(lasers) if lasers else 0.0,
                                               radius=tuple(m.robot.radius for m in self.members),
                                               rng=np.random.default_rng((self.seed, n))))
        self.stall.start(self.grid, min(m.robot.limits.v_max for m in self.members))
        self.observers.notify("on_start", self)
        active = self.active = list(range(n))
        while True:
            if self._pending is not None or self._sigint:   # a signal kept for this tick
                self._take_signal()
            self.robot_time = states[0].time - self._t0
            self.state = states[0]
            self._coordinate(active)
            for i in list(active):
                m = self.members[i]
                if self._stop is not None:
                    m._stop = self._stop
                try:
                    go_on = self._member_step(i, m, states[i])
                except RobotError as exc:
                    self._name_robot(i, exc)
                if not go_on:
                    active.remove(i)
                    if m.end is not EndReason.EXPLORED:
                        self._end_from(i, m)
                        return
                    m._safe_stop()
                    self._speed[i] = 0.0        # it stands from now on (its last state may have it driving)
            self._mark_bodies()
            self._share()
            self._count_idle(active)
            self._team_sample()
            if not active:
                self._all_done()
                return
            if self._stop is not None:
                self.reason, self.end = self._stop
                return
            self.clock.tick()
            states = self._read_all()

    def _read_all(self) -> list[RobotState]:
        """Every robot's state, in order (a robot that fails is named)."""
        states = []
        for i, m in enumerate(self.members):
            try:
                states.append(m.robot.read())
            except RobotError as exc:
                self._name_robot(i, exc)
        return states

    def _name_robot(self, i: int, exc: RobotError) -> NoReturn:
        """Raise robot `i`'s RobotError (its link lost, an emergency stop) saying which robot of the team it was
        (a try/except at each call: no cost on the loop's path while no robot fails)."""
        if len(self.members) < 2:
            raise exc
        raise RobotError(f"robot {i + 1}: {exc}") from exc

    def _member_step(self, i: int, m: ExplorationRun, state: RobotState) -> bool:
        """Member `i`'s tick from `state`, what the team takes from it, the observers of each robot's step, and
        the team's traffic rules on its command; whether it explores on."""
        go_on = m._tick(state)
        self._after_tick(i, m)
        if i == self.active[-1]:
            self._sum_metrics()         # every robot has stepped: the team's totals for this tick
        if self.observers.listening("on_robot_step"):     # recorders and views see every robot
            self.observers.notify("on_robot_step", self, i, StepEvent(m.robot_time, state, m.mapped_now, m.decision))
        if go_on:
            self._unjam(i, m, self._give_way(i, m))
        return go_on

    def _stand(self, i: int) -> None:
        """Member `i` tells the others where it stands and how fast it drives (its state now)."""
        s = self.members[i].state
        if s is None:
            self._xy[i] = np.nan
            self._speed[i] = 0.0
            return
        p = s.true_pose or s.pose
        self._xy[i] = (p.x, p.y)
        self._speed[i] = abs(s.velocity.v)

    def _after_tick(self, i: int, m: ExplorationRun) -> None:
        """What the team takes from member `i`'s step: where it stands, its scan (`_take_scan`), and the walls
        its scan, or its explorer, showed on the team's grid."""
        self._stand(i)
        if m.mapped_now:
            self._take_scan(i, m)
        self.walls.note(self.grid)          # after every scan, and every change an explorer made

    def _take_scan(self, i: int, m: ExplorationRun) -> None:
        """Member `i` mapped a scan: the cells it touched, the scan for the others, the area's bounds."""
        self.seen.note(i, m.grid)
        if self.exchange is not None and m.state is not None and m.mapped_scan is not None:
            self.exchange.log(i, m.state.pose, m.mapped_scan)
            self.grid.update(m.state.pose, m.mapped_scan)
        p = m.state.true_pose or m.state.pose if m.state is not None else None
        if self.area is not None and p is not None:
            from robotexp.world.bounds import inside
            if not inside(self.area, p.x, p.y, LEAVE_TOL):
                self.request_stop(f"robot {i + 1} left the exploration area at ({p.x:.2f}, {p.y:.2f}) m")

    def _give_way(self, robot: int, m: ExplorationRun) -> bool:
        """The traffic rule of the team: a robot about to drive towards a teammate of a smaller number that is
        moving and close ahead (gap under GIVE_WAY_GAP, within GIVE_WAY_ANGLE of its heading) stops its
        translation for this period (it may turn); a teammate standing still is left to the robot's own laser
        check. Two robots closing on each other would otherwise both brake for a still obstacle at twice the
        closing speed. True when a rule stopped the robot's translation this period."""
        d = m.decision
        s = m.state
        if not isinstance(d, Twist) or s is None:
            return False
        if self._keep_clear(robot, m, d, s):
            return True
        if d.v <= 0.0:
            return False
        if self._lower_ahead(robot, m, s.true_pose or s.pose):
            m.robot.command(Twist(0.0, d.w))
            self.gave_way[robot] += 1
            return True
        return False

    def _unjam(self, robot: int, m: ExplorationRun, stopped: bool) -> None:
        """Robots that hold for each other: member `robot`, held JAM_HELD s with teammates within JAM_NEAR held
        JAM_TEAMMATE_HELD s (or done), plans around their discs (`Explorer.plan_around`) until it has driven
        JAM_CLEAR, and is not told again before. The lowest-numbered robot of a held group is not told (unless
        a teammate near it is done): it keeps its goal, and its explorer's own timeouts run. A robot held is one
        that stands while its explorer commands no translation (its laser guard, or its follower, waits) or the
        team's rules stopped it (`stopped`: a teammate too close ahead)."""
        d, s = m.decision, m.state
        if not isinstance(d, Twist) or s is None:
            return
        p = s.true_pose or s.pose
        since = self._around_from[robot]
        if since is not None and math.hypot(p.x - since[0], p.y - since[1]) > JAM_CLEAR:
            m.explorer.plan_around(None)
            self._around_from[robot] = None
        held = abs(s.velocity.v) < JAM_SPEED and (stopped or abs(d.v) < STAND_V)
        self.held[robot] = self.held[robot] + self.period if held else 0.0
        if self.held[robot] < JAM_HELD or self._around_from[robot] is not None:
            return          # told once and not on its way yet: its own rules (giving a goal up) take it on
        done = np.array([t.end is not EndReason.UNKNOWN for t in self.members])
        near = (np.hypot(self._xy[:, 0] - p.x, self._xy[:, 1] - p.y) < JAM_NEAR) & (
            (self.held >= JAM_TEAMMATE_HELD) | done)
        near[robot] = False
        if not (near[:robot].any() or (near & done).any()):     # the lowest-numbered of a held group keeps its way
            return
        m.explorer.plan_around(np.column_stack([self._xy[near], self._swing[near] + self._swing[robot] + JAM_MARGIN]))
        self._around_from[robot] = (p.x, p.y)
        self.held[robot] = 0.0
        self.around[robot] += 1

    def _lower_ahead(self, robot: int, m: ExplorationRun, p: Pose) -> bool:
        """A teammate of a smaller number than `robot` (at pose `p`) still exploring, moving and close ahead."""
        dx, dy = self._xy[:robot, 0] - p.x, self._xy[:robot, 1] - p.y
        gap = np.hypot(dx, dy) - self._swing[robot] - self._swing[:robot]
        for j in np.flatnonzero((gap < GIVE_WAY_GAP) & (self._speed[:robot] >= GIVE_WAY_SPEED)).tolist():
            if (self.members[j].end is EndReason.UNKNOWN
                    and abs(wrap_angle(math.atan2(dy[j], dx[j]) - p.theta)) < GIVE_WAY_ANGLE):
                return True
        return False

    def _keep_clear(self, robot: int, m: ExplorationRun, d: Twist, s: RobotState) -> bool:
        """The robots tell each other where they stand: a command whose sweep (`footprint_blocked`, the
        robot's own outline along the command's arc or turn) would bring the body within TEAMMATE_CLEARANCE,
        plus the stopping distance of the fastest teammate near, of a teammate's disc is cut to its turn
        alone, or to a stop; a teammate the laser cannot see (lower than the laser, or behind it) is not
        driven into. True when the command was cut."""
        from robotexp.planning.follower import _sweep_length

        p = s.true_pose or s.pose
        # the teammates within 2 m of their discs, the farthest a moving one of them may still come before it
        # stops [m], and the least gap between the robot's centre and their discs [m]
        near = np.zeros(len(self._xy), np.bool_)
        found, closing, gap = teammates_near(p.x, p.y, self._xy, self._swing, self._speed, self._brake, robot, 2.0,
                                             near)
        if not found:
            return False
        # the sweep of `d` reaches no point nearer than its length plus the outline's swing and the clearance
        # (`footprint_blocked`), and a point on a teammate's disc lies no nearer than its centre less its radius:
        # when every disc lies beyond that, `d` keeps clear as it is (the common case: no ring to build)
        clear = TEAMMATE_CLEARANCE + closing
        lim = m.robot.limits
        sweep = (_sweep_length(d.v, lim.a_max, clear) if d.v > 0 else 0.0) + m.robot.footprint.swing + clear
        if gap > sweep + 1e-6:
            return False
        xy, r = self._xy[near], self._swing[near, None]
        world = np.column_stack([(xy[:, 0, None] + r * np.cos(_RING)).ravel(),
                                 (xy[:, 1, None] + r * np.sin(_RING)).ravel()])
        return self._cut_command(robot, m, d, p, world, closing)

    def _cut_command(self, robot: int, m: ExplorationRun, d: Twist, p: Pose, world: npt.NDArray[np.float64],
                     closing: float) -> bool:
        """Command `d` of member `robot` at pose `p`, or its turn alone, or a stop: the first whose sweep keeps
        the body TEAMMATE_CLEARANCE + `closing` [m] from the points `world` (n, 2) [m] on the teammates' discs; True
        when it is not `d`."""
        from robotexp.planning.follower import footprint_blocked

        c, sn = math.cos(p.theta), math.sin(p.theta)
        dx, dy = world[:, 0] - p.x, world[:, 1] - p.y
        pts = np.column_stack([c * dx + sn * dy, -sn * dx + c * dy])
        foot, lim = m.robot.footprint, m.robot.limits
        for cmd in (d, Twist(0.0, d.w), Twist.ZERO):
            if cmd == Twist.ZERO or not footprint_blocked(pts, foot, TEAMMATE_CLEARANCE + closing, max(cmd.v, 0.0),
                                                          cmd.w, lim.a_max, lim.alpha_max):
                break
        if cmd == d:
            return False
        m.robot.command(cmd)
        self.gave_way[robot] += 1
        return True

    def _without_teammates(self, robot: int, state: RobotState) -> LaserScan:
        """Robot `robot`'s scan for the maps: the beams that end on a teammate (within its radius plus
        TEAMMATE_MARGIN of where it stands, as the robots tell each other) read NaN, which the map skips,
        so that robots are not mapped as walls (the explorers get the whole scan)."""
        scan = state.laser
        assert scan is not None
        p = state.pose
        sx, sy = scan.origin(p)
        # only teammates a beam can end on (a hair of slack: the beams' own test below decides)
        reach = TEAMMATE_MARGIN + scan.range_max + 1e-6
        near = np.hypot(self._xy[:, 0] - sx, self._xy[:, 1] - sy) <= self._swing + reach   # a teammate is the
        near[robot] = False                                                                # disc it turns in
        if not near.any():
            return scan
        on = beams_on_teammates((sx, sy, p.theta), scan.angles, scan.ranges, self._xy[near],
                                self._swing[near] + TEAMMATE_MARGIN)
        if not on.any():
            return scan
        return replace(scan, ranges=np.where(on, np.nan, scan.ranges))

    def _mark_bodies(self) -> None:
        """Where each robot stands is free space: the unknown cells within its turning disc plus TEAMMATE_MARGIN
        (the zone whose beams the scan filter leaves out) are marked free on its map (passed on to the robots
        it talks to as its scans are) and on the team's. A teammate's body hides the floor under it from the
        others' lasers; left unknown, that floor is frontier at the teammate's feet, and a robot sent there
        waits behind the teammate until it gives the goal up."""
        for i, m in enumerate(self.members):
            if m.state is None:
                continue
            p, reach = m.state.pose, m.robot.footprint.swing + TEAMMATE_MARGIN
            if m.grid.mark_free_disc(p.x, p.y, reach) and self.exchange is not None:
                self.exchange.log_stand(i, p, reach)
            if m.grid is not self.grid:
                self.grid.mark_free_disc(p.x, p.y, reach)

    def _share(self) -> None:
        if self.exchange is not None:
            self.exchange.share(groups_within(self._positions(range(len(self.members))), self.comm_range))

    def _count_idle(self, active: Sequence[int]) -> None:
        for i, m in enumerate(self.members):
            d = m.decision
            if i not in active or not isinstance(d, Twist) or (abs(d.v) < STAND_V and abs(d.w) < STAND_W):
                self.idle[i] += 1

    def _positions(self, robots: Iterable[int]) -> npt.NDArray[np.float64]:
        out = []
        for i in robots:
            s = self.members[i].state
            assert s is not None
            p = s.true_pose or s.pose
            out.append((p.x, p.y))
        return np.asarray(out, np.float64).reshape(-1, 2)

    def _team_sample(self) -> None:
        slack = self.period / 2
        if self.robot_time < self._next_sample - slack:
            return
        self._sample()
        while self._next_sample <= self.robot_time + slack:
            self._next_sample += self.sample_period
        reason = self.stall.sample(self.robot_time, self.grid, self.explorer)
        if reason is not None:
            self.request_stop(reason, EndReason.STALLED)

    def _end_from(self, i: int, m: ExplorationRun) -> None:
        """Robot `i`'s run ended the team's (an error, Ctrl-C, a stop): the team ends as it did; a robot error
        says which robot failed."""
        self.reason, self.end, self.error = m.reason, m.end, m.error
        prefix = f"{EndReason.ROBOT_ERROR.value}: "
        if self.end is EndReason.ROBOT_ERROR and len(self.members) > 1 and m.reason.startswith(prefix):
            self.reason = f"{prefix}robot {i + 1}: {m.reason.removeprefix(prefix)}"

    def _all_done(self) -> None:
        """Every robot's explorer said done: the team's end is theirs, checked against the frontier left."""
        ends = [m.end for m in self.members]
        end = next(e for e in _END_ORDER if e in ends)
        m = self.members[ends.index(end)]
        self.reason, self.end, self.error = m.reason, m.end, m.error
        if end is EndReason.EXPLORED:
            s = self.members[0].state
            assert s is not None
            left = unexplored_left(self.grid, s.pose, self.members[0].robot.radius,
                                   np.asarray(self.members[0].metrics.path), self.walls.ever)
            if left is not None:
                self.end = EndReason.STOPPED
                self.reason = (f"stopped: the explorers ended ({m.reason}) with {left[0]} frontier cells left that "
                               f"robot 1 can reach, {left[1]:.1f} m2 of unknown space behind them")
            else:
                self.completed = True

    def _safe_stop(self) -> None:
        for m in self.members:
            m._safe_stop()

    # -- coordination -------------------------------------------------------------------------
    def _coordinate(self, active: Sequence[int]) -> None:
        """A coordinator round when one is due: for each group of robots that can talk, the frontier
        targets of its first robot's grid. A robot holds its target while some of the cells it was given
        are still frontier on its own explorer's map (not resolved by anyone's scans, not given up on);
        robots that hold one keep it and the others get one from the coordinator, or, with a coordinator
        that `reassigns`, every robot's target is chosen anew at every round (a robot told its held target
        again drives on undisturbed)."""
        if self.coordinator is None or not active or self.robot_time < self._next_round - self.period / 2:
            return
        self._next_round = self.robot_time + COORDINATION_PERIOD
        from robotexp.planning.targets import PlanCosts
        from robotexp.planning.team import team_candidates, with_costs

        if not self._costs:
            radius = max(m.robot.radius for m in self.members)
            self._costs = [PlanCosts(radius, 0.3) for _ in self.members]
        anew = self.coordinator.reassigns
        for group in groups_within(self._positions(active), self.comm_range):
            robots = [active[g] for g in group]
            leader = robots[0]
            grid = self.members[leader].grid
            radius = max(self.members[i].robot.radius for i in robots)
            # the targets first; the paths (a Dijkstra per robot) only when some robot needs a target
            frontier = self.members[leader].explorer.target_frontier(grid)
            cand = team_candidates(grid, None, [tuple(p) for p in self._positions(robots)], radius,
                                   frontier=frontier)
            labels = [k if k is not None and self._pursued(i) else None
                      for i, k in zip(robots, held_targets(cand, [self.targets[i] for i in robots]), strict=True)]
            if not anew and all(k is not None for k in labels):
                continue
            cand = self._own_frontier(robots, with_costs(cand, grid, self._costs[leader], radius))
            labels = [k if k is not None and math.isfinite(cand.cost[j, k]) else None for j, k in enumerate(labels)]
            self.rounds += 1
            if anew:
                cand = replace(cand, held=tuple(labels))
            chosen = self.coordinator.assign(cand, [None] * len(robots) if anew else labels)
            for j, i in enumerate(robots):
                k = chosen[j] if j < len(chosen) else None
                if k is not None and k == labels[j]:
                    continue            # the robot drives on to the cells it was given
                if k is None or not (0 <= k < len(cand)) or not math.isfinite(cand.cost[j, k]):
                    if self.targets[i] is not None:
                        self.targets[i] = None
                        self.members[i].explorer.assign_targets(None)
                    continue
                self.targets[i] = cand.cells[k]
                self.members[i].explorer.assign_targets(cand.cells[k])

    def _own_frontier(self, robots: Sequence[int], cand: Candidates) -> Candidates:
        """`cand` with the cost of each robot to each target none of whose cells is among the robot's own frontier
        (`target_frontier` of its explorer on its map: cells it gave up on, or its map shows resolved) set to
        inf: a robot is not sent to a target it would not choose a goal in."""
        if len(cand) == 0:
            return cand
        cells = np.concatenate(cand.cells).astype(np.int64, copy=False)
        owner = np.repeat(np.arange(len(cand)), [len(c) for c in cand.cells])
        cost = cand.cost.copy()
        for j, i in enumerate(robots):
            m = self.members[i]
            got = m.explorer.target_frontier(m.grid)
            if got is not None:
                cost[j, ~_any_in(got, cells, owner, len(cand))] = math.inf
        return replace(cand, cost=cost)

    def _pursued(self, robot: int) -> bool:
        """Robot `robot`'s explorer still has some of its target's cells among its own frontier (`target_frontier`
        on its map: cells resolved or given up on are not); True for an explorer that tells none."""
        cells = self.targets[robot]
        m = self.members[robot]
        got = m.explorer.target_frontier(m.grid)
        if cells is None or got is None:
            return cells is not None
        cells = np.asarray(cells, np.int64).reshape(-1, 2)
        return bool(_any_in(got, cells, np.zeros(len(cells), np.int64), 1)[0])

    # -- the record ---------------------------------------------------------------------------
    def team_record(self) -> RunRecord:
        """The record of the team (see `make_record`), with the team's keys."""
        record = make_record(self)
        n = len(self.members)
        paths = [m.metrics.path_length for m in self.members]
        seen, several = self.seen.counts()
        robots = []
        for i, m in enumerate(self.members):
            s = m.state
            p = None if s is None else (s.true_pose or s.pose)
            robot_collisions = getattr(m.robot, "robot_collisions", None)
            fields: dict[str, Any] = {
                "robot": m.robot.model, "start_pose": m.start_pose.as_list() if m.start_pose else None,
                "end_pose": None if p is None else p.as_list(),
                "path_length_m": round(m.metrics.path_length, 4), "collisions": m.metrics.collisions,
                "robot_collisions": None if robot_collisions is None else int(robot_collisions),
                "idle_time_s": round(self.idle[i] * self.period, 3),
                "give_way_s": round(self.gave_way[i] * self.period, 3),
                "planned_around": self.around[i],
                "end": m.end.value if m.end is not EndReason.UNKNOWN else self.end.value,
                "reason": m.reason if m.end is not EndReason.UNKNOWN else self.reason,
                "cells_seen": int(np.count_nonzero(self.seen.seen_by(i))),
            }
            if m.robot.address is not None:      # a robot over its driver
                fields["address"] = str(m.robot.address)
            if self.exchange is not None:
                fields["scans_received"] = int(self.exchange.received[i])
            try:
                fields.update(m.explorer.result_fields())
            except Exception:       # noqa: BLE001 - a plugin's fault must not lose the team's record
                pass
            robots.append(fields)
        rc = [r["robot_collisions"] for r in robots]
        return replace(
            record, path_length_m=round(sum(paths), 4), collisions=sum(m.metrics.collisions for m in self.members),
            visited_cells=len(set().union(*(m.metrics.visited for m in self.members))),
            team_size=n, coordinator=self.coordinator_name, comm_range_m=self.comm_range,
            total_path_m=round(sum(paths), 4), max_path_m=round(max(paths), 4),
            overlap_ratio=None if seen == 0 else round(several / seen, 5),
            idle_time_s=round(sum(self.idle) * self.period, 3),
            robot_collisions=None if any(c is None for c in rc) else int(sum(rc)),
            coordinator_rounds=self.rounds if self.coordinator is not None else None,
            robots=robots)

    def _make_record(self) -> RunRecord:
        return self.team_record()

    def _sum_metrics(self) -> None:
        """The team's path (the robots' total) and collisions as they stand after this tick (what the view, a
        video frame and the coverage samples read)."""
        self.metrics.path_length = sum(m.metrics.path_length for m in self.members)
        self.metrics.collisions = sum(m.metrics.collisions for m in self.members)

    def _sample(self) -> None:
        """A coverage sample of the team's grid, the path being the team's total."""
        self._sum_metrics()
        super()._sample()


def _any_in(frontier: tuple[npt.NDArray[np.bool_], tuple[int, int]], cells: npt.NDArray[np.int64],
            owner: npt.NDArray[np.int64], groups: int) -> npt.NDArray[np.bool_]:
    """For each of `groups` groups of grid `cells` ((m, 2), the group of each in `owner`), whether some cell
    is set in `frontier` (a bool mask of a window of the grid and the window's (row, col) offset)."""
    mask, off = frontier
    local = cells - np.asarray(off, np.int64)
    inside = (local[:, 0] >= 0) & (local[:, 0] < mask.shape[0]) & (local[:, 1] >= 0) & (local[:, 1] < mask.shape[1])
    on = np.zeros(len(cells), bool)
    on[inside] = mask[local[inside, 0], local[inside, 1]]
    return np.bincount(owner[on], minlength=groups) > 0


def held_targets(cand: Candidates, targets: Sequence[npt.NDArray[np.int64] | None]) -> list[int | None]:
    """For each robot's earlier target (grid cells (m, 2), or None), the candidate that holds most of its cells
    (the first of those that hold as many), None when none holds any: `robotexp.planning.team.label_cells` of
    every target, with the candidates' cells gathered once."""
    if len(cand) == 0:
        return [None] * len(targets)
    cells = np.concatenate(cand.cells).astype(np.int64, copy=False)
    owner = np.repeat(np.arange(len(cand)), [len(c) for c in cand.cells])
    span = int(cells[:, 1].max()) + 1
    keys = cells[:, 0] * span + cells[:, 1]
    out: list[int | None] = []
    for t in targets:
        if t is None or len(t) == 0:
            out.append(None)
            continue
        t = np.asarray(t, np.int64).reshape(-1, 2)
        ok = (t[:, 1] >= 0) & (t[:, 1] < span)          # a cell beyond every candidate's columns is in none
        counts = np.bincount(owner[np.isin(keys, t[ok, 0] * span + t[ok, 1])], minlength=len(cand))
        best = int(np.argmax(counts))
        out.append(best if counts[best] > 0 else None)
    return out


@dataclass
class TeamSpec:
    """The team of a run (`robotexp explore --team`): the robots' presets, their start poses, the
    coordinator and the communication range."""

    robots: tuple[str, ...] = ("p3dx",)         # simulator presets, one per robot
    coordinator: str = "none"                    # a `robotexp.coordinators` plugin
    coordinator_params: dict[str, Any] = field(default_factory=dict)
    comm_range: float | None = None              # [m] (None: one shared map)
    poses: tuple[str, ...] = ()                  # start poses, one per robot (names or x,y,theta in mm); () spread
    # robots over their drivers, BACKEND:ADDRESS[+LASER:ADDRESS] each (`robotexp.run.teamrobots`; `robots`
    # are then their backends); () simulated robots
    members: tuple[str, ...] = ()

    def validate(self) -> None:
        """Raise ConfigError on a team that cannot be run."""
        from robotexp.sim.presets import preset
        from robotexp.sim.team import MAX_TEAM

        if not 1 <= len(self.robots) <= MAX_TEAM:
            raise ConfigError(f"--team: a team has 1..{MAX_TEAM} robots, got {len(self.robots)}")
        if self.members and len(self.members) != len(self.robots):
            raise ConfigError(f"--team: {len(self.members)} addresses for {len(self.robots)} robots")
        for name in () if self.members else self.robots:
            preset(name)
        if self.comm_range is not None and not (math.isfinite(self.comm_range) and self.comm_range > 0):
            raise ConfigError(f"--comm-range must be > 0 mm, got {self.comm_range * 1000:g} mm")
        if self.poses and len(self.poses) != len(self.robots):
            raise ConfigError(f"--team-poses: {len(self.poses)} poses for {len(self.robots)} robots; give one each")


def parse_team(text: str, robot: str = "p3dx") -> tuple[str, ...]:
    """`--team`: a number of robots of preset `robot` ("4") or a list of presets ("p3dx,p3dx,kobuki")."""
    from robotexp.sim.team import MAX_TEAM

    text = text.strip()
    if re.fullmatch(r"[+-]?\d+", text):
        n = int(text) if len(text) < 12 else int(text[:1] + "9" * 11)      # a huge count: refused below
        if not 1 <= n <= MAX_TEAM:
            shown = text if len(text) < 12 else f"{len(text.lstrip('+-'))} digits"
            raise ConfigError(f"--team: a team has 1..{MAX_TEAM} robots, got {shown}")
        return (robot,) * n
    names = tuple(t.strip() for t in text.split(","))
    if not any(names):
        raise ConfigError(f"--team: give a number of robots or a list of presets (p3dx,kobuki), got {text!r}")
    if "" in names:
        raise ConfigError(f"--team: robot {names.index('') + 1} of {text!r} is empty: give one preset per robot, "
                          "separated by single commas (p3dx,p3dx,kobuki)")
    return names

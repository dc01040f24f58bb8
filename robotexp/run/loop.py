"""The control loop that runs one explorer on one robot (`ExplorationRun`) and the record it makes.

One iteration per control period: read the robot, integrate the scan, sample coverage, ask the explorer,
command the robot; observers hear about each step, sample and the end (docs/architecture.md, "One run")."""

from __future__ import annotations

import logging
import math
import signal
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from robotexp.errors import ConfigError, RobotError, Terminated, interrupt_in, raise_interrupt_in
from robotexp.robot import LaserScan, Pose, Robot, RobotState, Twist, new_scan
from robotexp.run.observers import Observers, RunObserver, SampleCallback, StepEvent
from robotexp.run.record import COVERAGE_MILESTONES, EndReason, RunRecord
from robotexp.world.bounds import clip_scan

if TYPE_CHECKING:
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.world.groundtruth import GroundTruth
from robotexp.explorer import Done, Explorer, ExplorerContext
from robotexp.run.record import milestone_keys

__all__ = ["RunMetrics", "RunInfo", "ExplorationRun", "make_record", "RANGE_WAIT"]

TERMINATED_REASON = "interrupted (SIGTERM)"     # a run that SIGTERM ended (`robotexp.errors.Terminated`)
# [s] of robot time a run waits, the robot standing, for the first laser scan (or sonar ring, for an explorer
# that uses sonar) before it ends as a robot error: a robot with no laser mounted maps nothing, and an explorer
# would drive it blind or call an empty map explored
RANGE_WAIT = 5.0

log = logging.getLogger(__name__)


def make_record(run: ExplorationRun) -> RunRecord:
    """The record of a run that ended (SI units; docs/reference/results.md has every key), named by
    `run.info`."""
    from robotexp.world.groundtruth import coverage_inside, map_iou, map_iou_tolerant

    m = run.metrics
    info = run.info
    cov = run.coverage()
    milestones: dict[str, Any] = {}
    for level in COVERAGE_MILESTONES:
        hit = m.milestones.get(level)
        t_key, p_key = milestone_keys(level)
        milestones[t_key] = None if hit is None else round(hit[0], 3)
        milestones[p_key] = None if hit is None else round(hit[1], 4)
    method_fields = _result_fields(run)
    nodes = method_fields.pop("nodes", None)
    iou: float | None = None
    iou_tolerant: float | None = None       # within one cell: a face a few millimetres off is not missed
    inside: float | None = None             # the floor over a cell from the walls (noisy hits land along them)
    if run.truth is not None:
        states = run.grid.states()
        iou = round(map_iou(states, run.truth), 5)
        iou_tolerant = round(map_iou_tolerant(states, run.truth, 1)[0], 5)
        inside = round(coverage_inside(states == 0, run.truth), 5)     # states' 0: the grid's free cells
    return RunRecord(
        run=info.name, method=info.method, world=info.world,
        start_pose=run.start_pose.as_list() if run.start_pose else None,
        max_speed_m_s=info.max_speed,
        path_length_m=round(m.path_length, 4),
        robot_time_s=round(run.robot_time, 3),
        wall_time_s=round(run.wall_time, 3),
        coverage=None if cov is None else round(cov, 5),
        coverage_inside=inside,
        collisions=m.collisions,
        nodes=nodes,
        visited_cells=len(m.visited),
        seed=run.seed,
        completed=run.completed,
        reason=run.reason,
        map_iou=iou,
        map_iou_tolerant=iou_tolerant,
        cell_m=run.grid.geo.cell,
        **milestones,
        pose=info.pose, laser_range_m=info.laser_range, robot=info.robot,
        method_fields=method_fields, extra=dict(info.extra), end=run.end)


def _result_fields(run: ExplorationRun) -> dict[str, Any]:
    """The explorer's `result_fields()`; none when it raises (an explorer whose `reset` failed has
    not set up what they count): the run's own plugin error stays what the record says."""
    try:
        return dict(run.explorer.result_fields())
    except Exception as exc:        # a plugin's fault: the record is still written, the fault in it
        if run.end is not EndReason.PLUGIN_ERROR:      # an earlier plugin error is the one the record names
            what = f"result_fields raised {type(exc).__name__}: {exc}"
            log.error("explorer %r: %s (the record has none of its fields)", run.info.method, what,
                      exc_info=log.isEnabledFor(logging.DEBUG))
            run.reason, run.end = f"plugin error: explorer {run.info.method!r}: {what}", EndReason.PLUGIN_ERROR
        return {}


@dataclass
class RunMetrics:
    """What a run measures as it goes."""

    path_length: float = 0.0                # [m] along the true path where known, else odometry
    path: list[tuple[float, float]] = field(default_factory=list)
    estimated: list[tuple[float, float]] = field(default_factory=list)   # the explorer's pose, beside `path`
    visited: set[tuple[int, int]] = field(default_factory=set)
    curve: list[tuple[float, float, float]] = field(default_factory=list)  # (robot time, path, coverage)
    milestones: dict[float, tuple[float, float] | None] = field(
        default_factory=lambda: dict.fromkeys(COVERAGE_MILESTONES))
    collisions: int = 0


@dataclass
class RunInfo:
    """What names a run in its record (the settings the loop itself does not know)."""

    name: str = "run"                       # the record's `run` (names its files)
    method: str = ""                        # the explorer's plugin name ("": its class name)
    world: str = ""
    pose: str | None = None                 # the start pose's label ("1", "home", "x,y,theta", "robot")
    robot: str | None = None                # the robot model (`Robot.model`)
    max_speed: float = 0.0                  # [m/s]
    laser_range: float | None = None        # [m]
    extra: dict[str, Any] = field(default_factory=dict)   # more record keys (`address`, `script`, ...)


class ExplorationRun:
    """Runs one explorer on one robot until it is done, times out, fails, is stopped or interrupted.

    Args:
        robot: an open robot (the run does not close it; it stops it when the run ends).
        explorer: the strategy.
        grid: the map the robot builds (its geometry bounds the exploration).
        truth: ground truth of the world for coverage (None on a real robot without a world).
        period: control period [s] (10 Hz by default).
        max_time: robot time [s] after which the run ends incomplete.
        sample_period: robot time [s] between coverage samples.
        on_sample: called after each coverage sample with (robot time, coverage or None); the same as
            an observer overriding `on_sample`, called before the `observers`.
        goals: the world's named waypoint lists [m], for goal-following explorers (ExplorerContext.goals).
        start_name: the name of the start pose in the world, if any (ExplorerContext.start_name).
        info: what names the run in its record (default: `RunInfo()` with the explorer's class name).
        observers: told about each step, sample and the end (`robotexp.run.observers.RunObserver`).
        area: [m] the exploration area (xmin, ymin, xmax, ymax): the explorer's scans end at its edge, as
            at a wall (`robotexp.world.bounds.clip_scan`); the map integrates the real scans.

    After `run()`: `end` (an `EndReason`), `reason` (its text), `completed`, `metrics`, `record`
    (the `RunRecord`), `error` (the explorer's exception of a PLUGIN_ERROR end, else None) and
    `observer_errors` (the observers that raised, detached).
    """

    def __init__(self, robot: Robot, explorer: Explorer, grid: OccupancyGrid, *,  # noqa: PLR0913
                 truth: GroundTruth | None = None, period: float = 0.1, max_time: float = 4 * 3600,
                 sample_period: float = 1.0, seed: int = 0,
                 on_sample: Callable[[float, float | None], None] | None = None,
                 goals: dict[str, list[tuple[float, float]]] | None = None, start_name: str | None = None,
                 info: RunInfo | None = None, observers: Iterable[RunObserver] = (),
                 area: tuple[float, float, float, float] | None = None) -> None:
        if not period > 0 or not max_time > 0 or not sample_period > 0:
            raise ConfigError(f"run: period, max_time and sample_period must be > 0 s, got "
                              f"{period}, {max_time}, {sample_period}")
        self.robot, self.explorer, self.grid, self.truth = robot, explorer, grid, truth
        self.period, self.max_time, self.sample_period = period, max_time, sample_period
        self.seed = seed
        self.goals = dict(goals or {})
        self.start_name = start_name
        self.info = info or RunInfo(method=type(explorer).__name__)
        self.observers = Observers([SampleCallback(on_sample)] if on_sample is not None else [])
        for observer in observers:
            self.observers.add(observer)
        self.metrics = RunMetrics()
        self.state: RobotState | None = None
        self.start_pose: Pose | None = None
        self.end = EndReason.UNKNOWN
        self.reason = "not started"
        self.completed = False
        self.robot_time = 0.0
        self.wall_time = 0.0
        self.record: RunRecord | None = None
        self.error: Exception | None = None
        self._stop: tuple[str, EndReason] | None = None
        self._sigint = False                # a second signal acted at once during run() (see _watch_signals)
        self._pending: tuple[Any, int] | None = None    # a first signal's handler, kept for the next step
        self.area = area
        self.sampling = True                # sample coverage (a team's members leave it to the team)
        self.rng: np.random.Generator | None = None     # the explorer's generator (None: from `seed`)
        self.decision: Twist | Done | None = None       # the last step's decision
        self.mapped_now = False             # the last step's scan went into the map
        self.mapped_scan: LaserScan | None = None  # the scan mapped last (after `scan_filter`)
        # what of a state's scan the map gets (None: all of it; a team leaves out the beams on its robots)
        self.scan_filter: Callable[[RobotState], LaserScan] | None = None
        self._next_sample = 0.0
        self._t0 = 0.0
        self._collisions0 = 0
        self._mapped: float | None = None   # the stamp of the last scan mapped

    @property
    def observer_errors(self) -> list[tuple[RunObserver, Exception]]:
        """The observers that raised during this run (each detached), with their errors."""
        return self.observers.errors

    def request_stop(self, reason: str, end: EndReason = EndReason.STOPPED) -> None:
        """End the run at its next step (`completed` stays False; the robot is stopped).

        Meant for observers (a script's --timeout, a view's stop button, a stall watch). The record's
        `reason` is `reason`, prefixed with `end`'s value ("stopped: ...") unless it starts with it.
        """
        if end is EndReason.EXPLORED or end is EndReason.UNKNOWN:
            raise ConfigError(f"request_stop: end reason {end.value!r} is not one an observer can give")
        self._stop = (reason if reason.startswith(end.value) else f"{end.value}: {reason}", end)

    def coverage(self) -> float | None:
        """Share of the explorable free space the map marks free now (None without ground truth)."""
        if self.truth is None:
            return None
        from robotexp.world.groundtruth import grid_coverage
        return grid_coverage(self.grid, self.truth)

    def run(self) -> ExplorationRun:
        """Run to the end. Ctrl-C, robot errors, explorer errors and stop requests end the run with
        `completed` False; the robot is stopped in every case, then the observers get `on_end` with
        the record. Returns self (read `record`, `end`, `reason`, `metrics`)."""
        wall0 = time.perf_counter()
        previous = self._watch_signals()
        try:
            try:
                self._loop()
            except RobotError as exc:
                self.reason, self.end = f"robot error: {exc}", EndReason.ROBOT_ERROR
            finally:
                try:
                    self._safe_stop()
                finally:
                    self.wall_time = time.perf_counter() - wall0
                    for sig, handler in previous.items():
                        signal.signal(sig, handler)
            # a signal kept at the last step, or before a robot error ended the run: interrupted all the same
            self._take_signal()
        except (KeyboardInterrupt, SystemError) as exc:
            # a SystemError: a Ctrl-C that landed in a numba kernel while the robot was read (a localizer's
            # scan matcher), the KeyboardInterrupt behind it
            interrupt = interrupt_in(exc)
            if interrupt is None:
                raise
            self.reason = TERMINATED_REASON if isinstance(interrupt, Terminated) else "interrupted (Ctrl-C)"
            self.end, self.completed = EndReason.INTERRUPTED, False
        self._sample()
        self.record = self._make_record()
        self.observers.end(self, self.record)
        return self

    def _make_record(self) -> RunRecord:
        """The record of the run that ended (`make_record`)."""
        return make_record(self)

    def _watch_signals(self) -> dict[int, Any]:
        """Keep a Ctrl-C (SIGINT) or SIGTERM that comes during the run for the start of the next step, where its
        handler is called (`_take_signal`): its exception then starts in the loop's own code, never inside an
        explorer's step or a call into compiled code (numba, pybullet, the Lua runtime), where an exception
        raised by a signal handler can be swallowed or leave that code's state broken. A second signal before
        then calls its handler at once (a step that hangs is cut), and is also noted, so that an exception
        swallowed on its way still ends the run at the next step. Gives the handlers to put back (none when
        not in the main thread or a signal is not handled by Python)."""
        if threading.current_thread() is not threading.main_thread():
            return {}
        previous: dict[int, Any] = {}
        for sig in (signal.SIGINT, signal.SIGTERM):
            handler = signal.getsignal(sig)
            if not callable(handler):
                continue

            def noted(signum: int, frame: Any, handler: Any = handler) -> None:
                if self._pending is None:
                    self._pending = (handler, signum)
                    return
                self._sigint = True
                handler(signum, frame)
            signal.signal(sig, noted)
            previous[sig] = handler
        return previous

    def _take_signal(self) -> None:
        """Call the handler of a signal kept by `_watch_signals` (it raises KeyboardInterrupt, or `Terminated`),
        or raise KeyboardInterrupt for one whose exception was swallowed on its way."""
        if self._pending is not None:
            (handler, signum), self._pending = self._pending, None
            handler(signum, None)
            raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt   # a handler that only noted it
        if self._sigint:
            raise KeyboardInterrupt

    def _loop(self) -> None:
        """The control loop, up to the end of the run (the caller stops the robot)."""
        clock = self.robot.make_clock(self.period)
        state = self._begin()
        while state is not None and self._tick(state):
            clock.tick()
            state = self.robot.read()

    def _begin(self) -> RobotState | None:
        """Read the first state, reset the explorer and tell the observers the run starts; the first
        state, or None when the explorer's reset failed (the run ends)."""
        robot = self.robot
        self._next_sample = 0.0
        state = robot.read()
        self.start_pose = state.true_pose or state.pose
        self._t0 = state.time
        self.state = state
        ctx = ExplorerContext(
            radius=robot.radius, limits=robot.limits, period=self.period, start=state.pose,
            laser_range=state.laser.range_max if state.laser else 0.0,
            rng=self.rng if self.rng is not None else np.random.default_rng(self.seed),
            sonar=state.sonar is not None, goals=self.goals, start_name=self.start_name,
            footprint=robot.footprint)
        if self._explorer_call(self.explorer.reset, ctx) is _FAILED:
            return None
        self.observers.notify("on_start", self)
        self._collisions0 = int(state.extra.get("collisions", 0))
        self._mapped = None
        self._sensed = False
        self._held = 0              # control periods the robot stood waiting for something to sense with
        return state

    def _tick(self, state: RobotState) -> bool:
        """One control period on `state`: track, map, sample, decide, command; False when the run ends
        at this tick (the caller then stops the robot), True to go on after the clock's tick."""
        if self._pending is not None or self._sigint:       # a signal kept for this step
            self._take_signal()
        robot = self.robot
        slack = self.period / 2
        self.state = state
        self.robot_time = state.time - self._t0
        self._track(state, self._collisions0)
        # a scan is evidence once: a backend whose loop outruns its laser hands the same scan
        # (same stamp) out again, and mapping it twice would count its hits twice
        updated = new_scan(state.laser, self._mapped)
        if updated:
            assert state.laser is not None
            self.mapped_scan = state.laser if self.scan_filter is None else self.scan_filter(state)
            self.grid.update(state.pose, self.mapped_scan)
            self._mapped = state.laser.stamp
        self.mapped_now = updated
        # half a period of slack: robot time summed from float periods reads 0.99999 s at
        # the tick meant for 1 s, and the sample (or the time limit) belongs to that tick
        if self.sampling and self.robot_time >= self._next_sample - slack:
            self._sample()
            behind = self.robot_time + slack - self._next_sample
            if behind > 1000 * self.sample_period:      # the robot's clock jumped: skip to now at once
                self._next_sample += math.floor(behind / self.sample_period) * self.sample_period
            while self._next_sample <= self.robot_time + slack:   # a late robot: no burst of samples
                self._next_sample += self.sample_period
        decision: Twist | Done | None = None
        if self._stop is not None:
            self.reason, self.end = self._stop
        elif self.robot_time >= self.max_time - slack:
            self.reason, self.end = f"time limit of {self.max_time:.0f} s reached", EndReason.TIME_LIMIT
        elif not self._sensed and not self._has_range(state):
            decision = self._wait_for_range(slack)
        else:
            view = state
            if self.area is not None and state.laser is not None:
                clipped = clip_scan(state.laser, state.pose, self.area)
                if clipped is not state.laser:      # most periods nothing is clipped: no new state
                    view = replace(state, laser=clipped)
            result = self._explorer_call(self.explorer.step, view, self.grid)
            if result is not _FAILED:
                decision = result
            if isinstance(decision, Done):
                self.reason, self.end = decision.reason, EndReason.EXPLORED
                self.completed = True
            elif decision is not None:
                robot.command(decision)
        self.decision = decision
        if self.observers.listening("on_step"):
            self.observers.notify("on_step", self, StepEvent(self.robot_time, state, updated, decision))
        return isinstance(decision, Twist)

    def _has_range(self, state: RobotState) -> bool:
        """The explorer has what it senses with in `state` (then for the rest of the run): a laser scan, a sonar
        ring for one that `uses_sonar`, anything for one that does not `needs_range`."""
        explorer = self.explorer
        self._sensed = (not explorer.needs_range or state.laser is not None
                        or (explorer.uses_sonar and state.sonar is not None))
        return self._sensed

    def _wait_for_range(self, slack: float) -> Twist | None:
        """Nothing to sense with yet: the robot stands (Twist.ZERO: it would drive blind, and the map stays
        empty) until RANGE_WAIT s of robot time have passed (or as many control periods, for a robot whose clock
        stands still); then the run ends as a robot error (None)."""
        self._held += 1
        if self.robot_time < RANGE_WAIT - slack and self._held * self.period < RANGE_WAIT - slack:
            self.robot.command(Twist.ZERO)
            return Twist.ZERO
        what = "no laser scan or sonar reading" if self.explorer.uses_sonar else "no laser scan"
        name = self.info.method or "the explorer"
        self.reason = (f"robot error: the robot sent {what} in the first {RANGE_WAIT:g} s: {name} has nothing to map "
                       "with; mount a laser (robotexp explore --laser NAME:ADDRESS, laser in a campaign set, "
                       "robot.setLaser in Lua, +LASER:ADDRESS in a --team list)")
        self.end = EndReason.ROBOT_ERROR
        return None

    def _explorer_call(self, method: Callable[..., Any], *args: Any) -> Any:
        """`method(*args)` of the explorer; its exception (a RobotError aside: that ends the run as a
        robot error), or a `step` return that is neither a Twist nor Done, ends the run with
        PLUGIN_ERROR (one line naming the plugin) and gives `_FAILED`."""
        name = self.info.method or type(self.explorer).__name__
        where = f"explorer {name!r} ({type(self.explorer).__module__}.{type(self.explorer).__qualname__})"
        try:
            result = method(*args)
        except RobotError:          # the robot's fault, met by the explorer (an emergency stop seen in a state)
            raise
        except Exception as exc:
            raise_interrupt_in(exc)     # Ctrl-C inside a numba kernel's call: an interruption, not a plugin error
            self.error = exc
            self.reason = f"plugin error: {where}: {method.__name__} raised {type(exc).__name__}: {exc}"
            self.end = EndReason.PLUGIN_ERROR
            if log.isEnabledFor(logging.DEBUG):     # robotexp --debug: the traceback as well
                log.error("%s", self.reason, exc_info=True)
            else:                                   # the record's reason says it; the caller reports it
                log.info("%s", self.reason)
            return _FAILED
        if method.__name__ == "step" and not isinstance(result, (Twist, Done)):
            self.reason = (f"plugin error: {where}: step returned {_short(result)}; it must return a "
                           "robotexp.Twist or robotexp.Done")
            self.end = EndReason.PLUGIN_ERROR
            return _FAILED
        return result

    def _track(self, state: RobotState, collisions0: int) -> None:
        m = self.metrics
        p = state.true_pose or state.pose
        if m.path:
            x0, y0 = m.path[-1]
            m.path_length += math.hypot(p.x - x0, p.y - y0)
        m.path.append((p.x, p.y))
        if state.true_pose is not None:        # the pose the explorer got (odometry or localized), for images
            m.estimated.append((state.pose.x, state.pose.y))
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
        self.observers.notify("on_sample", self, self.robot_time, cov)

    def _safe_stop(self) -> None:
        """Stop the robot; a robot that cannot be reached any more cannot be stopped either."""
        try:
            if not self.robot.closed:
                self.robot.command(Twist.ZERO)
        except (RobotError, OSError):
            pass


_FAILED = object()      # an explorer call that ended the run


def _short(value: object) -> str:
    """`value` for an error line: its repr cut to 60 characters, and its type."""
    text = repr(value)
    return f"{text[:57]}... ({type(value).__name__})" if len(text) > 60 else f"{text} ({type(value).__name__})"

"""The run observer that feeds the live view, and the pacer that holds a run's loop for it.

`Pacer` lives in the loop's thread (its `wait` is called at every control tick): it waits so that a
simulated run goes at `speed` times real time (MIN_SPEED..MAX_SPEED; None: as fast as it can), and holds
the loop while the view is paused. Its waits end early when the view is stopped, paused, resumed or given
another speed (a slow speed never keeps a Stop waiting). A simulated robot's time only passes in
`clock.tick()`, so no robot time passes while paused and the run's results do not change. A real robot
keeps moving under the last command unless told otherwise: while paused the pacer calls `halt()` (the
observer's: `robot.stop()`, a zero Twist) at once and again every `halt_period` seconds (a robot whose
driver has a command watchdog stays stopped either way); on resume the loop reads the robot afresh and
the explorer decides from there. On a real robot, robot time (the robot's clock) goes on while paused and counts
against the run's time limit, and the speed control does nothing (a real robot runs in real time).

`ViewObserver` turns a run into `Frame`s for a `ViewHub`: the pose and scan at most `frame_rate`
times per wall second, the path (points at least half a cell apart), the coverage samples, and while
a browser watches the map (at most `map_rate` per second, when the grid took a scan since) and the
explorer's overlays (`Explorer.overlays()`: potential and vectors, and its `markers()`) at most
`overlay_rate` per second. Its cost per tick when nothing is due is a clock read and a comparison;
the work of a message (laser points, the map's changed tiles, JSON) is the server thread's, at the
rate the browsers take messages (`robotexp.view.feed`, `robotexp.view.server`).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robotexp.markers import markers_problem
from robotexp.run.observers import RunObserver, StepEvent, ends_team_tick
from robotexp.run.record import EndReason
from robotexp.view.feed import Frame, MapLayer, ViewHub, classes_of_states, encode_classes, vector_arrows
from robotexp.view.feed import DEFAULT_SPEED, speed_value

if TYPE_CHECKING:
    from robotexp.run.loop import ExplorationRun
    from robotexp.run.record import RunRecord

__all__ = ["Pacer", "ViewObserver", "STOP_REASON", "DEFAULT_SPEED", "potential_levels",
           "run_meta", "pacer_command", "new_path_points", "SpeedMeter"]

log = logging.getLogger(__name__)

STOP_REASON = "stopped from the live view"


class Pacer:
    """Pace, pause, single-step and stop requests for a loop (thread-safe; `wait` is the loop's side).

    Args:
        speed: robot time per wall time (None: no pacing).
        clock: wall clock [s] (monotonic).
        sleep: sleeps [s] for pacing, instead of waiting on the pacer's condition (which a stop, pause,
            resume or speed change ends early); for a fake clock.
        halt_period: [s] between `halt()` calls while paused.

    Raises:
        ValueError: a speed outside MIN_SPEED..MAX_SPEED (`robotexp.view.live`).
    """

    def __init__(self, speed: float | None = DEFAULT_SPEED, *, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] | None = None, halt_period: float = 0.5) -> None:
        self._cond = threading.Condition()
        self.clock, self.sleep, self.halt_period = clock, sleep, halt_period
        self.speed = speed_value(speed)
        self._changes = 0           # stops, pauses, resumes, steps, wakes and speed changes so far
        self.paused = False
        self.stopped = False
        self._steps = 0
        self._woken = False
        self._ref: tuple[float, float] | None = None   # (robot time, wall time) pacing starts from

    def set_speed(self, speed: float | None) -> None:
        """Robot time per wall time from now on (None: as fast as possible); a pacing wait ends now.

        Raises:
            ValueError: outside MIN_SPEED..MAX_SPEED.
        """
        speed = speed_value(speed)
        with self._cond:
            self.speed, self._ref = speed, None
            self._changed()

    def _changed(self) -> None:
        """(Under the lock.) End the loop's pacing wait: something it waits for changed."""
        self._changes += 1
        self._cond.notify_all()

    def pause(self) -> None:
        """Hold the loop at its next tick."""
        with self._cond:
            self.paused, self._woken = True, False
            self._changed()

    def resume(self) -> None:
        """Let the loop go on."""
        with self._cond:
            self.paused, self._steps = False, 0
            self._changed()

    def step(self) -> None:
        """Paused: let exactly one more tick pass (then hold again). Running: pause."""
        with self._cond:
            if self.paused:
                self._steps += 1
            self.paused = True
            self._changed()

    def wake(self) -> None:
        """Let a held `wait` return now without a step (a replay's seek while paused); the pause stays."""
        with self._cond:
            self._woken = True
            self._changed()

    def unwake(self) -> None:
        """Forget a `wake` not yet taken by `wait` (its reason was dealt with)."""
        with self._cond:
            self._woken = False

    def stop(self) -> None:
        """Release the loop for good (it ends the run at its next tick)."""
        with self._cond:
            self.stopped, self.paused = True, False
            self._changed()

    def wait(self, robot_time: float | None, halt: Callable[[], None] | None = None,  # noqa: C901
             on_hold: Callable[[bool], None] | None = None) -> bool:
        """The loop's side, at each tick with robot time [s] (None: no pacing, a real robot): hold while
        paused (calling `halt()` at once and every `halt_period`; `on_hold(True)` when holding starts,
        `on_hold(False)` when it ends), then wait as pacing wants (until due, or a stop, pause, resume,
        step or speed change). Returns whether the loop was held."""
        if not (self.paused or self.stopped) and self.speed is None:
            return False            # as fast as it goes: nothing to hold or pace (no lock: read under the GIL)
        held = False
        with self._cond:
            while self.paused and not self.stopped:
                if self._steps > 0:
                    self._steps -= 1
                    break
                if self._woken:
                    self._woken = False
                    break
                if not held:
                    held = True
                    if on_hold is not None:
                        on_hold(True)
                if halt is not None:
                    halt()
                self._cond.wait(self.halt_period)
            if held:
                self._ref = None
                if on_hold is not None:
                    on_hold(False)
            speed = None if self.stopped else self.speed
            now = self.clock()
            if robot_time is None:
                return held
            if speed is None or self._ref is None:
                self._ref = (robot_time, now)
                return held
            t0, w0 = self._ref
            changes = self._changes
        due = w0 + (robot_time - t0) / speed
        if due > now:
            if self.sleep is not None:
                self.sleep(due - now)
            else:
                with self._cond:
                    while self._changes == changes and (left := due - self.clock()) > 0:
                        self._cond.wait(left)
        elif now - due > 0.5:           # far behind (a slow tick): pace from here, no burst to catch up
            with self._cond:
                self._ref = (robot_time, now)
        return held


class SpeedMeter:
    """Robot time per wall time, measured over spans of at least a wall second."""

    def __init__(self) -> None:
        self._ref: tuple[float, float] | None = None

    def reset(self) -> None:
        """Start a new span at the next `update` (after a pause: the pause is no slowness)."""
        self._ref = None

    def update(self, t: float, now: float) -> float | None:
        """Robot time `t` [s] at wall time `now` [s]: the speed-up over the span that ends here when it
        lasted a second or more (a new span starts), else None."""
        if self._ref is None:
            self._ref = (t, now)
            return None
        t0, w0 = self._ref
        if now - w0 < 1.0:
            return None
        self._ref = (t, now)
        return (t - t0) / (now - w0)


def pacer_command(pacer: Pacer, hub: ViewHub, msg: dict[str, Any]) -> bool:
    """Apply a page's pause, resume, step or speed (value: `speed_value`'s: a number within MIN_SPEED..MAX_SPEED
    or "max") command to `pacer` and show it in `hub`'s status; whether `msg` was one of these (a speed out
    of range is refused: nothing changes; the server tells the page why, `command_problem`)."""
    cmd = msg.get("cmd")
    if cmd == "pause":
        pacer.pause()
        hub.set_status(state="paused")
    elif cmd == "step":
        pacer.step()
        hub.set_status(state="paused")
    elif cmd == "resume":
        pacer.resume()
        if hub.status.get("state") != "ended":
            hub.set_status(state="running")
    elif cmd == "speed":
        try:
            speed = speed_value(msg.get("value"))
        except ValueError:
            return True
        pacer.set_speed(speed)
        hub.set_status(speed=speed)
    else:
        return False
    return True


def new_path_points(path: Sequence[tuple[float, float]], start: int, end: int, last: tuple[float, float] | None,
                    spacing: float) -> tuple[list[float], tuple[float, float] | None]:
    """The points of `path[start:end]` at least `spacing` [m] from the one kept before (`last`, None: keep
    the first), as a flat list x, y, ... rounded to mm, and the last point kept."""
    out: list[float] = []
    for x, y in path[start:end]:
        if last is None or math.hypot(x - last[0], y - last[1]) >= spacing:
            out += [round(x, 3), round(y, 3)]
            last = (x, y)
    return out, last


class ViewObserver(RunObserver):
    """Feeds a `ViewHub` from a run and holds the run for the view's controls.

    Args:
        hub: where the frames go (its commands come back here).
        speed: robot time per wall time for a simulated run (None: as fast as it can).
        frame_rate, map_rate, overlay_rate: [1/s] most pose-and-laser frames, maps and overlays per
            wall second.
        clock: wall clock [s].
    """

    def __init__(self, hub: ViewHub, *, speed: float | None = DEFAULT_SPEED, frame_rate: float = 10.0,
                 map_rate: float = 4.0, overlay_rate: float = 2.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.hub = hub
        self.clock = clock
        self.pacer = Pacer(speed, clock=clock)
        self.frame_period, self.map_period, self.overlay_period = 1 / frame_rate, 1 / map_rate, 1 / overlay_rate
        self.run: ExplorationRun | None = None
        self.simulated = True
        self._stop_requested = False
        hub.on_command = self.command
        hub.set_status(speed=speed)
        self._reset()

    def _reset(self) -> None:
        self._next_frame = self._next_map = self._next_overlay = -math.inf
        self._map_dirty = True
        self._path_sent = 0
        self._last_xy: tuple[float, float] | None = None
        self._speed = SpeedMeter()
        self._pending_curve: list[float] = []
        self._coverage: float | None = None
        self._team_sent: list[tuple[int, tuple[float, float] | None]] = []    # robots 2, 3, ...: path kept

    # -- commands from the page (server thread) --
    def command(self, msg: dict[str, Any]) -> None:
        """Act on a page's command: pause, resume, step, stop, speed (value: a number or "max")."""
        if msg.get("cmd") == "stop":
            run = self.run
            if run is not None:
                run.request_stop(STOP_REASON, EndReason.STOPPED)
                self._stop_requested = True
            self.pacer.stop()
        elif msg.get("cmd") != "speed" or self.simulated:
            pacer_command(self.pacer, self.hub, msg)

    # -- the run (loop thread) --
    def on_start(self, run: ExplorationRun) -> None:
        """Tell the hub about the new run: its map geometry, robot and names."""
        from robotexp.sim import SimRobot

        self.run = run
        # a replayed recording (robotexp replay --view) keeps robot time too: it is paced like a simulator
        self.simulated = isinstance(run.robot, SimRobot) or getattr(run.robot, "replayed", False)
        self._reset()
        self._stop_requested = False        # a stop from the view ended the previous run (of a script), not this one
        self.pacer.stopped = False
        self.hub.controls = ("pause", "step", "stop", "speed") if self.simulated else ("pause", "step", "stop")
        self.hub.start(run_meta(run, self.simulated))
        self.hub.set_status(state="paused" if self.pacer.paused else "running",
                            speed=self.pacer.speed if self.simulated else 1.0)
        self._send(run, run.robot_time, force=True)

    def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
        """Send what is due, then hold or pace the loop."""
        if step.map_updated:
            self._map_dirty = True
        now = self.clock()
        if now >= self._next_frame:
            self._send(run, step.time)
        if self._stop_requested:
            return
        pacer = self.pacer
        if pacer.speed is None and not (pacer.paused or pacer.stopped):
            return                  # nothing to hold or pace
        # a simulated robot stands still while the loop waits; a real one is told to stop (and again
        # every halt_period) while paused
        halt = None if self.simulated else run.robot.stop
        pacer.wait(step.time if self.simulated else None, halt, lambda holding: self._hold(run, step.time, holding))

    def on_robot_step(self, run: ExplorationRun, robot: int, step: StepEvent) -> None:
        """A team's robot's tick: every robot's scan marks the map changed; the last robot still exploring
        sends and paces as `on_step` does, once every robot has stepped (a frame shows the team's whole tick,
        with its totals)."""
        if step.map_updated:
            self._map_dirty = True
        if ends_team_tick(run, robot):
            self.on_step(run, step)

    def _hold(self, run: ExplorationRun, t: float, holding: bool) -> None:
        if holding:
            self._send(run, t, force=True)
            self.hub.set_status(state="paused")
        else:
            self._speed.reset()
            if not self._stop_requested:
                self.hub.set_status(state="paused" if self.pacer.paused else "running")

    def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
        """Keep the coverage sample for the next frame."""
        if coverage is not None:
            self._pending_curve += [round(time, 3), round(coverage, 5)]
            self._coverage = coverage

    def on_end(self, run: ExplorationRun, record: RunRecord) -> None:
        """Send the final state and say why the run ended."""
        self._map_dirty = True
        self._send(run, run.robot_time, force=True)
        self.hub.finish(f"{record.end.value}: {record.reason}" if not record.reason.startswith(record.end.value)
                        else record.reason)

    def _send(self, run: ExplorationRun, t: float, force: bool = False) -> None:
        """Publish the state of `run` at robot time `t`: the pose, the scan (the hub makes its points
        when a browser takes them), the new path and curve points, and, while a browser watches (or
        with `force`), the map and overlays when due."""
        now = self.clock()
        self._next_frame = now + self.frame_period
        state = run.state
        frame = Frame(time=t)
        if state is not None:
            p = state.pose
            frame.pose = (p.x, p.y, p.theta)
            if state.laser is None:
                frame.laser = []
            else:
                frame.scan = state.laser
        frame.path = self._new_path(run)
        frame.team = self._teammates(run)
        frame.curve, self._pending_curve = self._pending_curve, []
        frame.coverage = self._coverage
        frame.speedup = self._speed.update(t, now)
        watched = force or self.hub.watched
        if watched and self._map_dirty and (force or now >= self._next_map):
            self._next_map = now + self.map_period
            self._map_dirty = False
            frame.map = classes_of_states(run.grid.states())
        if watched and (force or now >= self._next_overlay):
            self._next_overlay = now + self.overlay_period
            frame.overlays = _explorer_overlays(run)
        self.hub.publish(frame)

    def _teammates(self, run: ExplorationRun) -> list[tuple[tuple[float, float, float] | None, list[float]]] | None:
        """A team's robots 2, 3, ...: each one's pose and new path points (None for one robot)."""
        members = getattr(run, "members", None)
        if members is None or len(members) < 2:
            return None
        out: list[tuple[tuple[float, float, float] | None, list[float]]] = []
        for i, m in enumerate(members[1:]):
            if i == len(self._team_sent):
                self._team_sent.append((0, None))
            sent, last = self._team_sent[i]
            path = m.metrics.path
            points, last = new_path_points(path, sent, len(path), last, run.grid.geo.cell / 2)
            self._team_sent[i] = (len(path), last)
            s = m.state
            out.append((None if s is None else (s.pose.x, s.pose.y, s.pose.theta), points))
        return out

    def _new_path(self, run: ExplorationRun) -> list[float]:
        path = run.metrics.path
        out, self._last_xy = new_path_points(path, self._path_sent, len(path), self._last_xy, run.grid.geo.cell / 2)
        self._path_sent = len(path)
        return out


def run_meta(run: ExplorationRun, simulated: bool) -> dict[str, Any]:
    """What the view's page is told about a run when it starts (`ViewHub.start`): its map geometry,
    robot radius, names, time limit, whether coverage is known, the start pose, and a team's other robots
    (`team`: each one's model and radius; [] for one robot)."""
    geo = run.grid.geo
    info = run.info
    start = run.start_pose
    return {"geo": {"origin_x": geo.origin_x, "origin_y": geo.origin_y, "cell": geo.cell, "rows": geo.rows,
                    "cols": geo.cols},
            "radius": run.robot.radius, "title": f"{info.world} - {info.method}", "run": info.name,
            "method": info.method, "world": info.world, "robot": info.robot, "simulated": simulated,
            "max_time": run.max_time, "truth": run.truth is not None,
            "start": None if start is None else [start.x, start.y, start.theta],
            "team": [{"robot": m.robot.model, "radius": m.robot.radius}      # a team's robots 2, 3, ...
                     for m in getattr(run, "members", [])[1:]]}


def potential_levels(potential: npt.NDArray[np.float64], free: npt.NDArray[np.bool_]) -> npt.NDArray[np.uint8]:
    """A potential in [0, 1] (0 at the goals, 1 at obstacles) as levels 0..254 on the free cells (255 elsewhere):
    log10(1 - p) spread over its range on the free cells below 1, goals 0, the free cell farthest from them
    254 (as are free cells at 1, the inflation around obstacles).

    A harmonic potential (BVP) falls off exponentially from the goals: linear levels would paint nearly
    every free cell 1 (`render_map`'s overlay); the log scale shows where its gradient leads."""
    ok = free & np.isfinite(potential)
    out = np.full(potential.shape, 255, np.uint8)
    out[ok & (potential >= 1.0)] = 254            # free cells held at the obstacles' value (inflation)
    ok &= potential < 1.0
    if not ok.any():
        return out
    q = np.log10(np.clip(1.0 - potential[ok], 1e-300, 1.0))
    lo, hi = float(q.min()), float(q.max())
    out[ok] = np.round(254 * (hi - q) / (hi - lo)) if hi > lo else 0
    return out


def _explorer_overlays(run: ExplorationRun) -> dict[str, Any]:
    """The explorer's overlays for the view: `Explorer.overlays()` (potential as a quantized layer,
    vectors as arrows on a lattice) and `Explorer.markers()` (left out, with a warning, when malformed)."""
    out: dict[str, Any] = {}
    geo = run.grid.geo
    overlays = run.explorer.overlays()
    pot = overlays.get("potential")
    if pot is not None and pot.shape == (geo.rows, geo.cols):
        out["potential"] = MapLayer(encode_classes(potential_levels(pot, run.grid.free())), geo.rows, geo.cols)
    vec = overlays.get("vectors")
    if vec is not None and vec.shape == (geo.rows, geo.cols, 2):
        spacing, arrows = vector_arrows(vec, (geo.origin_x, geo.origin_y), geo.cell)
        out["vectors"] = {"spacing": spacing, "arrows": arrows}
    markers = run.explorer.markers()
    problem = markers_problem(markers)
    if problem is None:
        out.update(markers)
    else:
        log.warning("explorer %s: %s; its markers are not drawn", run.info.method or type(run.explorer).__name__,
                    problem)
    return out

"""Play a recording in the live view, with seeking (`robotexp replay BAG --view`).

The replay's results come first, from its own pass through the run loop at full speed
(`robotexp.bag.replay.replay_bag`), which also keeps `Checkpoints`: copies of the grid every few
seconds of robot time. `ReplayPlayer` then shows the recording on a `ViewHub`, tick by tick, paced
at the view's speed, with pause / step / speed like a run, and `seek`: {"cmd": "seek", "value": t}
(robot time [s], from the page's slider or time box, the websocket, or POST /command) jumps to the
last tick at or before t. The map at that tick is rebuilt by integrating the recorded scans from the
newest checkpoint at or before it (or from the start), the same scans in the same order as the
replay's pass, so it is the map the replay had at that tick; the path and coverage curve are the
replay's up to it, the explorer's markers the recorded ones newest then. A team's recording plays every
robot: its other robots' scans are integrated after robot 1's of the same tick (the run's order), and
their poses and paths shown too (the timeline is robot 1's). Results are never touched
by what the page does. When the recording ends, the page keeps its last state; a seek plays on from
there. Ctrl-C ends the player.
"""

from __future__ import annotations

import bisect
import math
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from robotexp.mapping.grid import OccupancyGrid
from robotexp.run.observers import RunObserver, StepEvent
from robotexp.view.feed import Frame, ViewHub, classes_of_states
from robotexp.view.feed import DEFAULT_SPEED
from robotexp.view.observer import STOP_REASON, Pacer, SpeedMeter, new_path_points, pacer_command, run_meta

if TYPE_CHECKING:
    from robotexp.bag.replay import Bag
    from robotexp.run.loop import ExplorationRun

__all__ = ["Checkpoints", "ReplayPlayer", "checkpoint_every"]

CHECKPOINT_BYTES = 256e6    # most memory the checkpoints of one replay take


def checkpoint_every(duration: float, cells: int, budget: float = CHECKPOINT_BYTES) -> float:
    """[s] robot time between checkpoints of a `duration` [s] recording on a grid of `cells` cells: every
    10 s, or a 60th of the recording when longer, or farther apart when `budget` bytes would not hold
    them (a cell takes at most 8 bytes: its value and its scan stamp)."""
    most = max(1, int(budget // (8 * max(cells, 1))))
    return max(10.0, duration / 60.0, duration / most)


class Checkpoints(RunObserver):
    """Copies of a run's grid at the first tick at or after every `every` seconds of robot time.

    Args:
        every: [s] robot time between copies; None: `checkpoint_every(duration, cells of the run's grid)`.
        duration: [s] the recording's length (with `every` None).
    """

    def __init__(self, every: float | None = None, *, duration: float = 0.0) -> None:
        if every is not None and not every > 0:
            raise ValueError(f"checkpoint spacing must be > 0 s, got {every}")
        self.every = every or 10.0
        self._auto = every is None
        self.duration = duration
        self.items: list[tuple[float, OccupancyGrid]] = []     # (robot time of the tick, grid after it)
        self._next = self.every

    def on_start(self, run: ExplorationRun) -> None:
        """Choose the spacing from the grid's size when asked to."""
        if self._auto:
            self.every = checkpoint_every(self.duration, run.grid.geo.rows * run.grid.geo.cols)
        self.items, self._next = [], self.every

    def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
        """Keep a copy of the grid when one is due."""
        self._keep(run, step.time)

    def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
        """A team's replay (it has no `on_step`): keep a copy of the team's grid when one is due, at a coverage
        sample, where every robot has taken its scan of that tick."""
        if getattr(run, "members", None) is not None:
            self._keep(run, time)

    def _keep(self, run: ExplorationRun, t: float) -> None:
        if t >= self._next - 1e-9:
            self.items.append((t, run.grid.copy()))
            while self._next <= t + 1e-9:
                self._next += self.every


class ReplayPlayer:
    """Shows a recording on `hub`, paced, with pause, step, speed, stop and seek.

    Args:
        hub: the view's state (its commands come here).
        bag: the recording.
        run: the replay's pass over it (`replay_bag`): its grid's geometry and model, path, coverage curve.
        checkpoints: kept on that pass (None: every seek rebuilds from the start).
        speed: robot time per wall time (None: as fast as it goes).
        frame_rate, map_rate: [1/s] most frames and maps per wall second.
        clock: wall clock [s].
    """

    def __init__(self, hub: ViewHub, bag: Bag, run: ExplorationRun, checkpoints: Checkpoints | None = None, *,
                 speed: float | None = DEFAULT_SPEED, frame_rate: float = 10.0, map_rate: float = 4.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.hub, self.ticks, self.run = hub, bag.ticks, run
        self.times = [t.time for t in self.ticks]
        self.duration = self.times[-1]
        self.markers = bag.markers
        self._marker_times = [t for t, _ in bag.markers]
        self.checkpoints = checkpoints.items if checkpoints is not None else []
        self._checkpoint_times = [t for t, _ in self.checkpoints]
        self.clock = clock
        self.pacer = Pacer(speed, clock=clock)
        self.frame_period, self.map_period = 1 / frame_rate, 1 / map_rate
        g = run.grid
        self._blank = OccupancyGrid(g.geo, model=g.model, range_max=g.range_max)
        self.grid = self._blank.copy()
        self.i = 0                          # ticks integrated into `grid`
        # a team's recording: robots 2, 3, ... (their ticks, how many are integrated, their paths in the replay)
        self.team = bag.team[1:]
        self._team_times = [[t.time for t in ticks] for ticks in self.team]
        self.team_i = [0] * len(self.team)
        self._team_paths = [m.metrics.path for m in getattr(run, "members", [])[1:]]
        self.seeks = 0
        self._seek: float | None = None
        self._lock = threading.Lock()
        self._idle = threading.Event()
        self._stopped = False
        self._ended = False
        reason = run.reason or "end of the recording"
        self.end_reason = f"end of the recording ({reason})"
        hub.controls = ("pause", "step", "stop", "speed", "seek")
        hub.on_command = self.command
        self._reset_sent()

    def _reset_sent(self) -> None:
        self._team_sent: list[tuple[int, tuple[float, float] | None]] = [(0, None) for _ in self.team]
        self._path_sent = 0
        self._last_xy: tuple[float, float] | None = None
        self._curve_sent = 0
        self._coverage: float | None = None
        self._marker_index = -2
        self._next_frame = self._next_map = -math.inf
        self._map_dirty = True
        self._speed = SpeedMeter()

    # -- commands (server thread) --
    def command(self, msg: dict[str, Any]) -> None:
        """pause, resume, step, stop, speed (a number or "max"), seek (robot time [s])."""
        cmd = msg.get("cmd")
        if pacer_command(self.pacer, self.hub, msg):
            if cmd == "resume":
                self._idle.set()
        elif cmd == "stop":
            self._stopped = True
            self.pacer.stop()
            self._idle.set()
        elif cmd == "seek":
            try:
                t = float(msg.get("value"))  # type: ignore[arg-type]
            except (TypeError, ValueError):
                return
            if not math.isfinite(t):
                return
            with self._lock:
                self._seek = min(max(t, 0.0), self.duration)
            self.pacer.wake()
            self._idle.set()

    def _take_seek(self) -> float | None:
        with self._lock:
            t, self._seek = self._seek, None
        return t

    # -- playing (the caller's thread) --
    def play(self, until: Callable[[], bool] = lambda: False) -> None:
        """Play until `until()` is true (checked at least twice a second) or Ctrl-C (KeyboardInterrupt)."""
        meta = run_meta(self.run, True)
        self.hub.start({**meta, "title": f"{meta['title']} (replay)", "duration": self.duration, "replay": True})
        self.hub.set_status(state="paused" if self.pacer.paused else "running", speed=self.pacer.speed)
        self._send(0.0, force=True)
        n = len(self.ticks)
        while not until():
            seek = self._take_seek()
            if seek is not None:
                self.seek_to(seek)
                continue
            if self.i >= n or self._stopped:
                if not self._ended:
                    self._ended = True
                    self._send(self.times[max(self.i - 1, 0)], force=True)
                    self.hub.finish(STOP_REASON if self._stopped else self.end_reason)
                self._idle.wait(0.5)
                self._idle.clear()
                continue
            tick_time = self.times[self.i]
            self.pacer.wait(tick_time, None, self._hold)
            if self._seek is not None or self._stopped:
                continue
            self._advance()
            if self.clock() >= self._next_frame:
                self._send(tick_time)

    def _hold(self, holding: bool) -> None:
        if holding:
            self._send(self.times[max(self.i - 1, 0)], force=True)
            self.hub.set_status(state="paused")
        else:
            self._speed.reset()
            if not self._stopped and self._seek is None:
                self.hub.set_status(state="paused" if self.pacer.paused else "running")

    def _advance(self) -> None:
        """Integrate the next tick's scan (a team's: then the scans of its other robots at that tick, in the
        robots' order, as the run took them)."""
        tick = self.ticks[self.i]
        if tick.scan is not None:
            self.grid.update(tick.pose, tick.scan)
            self._map_dirty = True
        self.i += 1
        for j, ticks in enumerate(self.team):
            while self.team_i[j] < len(ticks) and ticks[self.team_i[j]].time <= tick.time + 1e-9:
                other = ticks[self.team_i[j]]
                if other.scan is not None:
                    self.grid.update(other.pose, other.scan)
                    self._map_dirty = True
                self.team_i[j] += 1

    def seek_to(self, t: float) -> None:
        """Show the recording at the last tick at or before robot time `t` [s]: the map rebuilt (from here
        when `t` is ahead, else from the newest checkpoint at or before it), path and curve up to it."""
        self.pacer.unwake()
        k = max(bisect.bisect_right(self.times, t + 1e-9) - 1, 0)
        if k < self.i - 1:          # back in time: from a checkpoint, or from the start
            c = bisect.bisect_right(self._checkpoint_times, self.times[k] + 1e-9) - 1
            if c >= 0:
                ct, grid = self.checkpoints[c]
                self.grid = grid.copy()
                self.i = bisect.bisect_right(self.times, ct + 1e-9)
                self.team_i = [bisect.bisect_right(times, ct + 1e-9) for times in self._team_times]
            else:
                self.grid, self.i = self._blank.copy(), 0
                self.team_i = [0] * len(self.team)
        while self.i <= k:
            self._advance()
        self.seeks += 1
        self._stopped = self._ended = False
        self.pacer.stopped = False
        self.pacer.set_speed(self.pacer.speed)     # pacing starts afresh from here
        self.hub.restart(self.times[k])
        self._reset_sent()
        self._send(self.times[k], force=True)
        self.hub.set_status(state="paused" if self.pacer.paused else "running", reason="")

    def _send(self, t: float, force: bool = False) -> None:
        """Publish the state at robot time `t` (the tick read last): pose, scan, new path and curve
        points, and the map (when due, watched or `force`) and markers (when they changed)."""
        now = self.clock()
        self._next_frame = now + self.frame_period
        frame = Frame(time=t)
        if self.i > 0:
            tick = self.ticks[self.i - 1]
            frame.pose = (tick.pose.x, tick.pose.y, tick.pose.theta)
            if tick.scan is not None:
                frame.scan = tick.scan
            else:
                frame.laser = []
        frame.path = self._new_path()
        frame.team = self._teammates() if self.team else None
        frame.curve = self._new_curve(t)
        frame.coverage = self._coverage
        frame.speedup = self._speed.update(t, now)
        if self._map_dirty and (force or (self.hub.watched and now >= self._next_map)):
            self._next_map = now + self.map_period
            self._map_dirty = False
            frame.map = classes_of_states(self.grid.states())
        m = bisect.bisect_right(self._marker_times, t + 1e-9) - 1
        if m != self._marker_index:
            self._marker_index = m
            frame.overlays = dict(self.markers[m][1]) if m >= 0 else {}
        self.hub.publish(frame)

    def _new_path(self) -> list[float]:
        path = self.run.metrics.path
        end = min(self.i, len(path))
        out, self._last_xy = new_path_points(path, self._path_sent, end, self._last_xy, self.run.grid.geo.cell / 2)
        self._path_sent = max(end, self._path_sent)
        return out

    def _teammates(self) -> list[tuple[tuple[float, float, float] | None, list[float]]]:
        """A team's robots 2, 3, ... at the ticks integrated: each one's pose and new path points."""
        out: list[tuple[tuple[float, float, float] | None, list[float]]] = []
        for j, ticks in enumerate(self.team):
            k = self.team_i[j]
            p = ticks[k - 1].pose if k > 0 else None
            path = self._team_paths[j] if j < len(self._team_paths) else []
            sent, last = self._team_sent[j]
            end = min(k, len(path))
            points, last = new_path_points(path, sent, end, last, self.run.grid.geo.cell / 2)
            self._team_sent[j] = (max(end, sent), last)
            out.append((None if p is None else (p.x, p.y, p.theta), points))
        return out

    def _new_curve(self, t: float) -> list[float]:
        curve = self.run.metrics.curve
        out: list[float] = []
        while self._curve_sent < len(curve) and curve[self._curve_sent][0] <= t + 1e-9:
            ct, _, cov = curve[self._curve_sent]
            self._curve_sent += 1
            if cov >= 0:
                out += [round(ct, 3), round(cov, 5)]
                self._coverage = cov
        return out

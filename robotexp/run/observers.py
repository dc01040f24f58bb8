"""Run observers: what the run loop tells about a run while it goes, and to whom.

`ExplorationRun` calls each observer's hooks in the order the observers were given:

    on_start(run)            once, after the explorer's reset, before the first step
    on_step(run, step)       every control tick: the state read, whether the map took its scan,
                             and the decision (a Twist sent, a Done, or None when the run ends at
                             this tick without deciding: time limit, stop requested)
    on_robot_step(run, i, step)  a team run (`robotexp.run.team.TeamRun`): every control tick of its
                             robot `i` (0-based), in the robots' order; a team run has no `on_step`
    on_sample(run, t, cov)   every coverage sample (1 s of robot time by default, and once at the end)
    on_end(run, record)      once, after the robot was stopped, with the run's `RunRecord`

Subclass `RunObserver` and override the hooks you need (each is a no-op here; the loop builds a
`StepEvent` only when some observer overrides `on_step`). An observer may call
`run.request_stop(reason, end)` to end the run at the next tick (a view's stop button, a stall
watch, a script's timeout). Observers run in the loop's thread; a slow observer slows the run (a
simulated run keeps its results: robot time does not pass while an observer works).

Errors: an observer that raises (an `Exception`; Ctrl-C is not caught) is logged with its
traceback and detached: it gets no further calls in this run, the run goes on, the robot is stopped
at its end as always and every other observer gets every call, `on_end` included. The error is
kept in `run.observer_errors`. An observer with `critical = True` (the results writer: a record
that cannot be written must not pass silently) has its error raised again by the caller of the run
(`robotexp.experiment.run_on_robot`) once the run has ended and every observer had its `on_end`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from robotexp.errors import RobotexpError, raise_interrupt_in
from robotexp.robot import RobotState, Twist

if TYPE_CHECKING:
    from robotexp.explorer import Done
    from robotexp.run.loop import ExplorationRun
    from robotexp.run.record import RunRecord

__all__ = ["RunObserver", "StepEvent", "SampleCallback", "Observers", "ends_team_tick"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StepEvent:
    """One control tick as the loop saw it."""

    time: float                        # [s] robot time since the run started
    state: RobotState                  # what the robot reported at this tick
    map_updated: bool                  # the grid integrated this state's laser scan
    decision: Twist | Done | None      # the command sent (clamped later by the robot), Done, or None


class RunObserver:
    """Base class of run observers: every hook does nothing; override the ones you need."""

    critical: ClassVar[bool] = False   # the caller re-raises this observer's error after the run

    def on_start(self, run: ExplorationRun) -> None:
        """The run starts: the explorer is reset, `run.start_pose` and `run.state` are set."""

    def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
        """One control tick (see `StepEvent`)."""

    def on_robot_step(self, run: ExplorationRun, robot: int, step: StepEvent) -> None:
        """One control tick of robot `robot` (0-based) of a team run (`run` is the `TeamRun`)."""

    def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
        """A coverage sample: robot time [s] and coverage (None without ground truth)."""

    def on_end(self, run: ExplorationRun, record: RunRecord) -> None:
        """The run ended and the robot was stopped; `record` is its result (`run.record` too)."""


def ends_team_tick(run: ExplorationRun, robot: int) -> bool:
    """Whether robot `robot`'s step ends its team's tick (`on_robot_step`): the last robot still exploring steps
    last, so every robot has stepped at that time and the team's totals are the tick's. True outside a team."""
    active = getattr(run, "active", None)
    return not active or robot == active[-1]


class SampleCallback(RunObserver):
    """An observer from the callbacks of old: `on_sample(t, cov)` and `on_run(run)` after each sample."""

    def __init__(self, on_sample: Callable[[float, float | None], None] | None = None,
                 on_run: Callable[[ExplorationRun], None] | None = None) -> None:
        self.sample_cb, self.run_cb = on_sample, on_run

    def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
        """Call `on_sample(time, coverage)`, then `on_run(run)`."""
        if self.sample_cb is not None:
            self.sample_cb(time, coverage)
        if self.run_cb is not None:
            self.run_cb(run)


class Observers:
    """The observers of one run, called in order; one that raises is logged and detached."""

    def __init__(self, observers: Iterable[RunObserver] = ()) -> None:
        self.active: list[RunObserver] = list(observers)
        self.errors: list[tuple[RunObserver, Exception]] = []
        self._listening: dict[str, bool] = {}

    def add(self, observer: RunObserver) -> None:
        """Append `observer`."""
        self.active.append(observer)
        self._listening.clear()

    def listening(self, hook: str) -> bool:
        """True when an attached observer overrides `hook` (the loop skips building what nobody reads)."""
        known = self._listening.get(hook)
        if known is None:
            base = getattr(RunObserver, hook)
            known = self._listening[hook] = any(getattr(type(o), hook, base) is not base for o in self.active)
        return known

    def notify(self, hook: str, *args: Any) -> None:
        """Call `hook` of every attached observer with `args`."""
        for observer in list(self.active):
            try:
                getattr(observer, hook)(*args)
            except Exception as exc:
                raise_interrupt_in(exc)     # Ctrl-C inside a numba kernel's call: the run is interrupted
                # a critical observer's error is raised by the run's caller as one line (a full disk): at
                # debug level only; any other is logged as one line, its traceback with --debug, or always when
                # it is not one of robotexp's own errors (a bug)
                expected = getattr(observer, "critical", False) and isinstance(exc, (OSError, RobotexpError))
                log.log(logging.DEBUG if expected else logging.ERROR,
                        "run observer %s raised in %s (detached for the rest of the run): %s: %s",
                        type(observer).__name__, hook, type(exc).__name__, exc,
                        exc_info=log.isEnabledFor(logging.DEBUG))
                self.errors.append((observer, exc))
                self.active.remove(observer)
                self._listening.clear()

    def end(self, run: ExplorationRun, record: RunRecord) -> None:
        """`on_end` of every observer still attached."""
        self.notify("on_end", run, record)

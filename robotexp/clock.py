"""Clocks for the control loop: a stepped clock for simulators and a wall clock for real robots."""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable

from robotexp.errors import RobotError

__all__ = ["Clock", "SimClock", "WallClock", "PacedClock", "TeamClock"]


class Clock(ABC):
    """Paces the control loop at a fixed `period` [s] and tells the robot time [s]."""

    def __init__(self, period: float) -> None:
        self.period = period

    @abstractmethod
    def now(self) -> float:
        """Robot time [s] since the clock started."""

    @abstractmethod
    def tick(self) -> None:
        """Let one period pass (advance the simulator, or sleep until the next period)."""


class SimClock(Clock):
    """A stepped clock: each tick advances the simulated world by exactly `period`.

    Runs are deterministic for a seed and go as fast as the CPU allows.
    """

    def __init__(self, period: float, advance: Callable[[float], None]) -> None:
        super().__init__(period)
        self._advance = advance
        self._ticks = 0

    def now(self) -> float:
        return self._ticks * self.period

    def tick(self) -> None:
        self._advance(self.period)
        self._ticks += 1


class WallClock(Clock):
    """Real time: each tick sleeps until the next multiple of `period` (skipping missed ones)."""

    def __init__(self, period: float) -> None:
        super().__init__(period)
        self._start = time.monotonic()
        self._next = self._start + period

    def now(self) -> float:
        return time.monotonic() - self._start

    def tick(self) -> None:
        now = time.monotonic()
        if self._next > now:
            time.sleep(self._next - now)
        else:       # we are late: do not try to catch up with a burst of ticks
            self._next = now
        self._next += self.period


class PacedClock(Clock):
    """Robot-paced: each tick waits for the robot's state packets covering one more `period`.

    `now()` is robot time (packets received x the robot's cycle), so one control loop runs in real
    time on a real robot and faster than real time against an emulator running with a speed-up.

    Args:
        period: control period [s].
        wait_until: blocks until the robot's time [s] reaches the given value and returns it
            (raising the backend's error when the robot falls silent).
        start: robot time [s] when the clock starts.
    """

    def __init__(self, period: float, wait_until: Callable[[float], float], start: float = 0.0) -> None:
        super().__init__(period)
        self._wait_until = wait_until
        self._start = start
        self._time = start

    def now(self) -> float:
        return self._time - self._start

    def tick(self) -> None:
        self._time = self._wait_until(self._time + self.period)


class TeamClock(Clock):
    """The clock of a team of robots with clocks of their own (robots over their drivers): a tick lets one
    `period` pass on every robot's clock, in turn (each waits for its own robot's time), so no robot is
    read before its time has moved on by a period; `now()` is the first robot's.

    Args:
        clocks: one clock per robot (`Robot.make_clock(period)`), of the same period.
    """

    def __init__(self, clocks: list[Clock]) -> None:
        if not clocks:
            raise ValueError("a team clock needs one clock per robot")
        super().__init__(clocks[0].period)
        self.clocks = list(clocks)

    def now(self) -> float:
        return self.clocks[0].now()

    def tick(self) -> None:
        """A period on every robot's clock; a robot whose clock fails (its link lost: RobotError) is named."""
        for i, clock in enumerate(self.clocks):
            try:
                clock.tick()
            except RobotError as exc:
                raise RobotError(f"robot {i + 1}: {exc}") from exc

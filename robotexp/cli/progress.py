"""The progress line of a run or a campaign on the terminal (a run observer)."""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from robotexp.run.observers import RunObserver

__all__ = ["Progress"]

class Progress(RunObserver):
    """Progress of a run on stderr: on a terminal one line redrawn at each coverage sample (coverage,
    robot time, wall time and, at the run's speed so far, the wall time left until its time limit at
    most; "no gain for N s" once coverage stopped growing); without a terminal one line a minute (logs).
    A run observer (`on_sample`), or called as `progress(t, coverage)`.

    Args:
        label: what the line starts with (None: the world and method of each run, at its start).
        enabled: redraw one line (default: whether stderr is a terminal); False: a line every `every` s.
        every: [s] wall time between lines without a terminal.
        clock: wall clock [s].
        notice: a line said on stderr when the run starts.
        say_start: say where the run starts (its pose's name; why, for a default start) on stderr.
    """

    STALL = 60.0        # [s] robot time without a coverage gain of GAIN before "no gain" is said
    GAIN = 0.001        # coverage

    def __init__(self, label: str | None, enabled: bool | None = None, every: float = 60.0,
                 clock: Callable[[], float] | None = None, notice: str | None = None,
                 say_start: bool = False) -> None:
        import time

        self.fixed = label
        self.label = label or ""
        self.notice = notice
        self.say_start = say_start
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.shown = False
        self.every = every
        self.clock = clock or time.monotonic
        self.wall0 = self.clock()
        self.next_line = self.wall0 + every
        self.max_time: float | None = None
        self.best = (-1.0, 0.0)         # (coverage, robot time it was reached)

    def on_start(self, run: Any) -> None:
        """Say the notice, note the run's time limit and start the wall clock."""
        if self.notice:
            click.echo(self.notice, err=True)
        if self.say_start:
            click.echo(f"robotexp: {_start_line(run)}", err=True)
        self.max_time = run.max_time
        self.wall0 = self.clock()
        self.next_line = self.wall0 + self.every
        self.best = (-1.0, 0.0)
        if self.fixed is None:
            self.label = f"{Path(run.info.world or '').stem} {run.info.method}".strip()

    def on_end(self, run: Any, record: Any) -> None:
        """End the run's line (the next run of a script starts its own)."""
        self.close()

    def on_sample(self, run: Any, time: float, coverage: float | None) -> None:
        """Show the sample."""
        self(time, coverage)

    def line(self, t: float, coverage: float | None) -> str:
        """The progress text at robot time `t` [s] with `coverage` (None: unknown)."""
        wall = self.clock() - self.wall0
        parts = [self.label]
        if coverage is not None:
            width = 30
            done = int(round(coverage * width))
            parts.append(f"[{'#' * done}{'-' * (width - done)}] {coverage * 100:5.1f}%")
            if coverage > self.best[0] + self.GAIN:
                self.best = (coverage, t)
            elif t - self.best[1] >= self.STALL:
                parts.append(f"no gain for {t - self.best[1]:.0f} s")
        parts.append(f"robot time {t:7.0f} s, wall {wall:5.0f} s")
        if self.max_time is not None and t > 0 and wall > 1.0:
            left = max(0.0, (self.max_time - t) * wall / t)     # a run's last sample may pass its limit
            parts.append(f"<= {round(left):d} s left (time limit)")
        return "  ".join(parts)

    def __call__(self, t: float, coverage: float | None) -> None:
        text = self.line(t, coverage)
        if self.enabled:
            click.echo(f"\r{text}\033[K", nl=False, err=True)
            self.shown = True
        elif self.clock() >= self.next_line:
            self.next_line = self.clock() + self.every
            click.echo(text, err=True)

    def close(self) -> None:
        """End the progress line."""
        if self.shown:
            click.echo("", err=True)
            self.shown = False


def _start_line(run: Any) -> str:
    """Where a run starts, with its pose's name (and, for the default start, why it lies there)."""
    from robotexp.world.start import chosen_start

    p = run.start_pose
    label = getattr(run.info, "pose", None)
    line = f"start {label or 'pose'!s}: ({p.x:.2f}, {p.y:.2f}) m, heading {math.degrees(p.theta):.0f} deg"
    choice = chosen_start(run.info.world) if label == "centre" else None
    if choice is not None and choice.pose.x == p.x and choice.pose.y == p.y:
        line += f" ({choice.describe()})"
    return line

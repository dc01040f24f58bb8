"""Shared fixtures: every test must close the robots it opens."""

from __future__ import annotations

import functools
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import os

import pytest
from hypothesis import settings

from robotexp.robot import Robot

# CI runs the property tests with a fixed seed, so a submission's result does not depend on luck;
# developers' runs keep exploring new examples (set HYPOTHESIS_PROFILE=ci to reproduce CI).
settings.register_profile("ci", derandomize=True, database=None)
if os.environ.get("CI") or os.environ.get("HYPOTHESIS_PROFILE") == "ci":
    settings.load_profile("ci")

pytest_plugins = ["pytester"]

# Robots opened during the current test. Strong references on purpose: a robot dropped without
# close() keeps its link (a pybullet client, a serial port) alive, and must still be found.
_OPENED: list[Robot] = []
_original_init = Robot.__init__


@functools.wraps(_original_init)
def _tracking_init(self: Robot, *args: Any, **kwargs: Any) -> None:
    _original_init(self, *args, **kwargs)
    _OPENED.append(self)        # backends call Robot.__init__ last, once their link is up


Robot.__init__ = _tracking_init  # type: ignore[method-assign]


@pytest.fixture(autouse=True)
def _robots_closed() -> Iterator[None]:
    """Fail the test when it leaves a robot (SimRobot or any backend) open."""
    _OPENED.clear()
    yield
    leaked = [r for r in _OPENED if not r.closed]
    _OPENED.clear()
    for robot in leaked:        # clean up so one leak does not spill into the next tests
        robot.close()
    if leaked:
        names = ", ".join(f"{type(r).__name__}({r.name})" for r in leaked)
        pytest.fail(f"the test left {len(leaked)} robot(s) open: {names}; close them (use `with`)")


class ViewCli:
    """`python -m robotexp.cli ARGS` processes that serve a live view (--view), for end-to-end tests."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen[str]] = []

    def start(self, *args: str, first: bool = True) -> tuple[subprocess.Popen[str], str]:
        """Start the command; returns it and the page's URL, read from its line "view: URL" (its first
        line, unless `first` is False)."""
        proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", *args], stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        self.procs.append(proc)
        assert proc.stdout is not None
        while True:
            line = proc.stdout.readline()
            assert line, "the command ended without serving its view"
            match = re.fullmatch(r"view: (http://127\.0\.0\.1:\d+/)\n", line)
            assert match or not first, f"expected 'view: URL' first, got {line!r}"
            if match:
                return proc, match.group(1)

    @staticmethod
    def interrupt(proc: subprocess.Popen[str]) -> str:
        """Ctrl-C the command (the view ends); returns the rest of its output after checking it exited 0."""
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=20)
        assert proc.returncode == 0, rest
        return rest


@pytest.fixture
def view_cli() -> Iterator[ViewCli]:
    """Start live-view commands; any still running at the end of the test is killed."""
    cli = ViewCli()
    yield cli
    for proc in cli.procs:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()

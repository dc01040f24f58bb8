"""Shared fixtures: every test must close the robots it opens."""

from __future__ import annotations

import functools
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

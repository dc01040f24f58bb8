"""What the laser tests share: a scan source with known answers (a box room around the sensor) and
timing a laser's failure."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConnectionLost
from robotexp.laser import Laser


class BoxSource:
    """The sensor at the origin of an axis-aligned box room [xmin, xmax] x [ymin, ymax] (metres, xmin < 0 <
    xmax, ymin < 0 < ymax): the range of each beam is where it leaves the box, inf beyond `reach`.
    `calls` counts the measurements."""

    def __init__(self, xmin: float = -1.5, xmax: float = 2.5, ymin: float = -0.8, ymax: float = 3.2) -> None:
        self.box = (xmin, xmax, ymin, ymax)
        self.calls = 0

    def ranges(self, angles: npt.NDArray[np.float64], reach: float = math.inf) -> npt.NDArray[np.float64]:
        """The exact ranges [m] along `angles` [rad]."""
        xmin, xmax, ymin, ymax = self.box
        c, s = np.cos(angles), np.sin(angles)
        with np.errstate(divide="ignore", invalid="ignore"):
            tx = np.where(c > 1e-12, xmax / c, np.where(c < -1e-12, xmin / c, np.inf))
            ty = np.where(s > 1e-12, ymax / s, np.where(s < -1e-12, ymin / s, np.inf))
        r = np.minimum(tx, ty)
        return np.where(r <= reach, r, np.inf)

    def __call__(self, angles: npt.NDArray[np.float64], reach: float) -> npt.NDArray[np.float64]:
        self.calls += 1
        return self.ranges(np.asarray(angles, np.float64), reach)


def seconds_until_lost(laser: Laser, fault: Callable[[], None], limit: float = 3.0, cpu_wait: Any = None) -> float:
    """Take scans from `laser`, call `fault()` (e.g. close its emulator), and return how long [s] it
    took `wait_scan` to raise ConnectionLost (AssertionError when it did not within `limit` s), less what
    the threads waited for a CPU meanwhile when given the `cpu_wait` fixture (a loaded machine's share)."""
    seq = laser.wait_scan(-1, 10.0).seq
    t0 = time.monotonic()
    mark = cpu_wait.total() if cpu_wait is not None else 0.0
    fault()
    while time.monotonic() - t0 < limit:
        try:
            seq = laser.wait_scan(seq, limit).seq
        except ConnectionLost:
            took = time.monotonic() - t0
            return took - cpu_wait.since(mark) if cpu_wait is not None else took
    raise AssertionError(f"{laser.name}: no ConnectionLost within {limit} s of the fault")

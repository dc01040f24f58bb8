"""Laser rangefinders as devices of their own: the contract every laser driver implements.

A real P3-DX carries a SICK LMS200 on a serial port of its own, a Kobuki carries none and a rover
gets whatever is bolted on: a laser is a device beside the robot, found through the entry-point
group `robotexp.lasers` (driver classes, subclasses of `Laser`) and `robotexp.laser_emulators`
(emulators that serve the same protocol from a simulated world, see `LaserEmulator`).

A laser reports scans in its own frame: beam angle 0 is the sensor's forward direction, angles grow
counter-clockwise, ranges in metres with `inf` for a beam that saw no echo within `range_max`.
Each scan is stamped with the host's monotonic clock (`time.monotonic()`) when it was complete, so
that whoever pairs it with a robot pose can interpolate the robot's state at that time. Where the
scan is mounted on the robot (`mount`, a `Pose` in the robot frame) is the caller's business.
"""

from __future__ import annotations

import bisect
import math
import threading
import time
from abc import ABC, abstractmethod
from collections import deque
from dataclasses import dataclass
from typing import ClassVar, Protocol, Self

import numpy as np
import numpy.typing as npt

from robotexp.robot import LaserScan, Pose, wrap_angle

__all__ = ["LASERS", "LASER_EMULATORS", "LaserGeometry", "StampedScan", "Laser", "ScanSource", "LaserEmulator",
           "PoseHistory", "scan_in_robot_frame"]


class PoseHistory:
    """The robot's poses at host times, for the pose at any time between them.

    Args:
        maxlen: how many (time, pose) samples to keep.
    """

    def __init__(self, maxlen: int = 2048) -> None:
        self._t: deque[float] = deque(maxlen=maxlen)
        self._p: deque[Pose] = deque(maxlen=maxlen)
        self._lock = threading.Lock()           # added to by a reader thread, read by the control loop
        self._floor = -math.inf                 # poses at or before this time are from before `clear`

    def add(self, t: float, pose: Pose) -> None:
        """Record `pose` at host time `t` [s]; a time not after the last one (or not after the last
        `clear`) replaces nothing and is dropped."""
        with self._lock:
            if t <= self._floor or self._t and t <= self._t[-1]:
                return
            self._t.append(t)
            self._p.append(pose)

    def clear(self) -> None:
        """Forget every pose (odometry jumped) and refuse any stamped before now."""
        with self._lock:
            self._floor = time.monotonic()
            self._t.clear()
            self._p.clear()

    def oldest(self) -> Pose | None:
        """The first pose kept (None when empty)."""
        with self._lock:
            return self._p[0] if self._p else None

    def at(self, t: float) -> Pose | None:
        """The pose at host time `t`: linear between the samples around it (the heading along the
        shorter arc), the newest pose after the last sample; None before the first or when empty."""
        with self._lock:
            if not self._t or t < self._t[0]:
                return None
            i = bisect.bisect_right(self._t, t)
            if i >= len(self._t):
                return self._p[-1]
            t0, t1 = self._t[i - 1], self._t[i]
            p0, p1 = self._p[i - 1], self._p[i]
        f = (t - t0) / (t1 - t0)
        return Pose(p0.x + f * (p1.x - p0.x), p0.y + f * (p1.y - p0.y),
                    wrap_angle(p0.theta + f * wrap_angle(p1.theta - p0.theta)))

    def samples(self) -> tuple[list[float], list[Pose]]:
        """A copy of the (times, poses) kept, oldest first."""
        with self._lock:
            return list(self._t), list(self._p)


def _poses_at(history: PoseHistory, ts: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], ...] | None:
    """(x, y, theta) arrays of the poses at host times `ts` (clamped to the history's span: before the
    first sample the first pose), interpolated as `PoseHistory.at`; None when the history is empty."""
    times, poses = history.samples()
    if not times:
        return None
    t = np.asarray(times, np.float64)
    x = np.fromiter((p.x for p in poses), np.float64, len(poses))
    y = np.fromiter((p.y for p in poses), np.float64, len(poses))
    th = np.unwrap(np.fromiter((p.theta for p in poses), np.float64, len(poses)))
    if t.size == 1:
        return np.full(ts.shape, x[0]), np.full(ts.shape, y[0]), np.full(ts.shape, th[0])
    return np.interp(ts, t, x), np.interp(ts, t, y), np.interp(ts, t, th)


def _compose(a: Pose, b: Pose) -> Pose:
    """`b` (in `a`'s frame) in the frame `a` is given in."""
    c, s = math.cos(a.theta), math.sin(a.theta)
    return Pose(a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, wrap_angle(a.theta + b.theta))


def scan_in_robot_frame(scan: LaserScan, sensor: Pose, robot: Pose,
                        beam_sensors: tuple[npt.NDArray[np.float64], ...] | None = None) -> LaserScan:
    """A scan taken in the sensor frame with the sensor at world pose `sensor`, as the robot at world
    pose `robot` sees it: `offset_x` is the sensor's position along the robot's heading, each echo
    lands exactly where it was (angle and range from that point), beams without echo (inf, NaN, or
    at `range_max` and beyond) keep their direction and range. The sensor's sideways offset from
    the robot's axis is not representable in a `LaserScan`: echoes stay exact, the rays towards them
    start up to that offset away (a few millimetres for a laser on the robot's axis).

    `beam_sensors` = (x, y, theta) arrays, one per beam: where the sensor was when it measured each
    beam (a turning laser measures its beams one after the other while the robot moves); the echoes
    are placed from those, the rays start from `sensor`.
    """
    c, s = math.cos(robot.theta), math.sin(robot.theta)

    def in_robot(x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        dx, dy = np.asarray(x, np.float64) - robot.x, np.asarray(y, np.float64) - robot.y
        return c * dx + s * dy, -s * dx + c * dy

    origin_x, _ = in_robot(sensor.x, sensor.y)                    # the rays' origin: (ox, 0)
    ox = float(origin_x)
    ranges = np.asarray(scan.ranges, np.float64)
    if beam_sensors is None:
        bx, by = in_robot(np.full(ranges.shape, sensor.x), np.full(ranges.shape, sensor.y))
        dth = np.full(ranges.shape, sensor.theta - robot.theta)
    else:
        bx, by = in_robot(beam_sensors[0], beam_sensors[1])
        dth = np.asarray(beam_sensors[2], np.float64) - robot.theta
    angles = np.asarray(scan.angles, np.float64) + dth           # beam directions in the robot frame
    hit = np.isfinite(ranges) & (ranges < scan.range_max)
    out_r = np.where(hit, 0.0, ranges)
    out_r = np.where(np.isfinite(ranges) & ~hit, math.inf, out_r)
    out_a = angles.copy()
    # an echo lies at (bx, by) + r (cos a, sin a) in the robot frame; seen from (ox, 0):
    ex = bx[hit] - ox + ranges[hit] * np.cos(angles[hit])
    ey = by[hit] + ranges[hit] * np.sin(angles[hit])
    out_a[hit] = np.arctan2(ey, ex)
    out_r[hit] = np.hypot(ex, ey)
    out_a = (out_a + math.pi) % (2 * math.pi) - math.pi
    return LaserScan(out_a, out_r, scan.range_max, offset_x=ox)

LASERS = "robotexp.lasers"                      # entry-point group: laser driver classes
LASER_EMULATORS = "robotexp.laser_emulators"    # entry-point group: their emulators, by the same names


@dataclass(frozen=True)
class LaserGeometry:
    """Where a laser's beams point and how far they reach.

    Beam i points at `angle_min + i * increment` [rad] in the sensor frame, i = 0 .. beams-1.
    """

    angle_min: float        # [rad] first beam
    increment: float        # [rad] between beams (> 0: counter-clockwise order)
    beams: int
    range_min: float        # [m] closer echoes are not reported
    range_max: float        # [m]
    period: float           # [s] one scan

    def angles(self) -> npt.NDArray[np.float64]:
        """The beam angles [rad] in the sensor frame, shape (beams,)."""
        return self.angle_min + self.increment * np.arange(self.beams, dtype=np.float64)

    @property
    def fov(self) -> float:
        """The angle [rad] from the first to the last beam."""
        return self.increment * (self.beams - 1)

    def scan(self, ranges: npt.NDArray[np.float64]) -> LaserScan:
        """A `LaserScan` of these beams with `ranges` [m] (inf: no echo)."""
        return LaserScan(self.angles(), np.asarray(ranges, dtype=np.float64), self.range_max)


@dataclass(frozen=True)
class StampedScan:
    """One complete scan as it arrived."""

    scan: LaserScan     # in the sensor frame
    stamp: float        # [s] time.monotonic() on this host when the scan was complete
    seq: int            # 0, 1, 2, ... in arrival order, per laser


class Laser(ABC):
    """A laser rangefinder on a link of its own (a serial port, USB-ACM, TCP).

    A driver connects in `__init__(address, **options)` (options keyword-only with defaults), starts
    the device's continuous output and decodes it in the background; `latest()` and `wait_scan()`
    hand out complete scans; `close()` stops the device's output and releases the link (safe twice).
    The link going away or staying silent makes `latest()`/`wait_scan()` raise `ConnectionLost`.

    Attributes:
        name: the entry-point name (e.g. "rplidar").
        address: where the device is (for messages).
        geometry: the beams of the configured scan mode.
    """

    name: ClassVar[str] = "laser"
    address: str
    geometry: LaserGeometry

    @abstractmethod
    def latest(self) -> StampedScan | None:
        """The newest complete scan, None before the first.

        Raises:
            ConnectionLost: the link closed or no valid scan came for the driver's timeout.
        """

    @abstractmethod
    def wait_scan(self, after_seq: int = -1, timeout: float = 1.0) -> StampedScan:
        """The first scan with `seq > after_seq`, waiting up to `timeout` [s] for it.

        Raises:
            ConnectionLost: the link closed, or no such scan came within `timeout`.
        """

    @abstractmethod
    def close(self) -> None:
        """Stop the device's output and release the link. Safe to call twice."""

    def describe(self) -> str:
        """One line: the device, its identity as it reported it, and its scan mode."""
        g = self.geometry
        return (f"{self.name} at {self.address}: {g.beams} beams over {math.degrees(g.fov):.1f} deg, "
                f"{g.range_max:g} m, {1 / g.period:.1f} Hz")

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class ScanSource(Protocol):
    """What a laser emulator measures: ranges [m] (inf: no echo within `reach`) along beam `angles`
    [rad] in the sensor frame, at the current instant of a simulated world."""

    def __call__(self, angles: npt.NDArray[np.float64], reach: float) -> npt.NDArray[np.float64]: ...


class LaserEmulator(Protocol):
    """A laser's protocol served from a `ScanSource`, on a pseudo-terminal or TCP.

    Emulator classes are constructed as `cls(source, *, pty=False, port=None, host="127.0.0.1")`
    (port None with pty False: a free TCP port), serve after `start()` in a background thread until
    `close()` (safe twice), and tell where they serve in `address` (a device path or "host:port"
    that the driver of the same name accepts).
    """

    address: str

    def start(self) -> Self: ...

    def close(self) -> None: ...

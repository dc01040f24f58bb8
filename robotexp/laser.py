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

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar, Protocol, Self

import numpy as np
import numpy.typing as npt

from robotexp.robot import LaserScan

__all__ = ["LASERS", "LASER_EMULATORS", "LaserGeometry", "StampedScan", "Laser", "ScanSource", "LaserEmulator"]

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

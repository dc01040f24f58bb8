"""CDR (little-endian, as ROS 2 writes it) encoding of the few messages a recording holds, with numpy
for the arrays: mcap-ros2's generic encoder packs each element in Python (a 222 x 172 map took 0.1 s),
which made recording cost 8x a simulated run. The decoding side stays mcap-ros2's (tests/bag decode
every topic with it).

Rules: a 4-byte encapsulation header (CDR_LE), then each primitive aligned to its size from the end
of that header; a string is a uint32 length (with its NUL), its bytes and a NUL; a sequence is a uint32
count then its elements; a fixed array (float64[36]) is its elements alone.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

__all__ = ["Cdr", "odometry", "tf_message", "laser_scan", "exact_scan", "occupancy_grid"]

_ZERO36 = bytes(36 * 8)


class Cdr:
    """A CDR_LE message being written."""

    def __init__(self) -> None:
        self.buf = bytearray(b"\x00\x01\x00\x00")

    def _align(self, n: int) -> None:
        pad = (-(len(self.buf) - 4)) % n
        if pad:
            self.buf += bytes(pad)

    def i32(self, v: int) -> None:
        self._align(4)
        self.buf += struct.pack("<i", v)

    def u32(self, v: int) -> None:
        self._align(4)
        self.buf += struct.pack("<I", v)

    def f32s(self, *values: float) -> None:
        """Consecutive float32 fields."""
        self._align(4)
        self.buf += struct.pack(f"<{len(values)}f", *values)

    def f64s(self, *values: float) -> None:
        """Consecutive float64 fields (a Pose, a fixed array)."""
        self._align(8)
        self.buf += struct.pack(f"<{len(values)}d", *values)

    def string(self, s: str) -> None:
        b = s.encode() + b"\x00"
        self.u32(len(b))
        self.buf += b

    def seq(self, values: npt.ArrayLike, dtype: str, size: int) -> None:
        """A sequence of `dtype` ('<f4', '<f8', 'i1') elements of `size` bytes."""
        arr = np.ascontiguousarray(values, dtype=dtype).ravel()
        self.u32(len(arr))
        if len(arr):
            self._align(size)
            self.buf += arr.tobytes()

    def header(self, ns: int, frame: str) -> None:
        self.i32(ns // 1_000_000_000)
        self.u32(ns % 1_000_000_000)
        self.string(frame)

    def pose(self, x: float, y: float, theta: float) -> None:
        """geometry_msgs/Pose of a planar pose (quaternion about z)."""
        self.f64s(x, y, 0.0, 0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2))

    def zeros36(self) -> None:
        """A float64[36] covariance of zeros."""
        self._align(8)
        self.buf += _ZERO36

    def data(self) -> bytes:
        """The encoded message."""
        return bytes(self.buf)


def odometry(ns: int, frame: str, child: str, x: float, y: float, theta: float, v: float, w: float) -> bytes:
    """nav_msgs/Odometry (covariances zero: unknown)."""
    c = Cdr()
    c.header(ns, frame)
    c.string(child)
    c.pose(x, y, theta)
    c.zeros36()
    c.f64s(v, 0.0, 0.0, 0.0, 0.0, w)
    c.zeros36()
    return c.data()


def tf_message(ns: int, transforms: Sequence[tuple[str, str, float, float, float]]) -> bytes:
    """tf2_msgs/TFMessage of planar transforms (parent, child, x, y, theta)."""
    c = Cdr()
    c.u32(len(transforms))
    for parent, child, x, y, theta in transforms:
        c.header(ns, parent)
        c.string(child)
        c.pose(x, y, theta)         # Transform: Vector3 translation, Quaternion rotation: the same 7 float64
    return c.data()


def laser_scan(ns: int, frame: str, angle_min: float, angle_max: float, angle_increment: float, scan_time: float,
               range_min: float, range_max: float, ranges: npt.ArrayLike) -> bytes:
    """sensor_msgs/LaserScan (no intensities)."""
    c = Cdr()
    c.header(ns, frame)
    c.f32s(angle_min, angle_max, angle_increment, 0.0, scan_time, range_min, range_max)
    c.seq(ranges, "<f4", 4)
    c.seq((), "<f4", 4)
    return c.data()


def exact_scan(ns: int, frame: str, angle_min: float, angle_increment: float, angles: npt.ArrayLike,
               ranges: npt.ArrayLike, range_max: float, offset_x: float) -> bytes:
    """robotexp_msgs/ExactScan."""
    c = Cdr()
    c.header(ns, frame)
    c.f64s(angle_min, angle_increment)
    c.seq(angles, "<f8", 8)
    c.seq(ranges, "<f8", 8)
    c.f64s(range_max, offset_x)
    return c.data()


def occupancy_grid(ns: int, frame: str, origin_x: float, origin_y: float, cell: float, rows: int, cols: int,
                   data: npt.ArrayLike) -> bytes:
    """nav_msgs/OccupancyGrid (row-major from the southmost row, as ROS has it)."""
    c = Cdr()
    c.header(ns, frame)
    c.i32(ns // 1_000_000_000)
    c.u32(ns % 1_000_000_000)
    c.f32s(cell)
    c.u32(cols)
    c.u32(rows)
    c.pose(origin_x, origin_y, 0.0)
    c.seq(data, "i1", 1)
    return c.data()

"""CARMEN laser logs: FLASER, ROBOTLASER1, RAWLASER1 and ODOM lines, plain or gzip-compressed.

Line formats (CARMEN logger; lengths in m, angles in rad):

- `FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta timestamp host logger_timestamp`: a front
  laser of n beams from -90 deg, spaced as CARMEN guesses from n (1 deg for 180 or 181 beams,
  0.5 deg for 360 or 361, 0.25 deg for 720 or 721, else 180 deg / (n - 1)); (x, y, theta) is the
  laser's pose, (odom_*) the robot's odometry.
- `ROBOTLASER1 type start_angle fov resolution max_range accuracy remission_mode n r_1 .. r_n
  m e_1 .. e_m laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv forward side turn
  timestamp host logger_timestamp`.
- `ODOM x y theta tv rv accel timestamp host logger_timestamp`.

- `RAWLASER1 type start_angle fov resolution max_range accuracy remission_mode n r_1 .. r_n m e_1 .. e_m
  timestamp host logger_timestamp`: the front laser without a pose. Used only in a log with no FLASER
  or ROBOTLASER1 line (newer CARMEN logs write both for the same laser): each reading is placed at the
  ODOM pose interpolated at its timestamp, moved forward by the `robot_frontlaser_offset` PARAM [m]
  when the log gives it; a reading outside the ODOM lines' time span is left out (and counted in
  `CarmenLog.problems`).

Other lines (PARAM, NEFF, RAWLASER2-4 (rear and other lasers: their mounting is not in the line),
comments) are ignored. A malformed line of a known kind is reported as `file:line: what` in
`CarmenLog.problems` and skipped.
"""

from __future__ import annotations

import bisect
import gzip
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.robot import LaserScan, Pose

__all__ = ["LogScan", "CarmenLog", "read_carmen", "flaser_angles", "format_flaser", "odometry_at"]


@dataclass(frozen=True)
class LogScan:
    """One laser reading of a log: beams, the laser's pose and the robot's odometry when it was taken.

    Attributes:
        stamp: [s] the reading's timestamp.
        angles: [rad] beam angles relative to the laser's heading.
        ranges: [m] the ranges as logged.
        pose: the laser's pose (in a pose-corrected log, the corrected one).
        odom: the robot's odometry pose.
        range_max: [m] the laser's maximum range when the line gives it (ROBOTLASER1), else None.
        line: the line number in the file (1-based).
    """

    stamp: float
    angles: npt.NDArray[np.float64]
    ranges: npt.NDArray[np.float64]
    pose: Pose
    odom: Pose
    range_max: float | None
    line: int

    def scan(self, range_max: float, no_echo: float = math.inf) -> LaserScan:
        """The reading as a `LaserScan` seen from `pose`: ranges at or beyond `no_echo` [m] (the sensor's
        "nothing seen" value) become NaN (skipped), the others are capped at `range_max` [m]."""
        r = self.ranges.astype(np.float64, copy=True)
        r[~(r >= 0.0) | (r >= no_echo)] = np.nan
        r[r >= range_max] = range_max
        return LaserScan(self.angles, r, range_max, 0.0)


@dataclass
class CarmenLog:
    """A parsed log: its laser readings in file order, the ODOM poses, PARAM values, and the problems."""

    path: str
    scans: list[LogScan] = field(default_factory=list)
    odometry: list[tuple[float, Pose]] = field(default_factory=list)
    params: dict[str, str] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    raw: list[LogScan] = field(default_factory=list)    # RAWLASER1 readings (pose: none yet, zeros)

    def no_echo(self) -> float:
        """[m] the range that means "no echo": the `robot_front_laser_max` PARAM when given; otherwise the
        largest logged range when at least 0.5 % of all beams read exactly it (a saturated sensor);
        else inf."""
        value = self.params.get("robot_front_laser_max")
        if value is not None:
            try:
                return float(value)
            except ValueError:
                pass
        if not self.scans:
            return math.inf
        ranges = np.concatenate([s.ranges for s in self.scans])
        top = float(ranges.max())
        return top if np.count_nonzero(ranges == top) >= 0.005 * len(ranges) else math.inf


_BEAM_STEPS = {180: 1.0, 181: 1.0, 360: 0.5, 361: 0.5, 720: 0.25, 721: 0.25}


def flaser_angles(n: int) -> npt.NDArray[np.float64]:
    """The beam angles [rad] of an n-beam FLASER line (see the module docstring)."""
    step = _BEAM_STEPS.get(n, 180.0 / max(n - 1, 1))
    return np.radians(-90.0 + step * np.arange(n))


def _open(path: Path):  # type: ignore[no-untyped-def]
    with open(path, "rb") as f:
        magic = f.read(2)
    if magic == b"\x1f\x8b":
        return gzip.open(path, "rt", encoding="utf-8", errors="replace")
    return open(path, encoding="utf-8", errors="replace")


def read_carmen(path: str | os.PathLike[str]) -> CarmenLog:
    """Read a CARMEN log (gzip detected by content, not name).

    Raises:
        ConfigError: the file cannot be read, or is not gzip-valid.
    """
    p = Path(path)
    log = CarmenLog(str(p))
    try:
        with _open(p) as f:
            for number, text in enumerate(f, 1):
                _line(log, number, text)
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read the log: {exc.strerror or exc}") from None
    except EOFError:
        raise ConfigError(f"{p}: the gzip stream ends early: the file is truncated") from None
    if not log.scans and log.raw:
        _place_raw(log)
    return log


def odometry_at(odometry: list[tuple[float, Pose]], stamp: float) -> Pose | None:
    """The pose of `odometry` ((timestamp, pose) in time order) interpolated at `stamp`: linear in x and y,
    along the shorter way round in heading; None outside its time span."""
    return _interpolate(odometry, [t for t, _ in odometry], stamp)


def _interpolate(odometry: list[tuple[float, Pose]], times: list[float], stamp: float) -> Pose | None:
    """`odometry_at` with the timestamps of `odometry` given (`times`: built once for a whole log)."""
    if not odometry or not odometry[0][0] <= stamp <= odometry[-1][0]:
        return None
    k = bisect.bisect_left(times, stamp)
    t1, b = odometry[k]
    if t1 == stamp or k == 0:
        return b
    t0, a = odometry[k - 1]
    f = (stamp - t0) / (t1 - t0)
    dth = math.remainder(b.theta - a.theta, 2 * math.pi)
    return Pose(a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), math.remainder(a.theta + f * dth, 2 * math.pi))


def _place_raw(log: CarmenLog) -> None:
    """RAWLASER1 readings as scans at the interpolated ODOM pose (see the module docstring)."""
    odometry = sorted(log.odometry, key=lambda tp: tp[0])
    try:
        offset = float(log.params.get("robot_frontlaser_offset", "0"))
    except ValueError:
        offset = 0.0
    times = [t for t, _ in odometry]
    outside = 0
    for r in log.raw:
        pose = _interpolate(odometry, times, r.stamp)
        if pose is None:
            outside += 1
            continue
        laser = Pose(pose.x + offset * math.cos(pose.theta), pose.y + offset * math.sin(pose.theta), pose.theta)
        log.scans.append(LogScan(r.stamp, r.angles, r.ranges, laser, pose, r.range_max, r.line))
    if outside:
        log.problems.append(f"{log.path}: {outside} of {len(log.raw)} RAWLASER1 readings lie outside the ODOM lines' "
                            "time span (no pose for them): left out")


def _floats(fields: list[str], start: int, count: int) -> list[float]:
    if start + count > len(fields):
        raise ValueError(f"expected at least {start + count} fields, got {len(fields)}")
    out = [float(v) for v in fields[start:start + count]]
    if not all(math.isfinite(v) for v in out):
        raise ValueError("a number is not finite")
    return out


def _count(fields: list[str], i: int, what: str) -> int:
    if i >= len(fields):
        raise ValueError(f"missing {what}")
    n = int(fields[i])
    if n < 0 or n > 100_000:
        raise ValueError(f"{what} {n} is out of range")
    return n


def _laser_head(fields: list[str]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], float, int]:
    """The fields ROBOTLASER1 and RAWLASER1 share (`type start_angle fov resolution max_range accuracy
    remission_mode n r_1 .. r_n m e_1 .. e_m`): beam angles, ranges, max range, and the index of the
    field after the remissions."""
    start, _fov, res, rmax, _acc, _mode = _floats(fields, 2, 6)
    n = _count(fields, 8, "beam count")
    ranges = np.array(_floats(fields, 9, n))
    m = _count(fields, 9 + n, "remission count")
    return np.asarray(start + res * np.arange(n), dtype=np.float64), ranges, rmax, 10 + n + m


def _line(log: CarmenLog, number: int, text: str) -> None:
    fields = text.split()
    if not fields or fields[0].startswith("#"):
        return
    kind = fields[0]
    try:
        if kind == "FLASER":
            n = _count(fields, 1, "beam count")
            ranges = np.array(_floats(fields, 2, n))
            x, y, th, ox, oy, oth, stamp = _floats(fields, 2 + n, 7)
            log.scans.append(LogScan(stamp, flaser_angles(n), ranges, Pose(x, y, th), Pose(ox, oy, oth), None, number))
        elif kind == "ROBOTLASER1":
            angles, ranges, rmax, k = _laser_head(fields)
            lx, ly, lth, rx, ry, rth = _floats(fields, k, 6)
            (stamp,) = _floats(fields, k + 11, 1)
            log.scans.append(LogScan(stamp, angles, ranges, Pose(lx, ly, lth), Pose(rx, ry, rth), rmax, number))
        elif kind == "RAWLASER1":
            angles, ranges, rmax, k = _laser_head(fields)
            (stamp,) = _floats(fields, k, 1)
            log.raw.append(LogScan(stamp, angles, ranges, Pose(0.0, 0.0, 0.0), Pose(0.0, 0.0, 0.0), rmax, number))
        elif kind == "ODOM":
            x, y, th, _tv, _rv, _acc, stamp = _floats(fields, 1, 7)
            log.odometry.append((stamp, Pose(x, y, th)))
        elif kind == "PARAM" and len(fields) >= 3:
            log.params[fields[1]] = fields[2]
    except ValueError as exc:
        log.problems.append(f"{log.path}:{number}: malformed {kind} line skipped: {exc}")


def format_flaser(ranges: npt.ArrayLike, pose: Pose, odom: Pose, stamp: float) -> str:
    """One FLASER line (the inverse of the reader, for tests and converters)."""
    r = np.asarray(ranges, np.float64)
    values = " ".join(f"{v:.3f}" for v in r)
    return (f"FLASER {len(r)} {values} {pose.x:.6f} {pose.y:.6f} {pose.theta:.6f} "
            f"{odom.x:.6f} {odom.y:.6f} {odom.theta:.6f} {stamp:.6f} robotexp {stamp:.6f}")

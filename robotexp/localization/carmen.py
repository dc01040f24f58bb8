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
`CarmenLog.problems` and skipped: a number that is not one, a laser line whose field count does not match
its beam (and remission) count (a corrupt line, e.g. two lines run together: its values would be read in
the wrong places), a `robot_front_laser_max` PARAM that is not a positive range or a
`robot_frontlaser_offset` that is not finite (the PARAM is then ignored).

What a log may hold is bounded, so that a small compressed file cannot take all memory (a gzip stream of
1 MB can hold 1 GB of text): a line is at most `MAX_LINE` bytes (read in pieces of that size: a longer one
is never held whole), and a log at most `MAX_SCANS` laser readings, `MAX_BEAMS` beams in all, `MAX_ODOM`
ODOM lines, `MAX_PARAMS` PARAM names and `MAX_PROBLEMS` malformed lines; `read_carmen` refuses a log
beyond one of them (`ConfigError`, naming the file, the line and the bound).
"""

from __future__ import annotations

import bisect
import gzip
import io
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.robot import LaserScan, Pose

__all__ = ["LogScan", "CarmenLog", "read_carmen", "flaser_angles", "format_flaser", "odometry_at", "MAX_LINE",
           "MAX_SCANS", "MAX_BEAMS", "MAX_ODOM", "MAX_PARAMS", "MAX_PROBLEMS"]

MAX_LINE = 2**20            # [bytes] longest line: a CARMEN line has some kB (1081 beams with remissions: ~15 kB)
# A real log of hours holds about a million laser readings (4 h at 75 Hz: 1.08 million). Read, a reading of
# 180 beams takes about 2.1 kB (ranges as float64, poses, the record; the beam angles are shared): a log of
# 1,000,001 such readings is refused at its last line after 58 s at 2.2 GB (peak resident), so the bounds
# below keep a log read at about 2 GB; `robotexp map --localize none` peaked at 1.5 times what reading took
# (200,000 readings: 0.51 GB read, 0.79 GB mapped), more with loop closure (which keeps every scan).
MAX_SCANS = 1_000_000       # laser readings (FLASER, ROBOTLASER1, RAWLASER1 lines) in one log
MAX_BEAMS = 250_000_000     # beams of all its laser readings (2 GB of ranges)
MAX_ODOM = 5_000_000        # ODOM lines (14 h at 100 Hz)
MAX_PARAMS = 10_000         # PARAM names (a CARMEN log has some hundred)
MAX_PARAM_TEXT = 4096       # [characters] longest PARAM name or value kept (longer: reported, skipped)
MAX_PROBLEMS = 100_000      # malformed lines: beyond them the file is not a CARMEN log, or a damaged one


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
                given = float(value)
            except ValueError:
                given = math.nan
            if math.isfinite(given) and given > 0.0:        # else no range: ignored (read_carmen reports it)
                return given
        # the largest range and how often it is read, scan by scan (no copy of all the ranges)
        top, count, total = -math.inf, 0, 0
        for s in self.scans:
            if not len(s.ranges):
                continue
            m = float(s.ranges.max())
            if m > top:
                top, count = m, 0
            if m == top:
                count += int(np.count_nonzero(s.ranges == top))
            total += len(s.ranges)
        return top if total and count >= 0.005 * total else math.inf


_BEAM_STEPS = {180: 1.0, 181: 1.0, 360: 0.5, 361: 0.5, 720: 0.25, 721: 0.25}


def flaser_angles(n: int) -> npt.NDArray[np.float64]:
    """The beam angles [rad] of an n-beam FLASER line (see the module docstring)."""
    step = _BEAM_STEPS.get(n, 180.0 / max(n - 1, 1))
    return np.radians(-90.0 + step * np.arange(n))


_ANGLES: dict[tuple[str, float, float, int], npt.NDArray[np.float64]] = {}


def _shared_angles(key: tuple[str, float, float, int]) -> npt.NDArray[np.float64]:
    """The beam angles of `key` ("flaser", 0, 0, n) or ("laser", start, resolution, n), one read-only array
    for all the readings that share them (a log's readings mostly do: not one copy per reading)."""
    angles = _ANGLES.get(key)
    if angles is None:
        kind, start, res, n = key
        angles = flaser_angles(n) if kind == "flaser" else np.asarray(start + res * np.arange(n), dtype=np.float64)
        angles.flags.writeable = False
        if n <= 4096:                   # kept: at most 256 arrays of 4096 beams (8 MiB) once the logs are gone
            if len(_ANGLES) >= 256:
                _ANGLES.clear()
            _ANGLES[key] = angles
    return angles


def _open(path: Path) -> io.BufferedIOBase:
    with open(path, "rb") as f:
        magic = f.read(2)
    if magic == b"\x1f\x8b":
        return gzip.GzipFile(path, "rb")
    return open(path, "rb")


def read_carmen(path: str | os.PathLike[str]) -> CarmenLog:
    """Read a CARMEN log (gzip detected by content, not name).

    Raises:
        ConfigError: the file cannot be read, or is not gzip-valid; a line is longer than `MAX_LINE`
            bytes, or the log holds more than one of the bounds (`MAX_SCANS`, ...) allows.
    """
    p = Path(path)
    log = CarmenLog(str(p))
    try:
        with _open(p) as f:
            number, beams = 0, 0
            while True:
                raw = f.readline(MAX_LINE + 1)      # never more: a longer line is not read whole
                if not raw:
                    break
                number += 1
                if len(raw) > MAX_LINE and not raw.endswith(b"\n"):     # MAX_LINE bytes and its newline: kept
                    raise ConfigError(f"{p}:{number}: a line longer than {MAX_LINE // 2**20} MiB (a CARMEN line is "
                                      "at most some kB): not a CARMEN log, or a damaged one; give a CARMEN log")
                beams += _line(log, number, raw.decode("utf-8", errors="replace"))
                if (len(log.scans) + len(log.raw) > MAX_SCANS or beams > MAX_BEAMS or len(log.odometry) > MAX_ODOM
                        or len(log.params) > MAX_PARAMS or len(log.problems) > MAX_PROBLEMS):
                    raise ConfigError(_too_much(log, number, beams))
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read the log: {exc.strerror or exc}") from None
    except EOFError:
        raise ConfigError(f"{p}: the gzip stream ends early: the file is truncated") from None
    if not log.scans and log.raw:
        _place_raw(log)
    return log


def _too_much(log: CarmenLog, number: int, beams: int) -> str:
    """The message refusing `log` at its line `number`, where it went beyond one of the bounds."""
    where = f"{log.path}:{number}:"
    if len(log.problems) > MAX_PROBLEMS:
        return (f"{where} more than {MAX_PROBLEMS:,} malformed lines (the first: {log.problems[0]}): not a CARMEN "
                "log, or a badly damaged one")
    if len(log.params) > MAX_PARAMS:
        return f"{where} more than {MAX_PARAMS:,} PARAM names (a CARMEN log has some hundred): not a CARMEN log"
    if len(log.odometry) > MAX_ODOM:
        what = f"more than {MAX_ODOM:,} ODOM lines (14 hours at 100 Hz)"
    elif beams > MAX_BEAMS:
        what = f"more than {MAX_BEAMS:,} laser beams in all (2 GB of ranges)"
    else:
        what = f"more than {MAX_SCANS:,} laser readings (about 4 hours at 75 Hz)"
    return f"{where} {what}, the most a log may hold here: split the log and map its parts"


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
    return _shared_angles(("laser", start, res, n)), ranges, rmax, 10 + n + m


def _fields_match(fields: list[str], expected: int, kind: str, counts: str) -> None:
    """Refuse a laser line whose field count is not the one its beam (and remission) counts make.

    Raises:
        ValueError: it is not (the line is corrupt: its values would be read in the wrong places).
    """
    if len(fields) != expected:
        raise ValueError(f"it has {len(fields)} fields where a {kind} line of {counts} has {expected}: the counts "
                         "do not match the values (a corrupt line)")


def _param(log: CarmenLog, number: int, name: str, value: str) -> None:
    """Keep a PARAM value; a laser max range that is not a positive number, or a laser offset that is not a
    finite one, is reported and ignored (read as given, it would discard or misplace every beam)."""
    if len(name) > MAX_PARAM_TEXT or len(value) > MAX_PARAM_TEXT:
        raise ValueError(f"a name or value longer than {MAX_PARAM_TEXT} characters")
    if name in ("robot_front_laser_max", "robot_frontlaser_offset"):
        try:
            number_value = float(value)
        except ValueError:
            number_value = math.nan
        positive = name == "robot_front_laser_max"
        if not math.isfinite(number_value) or (positive and number_value <= 0.0):
            what = "a positive range [m]" if positive else "a finite offset [m]"
            log.problems.append(f"{log.path}:{number}: PARAM {name} {value} is not {what}: ignored")
            return
    log.params[name] = value


def _line(log: CarmenLog, number: int, text: str) -> int:
    """Read one line into `log`; the number of beams of the laser reading it adds (0: none)."""
    fields = text.split()
    if not fields or fields[0].startswith("#"):
        return 0
    kind = fields[0]
    try:
        if kind == "FLASER":
            n = _count(fields, 1, "beam count")
            _fields_match(fields, n + 11, kind, f"{n} beams")
            ranges = np.array(_floats(fields, 2, n))
            x, y, th, ox, oy, oth, stamp = _floats(fields, 2 + n, 7)
            log.scans.append(LogScan(stamp, _shared_angles(("flaser", 0.0, 0.0, n)), ranges, Pose(x, y, th),
                                     Pose(ox, oy, oth), None, number))
            return n
        if kind == "ROBOTLASER1":
            angles, ranges, rmax, k = _laser_head(fields)
            _fields_match(fields, k + 14, kind, f"{len(ranges)} beams and {k - 10 - len(ranges)} remissions")
            lx, ly, lth, rx, ry, rth = _floats(fields, k, 6)
            (stamp,) = _floats(fields, k + 11, 1)
            log.scans.append(LogScan(stamp, angles, ranges, Pose(lx, ly, lth), Pose(rx, ry, rth), rmax, number))
            return len(ranges)
        if kind == "RAWLASER1":
            angles, ranges, rmax, k = _laser_head(fields)
            _fields_match(fields, k + 3, kind, f"{len(ranges)} beams and {k - 10 - len(ranges)} remissions")
            (stamp,) = _floats(fields, k, 1)
            log.raw.append(LogScan(stamp, angles, ranges, Pose(0.0, 0.0, 0.0), Pose(0.0, 0.0, 0.0), rmax, number))
            return len(ranges)
        if kind == "ODOM":
            x, y, th, _tv, _rv, _acc, stamp = _floats(fields, 1, 7)
            log.odometry.append((stamp, Pose(x, y, th)))
        elif kind == "PARAM" and len(fields) >= 3:
            _param(log, number, fields[1], fields[2])
    except ValueError as exc:
        log.problems.append(f"{log.path}:{number}: malformed {kind} line skipped: {exc}")
    return 0


def format_flaser(ranges: npt.ArrayLike, pose: Pose, odom: Pose, stamp: float) -> str:
    """One FLASER line (the inverse of the reader, for tests and converters)."""
    r = np.asarray(ranges, np.float64)
    values = " ".join(f"{v:.3f}" for v in r)
    return (f"FLASER {len(r)} {values} {pose.x:.6f} {pose.y:.6f} {pose.theta:.6f} "
            f"{odom.x:.6f} {odom.y:.6f} {odom.theta:.6f} {stamp:.6f} robotexp {stamp:.6f}")

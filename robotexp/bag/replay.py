"""Replay a recording: read a ROS 2 bag in MCAP (`read_bag`) and run its ticks through the run loop
(`replay_bag`), so that the map and every metric come from the same code as a live run's.

A recording made by `robotexp` (`robotexp.bag.recorder`) replays tick for tick: each /odom message is
a tick, with the scan (/robotexp/scan, float64 as the run had it; else /scan) and /ground_truth of the
same stamp; the grid takes the recorded geometry,
model and range cap, and coverage is measured against the recorded ground truth (/ground_truth/map),
or, at another cell size, against ground truth recomputed from the recorded world. A bag from a ROS 2
robot (/scan and /odom, optionally /tf_static base_link -> laser) replays one tick per scan, with the
newest odometry at or before the scan; it has no ground truth, so its coverage is n/a. A team's recording
(each robot under /robot_1, /robot_2, ...) replays its robots together in a team run
(`replay_team`): the team's map and record, every robot's path.
"""

from __future__ import annotations

import bisect
import json
import logging
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from robotexp.bag.markers import markers_of
from robotexp.bag.reading import (MAX_POSITION, MAX_ROBOTS, TEAM_TOPIC_TYPES, TOPIC_TYPES, decode_errors, finite,
                                  read_records, refuse)
from robotexp.bag.recorder import yaw_of
from robotexp.clock import Clock, SimClock
from robotexp.errors import ConfigError, WorldError
from robotexp.explorer import Done, Explorer, ExplorerContext
from robotexp.run.loop import ExplorationRun, RunInfo
from robotexp.mapping.geometry import MAX_CELLS, GridGeometry
from robotexp.world.groundtruth import GroundTruth, ground_truth
from robotexp.mapping.grid import OccupancyGrid
from robotexp.markers import Markers
from robotexp.run.observers import RunObserver
from robotexp.run.team import TeamRun
from robotexp.run.record import EndReason
from robotexp.robot import Capability, LaserScan, Limits, Pose, Robot, RobotState, Twist

__all__ = ["Tick", "Bag", "read_bag", "replay_bag", "replay_team", "ReplayRobot", "ReplayExplorer"]

log = logging.getLogger(__name__)

FOREIGN_MARGIN = 1.0    # [m] a foreign bag's map reaches this far beyond its poses plus the laser range


@dataclass
class Tick:
    """One control tick of a recording."""

    time: float                     # [s] since the recording's first tick
    pose: Pose                      # the pose the map used
    velocity: Twist
    scan: LaserScan | None = None   # the scan the map integrated at this tick
    true_pose: Pose | None = None


@dataclass
class Bag:
    """What a recording holds for a replay."""

    path: Path
    ticks: list[Tick]
    meta: dict[str, Any] | None = None          # `robotexp.run` metadata (None: not made by robotexp)
    record: dict[str, Any] | None = None        # the run's record (`robotexp.run.record` metadata)
    truth: GroundTruth | None = None            # the recorded ground truth
    topics: dict[str, str] = field(default_factory=dict)   # topic -> schema name
    markers: list[tuple[float, Markers]] = field(default_factory=list)   # (time [s], the explorer's markers)
    team: list[list[Tick]] = field(default_factory=list)    # a team's recording: each robot's ticks (robot 1's first)
    cut_at: int | None = None       # the byte where a file cut short ends (its whole records), None: complete


def _pose(msg: Any) -> Pose:
    p = msg.pose.pose
    return Pose(finite(p.position.x, "a position", MAX_POSITION), finite(p.position.y, "a position", MAX_POSITION),
                _yaw(p.orientation))


def _yaw(q: Any) -> float:
    for v in (q.x, q.y, q.z, q.w):
        finite(v, "a quaternion component", 1e6)
    return yaw_of(q)


@dataclass
class _RawScan:
    """A sensor_msgs/LaserScan as numbers (the decoded message's Python lists are not kept)."""

    frame: str
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray[Any, Any]


def _raw_scan(msg: Any) -> _RawScan:
    ranges = np.asarray(msg.ranges, np.float32)
    if ranges.ndim != 1:
        raise ValueError("a /scan's ranges are not a sequence")
    return _RawScan(str(msg.header.frame_id), finite(msg.angle_min, "a /scan's angle_min", 1e3),
                    finite(msg.angle_increment, "a /scan's angle_increment", 1e3),
                    float(msg.range_min), finite(msg.range_max, "a /scan's range_max", 1e6), ranges)


def _scan(msg: _RawScan, offset_x: float, yaw: float) -> LaserScan:
    """A LaserScan of a sensor_msgs/LaserScan: NaN and readings below range_min dropped, readings
    beyond range_max read as no echo (inf)."""
    ranges = msg.ranges.astype(np.float64)
    n = len(ranges)
    angles = msg.angle_min + np.arange(n, dtype=np.float64) * msg.angle_increment + yaw
    rmax = float(msg.range_max)
    ranges = np.where(ranges > rmax, np.inf, ranges)
    keep = ~np.isnan(ranges) & (ranges >= msg.range_min)
    return LaserScan(angles[keep], ranges[keep], rmax, offset_x)


def _exact_scan(msg: Any) -> LaserScan:
    """The LaserScan of a robotexp_msgs/ExactScan, exactly as it was recorded."""
    ranges = np.asarray(msg.ranges, np.float64)
    angles = np.asarray(msg.angles, np.float64) if len(msg.angles) else np.asarray(
        finite(msg.angle_min, "a scan's angle_min", 1e3) + np.arange(len(ranges), dtype=np.float64)
        * finite(msg.angle_increment, "a scan's angle_increment", 1e3), np.float64)
    if angles.shape != ranges.shape or ranges.ndim != 1:
        raise ValueError(f"a /robotexp/scan has {angles.size} angles for {ranges.size} ranges")
    if not np.isfinite(angles).all():
        raise ValueError("a /robotexp/scan has angles that are not finite")
    return LaserScan(angles, ranges, finite(msg.range_max, "a scan's range_max", 1e6),
                     finite(msg.offset_x, "a scan's offset_x", 100.0))


def _mount(transforms: list[Any], frame: str) -> tuple[float, float]:
    """The laser's offset ahead [m] and yaw [rad] on the robot from the static transform base_link (or
    base_footprint) -> `frame` (0, 0 when there is none; a sideways offset is not modelled: warned)."""
    for tf in transforms:
        if tf.child_frame_id == frame and tf.header.frame_id.rpartition("/")[2] in ("base_link", "base_footprint"):
            t = tf.transform.translation
            if abs(t.y) > 0.001:
                log.warning("laser frame %r sits %.3f m sideways on the robot: replayed as if centred", frame, t.y)
            return finite(t.x, "the laser's mount offset", 100.0), _yaw(tf.transform.rotation)
    return 0.0, 0.0


def _grid_of(msg: Any) -> tuple[GridGeometry, np.ndarray[Any, Any]]:
    info = msg.info
    rows, cols = int(info.height), int(info.width)
    if rows < 1 or cols < 1 or rows * cols > MAX_CELLS:
        raise ValueError(f"a map of {cols} x {rows} cells (limit {MAX_CELLS} cells)")
    cell = finite(info.resolution, "a map's resolution", 100.0)
    if not cell > 0:
        raise ValueError(f"a map's resolution is {cell:g} m, expected > 0")
    geo = GridGeometry(finite(info.origin.position.x, "a map's origin", MAX_POSITION),
                       finite(info.origin.position.y, "a map's origin", MAX_POSITION), cell, rows, cols)
    data = np.asarray(msg.data, np.int8)
    if data.size != rows * cols:
        raise ValueError(f"a map of {cols} x {rows} cells holds {data.size} values")
    return geo, data.reshape(geo.rows, geo.cols)


_NUMBERS = ("max_speed_m_s", "laser_range_m", "radius_m", "period_s", "sample_period_s", "max_time_s", "epoch_s")
_TEXTS = ("run", "method", "world", "world_source", "pose", "robot")
# what a replay's loop and ground truth can work with (a sample period of 1e-300 s would never end)
_RANGES = {"period_s": (1e-4, 10.0), "sample_period_s": (1e-3, 3600.0), "radius_m": (0.0, 10.0),
           "laser_range_m": (0.0, 1000.0), "max_speed_m_s": (0.0, 100.0)}


def _check_meta(meta: Any) -> dict[str, Any]:  # noqa: C901
    """The `robotexp.run` metadata, its fields checked (ValueError naming the first wrong one)."""
    if not isinstance(meta, dict):
        raise ValueError(f"robotexp.run metadata is a {type(meta).__name__}, expected a JSON object")
    for key in _TEXTS:
        if meta.get(key) is not None and not isinstance(meta[key], str):
            raise ValueError(f"robotexp.run metadata: {key} is {meta[key]!r}, expected text")
    for key in _NUMBERS:
        v = meta.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                              or v < 0 or (key != "epoch_s" and v > 1e9)):
            raise ValueError(f"robotexp.run metadata: {key} is {v!r}, expected a finite number >= 0")
    for key, (low, high) in _RANGES.items():
        if meta.get(key) is not None and not low <= meta[key] <= high:
            raise ValueError(f"robotexp.run metadata: {key} is {meta[key]!r}, expected {low:g}..{high:g}")
    seed = meta.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or abs(seed) >= 2**63):
        raise ValueError(f"robotexp.run metadata: seed is {seed!r}, expected an integer")
    start = meta.get("start")
    if start is not None and not (isinstance(start, list) and len(start) == 3 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and abs(v) <= MAX_POSITION
            for v in start)):
        raise ValueError(f"robotexp.run metadata: start is {start!r}, expected [x, y, theta] of finite numbers")
    g = meta.get("grid")
    if g is not None:
        if not isinstance(g, dict):
            raise ValueError(f"robotexp.run metadata: grid is {g!r}, expected a JSON object")
        for key in ("origin_x", "origin_y", "cell"):
            v = g.get(key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or \
                    abs(v) > MAX_POSITION or (key == "cell" and not v > 0):
                raise ValueError(f"robotexp.run metadata: grid {key} is {v!r}, expected a finite number"
                                 + (" > 0" if key == "cell" else ""))
        rows, cols = g.get("rows"), g.get("cols")
        if not (isinstance(rows, int) and isinstance(cols, int) and not isinstance(rows, bool)
                and not isinstance(cols, bool) and rows >= 1 and cols >= 1):
            raise ValueError(f"robotexp.run metadata: grid rows/cols {rows!r} x {cols!r}, expected integers >= 1")
        if rows * cols > MAX_CELLS:
            raise ValueError(f"robotexp.run metadata: a grid of {cols} x {rows} cells (limit {MAX_CELLS:.3g} cells)")
        if g.get("model") not in ("logodds", "himm"):
            raise ValueError(f"robotexp.run metadata: grid model is {g.get('model')!r}, expected logodds or himm")
        rm = g.get("range_max")
        if rm is not None and (isinstance(rm, bool) or not isinstance(rm, (int, float)) or not math.isfinite(rm)
                               or not rm > 0):
            raise ValueError(f"robotexp.run metadata: grid range_max is {rm!r}, expected a number > 0")
        pf = g.get("p_free")        # older recordings: none (the grid's default)
        if "p_free" in g and (isinstance(pf, bool) or not isinstance(pf, (int, float)) or not 0.0 < pf < 0.5):
            raise ValueError(f"robotexp.run metadata: grid p_free is {pf!r}, expected a number in (0, 0.5)")
    if meta.get("team") is not None:
        _check_team(meta["team"])
    return meta


def _check_team(team: Any) -> None:
    """A team recording's `team` metadata: robot_1, robot_2, ... in order, each with its model and radius."""
    if not isinstance(team, list) or not 1 <= len(team) <= MAX_ROBOTS:
        raise ValueError(f"robotexp.run metadata: team is {str(team)[:60]}, expected a list of 1..{MAX_ROBOTS} robots")
    for i, m in enumerate(team, start=1):
        if not isinstance(m, dict) or m.get("namespace") != f"robot_{i}":
            raise ValueError(f"robotexp.run metadata: team robot {i} is {str(m)[:60]}, expected namespace robot_{i}")
        r = m.get("radius_m")
        if isinstance(r, bool) or not isinstance(r, (int, float)) or not 0 < r <= 10:
            raise ValueError(f"robotexp.run metadata: team robot {i}'s radius_m is {r!r}, expected 0..10 m")
        if m.get("robot") is not None and not isinstance(m["robot"], str):
            raise ValueError(f"robotexp.run metadata: team robot {i}'s robot is {m['robot']!r}, expected text")


def _check_record(record: Any) -> dict[str, Any]:
    """The `robotexp.run.record` metadata, the fields a replay reads checked."""
    if not isinstance(record, dict):
        raise ValueError(f"robotexp.run.record metadata is a {type(record).__name__}, expected a JSON object")
    if record.get("reason") is not None and not isinstance(record["reason"], str):
        raise ValueError(f"robotexp.run.record metadata: reason is {record['reason']!r}, expected text")
    c = record.get("collisions")
    if c is not None and (isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c)):
        raise ValueError(f"robotexp.run.record metadata: collisions is {c!r}, expected a number")
    return record


@dataclass
class _Stream:
    """What one robot's topics hold (a team recording has one per robot, under its namespace)."""

    odom: list[tuple[int, Pose, Twist]] = field(default_factory=list)
    scans: list[tuple[int, _RawScan]] = field(default_factory=list)
    exact: dict[int, LaserScan] = field(default_factory=dict)
    truths: dict[int, Pose] = field(default_factory=dict)
    statics: list[Any] = field(default_factory=list)

    def take(self, topic: str, t: int, msg: Any) -> None:
        """A message of `topic` (without the namespace) at `t` [ns]."""
        if topic == "/odom":
            v = msg.twist.twist
            self.odom.append((t, _pose(msg), Twist(finite(v.linear.x, "a velocity", 1e3),
                                                   finite(v.angular.z, "a turn rate", 1e3))))
        elif topic == "/scan":
            self.scans.append((t, _raw_scan(msg)))
        elif topic == "/robotexp/scan":
            self.exact[t] = _exact_scan(msg)
        elif topic == "/ground_truth":
            self.truths[t] = _pose(msg)
        elif topic == "/tf_static":
            self.statics.extend(msg.transforms)

    def own_ticks(self, t0: int) -> list[Tick]:
        """robotexp's own recording: one tick per /odom, with the scan and true pose of the same stamp."""
        offset_x, yaw = _mount(self.statics, self.scans[0][1].frame) if self.scans else (0.0, 0.0)
        by_time = {t: msg for t, msg in self.scans if t not in self.exact}
        ticks = []
        for t, pose, vel in self.odom:
            raw = by_time.get(t)
            scan = self.exact.get(t) or (None if raw is None else _scan(raw, offset_x, yaw))
            ticks.append(Tick((t - t0) / 1e9, pose, vel, scan, self.truths.get(t)))
        return ticks


def _split(topic: str) -> tuple[str, str]:
    """("robot_1", "/odom") of a team's "/robot_1/odom"; ("", topic) of any other."""
    if topic.startswith("/robot_"):
        ns, _, rest = topic[1:].partition("/")
        return ns, "/" + rest
    return "", topic


def read_bag(path: Path) -> Bag:  # noqa: C901
    """Read a recording (see the module's docstring), within the limits of `robotexp.bag.reading`.

    Raises:
        ConfigError: the file is missing, is not MCAP, holds no /scan with /odom, a record or message
            over its size limit, a message that is not of its topic's type, malformed metadata.
    """
    if not path.is_file():
        raise ConfigError(f"{path}: no such recording; give an .mcap file (robotexp explore --record FILE.mcap)")
    streams: dict[str, _Stream] = {"": _Stream()}
    truth_grid: tuple[GridGeometry, np.ndarray[Any, Any]] | None = None
    marker_msgs: list[tuple[int, Markers]] = []
    meta = record = None
    topics: dict[str, str] = {}
    cut: list[int] = []
    try:
        with open(path, "rb") as f:
            for r in read_records(f, cut=cut):
                if r.topic is None:
                    text = (r.metadata or {}).get("json")
                    if r.name == "robotexp.run":
                        meta = _check_meta(json.loads(text or "null"))
                    elif r.name == "robotexp.run.record":
                        record = _check_record(json.loads(text or "null"))
                    continue
                topics[r.topic] = TOPIC_TYPES.get(r.topic) or TEAM_TOPIC_TYPES[r.topic]
                t, msg = r.time, r.msg
                if r.topic == "/ground_truth/map":
                    truth_grid = _grid_of(msg)
                elif r.topic == "/robotexp/markers":
                    marker_msgs.append((t, markers_of(msg)))
                else:
                    ns, topic = _split(r.topic)
                    streams.setdefault(ns, _Stream()).take(topic, t, msg)
        for stream in streams.values():
            stream.odom.sort(key=lambda o: o[0])
            stream.scans.sort(key=lambda s: s[0])
        marker_msgs.sort(key=lambda m: m[0])
        team = [] if meta is None else [m["namespace"] for m in meta.get("team") or []]
        cut_at = cut[0] if cut else None
        if meta is not None and team:
            return _checked_clock(_team_bag(path, meta, record, topics, streams, team, truth_grid, marker_msgs,
                                            cut_at))
        own = streams[""]
        odom, scans = own.odom, own.scans
        if odom and scans:
            offset_x, yaw = _mount(own.statics, scans[0][1].frame)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    except ConfigError:
        raise
    except decode_errors() as exc:
        raise refuse(path, exc) from None
    if not odom or not scans:
        if cut_at is not None:
            raise ConfigError(f"{path}: the file ends at byte {cut_at}, before its first /scan and /odom (cut "
                              "short); nothing to replay")
        raise ConfigError(f"{path}: a replay needs /scan (sensor_msgs/LaserScan) and /odom (nav_msgs/Odometry); "
                          f"this recording has {', '.join(sorted(topics)) or 'neither'}")
    truth = _truth_of(truth_grid)
    ticks: list[Tick] = []
    if meta is not None:        # robotexp's own: one /odom per tick, scans and true poses at the same stamps
        ticks = own.own_ticks(odom[0][0])
    else:                       # a robot's: one tick per scan, at the newest odometry up to its stamp
        stamps = [t for t, _, _ in odom]
        t0 = None
        for t, raw in scans:
            i = bisect.bisect_right(stamps, t) - 1
            if i < 0:
                continue
            if t0 is None:
                t0 = t
            _, pose, vel = odom[i]
            ticks.append(Tick((t - t0) / 1e9, pose, vel, _scan(raw, offset_x, yaw)))
        if not ticks:
            raise ConfigError(f"{path}: no /scan comes after the first /odom; nothing to replay")
    markers = [((t - odom[0][0]) / 1e9, m) for t, m in marker_msgs] if meta is not None else []
    streams.clear()
    return _checked_clock(Bag(path, ticks, meta, record, truth, topics, markers, cut_at=cut_at))


MAX_GAP = 3600.0        # [s] the longest time between two ticks of a recording (a robot's bag paused for an hour)


def _checked_clock(bag: Bag) -> Bag:
    bag = _checked_times(bag)
    if bag.cut_at is not None:
        log.warning("%s: the file ends at byte %d without its end (cut short, or its run was killed): replayed up "
                    "to there", bag.path, bag.cut_at)
    return bag


def _checked_times(bag: Bag) -> Bag:
    """`bag`, when its clock holds together: consecutive ticks at most MAX_GAP apart, and for robotexp's own
    recordings no later than the run's time limit (one stamp set to 0 or to the year 2500 would otherwise make
    a replay step through billions of seconds).

    Raises:
        ConfigError: a jump in the stamps, saying where.
    """
    limit = (bag.meta or {}).get("max_time_s")
    for robot, ticks in enumerate(bag.team or [bag.ticks], start=1):
        who = f"robot {robot}'s " if bag.team else ""
        times = [t.time for t in ticks]
        for i in range(1, len(times)):
            if times[i] - times[i - 1] > MAX_GAP:
                raise ConfigError(f"{bag.path}: {who}stamps jump by {times[i] - times[i - 1]:.3g} s after robot time "
                                  f"{times[i - 1]:.1f} s (tick {i} of {len(times)}); a recording's clock does not "
                                  "jump: the file is damaged")
        if isinstance(limit, (int, float)) and times and times[-1] > limit + 60.0:
            raise ConfigError(f"{bag.path}: {who}stamps run to robot time {times[-1]:.3g} s, past the run's limit of "
                              f"{limit:g} s: the file is damaged")
    return bag


def _truth_of(truth_grid: tuple[GridGeometry, np.ndarray[Any, Any]] | None) -> GroundTruth | None:
    """The recorded ground truth (/ground_truth/map: 100 occupied, 0 explorable)."""
    if truth_grid is None:
        return None
    geo, states = truth_grid
    explorable = states == 0
    return GroundTruth(geo, states == 100, explorable, explorable)


def _team_bag(path: Path, meta: dict[str, Any], record: dict[str, Any] | None, topics: dict[str, str],  # noqa: PLR0913
              streams: dict[str, _Stream], team: list[str],
              truth_grid: tuple[GridGeometry, np.ndarray[Any, Any]] | None,
              marker_msgs: list[tuple[int, Markers]], cut_at: int | None) -> Bag:
    """A team's recording: each robot's ticks from its namespace's topics, on one time line (the first
    robot's first tick is time 0); `ticks` are robot 1's.

    Raises:
        ConfigError: a robot of the team has no /odom or no scan.
    """
    missing = [ns for ns in team if ns not in streams or not streams[ns].odom or not streams[ns].scans]
    if missing:
        raise ConfigError(f"{path}: a team recording needs /{missing[0]}/odom and /{missing[0]}/scan for each robot "
                          f"of its `team` metadata; this one has {', '.join(sorted(topics)) or 'neither'}")
    t0 = min(streams[ns].odom[0][0] for ns in team)
    robots = [streams[ns].own_ticks(t0) for ns in team]
    markers = [((t - t0) / 1e9, m) for t, m in marker_msgs]
    return Bag(path, robots[0], meta, record, _truth_of(truth_grid), topics, markers, robots, cut_at)


class ReplayRobot(Robot):
    """A robot that reads a recording's ticks in order (commands go nowhere). `on_last()` is called when
    the last tick is read."""

    name = "replay"
    capabilities = frozenset({Capability.PACED_CLOCK})
    replayed = True         # the live view paces it by robot time, as a simulator (robotexp.view.observer)

    def __init__(self, ticks: list[Tick], *, radius: float = 0.25, model: str = "replay",
                 final_extra: dict[str, float] | None = None,
                 on_last: Callable[[], None] | None = None) -> None:
        self.ticks = ticks
        self.radius = radius
        self._model = model
        self.limits = Limits(10.0, 10.0, 100.0, 100.0)
        self._i = 0
        self._final_extra = dict(final_extra or {})
        self.on_last = on_last
        super().__init__()

    @property
    def model(self) -> str:
        """The recorded robot's model."""
        return self._model

    def make_clock(self, period: float) -> Clock:
        """A clock whose ticks take no time (the recording's stamps are the robot time)."""
        return SimClock(period, lambda dt: None)

    def _read(self) -> RobotState:
        i = min(self._i, len(self.ticks) - 1)
        self._i += 1
        t = self.ticks[i]
        last = i == len(self.ticks) - 1
        if last and self.on_last is not None:
            self.on_last()
        return RobotState(time=t.time, pose=t.pose, velocity=t.velocity, laser=t.scan, true_pose=t.true_pose,
                          extra=self._final_extra if last else {})

    def _command(self, twist: Twist) -> None:
        pass

    def _close(self) -> None:
        pass


class ReplayExplorer(Explorer):
    """Drives nothing: returns the recorded velocity until the last tick, then Done when the recorded
    run ended explored. Its markers are the recorded ones of the tick read last."""

    needs_range = False     # it plays back what was recorded, scans or none

    def __init__(self, robot: ReplayRobot, done_reason: str | None,
                 markers: Sequence[tuple[float, Markers]] = ()) -> None:
        self.robot, self.done_reason = robot, done_reason
        self._markers = list(markers)
        self._marker_times = [t for t, _ in self._markers]

    def markers(self) -> Markers:
        """The recorded markers newest at the robot time of the tick read last ({} before the first)."""
        ticks = self.robot.ticks
        if not self._markers or not ticks:
            return {}
        t = ticks[min(max(self.robot._i - 1, 0), len(ticks) - 1)].time
        i = bisect.bisect_right(self._marker_times, t + 1e-9) - 1
        return self._markers[i][1] if i >= 0 else {}

    def reset(self, ctx: ExplorerContext) -> None:
        """Nothing to reset."""

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        """The recorded velocity; Done(reason) at the last tick of a run that ended explored."""
        if self.robot._i >= len(self.robot.ticks) and self.done_reason is not None:
            return Done(self.done_reason)
        return state.velocity


def _truth_at(bag: Bag, geo: GridGeometry, world_file: Path | None = None) -> GroundTruth | None:
    """Ground truth on `geo`: the recorded one when it has that geometry, else recomputed from the
    recorded world (None, with a warning, when that cannot be done). A recording names its world; a built-in
    or generated one is made again, but a map file it names is never opened (a recording is data, and may
    come from anyone): `world_file`, given by the user, stands for it."""
    t = bag.truth
    if t is not None and (t.geo.rows, t.geo.cols) == (geo.rows, geo.cols) and \
            max(abs(t.geo.origin_x - geo.origin_x), abs(t.geo.origin_y - geo.origin_y)) < 1e-6 * geo.cell + 1e-9 \
            and abs(t.geo.cell - geo.cell) < 1e-6 * geo.cell:      # the message's resolution is a float32
        return GroundTruth(geo, t.occupied, t.reachable, t.explorable)
    meta = bag.meta
    if meta is None or bag.truth is None or not meta.get("world_source") or meta.get("start") is None:
        return None
    from robotexp.world.loader import is_map_file, load_world

    source = str(meta["world_source"])
    if world_file is None and is_map_file(source):
        log.warning("%s: its world is the map file %s, which a replay does not open by itself: coverage n/a at "
                    "a cell of %g m (give --world with that map to have it)", bag.path, source, geo.cell)
        return None
    try:
        world = load_world(str(world_file) if world_file is not None else source)
        return ground_truth(world, geo, robot_radius=meta["radius_m"], laser_range=meta["laser_range_m"],
                            start=Pose(*meta["start"]))
    except (WorldError, ConfigError, OSError) as exc:
        log.warning("%s: no ground truth at cell %g m (%s): coverage n/a", bag.path, geo.cell, exc)
        return None


def replay_bag(bag: Bag, out: Path | None, *, cell: float | None = None, image: bool = True,  # noqa: PLR0913
               observers: Iterable[RunObserver] = (), world_file: Path | None = None) -> ExplorationRun:
    """Rebuild the map and metrics of `bag` through the run loop and, with `out`, write the results
    there as `robotexp explore` does (results.jsonl, CSVs, map files and images).

    Args:
        cell: [m] map cell (None: the recorded one; a foreign bag: 0.1).
        world_file: the map file of the recorded world, for ground truth at another cell (`_truth_at`).

    Raises:
        ConfigError: a cell size out of range.
        OSError: the results could not be written.
    """
    from robotexp.output.results import ResultsWriter, run_id
    from robotexp.output.safefile import safe_name

    if cell is not None and not 0.005 <= cell <= 2.0:
        raise ConfigError(f"cell size must be within 5..2000 mm, got {cell * 1000:g} mm")
    meta = bag.meta or {}
    rec = bag.record or {}
    scans = [t.scan for t in bag.ticks if t.scan is not None]
    laser_range = meta.get("laser_range_m") or max(s.range_max for s in scans)
    g = meta.get("grid")
    if g is not None:
        recorded = GridGeometry(g["origin_x"], g["origin_y"], g["cell"], g["rows"], g["cols"])
        geo = recorded if cell is None or cell == recorded.cell else GridGeometry.covering(
            recorded.origin_x, recorded.origin_y, recorded.origin_x + recorded.width,
            recorded.origin_y + recorded.height, cell=cell)
        model, range_max = g["model"], g["range_max"]
        free = {"p_free": float(g["p_free"])} if "p_free" in g else {}     # older recordings: the default
    else:
        xs = [t.pose.x for t in bag.ticks]
        ys = [t.pose.y for t in bag.ticks]
        r = laser_range + FOREIGN_MARGIN
        geo = GridGeometry.covering(min(xs) - r, min(ys) - r, max(xs) + r, max(ys) + r, cell=cell or 0.1)
        model, range_max = "logodds", None
        free = {}
    grid = OccupancyGrid(geo, model=model, range_max=range_max, **free)
    truth = _truth_at(bag, geo, world_file)
    end = EndReason.classify(bool(rec.get("completed")), str(rec.get("reason", ""))) if rec else EndReason.STOPPED
    reason = str(rec.get("reason", "stopped: end of the recording")) if rec else "stopped: end of the recording"
    if bag.cut_at is not None:      # what the recorded record says of its end, the replay did not reach
        end, reason = EndReason.STOPPED, f"stopped: the recording ends at byte {bag.cut_at} (cut short)"
    run_box: list[ExplorationRun] = []

    def on_last() -> None:
        if end is not EndReason.EXPLORED and run_box:
            run_box[0].request_stop(reason, EndReason.STOPPED if end is EndReason.UNKNOWN else end)

    world = meta.get("world") or bag.path.stem
    method = meta.get("method") or "replay"
    pose = meta.get("pose") or "robot"
    speed = meta.get("max_speed_m_s") or 0.0
    info_extra: dict[str, Any] = {"replay_of": str(bag.path)}
    if out is None:
        name = safe_name(meta.get("run") or f"{world}_{method}_{pose}")    # the recording's word: one file name
    else:
        out.mkdir(parents=True, exist_ok=True)
        coordinator = rec.get("coordinator") if isinstance(rec.get("coordinator"), str) else "none"
        label = f"{method}-team{len(bag.team)}-{coordinator}" if bag.team else method     # as the team's run
        name = run_id(world, label, pose, speed, int(meta.get("seed", 0)), out)
    info = RunInfo(name=name, method=method, world=world, pose=pose, robot=meta.get("robot") or "replay",
                   max_speed=speed, laser_range=laser_range, extra=info_extra)
    chain: list[RunObserver] = [] if out is None else [ResultsWriter(out, image=image)]
    chain.extend(observers)
    if bag.team:        # a team's recording: its robots replayed together, as they ran
        run: ExplorationRun = replay_team(bag, grid, truth, info, chain, end, reason)
    else:
        extra = {"collisions": float(rec["collisions"])} if rec.get("collisions") else {}
        robot = ReplayRobot(bag.ticks, radius=meta.get("radius_m", 0.25), model=meta.get("robot") or "replay",
                            final_extra=extra, on_last=on_last)
        explorer = ReplayExplorer(robot, reason if end is EndReason.EXPLORED else None, bag.markers)
        run = ExplorationRun(robot, explorer, grid, truth=truth, period=meta.get("period_s", 0.1),
                             max_time=bag.ticks[-1].time + 1.0,
                             sample_period=meta.get("sample_period_s", 1.0), seed=int(meta.get("seed", 0)),
                             info=info, observers=chain)
        run_box.append(run)
        with robot:
            run.run()
    for observer, exc in run.observer_errors:
        if observer.critical:
            raise exc
    return run


def replay_team(bag: Bag, grid: OccupancyGrid, truth: GroundTruth | None, info: RunInfo,  # noqa: PLR0913
                observers: Iterable[RunObserver], end: EndReason, reason: str) -> TeamRun:
    """Replay a team's recording: each robot's recorded ticks stepped together in a `TeamRun`, so that
    the team's map, coverage and record come from the same code as the run's (the teammates' beams left
    out of the map as they were, every robot's path kept), ending as the recording did (`end`, `reason`:
    the record's); returns the finished run.

    The robots drive nothing: each one's explorer hands back the recorded velocity, ending explored at
    its last tick when the record says that robot ended so. No coordinator assigns targets (the robots
    went where the run's coordinator sent them), and the replay keeps one map for the team whatever the
    run's communication range (the team's map of the run held every robot's scans too)."""
    meta = bag.meta or {}
    rec = bag.record or {}
    robots_meta = meta["team"]
    listed = rec.get("robots")
    per: list[Any] = listed if isinstance(listed, list) else []
    n = len(bag.team)
    longest = max(range(n), key=lambda i: (len(bag.team[i]), -i))     # its last tick is the recording's end
    box: list[TeamRun] = []

    def on_last() -> None:
        if end is not EndReason.EXPLORED and box:
            box[0].request_stop(reason, EndReason.STOPPED if end is EndReason.UNKNOWN else end)

    robots, explorers = [], []
    for i, ticks in enumerate(bag.team):
        r: dict[str, Any] = per[i] if i < len(per) and isinstance(per[i], dict) else {}
        hits = r.get("collisions")
        extra = {"collisions": float(hits)} if isinstance(hits, int) and not isinstance(hits, bool) and hits else {}
        robot = ReplayRobot(ticks, radius=robots_meta[i]["radius_m"], model=robots_meta[i].get("robot") or "replay",
                            final_extra=extra, on_last=on_last if i == longest else None)
        done = r.get("reason") if r.get("end") == EndReason.EXPLORED.value and isinstance(r.get("reason"), str) \
            and bag.cut_at is None else None
        robots.append(robot)
        explorers.append(ReplayExplorer(robot, done, bag.markers if i == 0 else ()))
    period = meta.get("period_s", 0.1)
    run = TeamRun(robots, explorers, [grid] * n, SimClock(period, lambda dt: None), truth=truth, period=period,
                  max_time=max(t[-1].time for t in bag.team) + 1.0, seed=int(meta.get("seed", 0)), info=info,
                  observers=observers)
    coordinator = rec.get("coordinator")
    run.coordinator_name = coordinator if isinstance(coordinator, str) else "none"
    box.append(run)
    try:
        run.run()
    finally:
        for robot in robots:
            robot.close()
    return run

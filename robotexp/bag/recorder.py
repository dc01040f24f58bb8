"""Record a run as a ROS 2 bag in MCAP (`BagRecorder`, a run observer).

Topics (message time = the run's robot time since its start plus `EPOCH`, so that ROS 2 tools see
plausible stamps; every tick of the run has one /odom and one /tf at the same stamp):

    /odom              nav_msgs/Odometry        every tick: the pose the map used (odom -> base_link)
    /tf                tf2_msgs/TFMessage       every tick: map -> odom (identity) and odom -> base_link
    /tf_static         tf2_msgs/TFMessage       once: base_link -> laser (the scan's offset ahead)
    /scan              sensor_msgs/LaserScan    the ticks whose scan the map integrated, in frame `laser`
    /robotexp/scan     robotexp_msgs/ExactScan  the same scans in float64 (LaserScan's float32 rounds them), so
                                                that a replay integrates exactly what the run did
    /ground_truth      nav_msgs/Odometry        every tick with a true pose (simulators): map -> base_link
    /map               nav_msgs/OccupancyGrid   every coverage sample (1 s of robot time) and at the end
    /ground_truth/map  nav_msgs/OccupancyGrid   once, with ground truth: 100 occupied, 0 explorable, -1 other
    /robotexp/markers  visualization_msgs/MarkerArray  the explorer's markers (`Explorer.markers()`: tree
                                                nodes and edges, safe regions, the target) at the coverage
                                                samples where they changed (at most once a robot second;
                                                `robotexp.bag.markers`)

A team run (`robotexp explore --team`) records each robot under its namespace, `/robot_1`, `/robot_2`, ...
(numbered from 1, as the team's record and files number them): /robot_1/odom, /robot_1/tf,
/robot_1/tf_static, /robot_1/scan, /robot_1/robotexp/scan and /robot_1/ground_truth, the same messages
as above with frames prefixed by the namespace (robot_1/odom, robot_1/base_link, robot_1/laser; map ->
robot_1/odom is the identity); a robot's /robotexp/scan is its scan as the maps took it (the beams that
ended on a teammate, which the team does not map, read NaN). /map is the team's map (every robot's
scans); with a communication range each robot's own map is /robot_1/map as well. /robotexp/markers are
robot 1's. The `robotexp.run` metadata then has a `team` list: each robot's namespace, model, radius [m]
and start pose.

and two metadata records: `robotexp.run` (what a replay needs: the grid's geometry, model and range
cap, the run's names, period and robot radius; JSON text under the key `json`) at the start and
`robotexp.run.record` (the run's record, as written to results.jsonl) at the end.

The recorder only exists when asked for (`--record`): a run without it does no work for it. Messages
are encoded by `robotexp.bag.cdr` (numpy; recording a 300 s run on `dense` costs about 10 % of its
wall time: `python benchmarks/speed/bench_record.py`) and written with the `mcap` writer (zstd chunks).
"""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from robotexp.bag import cdr
from robotexp.bag.markers import marker_array
from robotexp.bag.schemas import EXACT_SCAN, LASER_SCAN, MARKER_ARRAY, OCCUPANCY_GRID, ODOMETRY, TF_MESSAGE
from robotexp.errors import ConfigError
from robotexp.markers import markers_problem
from robotexp.mapping.geometry import GridGeometry
from robotexp.run.observers import RunObserver, StepEvent
from robotexp.robot import LaserScan, Pose, RobotState

if TYPE_CHECKING:
    from mcap.writer import Writer

    from robotexp.run.loop import ExplorationRun
    from robotexp.world.groundtruth import GroundTruth
    from robotexp.run.record import RunRecord

__all__ = ["BagRecorder", "EPOCH", "stamp_ns", "yaw_of", "robot_namespace", "_check_record_path"]

log = logging.getLogger(__name__)

EPOCH = 1_700_000_000.0     # [s] added to robot time in message stamps (a plausible wall-clock time)
FORMAT = 1                  # version of the `robotexp.run` metadata


def robot_namespace(robot: int) -> str:
    """The namespace of a team's robot `robot` (0-based) in a recording: "robot_1" for the first."""
    return f"robot_{robot + 1}"


def stamp_ns(t: float) -> int:
    """The message time [ns] of robot time `t` [s]."""
    return int(round((EPOCH + t) * 1e9))


def yaw_of(q: Any) -> float:
    """The heading [rad] of a quaternion (its rotation about z; x and y taken as a tilt-free pose)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _check_record_path(path: Path) -> None:
    """Raise ConfigError unless `path` names an .mcap file in an existing folder.

    Raises:
        ConfigError: wrong suffix or missing folder.
    """
    if path.suffix.lower() != ".mcap":
        raise ConfigError(f"--record {path}: a recording is an .mcap file; name it FILE.mcap")
    if not path.parent.is_dir():
        raise ConfigError(f"--record {path}: folder {path.parent} does not exist; create it first")


def _laser_scan_message(ns: int, scan: LaserScan, period: float, frame: str = "laser") -> bytes:
    """A sensor_msgs/LaserScan of `scan` (frame `laser`; beams evenly spread from the first angle to the last)."""
    n = len(scan.angles)
    a0, a1 = (float(scan.angles[0]), float(scan.angles[-1])) if n else (0.0, 0.0)
    return cdr.laser_scan(ns, frame, a0, a1, (a1 - a0) / (n - 1) if n > 1 else 0.0, period, 0.0,
                          float(scan.range_max), scan.ranges)


def exact_scan_message(ns: int, scan: LaserScan, frame: str = "laser") -> bytes:
    """A robotexp_msgs/ExactScan of `scan`: `angles` left empty when angle_min + i * angle_increment
    gives every beam's angle exactly."""
    angles = np.asarray(scan.angles, np.float64)
    n = len(angles)
    a0 = float(angles[0]) if n else 0.0
    inc = float((angles[-1] - angles[0]) / (n - 1)) if n > 1 else 0.0
    regular = bool(np.array_equal(a0 + np.arange(n) * inc, angles))
    return cdr.exact_scan(ns, frame, a0, inc, () if regular else angles, scan.ranges, float(scan.range_max),
                          float(scan.offset_x))


def _truth_states(truth: GroundTruth) -> np.ndarray[Any, Any]:
    """The ground truth as map states: 100 occupied, 0 explorable, -1 any other cell."""
    out = np.full(truth.explorable.shape, -1, np.int8)
    out[truth.explorable] = 0
    out[truth.occupied] = 100
    return out


class BagRecorder(RunObserver):
    """Writes a run to `path` as a ROS 2 bag in MCAP (see the module's docstring for what it holds).

    It is `critical`: a recording asked for that cannot be written is an error of the run's caller
    (raised after the run, whose results are written first), never a silent gap.

    Args:
        path: the .mcap file (replaced if it exists), opened at once.
        folder: instead of `path`: the run is written to `folder/<run>.mcap`, opened when the run
            starts (a script's or a campaign's runs, one file each).
        world: what names the run's world for a replay that recomputes ground truth at another cell
            size (a built-in name or a world file), None when unknown.
        start: the start pose ground truth was computed from (None: the run's first true pose).

    Raises:
        ConfigError: `path` is not a writable .mcap file.
    """

    critical = True

    def __init__(self, path: Path | None = None, *, folder: Path | None = None, world: str | None = None,
                 start: Pose | None = None) -> None:
        if (path is None) == (folder is None):
            raise ConfigError("BagRecorder: give a path or a folder")
        self.folder = folder
        self.path = path if path is not None else Path("unstarted.mcap")
        self.world = world if world is None or not Path(world).exists() else str(Path(world).resolve())
        self.start = start
        self._file: IO[bytes] | None = None
        self._writer: Writer | None = None
        if path is not None:
            _check_record_path(path)
            self._open(path)
        self._channels: dict[str, int] = {}
        self._schema_ids: dict[str, int] = {}
        self._seq: dict[str, int] = {}
        self._static_done: set[str] = set()     # the namespaces whose /tf_static is written
        self._last_ns = 0
        self._period = 0.1
        self._closed = False
        self._started = False
        self._map_ns = -1
        self._markers: dict[str, Any] | None = None
        self._markers_warned = False

    def _open(self, path: Path) -> None:
        from mcap.writer import CompressionType, Writer

        try:
            self._file = open(path, "wb")
        except OSError as exc:
            raise ConfigError(f"recording {path}: cannot write it ({exc.strerror}); pick another file") from None
        self.path = path
        self._writer = Writer(self._file, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="robotexp")

    def _write(self, topic: str, schema: tuple[str, str], data: bytes, ns: int) -> None:
        assert self._writer is not None
        channel = self._channels.get(topic)
        if channel is None:
            name, text = schema
            schema_id = self._schema_ids.get(name)
            if schema_id is None:
                schema_id = self._schema_ids[name] = self._writer.register_schema(name, "ros2msg", text.encode())
            channel = self._channels[topic] = self._writer.register_channel(topic, "cdr", schema_id)
        seq = self._seq.get(topic, 0)
        self._seq[topic] = seq + 1
        self._writer.add_message(channel, log_time=ns, data=data, publish_time=ns, sequence=seq)

    def _write_grid(self, topic: str, geo: GridGeometry, states: np.ndarray[Any, Any], ns: int) -> None:
        self._write(topic, OCCUPANCY_GRID, cdr.occupancy_grid(ns, "map", geo.origin_x, geo.origin_y, geo.cell,
                                                               geo.rows, geo.cols, states), ns)

    def on_start(self, run: ExplorationRun) -> None:
        """Write the `robotexp.run` metadata and the ground truth map."""
        if self._writer is None:
            assert self.folder is not None
            try:
                self.folder.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise ConfigError(f"recording folder {self.folder}: cannot make it ({exc.strerror})") from None
            self._open(self.folder / f"{run.info.name}.mcap")
        assert self._writer is not None
        self._started = True
        g = run.grid.geo
        self._period = run.period
        start = self.start or run.start_pose
        meta = {"format": FORMAT, "run": run.info.name, "method": run.info.method, "world": run.info.world,
                "world_source": self.world, "pose": run.info.pose, "robot": run.info.robot,
                "max_speed_m_s": run.info.max_speed, "laser_range_m": run.info.laser_range,
                "radius_m": run.robot.radius, "period_s": run.period, "sample_period_s": run.sample_period,
                "max_time_s": run.max_time, "seed": run.seed,
                "start": None if start is None else start.as_list(),
                "grid": {"origin_x": g.origin_x, "origin_y": g.origin_y, "cell": g.cell, "rows": g.rows,
                         "cols": g.cols, "model": run.grid.model, "range_max": run.grid.range_max,
                         "p_free": run.grid.p_free},
                "epoch_s": EPOCH}
        members = getattr(run, "members", None)        # a team run (robotexp.run.team.TeamRun)
        if members is not None:
            meta["team"] = [{"namespace": robot_namespace(i), "robot": m.robot.model, "radius_m": m.robot.radius,
                             "start": None if m.start_pose is None else m.start_pose.as_list()}
                            for i, m in enumerate(members)]
        self._writer.add_metadata("robotexp.run", {"json": json.dumps(meta)})
        if run.truth is not None:
            self._write_grid("/ground_truth/map", run.truth.geo, _truth_states(run.truth), stamp_ns(0.0))

    def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
        """Write the tick's odometry, transforms, true pose and (when the map took it) scan."""
        self.write_state(step.time, step.state, step.map_updated, run.period)

    def on_robot_step(self, run: ExplorationRun, robot: int, step: StepEvent) -> None:
        """A team's robot's tick: as `on_step`, under the robot's namespace (/robot_1/odom, ...); its
        /robotexp/scan is the scan as the map took it (the beams that ended on a teammate read NaN)."""
        members = getattr(run, "members", None)
        mapped = members[robot].mapped_scan if members is not None and step.map_updated else None
        self.write_state(step.time, step.state, step.map_updated, run.period, namespace=robot_namespace(robot),
                         mapped=mapped)

    def write_state(self, time: float, state: RobotState, scan: bool = True, period: float = 0.1,  # noqa: PLR0913
                    namespace: str = "", mapped: LaserScan | None = None) -> None:
        """Write a state read at robot time `time` [s]: /odom, /tf, /ground_truth when known and, with
        `scan`, its laser scan (/scan, /robotexp/scan; /tf_static once). `robotexp connect --record`
        calls this for each state it reads (no run, no map: such a bag replays as a robot's). A
        `namespace` ("robot_1") puts the topics under it and prefixes the frames with it; `mapped`: the scan
        as the map took it, for /robotexp/scan (default: the state's)."""
        if self._writer is None:
            raise ConfigError("BagRecorder: a recorder given a folder opens its file when a run starts")
        ns = stamp_ns(time)
        self._last_ns = ns
        top = f"/{namespace}" if namespace else ""
        pre = f"{namespace}/" if namespace else ""
        s = state
        p = s.pose
        v = s.velocity
        self._write(f"{top}/odom", ODOMETRY, cdr.odometry(ns, f"{pre}odom", f"{pre}base_link", p.x, p.y, p.theta,
                                                           v.v, v.w), ns)
        self._write(f"{top}/tf", TF_MESSAGE, cdr.tf_message(ns, [("map", f"{pre}odom", 0.0, 0.0, 0.0),
                                                                 (f"{pre}odom", f"{pre}base_link", p.x, p.y,
                                                                  p.theta)]), ns)
        t = s.true_pose
        if t is not None:
            self._write(f"{top}/ground_truth", ODOMETRY, cdr.odometry(ns, "map", f"{pre}base_link_true", t.x, t.y,
                                                                       t.theta, 0.0, 0.0), ns)
        if scan and s.laser is not None:
            if namespace not in self._static_done:
                self._static_done.add(namespace)
                self._write(f"{top}/tf_static", TF_MESSAGE,
                            cdr.tf_message(ns, [(f"{pre}base_link", f"{pre}laser", s.laser.offset_x, 0.0, 0.0)]), ns)
            self._write(f"{top}/scan", LASER_SCAN, _laser_scan_message(ns, s.laser, period, f"{pre}laser"), ns)
            self._write(f"{top}/robotexp/scan", EXACT_SCAN, exact_scan_message(ns, mapped or s.laser, f"{pre}laser"),
                        ns)
        self._started = True

    def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
        """Write the map (once per coverage sample: 1 Hz of robot time; the end's sample repeats the last
        tick's, whose map is written already)."""
        ns = stamp_ns(time)
        if ns != self._map_ns:
            self._map_ns = ns
            self._write_grid("/map", run.grid.geo, run.grid.states(), ns)
            members = getattr(run, "members", None)
            if members is not None and getattr(run, "comm_range", None) is not None:   # a map each
                for i, m in enumerate(members):
                    self._write_grid(f"/{robot_namespace(i)}/map", m.grid.geo, m.grid.states(), ns)
            self._write_markers(run, ns)

    def _write_markers(self, run: ExplorationRun, ns: int) -> None:
        """The explorer's markers when they changed since the last ones written (malformed ones: skipped
        with a warning, once)."""
        markers = run.explorer.markers()
        if markers == self._markers:
            return
        problem = markers_problem(markers)
        if problem is not None:
            if not self._markers_warned:
                self._markers_warned = True
                log.warning("recording %s: %s; markers not recorded", self.path, problem)
            return
        self._markers = markers
        self._write("/robotexp/markers", MARKER_ARRAY, marker_array(ns, markers), ns)

    def on_end(self, run: ExplorationRun, record: RunRecord) -> None:
        """Write the record as metadata and close the file."""
        assert self._writer is not None
        self._writer.add_metadata("robotexp.run.record", {"json": json.dumps(record.as_dict())})
        self.close()

    def close(self) -> None:
        """Finish the file (its summary and index); a run that never started leaves no file. Safe to
        call twice."""
        if not self._closed and self._writer is not None and self._file is not None:
            self._closed = True
            try:
                self._writer.finish()
            finally:
                self._file.close()
                if not self._started:
                    self.path.unlink(missing_ok=True)

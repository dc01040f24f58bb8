"""Recordings: a run recorded as a ROS 2 bag in MCAP, read back with the mcap reader, replayed to the
same metrics; a bag written by another tool (the mcap-ros2 writer, /scan + /odom only) replays too."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.writer import Writer

from robotexp.bag.recorder import EPOCH
from robotexp.bag.replay import read_bag, replay_bag
from robotexp.cli import main
from robotexp.output.results import read_jsonl


def _last(path: Path) -> dict[str, object]:
    return read_jsonl(path)[-1]

TOPICS = {"/scan": "sensor_msgs/msg/LaserScan", "/odom": "nav_msgs/msg/Odometry", "/tf": "tf2_msgs/msg/TFMessage",
          "/tf_static": "tf2_msgs/msg/TFMessage", "/map": "nav_msgs/msg/OccupancyGrid",
          "/ground_truth": "nav_msgs/msg/Odometry", "/ground_truth/map": "nav_msgs/msg/OccupancyGrid",
          "/robotexp/scan": "robotexp_msgs/msg/ExactScan", "/robotexp/markers": "visualization_msgs/msg/MarkerArray"}


def test_recording_holds_ros2_topics(recorded: tuple[Path, dict[str, object]]) -> None:
    bag, record = recorded
    counts: dict[str, int] = {}
    with open(bag, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        assert {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()} == TOPICS
        assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
        first_scan = first_map = None
        stamps = []
        for _, channel, message, msg in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/scan" and first_scan is None:
                first_scan = msg
            if channel.topic == "/map":
                first_map = first_map or msg
            if channel.topic == "/odom":
                stamps.append(message.log_time)
                assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == message.log_time
    # one /odom and /tf per 0.1 s tick over 25 s (ticks 0 .. 25 s), a map per second and at the end
    assert counts["/odom"] == counts["/tf"] == counts["/ground_truth"] == 251
    assert 1 <= counts["/scan"] == counts["/robotexp/scan"] <= 251
    assert counts["/tf_static"] == counts["/ground_truth/map"] == 1
    assert counts["/map"] == 26
    assert stamps[0] == round(EPOCH * 1e9) and stamps[-1] - stamps[0] == pytest.approx(25e9, abs=1e6)
    assert first_scan is not None and first_scan.header.frame_id == "laser"
    assert first_scan.range_max == pytest.approx(3.0)
    n = len(first_scan.ranges)
    assert first_scan.angle_min + (n - 1) * first_scan.angle_increment == pytest.approx(first_scan.angle_max, abs=1e-6)
    assert first_map is not None and first_map.info.resolution == pytest.approx(record["cell_m"])
    assert len(first_map.data) == first_map.info.width * first_map.info.height
    assert set(first_map.data) <= {-1, 0, 100}


def test_replay_reproduces_the_run(recorded: tuple[Path, dict[str, object]], tmp_path: Path) -> None:
    bag, record = recorded
    res = CliRunner().invoke(main, ["replay", str(bag), "-o", str(tmp_path / "rep")])
    assert res.exit_code == 0, res.output
    again = _last(tmp_path / "rep" / "results.jsonl")
    assert isinstance(record["coverage"], float) and record["coverage"] > 0.2
    for key in ("coverage", "path_length_m", "robot_time_s", "map_iou", "visited_cells", "collisions", "completed",
                "reason", "cell_m", "world", "method"):
        assert again[key] == record[key], key
    assert again["start_pose"] == pytest.approx(record["start_pose"], abs=1e-12)   # heading through a quaternion
    assert (tmp_path / "rep" / f"{again['run']}.png").is_file()
    # another cell size: ground truth is recomputed from the recorded world, coverage stays close
    res = CliRunner().invoke(main, ["replay", str(bag), "-o", str(tmp_path / "rep2"), "--cell", "50"])
    assert res.exit_code == 0, res.output
    fine = _last(tmp_path / "rep2" / "results.jsonl")
    assert fine["cell_m"] == 0.05 and fine["path_length_m"] == record["path_length_m"]
    assert isinstance(fine["coverage"], float) and abs(fine["coverage"] - record["coverage"]) < 0.05


# -- a bag written by another tool: the mcap-ros2 writer with schemas typed here, /scan + /odom only --
SCAN_DEF = """std_msgs/Header header
float32 angle_min
float32 angle_max
float32 angle_increment
float32 time_increment
float32 scan_time
float32 range_min
float32 range_max
float32[] ranges
float32[] intensities
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id"""
ODOM_DEF = """std_msgs/Header header
string child_frame_id
geometry_msgs/PoseWithCovariance pose
geometry_msgs/TwistWithCovariance twist
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: geometry_msgs/PoseWithCovariance
Pose pose
float64[36] covariance
================================================================================
MSG: geometry_msgs/Pose
Point position
Quaternion orientation
================================================================================
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
================================================================================
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
================================================================================
MSG: geometry_msgs/TwistWithCovariance
Twist twist
float64[36] covariance
================================================================================
MSG: geometry_msgs/Twist
Vector3 linear
Vector3 angular
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z"""

HALF = 2.0          # [m] the room is the square |x|, |y| <= HALF


def _room_ranges(x: float, y: float, theta: float, angles: np.ndarray, rmax: float) -> list[float]:
    """Ranges from (x, y) to the walls of the square room; beyond rmax: +inf (no echo, REP 117)."""
    out = []
    for a in angles:
        c, s = math.cos(theta + a), math.sin(theta + a)
        t = min([(HALF - x) / c if c > 1e-12 else math.inf, (-HALF - x) / c if c < -1e-12 else math.inf,
                 (HALF - y) / s if s > 1e-12 else math.inf, (-HALF - y) / s if s < -1e-12 else math.inf])
        out.append(t if t <= rmax else math.inf)
    return out


def _stamp(t: float) -> dict[str, int]:
    ns = int(round((1000 + t) * 1e9))
    return {"sec": ns // 10**9, "nanosec": ns % 10**9}


def test_foreign_bag_replays(tmp_path: Path) -> None:
    bag = tmp_path / "robot.mcap"
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    with open(bag, "wb") as f:
        w = Writer(f)
        scan_s = w.register_msgdef("sensor_msgs/msg/LaserScan", SCAN_DEF)
        odom_s = w.register_msgdef("nav_msgs/msg/Odometry", ODOM_DEF)
        # odometry at 20 Hz, driving +x at 0.2 m/s for 5 s from (-1, 0); scans at 10 Hz, 0.01 s after
        for i in range(101):
            t = i * 0.05
            ns = int(round((1000 + t) * 1e9))
            w.write_message("/odom", odom_s, {
                "header": {"stamp": _stamp(t), "frame_id": "odom"}, "child_frame_id": "base_footprint",
                "pose": {"pose": {"position": {"x": -1.0 + 0.2 * t, "y": 0.0, "z": 0.0},
                                  "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}, "covariance": [0.0] * 36},
                "twist": {"twist": {"linear": {"x": 0.2, "y": 0.0, "z": 0.0},
                                    "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
                          "covariance": [0.0] * 36}}, log_time=ns, publish_time=ns)
        for i in range(50):
            t = i * 0.1 + 0.01
            ns = int(round((1000 + t) * 1e9))
            x = -1.0 + 0.2 * (t - 0.01)         # the newest odometry at or before the scan
            w.write_message("/scan", scan_s, {
                "header": {"stamp": _stamp(t), "frame_id": "base_scan"}, "angle_min": float(angles[0]),
                "angle_max": float(angles[-1]), "angle_increment": float(angles[1] - angles[0]),
                "time_increment": 0.0, "scan_time": 0.1, "range_min": 0.12, "range_max": 3.5,
                "ranges": _room_ranges(x, 0.0, 0.0, angles, 3.5), "intensities": []}, log_time=ns, publish_time=ns)
        w.finish()
    data = read_bag(bag)
    assert data.meta is None and data.truth is None and len(data.ticks) == 50
    assert data.ticks[-1].pose.x == pytest.approx(-1.0 + 0.2 * 4.9)
    run = replay_bag(data, None, cell=0.1)
    grid = run.grid
    occ, free = grid.occupied(), grid.free()
    # the walls are mapped where they are, the room's inside is free
    for wx, wy in ((HALF + 0.03, 0.0), (-HALF - 0.03, 0.0), (0.0, HALF + 0.03), (0.0, -HALF - 0.03)):
        assert occ[grid.geo.cell_of(wx, wy)], (wx, wy)
    for fx, fy in ((0.0, 0.0), (1.5, 1.5), (-1.5, -1.5), (1.0, -1.2)):
        assert free[grid.geo.cell_of(fx, fy)], (fx, fy)
    assert run.record is not None and run.record.coverage is None
    assert run.record.path_length_m == pytest.approx(0.2 * 4.9, abs=1e-4)
    assert run.record.robot_time_s == pytest.approx(4.9)
    # the command writes results as explore does
    res = CliRunner().invoke(main, ["replay", str(bag), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    rec = _last(tmp_path / "out" / "results.jsonl")
    assert rec["coverage"] is None and rec["path_length_m"] == pytest.approx(0.98, abs=1e-4)
    # the view's player seeks in it too: the map at the end is the replay's, at 2 s that of 21 scans
    from robotexp.view.feed import ViewHub
    from robotexp.view.player import Checkpoints, ReplayPlayer

    checkpoints = Checkpoints(duration=data.ticks[-1].time)
    run = replay_bag(data, None, cell=0.1, observers=(checkpoints,))
    player = ReplayPlayer(ViewHub(), data, run, checkpoints, speed=None)
    player.seek_to(10.0)
    assert player.i == 50 and np.array_equal(player.grid.states(), run.grid.states())
    player.seek_to(2.0)
    assert player.i == 21 and player.grid.scans == 21


def test_replay_bad_input(tmp_path: Path) -> None:
    res = CliRunner().invoke(main, ["replay", str(tmp_path / "missing.mcap")])
    assert res.exit_code == 2 and "no such recording" in res.output
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    res = CliRunner().invoke(main, ["replay", str(junk)])
    assert res.exit_code == 2 and "not a readable MCAP recording" in res.output
    res = CliRunner().invoke(main, ["explore", "--record", str(tmp_path / "run.bag")])
    assert res.exit_code == 2 and "FILE.mcap" in res.output


def test_replay_feeds_the_live_view(recorded: tuple[Path, dict[str, object]]) -> None:
    """A replay drives the live view's observer as a run does, paced by the recording's robot time."""
    from robotexp.view.feed import ViewHub
    from robotexp.view.observer import ViewObserver

    bag, record = recorded
    hub = ViewHub()
    clock = [0.0]
    sleeps: list[float] = []

    def sleep(dt: float) -> None:
        sleeps.append(dt)
        clock[0] += dt

    observer = ViewObserver(hub, speed=50.0, clock=lambda: clock[0])
    observer.pacer.sleep = sleep
    run = replay_bag(read_bag(bag), None, observers=(observer,))
    assert run.record is not None and run.record.coverage == record["coverage"]
    assert hub.meta["world"] == "ufmg-static" and hub.meta["simulated"] is True
    assert hub.classes is not None and len(hub.path) >= 4
    # paced at 50x: 25 s of robot time take 0.5 s of (fake) wall time
    assert sum(sleeps) == pytest.approx(25.0 / 50.0, rel=0.05)


def test_exact_scan_round_trip() -> None:
    """The float64 scan topic, encoded by robotexp.bag.cdr and decoded by mcap-ros2, gives back every
    angle and range bit for bit, regular or not."""
    from mcap.records import Schema

    from robotexp.bag.recorder import exact_scan_message
    from robotexp.bag.replay import _exact_scan
    from robotexp.bag.schemas import EXACT_SCAN
    from robotexp.robot import LaserScan

    decode = DecoderFactory().decoder_for("cdr", Schema(id=1, name=EXACT_SCAN[0], encoding="ros2msg",
                                                         data=EXACT_SCAN[1].encode()))
    assert decode is not None
    rng = np.random.default_rng(1)
    regular = np.linspace(-2.0, 2.0, 181)
    irregular = np.sort(rng.uniform(-3, 3, 50))
    for angles in (regular, irregular):
        ranges = rng.uniform(0.1, 3.0, len(angles))
        ranges[::7] = np.inf
        msg = decode(exact_scan_message(1_700_000_000_123_456_789, LaserScan(angles, ranges, 3.0, 0.12)))
        assert (len(msg.angles) == 0) == (angles is regular)
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == \
            (1_700_000_000, 123_456_789, "laser")
        back = _exact_scan(msg)
        assert np.array_equal(back.angles, angles) and np.array_equal(back.ranges, ranges)
        assert (back.range_max, back.offset_x) == (3.0, 0.12)


def test_a_localized_run_replays_to_its_record(tmp_path: Path) -> None:
    """A run that localized mapped with its own p_free (a miss weighs less than a hit: `MAP_P_FREE`); the
    recording keeps it and the replay maps the recorded scans with it, to the same coverage and map IoU."""
    from robotexp.run.localize import MAP_P_FREE

    bag = tmp_path / "run.mcap"
    res = CliRunner().invoke(main, ["explore", "-w", "dense", "-m", "frontier", "--max-time", "30",
                                    "--odometry-error", "p3dx", "--localize", "scan-match", "--record", str(bag),
                                    "--out", str(tmp_path / "run")])
    assert res.exit_code == 0, res.output
    assert read_bag(bag).meta["grid"]["p_free"] == MAP_P_FREE
    res = CliRunner().invoke(main, ["replay", str(bag), "--out", str(tmp_path / "replay")])
    assert res.exit_code == 0, res.output
    ran = read_jsonl(tmp_path / "run" / "results.jsonl")[-1]
    replayed = read_jsonl(tmp_path / "replay" / "results.jsonl")[-1]
    for key in ("coverage", "map_iou", "visited_cells"):
        assert replayed[key] == ran[key], key

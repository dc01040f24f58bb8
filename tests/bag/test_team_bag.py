"""A team's recording: `robotexp explore --team 2 --record` writes each robot under /robot_N (read back with
the mcap reader: topics, counts, frames and poses against the team's record and path files), replays to
the same record, and its frames, video and figure draw every robot."""

from __future__ import annotations

import bisect
import itertools
import math
from pathlib import Path

import imageio.v3 as iio3
import numpy as np
import pytest
from click.testing import CliRunner
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from PIL import Image

from robotexp.bag.recorder import EPOCH
from robotexp.bag.replay import read_bag, replay_bag
from robotexp.cli import main
from robotexp.mapping.geometry import GridGeometry
from robotexp.output.render import COLORS, TEAM_COLORS, map_layout
from robotexp.output.results import read_jsonl
from robotexp.output.trajectory import read_path_csv
from robotexp.output.video import FRAME_SIZE
from robotexp.robot import Pose
from robotexp.view.feed import ViewClient, ViewHub
from robotexp.view.player import Checkpoints, ReplayPlayer

ROBOT_TOPICS = {"odom": "nav_msgs/msg/Odometry", "tf": "tf2_msgs/msg/TFMessage", "tf_static": "tf2_msgs/msg/TFMessage",
                "scan": "sensor_msgs/msg/LaserScan", "robotexp/scan": "robotexp_msgs/msg/ExactScan",
                "ground_truth": "nav_msgs/msg/Odometry", "map": "nav_msgs/msg/OccupancyGrid"}


@pytest.fixture(scope="module")
def team_bag(tmp_path_factory: pytest.TempPathFactory, team_room: str) -> tuple[Path, dict, Path]:
    """An 8 s run of two robots with a communication range (a map each), recorded, frames every 4 s."""
    tmp = tmp_path_factory.mktemp("teambag")
    (tmp / "room.map").write_text(team_room)
    bag = tmp / "team.mcap"
    res = CliRunner().invoke(main, ["explore", "-w", str(tmp / "room.map"), "--team", "2", "--coordinator", "greedy",
                                    "--comm-range", "2500", "--max-time", "8", "-o", str(tmp / "out"),
                                    "--record", str(bag), "--frames", str(tmp / "frames"), "--frame-every", "4"])
    assert res.exit_code == 0, res.output
    return bag, read_jsonl(tmp / "out" / "results.jsonl")[-1], tmp


def _poses(msgs: list) -> list[Pose]:
    from robotexp.bag.recorder import yaw_of

    return [Pose(m.pose.pose.position.x, m.pose.pose.position.y, yaw_of(m.pose.pose.orientation)) for m in msgs]


def test_each_robot_is_recorded_under_its_namespace(team_bag):
    bag, record, tmp = team_bag
    by_topic: dict[str, list] = {}
    stamps: dict[str, list[int]] = {}
    with open(bag, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None
        types = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        for _, channel, message, msg in reader.iter_decoded_messages():
            by_topic.setdefault(channel.topic, []).append(msg)
            stamps.setdefault(channel.topic, []).append(message.log_time)
    expected = {f"/robot_{i}/{t}": kind for i in (1, 2) for t, kind in ROBOT_TOPICS.items()}
    expected |= {"/map": "nav_msgs/msg/OccupancyGrid", "/ground_truth/map": "nav_msgs/msg/OccupancyGrid",
                 "/robotexp/markers": "visualization_msgs/msg/MarkerArray"}
    assert types == expected            # no un-namespaced /odom, /scan or /tf: those are a single robot's
    count = {t: len(v) for t, v in by_topic.items()}
    for i in (1, 2):
        ns = f"/robot_{i}"
        # one /odom, /tf and /ground_truth a tick of 0.1 s over 8 s (robot 2 may miss the last: the run ends
        # at robot 1's step), a scan a tick, /tf_static once, a map a second and at the end
        assert 80 <= count[f"{ns}/odom"] == count[f"{ns}/tf"] == count[f"{ns}/ground_truth"] <= 81
        assert 70 <= count[f"{ns}/scan"] == count[f"{ns}/robotexp/scan"] <= count[f"{ns}/odom"]
        assert count[f"{ns}/tf_static"] == 1 and count[f"{ns}/map"] == count["/map"] == 9
        assert stamps[f"{ns}/odom"][0] == round(EPOCH * 1e9)
        p = f"robot_{i}/"
        assert by_topic[f"{ns}/odom"][0].header.frame_id == f"{p}odom"
        assert by_topic[f"{ns}/odom"][0].child_frame_id == f"{p}base_link"
        assert [(t.header.frame_id, t.child_frame_id) for t in by_topic[f"{ns}/tf"][0].transforms] == \
            [("map", f"{p}odom"), (f"{p}odom", f"{p}base_link")]
        assert [(t.header.frame_id, t.child_frame_id) for t in by_topic[f"{ns}/tf_static"][0].transforms] == \
            [(f"{p}base_link", f"{p}laser")]
        assert by_topic[f"{ns}/scan"][0].header.frame_id == f"{p}laser"
        # the true poses are the team record's: first its start, last its end, their steps its path length
        robot = record["robots"][i - 1]
        poses = _poses(by_topic[f"{ns}/ground_truth"])
        assert poses[0].as_list() == pytest.approx(robot["start_pose"], abs=1e-9)
        assert poses[-1].as_list() == pytest.approx(robot["end_pose"], abs=1e-9)
        length = sum(math.dist((a.x, a.y), (b.x, b.y)) for a, b in itertools.pairwise(poses))
        assert length == pytest.approx(robot["path_length_m"], abs=1e-3)
        # ... and the robot's path file (thinned, 0.1 mm): every point of it is a recorded pose
        name = f"{record['run']}.path.csv" if i == 1 else f"{record['run']}.robot_{i}.path.csv"
        csv = read_path_csv(tmp / "out" / name)
        xy = np.array([(q.x, q.y) for q in poses])
        assert len(csv) >= 2 and all(np.hypot(*(xy - c).T).min() < 1e-4 for c in csv)
    # the robots' own maps differ from the team's (each merges its teammate's scans within 2.5 m only)
    team_map = np.asarray(by_topic["/map"][-1].data)
    own = [np.asarray(by_topic[f"/robot_{i}/map"][-1].data) for i in (1, 2)]
    assert all(np.count_nonzero(m >= 0) <= np.count_nonzero(team_map >= 0) for m in own)


def test_a_team_recording_replays_to_the_team_record(team_bag, tmp_path):
    bag, record, _ = team_bag
    data = read_bag(bag)
    assert [m["namespace"] for m in data.meta["team"]] == ["robot_1", "robot_2"]
    assert len(data.team) == 2 and data.ticks is data.team[0]
    run = replay_bag(data, tmp_path, image=False)
    r = run.record
    assert r.run == record["run"] and (tmp_path / f"{r.run}.robot_2.path.csv").is_file()   # named as the run
    assert r.team_size == 2 and r.end.value == record["end"] and r.reason == record["reason"]
    assert r.coverage == pytest.approx(record["coverage"], abs=1e-9)
    assert r.robot_time_s == pytest.approx(record["robot_time_s"])
    for mine, theirs in zip(r.robots, record["robots"], strict=True):
        assert mine["path_length_m"] == pytest.approx(theirs["path_length_m"], abs=1e-9)
        assert mine["start_pose"] == pytest.approx(theirs["start_pose"], abs=1e-12)
        assert mine["end_pose"] == pytest.approx(theirs["end_pose"], abs=1e-12)       # a heading through a quaternion


def _fill_at(image: np.ndarray, lay, pose: list[float]) -> np.ndarray:
    """The colour of a robot's disc drawn at `pose`, half its radius behind its heading tick."""
    u, v = lay.to_pixel(pose[0], pose[1])
    r = max(4.0, 0.2 * lay.pixels_per_metre)
    return image[round(v + 0.5 * r * math.sin(pose[2])), round(u - 0.5 * r * math.cos(pose[2]))][:3]


def test_frames_and_video_of_a_team_draw_every_robot(team_bag, tmp_path):
    bag, record, tmp = team_bag
    meta = read_bag(bag).meta
    g = meta["grid"]
    geo = GridGeometry(g["origin_x"], g["origin_y"], g["cell"], g["rows"], g["cols"])
    scale = map_layout(geo, title="t", max_size=FRAME_SIZE).scale
    lay = map_layout(geo, scale=scale, title="t", max_size=FRAME_SIZE)
    ends = [r["end_pose"] for r in record["robots"]]
    frames = sorted((tmp / "frames").glob("*.png"))
    assert len(frames) == 3                 # 0, 4 and 8 s
    last = np.asarray(Image.open(frames[-1]).convert("RGB"))
    assert tuple(_fill_at(last, lay, ends[0])) == COLORS["end"]         # robot 1
    assert tuple(_fill_at(last, lay, ends[1])) == TEAM_COLORS[0]        # robot 2
    assert np.count_nonzero(np.all(last == TEAM_COLORS[0], axis=2)) > 50    # its disc and path
    gif = tmp_path / "team.gif"
    res = CliRunner().invoke(main, ["video", str(bag), "-o", str(gif), "--every", "4"])
    assert res.exit_code == 0, res.output
    video = iio3.imread(gif, index=None)
    assert len(video) == 3
    final = video[-1]
    for end, color in zip(ends, (COLORS["end"], TEAM_COLORS[0]), strict=True):
        assert np.abs(_fill_at(final, lay, end).astype(int) - color).max() <= 24   # the GIF's palette


def test_a_team_videos_last_title_says_the_team_and_its_recorded_path(team_bag, tmp_path, monkeypatch):
    import robotexp.output.render as render

    bag, record, _ = team_bag
    titles = []
    draw = render.render_map

    def noting(*args, **kwargs):
        titles.append(kwargs["title"])
        return draw(*args, **kwargs)

    monkeypatch.setattr(render, "render_map", noting)
    res = CliRunner().invoke(main, ["video", str(bag), "-o", str(tmp_path / "v.gif"), "--every", "4"])
    assert res.exit_code == 0, res.output
    assert titles[-1].endswith(f"(8 s, 2 robots, {record['path_length_m']:.1f} m, coverage "
                               f"{record['coverage'] * 100:.1f} %)"), titles[-1]


def test_the_figure_of_a_team_recording_draws_every_path(team_bag, tmp_path):
    bag, _, _ = team_bag
    res = CliRunner().invoke(main, ["figure", str(bag), "-o", str(tmp_path), "--format", "png"])
    assert res.exit_code == 0, res.output
    (png,) = tmp_path.glob("*.map.png")
    px = np.asarray(Image.open(png).convert("RGB")).astype(int)
    blue = np.all(np.abs(px - (31, 119, 180)) <= 40, axis=2) | np.all(np.abs(px - COLORS["path"]) <= 30, axis=2)
    second = np.all(np.abs(px - TEAM_COLORS[0]) <= 30, axis=2)      # robot 2: in its colour of the video and view
    assert np.count_nonzero(blue) > 30 and np.count_nonzero(second) > 30


def test_the_player_shows_every_robot_and_seeks_to_the_replays_map(team_bag):
    bag, record, _ = team_bag
    data = read_bag(bag)
    checkpoints = Checkpoints(2.0)
    run = replay_bag(data, None, observers=(checkpoints,))
    assert [round(t, 6) for t, _ in checkpoints.items] == [2.0, 4.0, 6.0, 8.0]     # a team's: at its samples
    hub = ViewHub()
    player = ReplayPlayer(hub, data, run, checkpoints, speed=None)
    hub.start({"geo": {"rows": run.grid.geo.rows, "cols": run.grid.geo.cols}})
    client = ViewClient()
    robot2 = data.team[1]
    for target in (8.0, 3.05, 0.0, 5.0, 8.0):       # to the end, back (from a checkpoint, from the start), ahead
        player.seek_to(target)
        k = bisect.bisect_right([t.time for t in robot2], target + 1e-9)
        assert player.team_i == [k]
        msg = hub.message_for(client)
        p = robot2[k - 1].pose
        (mate,) = msg["team"]
        assert mate["pose"] == (p.x, p.y, p.theta) and mate["path_from"] == 0
        # robot 2's path as the replay kept it, thinned to half a cell, up to that tick
        sent = np.array(mate["path"]).reshape(-1, 2)
        assert len(sent) >= 1 and np.allclose(sent[0], run.members[1].metrics.path[0], atol=1e-3)
    # at the end the player's map is the replay's team map, cell for cell: every robot's scan of each tick,
    # as the run mapped it (the recorded scans leave out the beams that ended on a teammate)
    assert np.array_equal(player.grid.values, run.grid.values)
    assert record["robots"][1]["end_pose"][:2] == pytest.approx([robot2[-1].pose.x, robot2[-1].pose.y], abs=1e-9)


def test_team_metadata_is_checked_and_every_robot_number_is_read():
    from robotexp.bag.reading import MAX_ROBOTS, TEAM_TOPIC_TYPES
    from robotexp.bag.replay import _check_meta
    from robotexp.sim.team import MAX_TEAM

    assert MAX_ROBOTS == MAX_TEAM and f"/robot_{MAX_TEAM}/odom" in TEAM_TOPIC_TYPES
    good = {"namespace": "robot_1", "robot": "p3dx", "radius_m": 0.26, "start": [1.0, 1.0, 0.0]}
    assert _check_meta({"team": [good]})["team"] == [good]
    for team, words in (([], "expected a list of 1..64 robots"),
                        ([dict(good, namespace="robot_2")], "team robot 1 is"),
                        ([dict(good, radius_m=-1)], "radius_m is -1"),
                        ([dict(good, robot=5)], "robot is 5"),
                        ([good] * 65, "1..64 robots")):
        with pytest.raises(ValueError, match=words):
            _check_meta({"team": team})

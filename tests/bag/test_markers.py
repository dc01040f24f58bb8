"""Explorer markers in recordings: an SRT run recorded as a bag holds /robotexp/markers as
visualization_msgs/MarkerArray (ROS 2 schema, decoded by mcap-ros2-support): a DELETEALL first, then
the tree's nodes, edges and safe regions, the numbers the explorer gave; a replay gives them back to
the live view's overlays."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from robotexp.bag.markers import marker_array, markers_of
from robotexp.bag.recorder import BagRecorder, stamp_ns
from robotexp.bag.replay import read_bag, replay_bag
from robotexp.bag.schemas import MARKER_ARRAY
from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.run.loop import ExplorationRun
from robotexp.run.observers import RunObserver
from robotexp.view.feed import ViewHub
from robotexp.view.observer import ViewObserver


class Samples(RunObserver):
    """The explorer's markers at each coverage sample (what the recorder sees)."""

    def __init__(self) -> None:
        self.at: dict[int, Any] = {}

    def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
        self.at[stamp_ns(time)] = run.explorer.markers()


@pytest.fixture(scope="module")
def srt_bag(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Samples, Any]:
    bag = tmp_path_factory.mktemp("markers") / "srt.mcap"
    samples = Samples()
    out = run_experiment(RunSpec(world="ufmg-static", method="srt-star", max_time=20.0), None,
                         observers=[samples, BagRecorder(bag)], image=False)
    return bag, samples, out.run


def test_bag_holds_marker_arrays_with_the_ros2_schema(srt_bag: tuple[Path, Samples, Any]) -> None:
    bag, samples, run = srt_bag
    with open(bag, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None
        channel = next(c for c in summary.channels.values() if c.topic == "/robotexp/markers")
        schema = summary.schemas[channel.schema_id]
        assert (schema.name, schema.encoding, channel.message_encoding) == \
            ("visualization_msgs/msg/MarkerArray", "ros2msg", "cdr")
        assert schema.data.decode() == MARKER_ARRAY[1]
        got = [(message.log_time, msg) for _, _, message, msg in reader.iter_decoded_messages(
            topics=["/robotexp/markers"])]
    assert len(got) >= 2
    # written when they changed, at the coverage samples: each is what the explorer returned then
    written = {ns: markers_of(msg) for ns, msg in got}
    assert set(written) <= set(samples.at)
    for ns, markers in written.items():
        assert markers == {k: v for k, v in samples.at[ns].items() if any(v.values())}
    changes = [ns for ns in sorted(samples.at) if ns == min(samples.at)
               or samples.at[ns] != samples.at[max(t for t in samples.at if t < ns)]]
    assert sorted(written) == changes
    # the last message: DELETEALL, then one SPHERE_LIST of nodes, a LINE_LIST of edges, a closed
    # LINE_STRIP per safe region, in frame map
    last = got[-1][1]
    nodes = len(run.explorer.tree)
    assert nodes >= 2
    assert last.markers[0].action == 3
    by_ns: dict[str, list[Any]] = {}
    for m in last.markers[1:]:
        assert m.header.frame_id == "map" and m.action == 0
        by_ns.setdefault(m.ns, []).append(m)
    assert [m.type for m in by_ns["points/SRT nodes"]] == [7] and len(by_ns["points/SRT nodes"][0].points) == nodes
    assert [m.type for m in by_ns["lines/SRT tree"]] == [5]
    assert len(by_ns["lines/SRT tree"][0].points) == 2 * (nodes - 1)
    regions = by_ns["polygons/safe regions"]
    assert len(regions) == nodes and {m.type for m in regions} == {4}
    assert all(m.points[0] == m.points[-1] for m in regions)      # closed outlines
    final = run.explorer.markers()
    assert markers_of(last)["points"]["SRT nodes"] == final["points"]["SRT nodes"]


def test_markers_round_trip_through_cdr() -> None:
    """Every kind, through our CDR encoder and mcap-ros2's decoder, comes back with the same numbers."""
    from mcap_ros2._dynamic import generate_dynamic

    decode = generate_dynamic(*MARKER_ARRAY)[MARKER_ARRAY[0]]
    markers = {"points": {"SRT nodes": [1.0, 2.0, 3.5, -4.25], "target": [0.1, 0.2]},
               "lines": {"SRT tree": [1.0, 2.0, 3.5, -4.25]},
               "circles": {"reach": [1.0, 1.0, 0.5, 2.0, 2.0, 0.75]},
               "polygons": {"safe regions": [[0.0, 0.0, 1.0, 0.0, 1.0, 1.0], [2.0, 2.0, 3.0, 2.0, 3.0, 3.0, 2.0, 3.0]]}}
    msg = decode(marker_array(stamp_ns(12.5), markers))
    assert msg.markers[0].action == 3 and len(msg.markers) == 1 + 2 + 1 + 2 + 2
    assert msg.markers[1].header.stamp.sec * 10**9 + msg.markers[1].header.stamp.nanosec == stamp_ns(12.5)
    cyl = [m for m in msg.markers if m.ns == "circles/reach"]
    assert [(m.type, m.pose.position.x, m.scale.x) for m in cyl] == [(3, 1.0, 1.0), (3, 2.0, 1.5)]
    assert markers_of(msg) == markers
    assert markers_of(decode(marker_array(0, {}))) == {}


def test_replay_drives_the_views_markers(srt_bag: tuple[Path, Samples, Any]) -> None:
    bag, _, run = srt_bag
    data = read_bag(bag)
    assert data.markers and data.markers[0][0] >= 0.0
    hub = ViewHub()
    replay_bag(data, None, observers=(ViewObserver(hub, speed=None),))
    final = run.explorer.markers()
    assert hub.overlays["points"]["SRT nodes"] == final["points"]["SRT nodes"]
    assert hub.overlays["polygons"]["safe regions"] == final["polygons"]["safe regions"]

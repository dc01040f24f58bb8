import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robotexp.errors import ConfigError, WorldError
from robotexp.robot import Pose
from robotexp.world.mobilesim import load_mobilesim
from robotexp.world.model import World, segment_box

DATA = Path(__file__).parent / "data"
ROOM = DATA / "room.map"
SENSORS = DATA / "sensors.map"

# room.map, by hand: a 10 m x 8 m room, an inner wall at x = 5 m up to y = 5 m, 3 points of 100 mm
ROOM_BOXES = [
    (5.0, 0.0, 5.01, 0.01, 0.0),
    (10.0, 4.0, 4.01, 0.01, math.pi / 2),
    (5.0, 8.0, 5.01, 0.01, math.pi),
    (0.0, 4.0, 4.01, 0.01, -math.pi / 2),
    (5.0, 2.5, 2.51, 0.01, math.pi / 2),
    (1.0, 6.0, 0.05, 0.05, 0.0),
    (2.0, 6.0, 0.05, 0.05, 0.0),
    (3.0, 6.0, 0.05, 0.05, 0.0),
]


def write(tmp_path: Path, text: str, name: str = "m.map") -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8"))
    return path


def minimal(body: str = "", header: str = "") -> str:
    return "2D-Map\n" + header + "LINES\n0 0 1000 0\n" + body


def test_room_boxes_are_the_hand_computed_ones():
    world = load_mobilesim(ROOM)
    assert isinstance(world, World)
    np.testing.assert_allclose(world.boxes, np.array(ROOM_BOXES), atol=1e-12)
    assert world.discs.shape == (0, 3)
    assert world.name == "room"
    assert world.source == str(ROOM)
    np.testing.assert_allclose(world.bounds, (-0.01, -0.01, 10.01, 8.01), atol=1e-12)


def test_room_cairns_become_named_poses():
    world = load_mobilesim(ROOM)
    assert list(world.poses) == ["Start", "Far corner", "goal"]
    assert world.poses["Start"] == Pose(2.0, 2.0, math.pi / 2)
    assert world.poses["Far corner"] == Pose(8.0, 6.0, 0.0)       # a Goal's theta is ignored
    assert world.poses["goal"].x == 7.0 and world.poses["goal"].y == 1.0
    assert world.poses["goal"].theta == pytest.approx(math.radians(-45.5), abs=1e-12)
    assert world.home == Pose(2.0, 2.0, math.pi / 2)
    assert world.goals == {"cairns": [(8.0, 6.0), (7.0, 1.0)]}
    assert "1 ForbiddenLine" in world.description
    assert "0 ForbiddenArea" in world.description
    assert "5 lines, 3 points" in world.description


def test_line_boxes_match_segment_box():
    world = load_mobilesim(ROOM, thickness=0.1)
    lines_mm = [(0, 0, 10000, 0), (10000, 0, 10000, 8000), (10000, 8000, 0, 8000),
                (0, 8000, 0, 0), (5000, 0, 5000, 5000)]
    expected = [segment_box(*(v / 1000 for v in seg), 0.1) for seg in lines_mm]
    np.testing.assert_allclose(world.boxes[:5], np.array(expected), rtol=0, atol=1e-15)
    np.testing.assert_allclose(world.bounds, (-0.05, -0.05, 10.05, 8.05), atol=1e-12)


@pytest.mark.parametrize("ending", [b"\r\n", b"\r"])
def test_crlf_and_cr_line_endings_give_the_same_world(tmp_path, ending):
    path = tmp_path / "room_crlf.map"
    path.write_bytes(ROOM.read_bytes().replace(b"\n", ending))
    world = load_mobilesim(path)
    reference = load_mobilesim(ROOM)
    np.testing.assert_array_equal(world.boxes, reference.boxes)
    assert world.poses == reference.poses
    assert world.name == "room_crlf"


def test_ex2_map_with_sources_sensor_sections_and_repeated_labels():
    world = load_mobilesim(SENSORS)
    sonar = (0.5, 0.0, 0.51, 0.01, 0.0)
    point = (-0.5, 2.5, 0.01, 0.01, 0.0)        # Resolution: 20 [mm]
    assert world.boxes.shape == (6, 5)
    np.testing.assert_allclose(world.boxes[4], sonar, atol=1e-12)
    np.testing.assert_allclose(world.boxes[5], point, atol=1e-12)
    np.testing.assert_allclose(world.boxes[0], (0.0, -3.0, 3.01, 0.01, 0.0), atol=1e-12)
    assert list(world.poses) == ["Charger", "home", "home2", "home3",
                                 "Lobby door, west side", "Lobby door, west side2"]
    assert world.poses["Charger"] == Pose(0.5, -0.5, -math.pi)    # 180 deg wrapped to [-pi, pi)
    assert world.poses["home"] == Pose(-1.0, 0.0, 0.0)
    assert world.poses["home2"] == Pose(1.0, 0.0, 0.0)
    assert world.poses["home3"].theta == pytest.approx(math.pi / 6, abs=1e-12)
    assert world.home == Pose(-1.0, 0.0, 0.0)
    assert world.goals == {"cairns": [(2.0, -2.0), (2.5, -2.0)]}
    assert "1 ForbiddenArea" in world.description and "sources SickLaser sonar" in world.description
    assert world.description.startswith("2D-Map-Ex2")
    np.testing.assert_allclose(world.bounds, (-3.01, -3.01, 3.01, 3.01), atol=1e-12)


def test_default_resolution_is_20_mm_and_duplicate_points_give_one_box(tmp_path):
    path = write(tmp_path, "2D-Map\nDATA\n100 -200\n100 -200\n-300 400\n")
    world = load_mobilesim(path)
    expected = sorted([(0.1, -0.2, 0.01, 0.01, 0.0), (-0.3, 0.4, 0.01, 0.01, 0.0)])
    np.testing.assert_allclose(sorted(map(tuple, world.boxes)), expected, atol=1e-12)
    assert world.poses == {} and world.home is None and world.goals == {}


def test_a_home_outside_the_obstacles_refuses_the_map_and_other_cairns_outside_are_dropped(tmp_path, caplog):
    path = write(tmp_path, minimal(header='Cairn: RobotHome 5000 -3000 0 "" ICON ""\n'))
    with pytest.raises(WorldError) as info:
        load_mobilesim(path)
    assert str(info.value).startswith(f"{path}:2: RobotHome (5000, -3000) mm lies outside the map's obstacles "
                                      "(x -10..1010, y -10..10 mm)")
    path = write(tmp_path, "2D-Map\n" 'Cairn: Goal 5000 500 0 "" ICON "far"\n' 'Cairn: Goal 500 500 0 "" ICON "in"\n'
                 "LINES\n0 0 1000 0\n0 1000 1000 1000\n")
    world = load_mobilesim(path)
    assert list(world.poses) == ["in"]
    assert f"{path}:2: Goal (5000, 500) mm lies outside" in caplog.text
    # bounds are the obstacles' box
    np.testing.assert_allclose(world.bounds, (-0.01, -0.01, 1.01, 1.01), atol=1e-12)


def test_header_bounds_are_the_declared_area(tmp_path):
    path = write(tmp_path, "2D-Map\nMinPos: -500 -400\nMaxPos: 1500 800\nLineMinPos: 0 -1000\n"
                 "LineMaxPos: 1000 0\nLINES\n0 0 1000 0\n")
    assert load_mobilesim(path).declared == (-0.5, -1.0, 1.5, 0.8)
    assert load_mobilesim(write(tmp_path, minimal(header="MinPos: 0 0\n"))).declared is None
    with pytest.raises(WorldError, match=r":2: bad MinPos 'x 0'"):
        load_mobilesim(write(tmp_path, minimal(header="MinPos: x 0\n")))


def test_malformed_data_lines_are_skipped_with_a_warning_naming_file_and_line(tmp_path, caplog):
    text = ("2D-Map\nResolution: 100\nLINES\n0 0 1000\n0 0 1000 0\nDATA\n1000 2000\n3.5 4\n"
            "99999999999 0\n2000 2000\n")
    path = write(tmp_path, text)
    world = load_mobilesim(path)
    assert len(world.boxes) == 3            # the line and two points
    for line, bad in ((4, "'0 0 1000'"), (8, "'3.5 4'"), (9, "'99999999999 0'")):
        assert f"{path}:{line}: skipped malformed data line {bad}" in caplog.text
    assert "3 malformed data lines skipped" in world.description
    assert "expected 2 integers 'x y' [mm] of at most 9 digits (1000 km)" in caplog.text
    caplog.clear()
    many = "2D-Map\nDATA\n0 0\n" + "x y\n" * 25
    world = load_mobilesim(write(tmp_path, many))
    assert caplog.text.count("skipped malformed data line") == 10
    assert "15 more malformed data lines skipped" in caplog.text


def test_points_one_resolution_apart_merge_into_rectangles_covering_the_same_squares(tmp_path):
    # an L of points at 100 mm: a row of 5 (x 0..400, y 0), a 3 x 2 block (x 0..200, y 100..200)
    # and a lone point off the lattice (x 1050)
    pts = [(x, 0) for x in range(0, 500, 100)] + [(x, y) for x in (0, 100, 200) for y in (100, 200)] + [(1050, 0)]
    text = "2D-Map\nResolution: 100\nDATA\n" + "\n".join(f"{x} {y}" for x, y in pts) + "\n"
    world = load_mobilesim(write(tmp_path, text))
    expected = sorted([(0.2, 0.0, 0.25, 0.05, 0.0), (0.1, 0.15, 0.15, 0.1, 0.0), (1.05, 0.0, 0.05, 0.05, 0.0)])
    np.testing.assert_allclose(sorted(map(tuple, world.boxes)), expected, atol=1e-12)
    from robotexp.mapping.geometry import GridGeometry
    from robotexp.world.groundtruth import occupancy
    geo = GridGeometry.covering(-0.2, -0.2, 1.2, 0.4, 0.05)
    squares = World("s", [(x / 1000, y / 1000, 0.05, 0.05, 0.0) for x, y in pts])
    np.testing.assert_array_equal(occupancy(world, geo), occupancy(squares, geo))


def test_blank_lines_whitespace_signs_and_unknown_metadata_are_accepted(tmp_path):
    text = ("2D-Map-Ex4 extra words\n\nWeird line without colon\nFoo: bar\n"
            'Cairn:   RobotHome   +100 +2200   45.0   ""   ICON   "a  b"  \n'
            "LINES\n\n  -1000\t+2000  3000 4000  \n\nDATA\n\n")
    world = load_mobilesim(write(tmp_path, text))
    np.testing.assert_allclose(world.boxes[0], segment_box(-1, 2, 3, 4, 0.02), atol=1e-15)
    assert world.poses == {"a  b": Pose(0.1, 2.2, math.radians(45.0))}


def test_latin1_label_is_read(tmp_path):
    path = tmp_path / "latin.map"
    path.write_bytes('2D-Map\nCairn: Goal 0 0 0 "" ICON "Sala de reunião"\nDATA\n0 0\n'.encode("latin-1"))
    world = load_mobilesim(path)
    assert list(world.poses) == ["Sala de reunião"]


def test_utf8_bom_is_accepted(tmp_path):
    path = tmp_path / "bom.map"
    path.write_bytes(b"\xef\xbb\xbf" + minimal().encode())
    assert load_mobilesim(path).boxes.shape == (1, 5)


def test_many_points_and_lines_load_vectorised(tmp_path):
    rng = np.random.default_rng(3)
    pts = rng.integers(-7000, 7000, size=(100_000, 2)) * 7     # never 50 mm apart: no run merges
    segs = rng.integers(-50000, 50000, size=(5_000, 4))
    text = ("2D-Map\nResolution: 50\nLINES\n" + "\n".join(" ".join(map(str, s)) for s in segs.tolist())
            + "\nDATA\n" + "\n".join(f"{x} {y}" for x, y in pts.tolist()) + "\n")
    world = load_mobilesim(write(tmp_path, text, "big.map"))
    n_unique = len(np.unique(pts, axis=0))
    assert world.boxes.shape == (5_000 + n_unique, 5)
    np.testing.assert_allclose(world.boxes[17], segment_box(*(segs[17] / 1000.0), 0.02), atol=1e-12)
    points = world.boxes[5_000:]
    np.testing.assert_array_equal(np.unique(np.round(points[:, :2] * 1000).astype(np.int64), axis=0),
                                  np.unique(pts, axis=0))
    assert np.all(points[:, 2:4] == 0.025)


@pytest.mark.parametrize("text, line, fragment", [
    ("", 1, "2D-Map"),
    ("LINES\n0 0 1 1\n", 1, "2D-Map"),
    ("2D-Map\nLINES\n0 0 1000\n", 4, "no obstacle"),
    ('2D-Map\nCairn: Goal 0 0 0 "" ICON "g\nDATA\n1 1\n', 2, "unbalanced quote"),
    ('2D-Map\nCairn: Goal 12a 0 0 "" ICON "g"\nDATA\n1 1\n', 2, "bad cairn X"),
    ('2D-Map\nCairn: Goal 0 nan 0 "" ICON "g"\nDATA\n1 1\n', 2, "bad cairn Y"),
    ('2D-Map\nCairn: Goal 0 0\nDATA\n1 1\n', 2, "incomplete cairn"),
    ('2D-Map\nCairn: RobotHome 0 0 "90" ICON "g"\nDATA\n1 1\n', 2, "bad cairn Theta"),
    ("2D-Map\nResolution: fine\nDATA\n1 1\n", 2, "bad Resolution"),
    ('2D-Map\nCairn: RobotHome 0 0 0 "" ICON ""\nLINES\nDATA\n\n', 6, "no obstacle"),
    ("2D-Map\nMinPos: 0 0\n", 3, "no obstacle"),
    ("2D-Map\nDATA\n1\x002\n", 3, "binary byte 0x00"),
])
def test_malformed_files_raise_world_error_with_file_and_line(tmp_path, text, line, fragment):
    path = write(tmp_path, text, "bad.map")
    with pytest.raises(WorldError) as info:
        load_mobilesim(path)
    message = str(info.value)
    assert message.startswith(f"{path}:{line}: "), message
    assert fragment in message
    assert "\n" not in message


def test_missing_file_and_directory_raise_world_error(tmp_path):
    with pytest.raises(WorldError, match=r"nope\.map:0: cannot read"):
        load_mobilesim(tmp_path / "nope.map")
    with pytest.raises(WorldError, match="cannot read"):
        load_mobilesim(tmp_path)


@pytest.mark.parametrize("thickness", [0.0, -0.1, float("nan"), float("inf")])
def test_bad_thickness_is_a_config_error(thickness):
    with pytest.raises(ConfigError, match="thickness"):
        load_mobilesim(ROOM, thickness=thickness)


def check_hostile(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "fuzz.map"
    path.write_bytes(data)
    try:
        world = load_mobilesim(path)
    except WorldError as exc:
        assert str(path) in str(exc)
        return
    assert world.boxes.ndim == 2 and world.boxes.shape[1] == 5 and len(world.boxes) > 0
    assert np.all(np.isfinite(world.boxes))
    xmin, ymin, xmax, ymax = world.bounds
    assert xmin <= xmax and ymin <= ymax


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=300))
def test_fuzz_random_bytes_give_a_world_or_world_error(tmp_path, data):
    check_hostile(tmp_path, data)
    check_hostile(tmp_path, b"2D-Map\n" + data)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(edits=st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 3),
                                st.binary(min_size=0, max_size=4)), max_size=6),
       which=st.sampled_from([ROOM, SENSORS]))
def test_fuzz_mutated_valid_files_give_a_world_or_world_error(tmp_path, edits, which):
    data = bytearray(which.read_bytes())
    for pos, cut, insert in edits:
        pos %= len(data) + 1
        data[pos:pos + cut] = insert
    check_hostile(tmp_path, bytes(data))

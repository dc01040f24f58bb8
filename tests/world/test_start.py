"""The default start pose: in the largest region the robot fits, well inside it, never a closet."""

from __future__ import annotations

import re

import numpy as np
import pytest

from robotexp.errors import WorldError
from robotexp.mapping.geometry import GridGeometry
from robotexp.world.groundtruth import ground_truth
from robotexp.world.model import World, segment_box
from robotexp.world.start import WELL_INSIDE, default_start


def walls(*segments: tuple[float, float, float, float], t: float = 0.1) -> list[tuple[float, ...]]:
    return [segment_box(*s, t) for s in segments]


ROOM = [(0, 0, 10, 0), (10, 0, 10, 8), (10, 8, 0, 8), (0, 8, 0, 0)]
# a closed 1.6 x 1.6 m closet around the map's centre (5, 4)
CLOSET = [(4.2, 3.2, 5.8, 3.2), (5.8, 3.2, 5.8, 4.8), (5.8, 4.8, 4.2, 4.8), (4.2, 4.8, 4.2, 3.2)]


def test_the_start_is_in_the_big_room_not_in_the_closet_at_the_centre():
    world = World("closet", walls(*ROOM, *CLOSET))
    choice = default_start(world, 0.25)
    p = choice.pose
    assert not (4.2 < p.x < 5.8 and 3.2 < p.y < 4.8)
    assert choice.regions == 2 and not choice.edge
    # the big room: 9.9 x 7.9 m shrunk by the radius on every face, minus the closet's 1.7 x 1.7 m
    # grown by the radius with rounded corners (the exact free space of the robot's centre)
    assert choice.area == pytest.approx(9.4 * 7.4 - (2.2 * 2.2 - (4 - np.pi) * 0.25**2), rel=0.002)
    # well inside: at least WELL_INSIDE from every wall
    boxes = world.boxes
    d = min(abs(p.x - 0.05), abs(9.95 - p.x), abs(p.y - 0.05), abs(7.95 - p.y))
    assert d >= WELL_INSIDE - 0.05
    assert not (4.2 - WELL_INSIDE < p.x < 5.8 + WELL_INSIDE and 3.2 - WELL_INSIDE < p.y < 4.8 + WELL_INSIDE)
    assert len(boxes) == 8
    # coverage counts what the robot reaches from there: the room around the closet, not the closet
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.2)
    truth = ground_truth(world, geo, robot_radius=0.25, laser_range=3.0, start=p)
    r, c = geo.cell_of(5.0, 4.0)
    assert not truth.explorable[r, c] and truth.reachable[geo.cell_of(1.0, 1.0)]
    assert "largest of 2 regions" in choice.describe()


def test_regions_that_reach_the_map_edge_are_left_out_when_a_closed_one_exists():
    # a closed 3 x 3 m room and, beside it, a larger U open to the map's edge
    world = World("open", walls((0, 0, 3, 0), (3, 0, 3, 3), (3, 3, 0, 3), (0, 3, 0, 0),
                                (4, 0, 12, 0), (12, 0, 12, 6), (4, 0, 4, 6)))
    choice = default_start(world, 0.25)
    assert 0 < choice.pose.x < 3 and 0 < choice.pose.y < 3 and not choice.edge
    only_open = World("u", walls((4, 0, 12, 0), (12, 0, 12, 6), (4, 0, 4, 6)))
    choice = default_start(only_open, 0.25)
    assert choice.edge and "outline not closed" in choice.describe()


def test_a_pocket_among_clutter_does_not_outweigh_a_building_open_to_the_map_edge():
    # the same U open to the edge (7.9 x 5.95 m, 7.4 x 5.7 m2 where the centre fits) and, beside it, a closed
    # 1 x 1 m box (0.4 x 0.4 m2 where the centre fits: 0.4 % of the U, below INNER_SHARE): the U is explored
    u = ((4, 0, 12, 0), (12, 0, 12, 6), (4, 0, 4, 6))
    pocket = ((0, 0, 1, 0), (1, 0, 1, 1), (1, 1, 0, 1), (0, 1, 0, 0))
    choice = default_start(World("pocket", walls(*u, *pocket)), 0.25)
    assert 4 < choice.pose.x < 12 and 0 < choice.pose.y < 6 and choice.edge
    assert choice.area == pytest.approx(7.4 * 5.7, rel=0.02)
    # a closed room of 5 % of the U's area or more is still preferred to it: 2.2 x 2.2 m, 1.6 x 1.6 m2 (6 %)
    room = ((0, 0, 2.2, 0), (2.2, 0, 2.2, 2.2), (2.2, 2.2, 0, 2.2), (0, 2.2, 0, 0))
    choice = default_start(World("room", walls(*u, *room)), 0.25)
    assert choice.pose.x < 2.2 and not choice.edge
    assert choice.area == pytest.approx(1.6 * 1.6, rel=0.02)


def test_nowhere_to_fit_is_one_clear_error():
    world = World("tight", walls((0, 0, 0.4, 0), (0.4, 0, 0.4, 0.4), (0.4, 0.4, 0, 0.4), (0, 0.4, 0, 0)))
    with pytest.raises(WorldError, match="no place where a robot of radius 0.25 m fits"):
        default_start(world, 0.25)


def test_a_ros_map_read_wrong_is_told_what_to_check(tmp_path):
    # a room drawn black on white read with negate: 1 (its walls the only free cells: 196 of 60 x 40, 8.2 %),
    # and the same room at a resolution 100 times too fine (3 x 2 cm): each refusal says what to check
    from robotexp.world.rosmap import load_ros_world

    image = np.full((40, 60), 254, np.uint8)
    image[0, :] = image[-1, :] = image[:, 0] = image[:, -1] = 0
    (tmp_path / "room.pgm").write_bytes(b"P5\n60 40\n255\n" + image.tobytes())
    yaml = "image: room.pgm\nresolution: {res}\norigin: [0.0, 0.0, 0.0]\nnegate: {neg}\noccupied_thresh: 0.65\n" \
           "free_thresh: 0.196\n"
    (tmp_path / "neg.yaml").write_text(yaml.format(res=0.05, neg=1))
    (tmp_path / "fine.yaml").write_text(yaml.format(res=0.0005, neg=0))
    with pytest.raises(WorldError, match=r"fits: give a start pose or a larger map \(only 8\.2 % of the map is "
                                         r"free: is its negate, mode or free_thresh right"):
        default_start(load_ros_world(tmp_path / "neg.yaml"), 0.25)
    with pytest.raises(WorldError, match=r"larger map \(the map is 0\.03 x 0\.02 m: is its resolution right\?\)"):
        default_start(load_ros_world(tmp_path / "fine.yaml"), 0.25)


def test_the_start_is_deterministic_and_free_on_generated_maps():
    from robotexp.world.generate import generated_world

    world = generated_world("office", 1, scanned=True)
    a, b = default_start(world, 0.25), default_start(world, 0.25)
    assert a == b
    from robotexp.mapping.kernels import clearance_mask, flood8

    geo = GridGeometry.covering(*world.bounds, cell=0.1)
    from robotexp.world.groundtruth import occupancy
    fits = clearance_mask(occupancy(world, geo), 0.25 / geo.cell)
    reach = flood8(fits, *geo.cell_of(a.pose.x, a.pose.y))
    # the region holds the building's floor: much of the 30 x 20 m
    assert np.count_nonzero(reach) * geo.cell ** 2 > 0.4 * 30 * 20


def test_rooms_joined_by_a_door_the_robot_just_fits_through_are_one_region():
    # two 4 x 4 m rooms joined by a door 4 cm wider than the robot (0.54 m for a 0.5 m disc), and a closed
    # 5 x 5 m room apart: the pair (2 x 3.4 x 3.4 m2 where the centre fits) outweighs the single room
    # (4.4 x 4.4 m2), so the start lies in the pair; with a margin beyond the radius (the door closed)
    # the single room would be the largest
    door = (1.7, 1.7 + 0.54)
    world = World("pair", walls((0, 0, 8, 0), (8, 0, 8, 4), (8, 4, 0, 4), (0, 4, 0, 0),
                                (4, 0, 4, door[0] - 0.05), (4, door[1] + 0.05, 4, 4),
                                (10, 0, 15, 0), (15, 0, 15, 5), (15, 5, 10, 5), (10, 5, 10, 0)))
    choice = default_start(world, 0.25)
    assert 0 < choice.pose.x < 8 and 0 < choice.pose.y < 4
    assert choice.area == pytest.approx(2 * 3.4 * 3.4, rel=0.01)
    assert choice.regions == 3          # the pair, the single room, the 2 m gap between them (open)
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.2)
    truth = ground_truth(world, geo, robot_radius=0.25, laser_range=3.0, start=choice.pose)
    assert truth.reachable[geo.cell_of(1.0, 1.0)] and truth.reachable[geo.cell_of(7.0, 3.0)]
    assert not truth.reachable[geo.cell_of(12.5, 2.5)]


def test_explore_says_where_the_default_start_is_and_why(tmp_path):
    from click.testing import CliRunner

    from robotexp.cli import main
    from robotexp.world.rosmap import save_ros_map

    values = np.zeros((40, 40), np.int8)            # a closed 4 x 4 m room on 0.1 m cells
    values[0, :] = values[-1, :] = values[:, 0] = values[:, -1] = 100
    save_ros_map(tmp_path / "room.yaml", values, GridGeometry(0.0, 0.0, 0.1, 40, 40))
    result = CliRunner().invoke(main, ["explore", "-w", str(tmp_path / "room.yaml"), "-o", str(tmp_path / "out"),
                                       "--robot", "kobuki", "--max-time", "1"])
    assert result.exit_code == 0, result.output
    line = next(s for s in result.stderr.splitlines() if s.startswith("robotexp: start "))
    # the room's middle (on the 5 cm search grid), the pose's name, and why: the one region, 3.45 x 3.45 m2
    # where the Kobuki's centre fits (3.8 m inside the walls less 2 x 0.175 m)
    m = re.fullmatch(r"robotexp: start centre: \((\S+), (\S+)\) m, heading 0 deg \(default start \(\S+, \S+\) m: "
                     r"largest of 1 regions where the robot fits, (\S+) m2\)", line)
    assert m is not None, line
    assert abs(float(m[1]) - 2.0) <= 0.05 and abs(float(m[2]) - 2.0) <= 0.05
    assert float(m[3]) == pytest.approx(3.45 * 3.45, rel=0.01)

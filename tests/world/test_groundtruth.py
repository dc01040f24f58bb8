"""Ground truth: rasterised occupancy, reachable and explorable cells, coverage and IoU."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError, WorldError
from robotexp.mapping.geometry import GridGeometry
from robotexp.world.groundtruth import (GroundTruth, coverage, coverage_inside, ground_truth, map_iou, map_iou_tolerant,
                                        ray_tree)
from robotexp.mapping.kernels import view_free
from robotexp.mapping.reference import beam_cells
from robotexp.robot import Pose
from robotexp.world.model import World

GEO = GridGeometry(0.0, 0.0, 0.1, 24, 24)      # 2.4 m square, walls on cell borders


def _room(inner_top: float) -> World:
    """Outer walls fill rows/cols 0 and 23; an inner wall fills col 11 from y = 0.1 to `inner_top`."""
    h = (inner_top - 0.1) / 2
    boxes = [(1.2, 0.05, 1.2, 0.05, 0.0), (1.2, 2.35, 1.2, 0.05, 0.0),
             (0.05, 1.2, 0.05, 1.2, 0.0), (2.35, 1.2, 0.05, 1.2, 0.0),
             (1.15, 0.1 + h, 0.05, h, 0.0)]
    return World("room", np.array(boxes))


def _gt(world, start=None, **kw):
    args = {"robot_radius": 0.25, "laser_range": 10.0, "start": start or Pose(0.55, 0.55)}
    args.update(kw)
    return ground_truth(world, GEO, **args)


def test_room_with_a_door_counts_by_hand():
    gt = _gt(_room(1.5))                       # inner wall rows 1..14, door rows 15..22
    # Occupied: 92 outer-wall cells + 14 inner-wall cells.
    assert gt.occupied.sum() == 92 + 14
    assert gt.occupied[1:15, 11].all() and not gt.occupied[15:23, 11].any()
    # C-free (radius 2.5 cells, equality blocks): rows and cols 4..19 (256 cells) minus, around the
    # inner wall, rows 4..14 x cols 8..14 (77), row 15 cols 9..13 (5), row 16 cols 9..13 (5) and
    # (17, 11), whose square distance to the wall end is exactly 2.5 cells. All of it connects
    # through rows 17..19 of the door.
    expected = np.zeros((24, 24), bool)
    expected[4:20, 4:20] = True
    expected[4:15, 8:15] = False
    expected[15:17, 9:14] = False
    expected[17, 11] = False
    np.testing.assert_array_equal(gt.reachable, expected)
    assert gt.reachable.sum() == 256 - 88
    # With a 10 m laser every free cell is seen from somewhere.
    np.testing.assert_array_equal(gt.explorable, ~gt.occupied)
    assert gt.explorable.sum() == 576 - 106


def test_closed_room_is_not_explorable():
    gt = _gt(_room(2.3))                       # the inner wall closes the right room
    expected = np.zeros((24, 24), bool)
    expected[4:20, 4:8] = True                 # cols 8..10 are within 2.5 cells of the wall
    np.testing.assert_array_equal(gt.reachable, expected)
    explorable = np.zeros((24, 24), bool)
    explorable[1:23, 1:11] = True              # every free cell of the left room, none on the right
    np.testing.assert_array_equal(gt.explorable, explorable)


def test_short_laser_sees_only_nearby_cells():
    gt = _gt(_room(2.3), laser_range=0.14)
    # Rays of 1.4 cells from the centres of the reachable cells (cols 4..7, rows 4..19) reach
    # col 8 (x < 8.9 cells) but not col 9, row 3 (y > 3.1) but not row 2, row 20 but not row 21.
    assert gt.explorable[4:20, 8].all() and not gt.explorable[:, 9:].any()
    assert gt.explorable[3, 4:8].all() and not gt.explorable[2, 4:8].any()
    assert gt.explorable[20, 4:8].all() and not gt.explorable[21, 4:8].any()


@pytest.mark.parametrize("start, what", [
    (Pose(1.15, 0.5), "inside an obstacle"),   # in the inner wall
    (Pose(0.3, 1.0), "closer than the robot radius"),
    (Pose(-1.0, 1.0), "outside the map"),
    (Pose(1.5, 2.39), "inside an obstacle"),
])
def test_bad_start_raises_world_error(start, what):
    with pytest.raises(WorldError, match=what):
        _gt(_room(1.5), start=start)


def test_start_in_the_closed_room_reaches_only_it():
    gt = _gt(_room(2.3), start=Pose(1.8, 1.2))
    assert gt.reachable.sum() == 16 * 5       # cols 15..19, rows 4..19
    assert not gt.explorable[:, :12].any() and gt.explorable[1:23, 12:23].all()


def test_bad_parameters_raise_config_error():
    for kw in ({"robot_radius": -0.1}, {"laser_range": 0.0}, {"n_rays": 0}, {"sample_step": 0.0}):
        with pytest.raises(ConfigError):
            _gt(_room(1.5), **kw)


def test_view_free_matches_ray_by_ray_reference():
    rng = np.random.default_rng(11)
    geo = GridGeometry(0.0, 0.0, 0.1, 30, 34)
    occ = rng.random((30, 34)) < 0.08
    free = np.argwhere(~occ)
    views = free[rng.choice(len(free), 12, replace=False)].astype(np.int64)
    n_rays, laser_range = 90, 1.3
    offsets, skip = ray_tree(n_rays, laser_range / geo.cell)
    got = view_free(occ, views, offsets, skip)
    ref = np.zeros_like(occ)
    for r, c in views:
        x, y = geo.center_of(r, c)
        for i in range(n_rays):
            cells, _ = beam_cells(geo, x, y, 2 * math.pi * i / n_rays, laser_range)
            for rr, cc in cells:
                if occ[rr, cc]:
                    break
                ref[rr, cc] = True
    np.testing.assert_array_equal(got, ref)
    assert ref.sum() > 200
    assert len(offsets) < n_rays * 14           # the tree shares the cells near the viewpoint


def test_coverage_and_iou():
    gt = _gt(_room(2.3))
    n_expl = int(gt.explorable.sum())
    assert coverage(gt.explorable, gt) == 1.0
    half = gt.explorable.copy()
    half[:12] = False
    assert coverage(half, gt) == pytest.approx(half.sum() / n_expl)
    # A perfect map: occupied where occupied, free where explorable.
    states = np.full((24, 24), -1, np.int8)
    states[gt.explorable] = 0
    states[gt.occupied] = 100
    assert map_iou(states, gt) == 1.0
    # Only the free part: IoU_occ = 0 -> 0.5.
    free_only = np.where(gt.explorable, 0, -1).astype(np.int8)
    assert map_iou(free_only, gt) == 0.5
    # Observable occupied target O: the left room's walls, every cell 8-adjacent to its inside:
    # rows 0..23 of cols 0 and 11 (48) + cols 1..10 of rows 0 and 23 (20) = 68 cells.
    observable = np.where(gt.explorable, 0, -1).astype(np.int8)
    observable[:, [0, 11]] = 100
    observable[[0, 23], 1:11] = 100
    assert map_iou(observable, gt) == 1.0
    observable[:, 11] = -1                     # 24 of the 68 missing
    assert map_iou(observable, gt) == pytest.approx(0.5 * (44 / 68 + 1.0))
    # A free cell mapped occupied: one wrong mark in each IoU (114 occupied cells, all mapped).
    wrong = states.copy()
    wrong[5, 5] = 100
    expected = 0.5 * (114 / 115 + (n_expl - 1) / n_expl)
    assert gt.occupied.sum() == 114
    assert map_iou(wrong, gt) == pytest.approx(expected)
    with pytest.raises(ConfigError, match="same GridGeometry"):
        coverage(np.zeros((3, 3), bool), gt)
    with pytest.raises(ConfigError):
        map_iou(np.zeros((3, 3), np.int8), gt)


def test_coverage_inside_leaves_out_the_cells_along_faces_and_nothing_farther():
    gt = _gt(_room(2.3))
    # the left room: rows 1..22, cols 1..10 explorable (220 cells); those not 8-adjacent to a wall
    # cell are rows 2..21, cols 2..9 (160)
    assert gt.explorable.sum() == 220
    free = gt.explorable.copy()
    free[1:23, 10] = False                     # the inner wall's hits a cell short: col 10 not free
    free[1, 1:11] = False                      # and the south wall's
    assert coverage(free, gt) == pytest.approx((220 - 22 - 9) / 220)
    assert coverage_inside(free, gt) == 1.0
    free[5, 5] = False                         # a cell in the middle of the floor stays missed
    assert coverage_inside(free, gt) == pytest.approx(159 / 160)
    free[2, 2] = False                         # two cells from the walls: inside with 1, not with 2
    assert coverage_inside(free, gt) == pytest.approx(158 / 160)
    # with 2 cells: rows 3..20, cols 3..8 (108 cells), [5, 5] the one missed
    assert coverage_inside(free, gt, 2) == pytest.approx(107 / 108)
    assert coverage_inside(np.zeros((24, 24), bool), gt) == 0.0
    with pytest.raises(ConfigError, match="same GridGeometry"):
        coverage_inside(np.zeros((3, 3), bool), gt)


def test_tolerant_iou_forgives_a_face_one_cell_off_and_nothing_farther():
    gt = _gt(_room(2.3))
    n_expl = int(gt.explorable.sum())
    observable = np.where(gt.explorable, 0, -1).astype(np.int8)
    observable[:, [0, 11]] = 100
    observable[[0, 23], 1:11] = 100
    # The inner wall's face lies on the border of cols 10 and 11: a pose 2 mm west puts its hits in
    # col 10, the free cell in front of it (rows 1..22), and leaves col 11 unseen.
    shifted = observable.copy()
    shifted[:, 11] = -1
    shifted[1:23, 10] = 100
    # map_iou: 66 occupied marks, 44 of them right, the 24 cells of col 11 missed; 22 free cells lost.
    strict = 0.5 * (44 / 90 + (n_expl - 22) / n_expl)
    assert map_iou(shifted, gt) == pytest.approx(strict)
    assert map_iou_tolerant(shifted, gt, 0) == pytest.approx((strict, 44 / 90, (n_expl - 22) / n_expl))
    # one cell of tolerance: every mark lies next to its truth and every target next to a mark
    assert map_iou_tolerant(shifted, gt, 1) == (1.0, 1.0, 1.0)
    # a free cell five cells from any wall mapped occupied stays wrong (114 occupied cells, all mapped)
    states = np.full((24, 24), -1, np.int8)
    states[gt.explorable] = 0
    states[gt.occupied] = 100
    states[5, 5] = 100
    assert map_iou_tolerant(states, gt, 1) == pytest.approx((0.5 * (114 / 115 + 1.0), 114 / 115, 1.0))
    assert map_iou_tolerant(states, gt, 0)[0] == pytest.approx(map_iou(states, gt))
    with pytest.raises(ConfigError, match="cells must be >= 0"):
        map_iou_tolerant(states, gt, -1)
    with pytest.raises(ConfigError):
        map_iou_tolerant(np.zeros((3, 3), np.int8), gt)


def test_ground_truth_is_a_frozen_record():
    gt = _gt(_room(1.5))
    assert isinstance(gt, GroundTruth) and gt.geo == GEO
    np.testing.assert_array_equal(gt.free, ~gt.occupied)


def _two_rooms(door_right: float) -> World:
    """3 x 5 m, walls on cell borders; a wall across at y 2.4..2.5 m with a door from x = 1.02 m to
    `door_right` [m] (faces off the 10 cm cell borders)."""
    boxes = [(1.5, 0.05, 1.5, 0.05, 0.0), (1.5, 4.95, 1.5, 0.05, 0.0),
             (0.05, 2.5, 0.05, 2.5, 0.0), (2.95, 2.5, 0.05, 2.5, 0.0),
             ((0.1 + 1.02) / 2, 2.45, (1.02 - 0.1) / 2, 0.05, 0.0),
             ((door_right + 2.9) / 2, 2.45, (2.9 - door_right) / 2, 0.05, 0.0)]
    return World("two rooms", np.array(boxes))


def test_a_door_closed_at_the_grid_s_cells_but_open_to_the_robot_joins_the_rooms():
    geo = GridGeometry(0.0, 0.0, 0.1, 50, 30)
    above = geo.cell_of(1.5, 3.8)
    # A 0.71 m door for a 0.5 m robot. At 10 cm its wall ends fill the cells [1.0, 1.1) and [1.7, 1.8):
    # the best centre in between (1.35 or 1.45 m) is exactly 0.25 m from one of them, and equality
    # blocks - the grid's C-free alone holds no cell in the doorway.
    from robotexp.world.groundtruth import occupancy
    from robotexp.mapping.kernels import clearance_mask, flood8
    world = _two_rooms(1.73)
    cfree = clearance_mask(occupancy(world, geo), 0.25 / 0.1)
    assert not flood8(cfree, *geo.cell_of(1.5, 1.2))[above]
    # The exact geometry has 0.71 m between the wall ends: the robot passes with 0.105 m to spare on
    # each side and the room above counts. Beyond the coarse C-free it holds the cells whose centre is
    # more than 0.25 m from the exact wall: the doorway's (2.45 m; x 1.35 m: 0.33 m from the end at
    # 1.02 m, 1.45 m: 0.28 m from 1.73 m), (1.05, 2.15) and (1.05, 2.75) m (0.2518 m from the corner
    # (1.02, 2.4) or (1.02, 2.5)), (1.25, 2.25) and (1.25, 2.65) m (0.2746 m from the corner).
    gt = ground_truth(world, geo, robot_radius=0.25, laser_range=3.0, start=Pose(1.5, 1.2))
    assert gt.reachable[above]
    extra = {tuple(rc) for rc in np.argwhere(gt.reachable & ~cfree).tolist()}
    assert extra == {(24, 13), (24, 14), (21, 10), (27, 10), (22, 12), (26, 12)}
    assert not (cfree & ~gt.reachable).any()
    # A 0.50 m door (1.02..1.52 m) for a 0.5 m robot: no point lies farther than 0.25 m from both ends.
    gt = ground_truth(_two_rooms(1.52), geo, robot_radius=0.25, laser_range=3.0, start=Pose(1.5, 1.2))
    assert not gt.reachable[above]
    assert not gt.reachable[geo.cell_of(1.5, 2.7)]

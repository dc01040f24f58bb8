"""Reachable from the exact geometry: a door 2 cm wider than the robot is open, 2 cm narrower closed,
whatever the cell; exact clearance against a plain numpy reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.world.clearance import BUCKET, TOL, clearance, reach_regions, world_index
from robotexp.mapping.geometry import GridGeometry
from robotexp.world.groundtruth import ground_truth, occupancy
from robotexp.robot import Pose
from robotexp.sim.presets import PRESETS
from robotexp.world.model import World, segment_box


def _wall_with_door(left: float, width: float, yaw: float = 0.0) -> World:
    """A 4 x 6 m room split at y = 3 m by a 0.1 m wall with a door from x = `left` to `left + width`;
    the whole world turned by `yaw` about (2, 3) m."""
    t = 0.1
    segs = [((0, 0), (4, 0)), ((4, 0), (4, 6)), ((4, 6), (0, 6)), ((0, 6), (0, 0)),
            ((0, 3), (left, 3)), ((left + width, 3), (4, 3))]
    c, s = math.cos(yaw), math.sin(yaw)

    def turn(p: tuple[float, float]) -> tuple[float, float]:
        x, y = p[0] - 2, p[1] - 3
        return (2 + c * x - s * y, 3 + s * x + c * y)

    boxes = []
    for a, b in segs:
        if (a, b) in segs[4:]:       # the door's walls end exactly at the door (no half-thickness past it)
            (x0, y0), (x1, y1) = turn(a), turn(b)
            length = math.hypot(x1 - x0, y1 - y0)
            boxes.append(((x0 + x1) / 2, (y0 + y1) / 2, length / 2, t / 2, math.atan2(y1 - y0, x1 - x0)))
        else:
            boxes.append(segment_box(*turn(a), *turn(b), t))
    return World("door", np.array(boxes))


@pytest.mark.parametrize("robot", ["kobuki", "p3dx"])
@pytest.mark.parametrize("cell", [0.1, 0.05])
@pytest.mark.parametrize("left,yaw", [(1.237, 0.0), (0.861, 0.0), (1.5, math.radians(17.0))])
def test_a_door_two_centimetres_wider_than_the_robot_is_open_two_narrower_closed(robot, cell, left, yaw):
    radius = PRESETS[robot].radius
    width = 2 * radius
    geo = GridGeometry.covering(-1.0, -1.0, 5.0, 7.0, cell)
    c, s = math.cos(yaw), math.sin(yaw)
    start = Pose(2 + c * 0.0 - s * (-1.5), 3 + s * 0.0 + c * (-1.5))          # (2, 1.5) m turned
    behind = (2 + c * 0.0 - s * 1.5, 3 + s * 0.0 + c * 1.5)                  # (2, 4.5) m turned
    for extra, open_ in ((0.02, True), (-0.02, False)):
        gt = ground_truth(_wall_with_door(left, width + extra, yaw), geo, robot_radius=radius, laser_range=3.0,
                          start=start)
        assert gt.reachable[geo.cell_of(*behind)] == open_, (robot, cell, extra)
        # the room behind counts wholly or not at all (its free cells farther than the radius from the walls)
        assert gt.reachable.sum() > (2.0 if open_ else 1.0) * (4 - 2 * radius - 0.2) * (3 - 2 * radius - 0.2) / cell**2


def _distance_reference(world: World, x: float, y: float) -> float:
    """Distance [m] from (x, y) to the nearest box or disc of `world`, by sampling nothing: each box's
    frame, clamped."""
    best = math.inf
    for cx, cy, hx, hy, yaw in world.boxes:
        px, py = x - cx, y - cy
        lx = math.cos(yaw) * px + math.sin(yaw) * py
        ly = -math.sin(yaw) * px + math.cos(yaw) * py
        qx, qy = np.clip(lx, -hx, hx), np.clip(ly, -hy, hy)
        best = min(best, math.hypot(lx - qx, ly - qy))
    for cx, cy, r in world.discs:
        best = min(best, max(math.hypot(x - cx, y - cy) - r, 0.0))
    return best


def test_clearance_is_the_exact_distance_to_the_shapes():
    rng = np.random.default_rng(3)
    boxes = np.column_stack([rng.uniform(0, 6, 40), rng.uniform(0, 6, 40), rng.uniform(0.02, 0.6, 40),
                             rng.uniform(0.02, 0.3, 40), rng.uniform(-math.pi, math.pi, 40)])
    discs = np.column_stack([rng.uniform(0, 6, 10), rng.uniform(0, 6, 10), rng.uniform(0.05, 0.4, 10)])
    world = World("clutter", boxes, discs)
    geo = GridGeometry(-0.5, -0.5, 0.1, 70, 70)
    cap = 0.6
    occ = occupancy(world, geo)
    got = clearance(world, geo, cap, occupied=occ)
    plain = clearance(world, geo, cap, index=world_index(world))      # every cell searched
    np.testing.assert_array_equal(got, plain)
    for r, c in rng.integers(0, 70, (300, 2)):
        x, y = geo.center_of(int(r), int(c))
        assert got[r, c] == pytest.approx(min(_distance_reference(world, x, y), cap), abs=1e-12)


def _crossing_walls(n: int, size: float, seed: int) -> World:
    """`n` walls between random points of a `size` m square: long lines crossing one another everywhere
    (a map file of random lines)."""
    rng = np.random.default_rng(seed)
    ends = rng.uniform(0, size, (n, 4))
    return World("crossing", np.array([segment_box(*e, 0.02) for e in ends]))


def test_clearance_among_long_crossing_walls_is_exact_and_searches_few_shapes():
    world = _crossing_walls(150, 20.0, 4)
    index = world_index(world)
    # buckets of at most BUCKET, each wall listed in the buckets it crosses: few walls per bucket
    assert index.bucket <= BUCKET and np.diff(index.starts).max() < 30
    geo = GridGeometry(-0.5, -0.5, 0.1, 210, 210)
    occ = occupancy(world, geo)
    got = clearance(world, geo, 0.8, occupied=occ, index=index)
    rng = np.random.default_rng(5)
    for r, c in rng.integers(0, 210, (300, 2)):
        x, y = geo.center_of(int(r), int(c))
        assert got[r, c] == pytest.approx(min(_distance_reference(world, x, y), 0.8), abs=1e-12)


def test_a_floor_skips_the_cells_the_raster_proves_near_and_changes_no_region():
    world = _crossing_walls(60, 12.0, 6)
    geo = GridGeometry(-0.3, -0.3, 0.05, 250, 250)
    occ = occupancy(world, geo)
    exact = clearance(world, geo, 0.5, occupied=occ)
    floor = 0.2
    got = clearance(world, geo, 0.5, occupied=occ, floor=floor)
    above = exact > floor
    np.testing.assert_array_equal(got[above], exact[above])          # exact where it may exceed the floor
    assert (got[~above] <= floor).all() and (got >= exact).all()      # a bound elsewhere, never below
    assert (got != exact).sum() > 0.2 * geo.rows * geo.cols            # most cells near the walls skipped
    for radius in (0.18, 0.25):
        regions = reach_regions(world, geo, radius, occupied=occ)
        h = geo.cell
        sure = exact > radius + h * math.sqrt(0.5) + TOL
        band = ~sure & (exact + h * math.sqrt(0.5) > radius + TOL)
        np.testing.assert_array_equal(regions.coarse > 0, sure)
        np.testing.assert_array_equal(regions.mid >= 0, band)
        np.testing.assert_array_equal(regions.clear[band | sure], exact[band | sure].clip(max=radius + h))


def test_regions_area_counts_the_free_space_once():
    # an empty 3 x 2 m box (inner faces off the cell borders): the free space of a disc of 0.2 m is a
    # (3 - 0.4) x (2 - 0.4) m rectangle, counted at 1 cm along its border
    world = World("box", np.array([segment_box(0.013, 0.013, 3.013, 0.013, 0.02),
                                   segment_box(3.013, 0.013, 3.013, 2.013, 0.02),
                                   segment_box(3.013, 2.013, 0.013, 2.013, 0.02),
                                   segment_box(0.013, 2.013, 0.013, 0.013, 0.02)]))
    geo = GridGeometry.covering(-0.2, -0.2, 3.3, 2.3, 0.1)
    regions = reach_regions(world, geo, 0.2, occupied=occupancy(world, geo))
    inner = regions.area[1:]
    big = inner.max()
    assert big == pytest.approx((2.98 - 0.4) * (1.98 - 0.4), rel=0.01)

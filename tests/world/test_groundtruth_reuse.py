"""`ground_truth` keeps a world's grid and the sight of its reachable regions between calls (a campaign
makes many runs per world): every start pose must still get exactly what a computation from scratch
gives, the start cell's own view included, and what it returns must not alias what it keeps.

Small worlds and few rays: these tests also run without numba (NUMBA_DISABLE_JIT=1 in CI)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robotexp.world import groundtruth
from robotexp.mapping.geometry import GridGeometry
from robotexp.world.groundtruth import _border, ground_truth, occupancy, ray_tree
from robotexp.world.clearance import reach_regions
from robotexp.mapping.kernels import view_free
from robotexp.robot import Pose
from robotexp.world.model import World

GEO = GridGeometry(0.0, 0.0, 0.1, 30, 40)       # 4 m x 3 m
RAYS = 90


def _two_rooms(extra: list[tuple[float, float, float, float, float]] = ()) -> World:
    """A 4 x 3 m hall: a wall at x = 2 m with a 0.9 m door, a pillar, and a closed 1 m box room (a
    second reachable region, for a start inside it)."""
    boxes = [(2.0, 0.05, 2.0, 0.05, 0.0), (2.0, 2.95, 2.0, 0.05, 0.0), (0.05, 1.5, 0.05, 1.5, 0.0),
             (3.95, 1.5, 0.05, 1.5, 0.0), (2.0, 0.9, 0.05, 0.8, 0.0), (2.0, 2.75, 0.05, 0.2, 0.0),
             (0.7, 2.0, 0.55, 0.05, 0.0), (0.7, 2.9, 0.55, 0.05, 0.0), (0.15, 2.45, 0.05, 0.45, 0.0),
             (1.25, 2.45, 0.05, 0.45, 0.0), *extra]
    return World("two-rooms", np.array(boxes), discs=np.array([(3.0, 1.0, 0.2)]))


def _from_scratch(world: World, start: Pose, laser_range: float,
                  step: int) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """The ground truth as one computation from scratch (the code before the reuse)."""
    occ = occupancy(world, GEO)
    row, col = GEO.cell_of(start.x, start.y)
    regions = reach_regions(world, GEO, 0.25, occupied=occ)
    reachable = (regions.centre_labels() == regions.region_at(start.x, start.y)) & ~occ
    reachable[row, col] = True
    views = _border(reachable)
    views[::step, ::step] |= reachable[::step, ::step]
    views[row, col] = True
    offsets, skip = ray_tree(RAYS, laser_range / GEO.cell)
    return occ, reachable, view_free(occ, np.argwhere(views).astype(np.int64), offsets, skip) | reachable


def test_every_start_gets_the_from_scratch_truth_and_the_sight_is_kept() -> None:
    world = _two_rooms()
    groundtruth._GRIDS.clear()
    # on and off the 2-cell lattice, both sides of the door, inside the box room (another region)
    starts = [Pose(0.55, 0.55), Pose(0.65, 0.75), Pose(3.35, 2.45), Pose(2.85, 0.45), Pose(0.7, 2.45)]
    for laser_range, sample_step in ((1.5, None), (1.0, 0.6)):
        step = 2 if sample_step is None else round(sample_step / GEO.cell)
        for start in starts:
            got = ground_truth(world, GEO, robot_radius=0.25, laser_range=laser_range, start=start, n_rays=RAYS,
                               sample_step=sample_step)
            occ, reachable, explorable = _from_scratch(world, start, laser_range, step)
            assert np.array_equal(got.occupied, occ)
            assert np.array_equal(got.reachable, reachable)
            assert np.array_equal(got.explorable, explorable), (laser_range, start)
    kept = groundtruth._GRIDS[next(iter(groundtruth._GRIDS))]
    # two regions (the hall, the box room) per sight: the other starts reused them
    assert len(kept.components) == 4


def test_what_it_returns_is_the_callers_own() -> None:
    world = _two_rooms()
    first = ground_truth(world, GEO, robot_radius=0.25, laser_range=1.5, start=Pose(0.55, 0.55), n_rays=RAYS)
    first.occupied[:] = True
    first.reachable[:] = False
    first.explorable[:] = False
    again = ground_truth(world, GEO, robot_radius=0.25, laser_range=1.5, start=Pose(0.55, 0.55), n_rays=RAYS)
    assert again.reachable.any() and not again.occupied.all() and again.explorable.any()


def test_a_changed_world_is_not_taken_for_the_kept_one() -> None:
    start = Pose(0.55, 0.55)
    before = ground_truth(_two_rooms(), GEO, robot_radius=0.25, laser_range=1.5, start=start, n_rays=RAYS)
    moved = _two_rooms([(1.4, 0.6, 0.2, 0.2, 0.0)])          # a box in the start's region
    after = ground_truth(moved, GEO, robot_radius=0.25, laser_range=1.5, start=start, n_rays=RAYS)
    assert after.occupied.sum() > before.occupied.sum()
    assert np.array_equal(after.explorable, _from_scratch(moved, start, 1.5, 2)[2])

"""`ground_truth` keeps a world's grid and the sight of its reachable regions between calls (a campaign
makes many runs per world): every start pose must still get exactly what a computation from scratch
gives, the start cell's own view included, and what it returns must not alias what it keeps."""

from __future__ import annotations

import numpy as np
import pytest

from robotexp.mapping import groundtruth
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.groundtruth import _border, ground_truth, occupancy, ray_tree
from robotexp.mapping.kernels import clearance_mask, flood8, view_free
from robotexp.robot import Pose
from robotexp.world.loader import load_world


def _from_scratch(world, geo, radius, laser_range, start, step=2, n_rays=720):
    """The ground truth as one computation from scratch (the code before the reuse)."""
    occ = occupancy(world, geo)
    row, col = geo.cell_of(start.x, start.y)
    reachable = flood8(clearance_mask(occ, radius / geo.cell), row, col)
    views = _border(reachable)
    views[::step, ::step] |= reachable[::step, ::step]
    views[row, col] = True
    offsets, skip = ray_tree(n_rays, laser_range / geo.cell)
    return occ, reachable, view_free(occ, np.argwhere(views).astype(np.int64), offsets, skip) | reachable


@pytest.mark.parametrize("name", ["dense", "ufmg-static"])
def test_every_start_pose_gets_the_from_scratch_truth(name: str) -> None:
    world = load_world(name)
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.2)
    groundtruth._GRIDS.clear()
    starts = list(world.poses.values())
    # off-lattice starts (odd cells: not on the 2-cell lattice of viewpoints) near each named pose
    starts += [Pose(p.x + 0.1, p.y + 0.1, 0.0) for p in starts]
    # a sparse lattice of viewpoints (every 2 m) and a short laser: there the start cell's own view counts
    for laser_range, sample_step in ((3.0, None), (1.0, None), (0.8, 2.0)):
        step = 2 if sample_step is None else round(sample_step / geo.cell)
        for start in starts:
            row, col = geo.cell_of(start.x, start.y)
            if not clearance_mask(occupancy(world, geo), 0.25 / geo.cell)[row, col]:
                continue
            got = ground_truth(world, geo, robot_radius=0.25, laser_range=laser_range, start=start,
                               sample_step=sample_step)
            occ, reachable, explorable = _from_scratch(world, geo, 0.25, laser_range, start, step)
            assert np.array_equal(got.occupied, occ)
            assert np.array_equal(got.reachable, reachable)
            assert np.array_equal(got.explorable, explorable), (name, laser_range, start)
    kept = next(iter(groundtruth._GRIDS.values()))
    assert len(kept.components) >= 3          # one region per laser range at least: the sight was reused


def test_what_it_returns_is_the_callers_own() -> None:
    world = load_world("ufmg-static")
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.2)
    start = next(iter(world.poses.values()))
    first = ground_truth(world, geo, robot_radius=0.25, laser_range=3.0, start=start)
    first.occupied[:] = True
    first.reachable[:] = False
    first.explorable[:] = False
    again = ground_truth(world, geo, robot_radius=0.25, laser_range=3.0, start=start)
    assert again.reachable.any() and not again.occupied.all()


def test_a_changed_world_is_not_taken_for_the_kept_one() -> None:
    world = load_world("ufmg-static")
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.2)
    start = next(iter(world.poses.values()))
    before = ground_truth(world, geo, robot_radius=0.25, laser_range=3.0, start=start)
    # a box in the middle of the start's region, away from the start
    box = np.array([[start.x + 1.5, start.y, 0.3, 0.3, 0.0]])
    moved = type(world)(**{**world.__dict__, "boxes": np.vstack([world.boxes, box])})
    after = ground_truth(moved, geo, robot_radius=0.25, laser_range=3.0, start=start)
    assert after.occupied.sum() > before.occupied.sum()
    assert np.array_equal(after.explorable, _from_scratch(moved, geo, 0.25, 3.0, start)[2])

"""The planning helpers goal-seeking explorers share (robotexp.planning.targets, PathFollower.follow_cells),
and the rule that keeps them shared: no explorer plugin imports another."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

from robotexp.mapping.geometry import GridGeometry
from robotexp.planning.follower import PathFollower, path_points
from robotexp.robot import Limits
from robotexp.mapping.grid import OccupancyGrid
from robotexp.planning.kernels import SUB_POINTS
from robotexp.planning.targets import (away_from, beside_large_unknown, frontier_targets, nearest_passable,
                                      passable_cell, surface_distance)

GEO = GridGeometry(origin_x=-1.0, origin_y=2.0, cell=0.1, rows=10, cols=8)
PLUGINS = Path(__file__).resolve().parents[2] / "plugins"


def test_nearest_passable_nearest_first_row_major_on_ties_and_bounded_by_reach() -> None:
    passable = np.zeros((10, 8), dtype=bool)
    passable[2, 5] = passable[5, 2] = True       # both at squared distance 9 from (2, 2)
    assert nearest_passable(passable, 2, 2, 3) == (2, 5)        # the tie goes to the first in row-major order
    assert nearest_passable(passable, 2, 2, 2) is None          # neither lies within the 5 x 5 square
    passable[3, 3] = True
    assert nearest_passable(passable, 2, 2, 3) == (3, 3)        # squared distance 2 beats 9
    passable[2, 2] = True
    assert nearest_passable(passable, 2, 2, 0) == (2, 2)        # a passable cell is its own nearest
    assert nearest_passable(passable, 9, 7, 1) is None          # the square is clipped at the grid's corner


def test_passable_cell_own_cell_nearest_within_reach_and_off_grid() -> None:
    passable = np.zeros((10, 8), dtype=bool)
    passable[4, 6] = True                        # centre (-1 + 6.5 * 0.1, 2 + 4.5 * 0.1) = (-0.35, 2.45)
    assert passable_cell(GEO, passable, -0.35, 2.45) == (4, 6)
    # from cell (4, 2) [x = -0.75] the passable cell is 4 cells away: found with a 0.5 m reach, not 0.3 m
    assert passable_cell(GEO, passable, -0.75, 2.45) == (4, 6)
    assert passable_cell(GEO, passable, -0.75, 2.45, reach=0.3) is None
    assert passable_cell(GEO, passable, -1.05, 2.45) is None    # left of the grid: no cell at all
    assert passable_cell(GEO, passable, 0.0, 3.0) is None       # col 10 > 7


def test_path_points_string_pulls_and_follow_cells_starts_at_the_robot() -> None:
    passable = np.ones((10, 8), dtype=bool)
    cells = np.array([[1, 1], [2, 2], [3, 3], [4, 3], [5, 3]], dtype=np.int32)
    pts = path_points(cells, passable, GEO)
    # open space: only the ends survive, at their cell centres
    np.testing.assert_allclose(pts, [[-1 + 1.5 * 0.1, 2 + 1.5 * 0.1], [-1 + 3.5 * 0.1, 2 + 5.5 * 0.1]])
    follower = PathFollower(Limits(v_max=0.5, w_max=1.0, a_max=0.5, alpha_max=1.0), radius=0.2)
    follower.follow_cells(cells, passable, GEO, (-0.87, 2.14))
    np.testing.assert_allclose(follower.path, [[-0.87, 2.14], [-0.65, 2.55]])
    assert not follower.done
    follower.follow_cells(cells[:1], passable, GEO, (-0.87, 2.14))      # one cell: a two-point path to itself
    np.testing.assert_allclose(follower.path, [[-0.87, 2.14], [-0.87, 2.14]])


def test_no_plugin_imports_another_plugin() -> None:
    """Plugins share code through robotexp (e.g. robotexp.planning), never through each other."""
    offenders = []
    for path in sorted(PLUGINS.rglob("*.py")):
        own = path.relative_to(PLUGINS).parts[0].removesuffix(".py")     # "srt" for plugins/srt/core.py
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            for name in names:
                parts = name.split(".")
                if parts[0] == "robotexp_plugins" and len(parts) > 1 and parts[1] != own:
                    offenders.append(f"{path.relative_to(PLUGINS)}:{node.lineno} imports {name}")
    assert offenders == []


def test_frontier_targets_are_the_large_groups_cells_less_the_dropped_ones() -> None:
    """frontier_targets (labels and group sizes) equals its definition, group by group through
    `frontier_groups`: the cells of groups of at least min_cells, less wall faces and skipped cells."""
    rng = np.random.default_rng(7)
    geo = GridGeometry(0.0, 0.0, 0.1, 60, 80)
    shape = (geo.rows, geo.cols)
    grid = OccupancyGrid(geo)
    free = np.zeros(shape, bool)
    for _ in range(25):             # rooms of free space, some touching: groups of many sizes
        r, c = int(rng.integers(0, 55)), int(rng.integers(0, 75))
        free[r:r + int(rng.integers(1, 12)), c:c + int(rng.integers(1, 12))] = True
    grid.mark_free(free)
    grid.mark_occupied((rng.random(shape) < 0.02) & free)
    skip = rng.random(shape) < 0.05
    for min_cells in (1, 3, 8, 40):
        ref = np.zeros(shape, bool)
        drop = grid.near_occupied() | skip
        groups = grid.frontier_groups(min_cells)
        for cells in groups:
            keep = cells[~drop[cells[:, 0], cells[:, 1]]]
            ref[keep[:, 0], keep[:, 1]] = True
        got = frontier_targets(grid, min_cells, skip)
        np.testing.assert_array_equal(got, ref)
    assert frontier_targets(grid, 1).sum() > frontier_targets(grid, 40).sum() > 0
    assert not frontier_targets(OccupancyGrid(geo), 1).any()


def _surface_reference(occ: np.ndarray, hit_box: np.ndarray, qy: np.ndarray, qx: np.ndarray) -> np.ndarray:
    """Distance [cells] from points (qy, qx) [cells from the grid's lower-left corner] to the nearest box of
    laser endpoints of an occupied cell (a whole cell where it holds none): every box, by brute force."""
    rr, cc = np.nonzero(occ)
    box = hit_box[rr, cc].astype(np.float64) / 255.0
    whole = box[:, 0] > box[:, 1]
    box[whole] = (0.0, 1.0, 0.0, 1.0)
    xl, xh, yl, yh = cc + box[:, 0], cc + box[:, 1], rr + box[:, 2], rr + box[:, 3]
    dx = np.maximum(np.maximum(xl - qx[..., None], 0.0), qx[..., None] - xh)
    dy = np.maximum(np.maximum(yl - qy[..., None], 0.0), qy[..., None] - yh)
    return np.hypot(dx, dy).min(axis=-1)


def test_cell_points_against_a_brute_force_reference() -> None:
    # walls with random boxes of laser endpoints (and some whole cells) on a 40 x 40 grid; a cell within
    # `below` of the surface at its centre takes the farthest of its other eight points when that one is
    # farther than `below`, else it stays blocked at its centre's distance
    rng = np.random.default_rng(3)
    occ = rng.random((40, 40)) < 0.04
    lo = rng.integers(0, 200, (40, 40, 2))
    hit_box = np.zeros((40, 40, 4), np.uint8)
    hit_box[..., 0], hit_box[..., 1] = lo[..., 0], lo[..., 0] + rng.integers(0, 56, (40, 40))
    hit_box[..., 2], hit_box[..., 3] = lo[..., 1], lo[..., 1] + rng.integers(0, 56, (40, 40))
    hit_box[rng.random((40, 40)) < 0.3, :2] = (1, 0)             # no endpoint: the whole cell
    below = 2.7
    points = np.zeros((40, 40), np.uint8)
    dist = surface_distance(occ, hit_box, below + 2.0, below, None, points)
    rows, cols = np.mgrid[0:40, 0:40]
    each = np.stack([_surface_reference(occ, hit_box, rows + 0.5 + dy, cols + 0.5 + dx) for dy, dx in SUB_POINTS])
    centre, farthest = each[0], each[1:].max(axis=0)
    moved = (centre <= below) & (farthest > below)
    assert 20 < np.count_nonzero(moved) < np.count_nonzero(centre <= below)
    assert np.array_equal(points != 0, moved)
    # the point named is the farthest (ties: any of them), its distance the cell's up to below + 1
    named = np.take_along_axis(each, points[None].astype(np.intp), axis=0)[0]
    assert np.allclose(named[moved], farthest[moved], atol=1e-9)
    assert np.allclose(dist[moved], np.minimum(farthest[moved], below + 1.0), atol=1e-5)
    # the others keep the distance from their centre where it is exact (up to `below`)
    near = ~moved & (centre <= below)
    assert np.allclose(dist[near], centre[near], atol=1e-5)


def test_beside_large_unknown_by_hand() -> None:
    # 10 cm cells: a 2 x 2-cell speck (0.04 m2) and a 5 x 6-cell piece (0.30 m2) in a 12 x 20 window
    unknown = np.zeros((12, 20), bool)
    unknown[2:4, 2:4] = True
    unknown[5:10, 12:18] = True
    near = beside_large_unknown(unknown, 0.25, 0.1)
    assert not near[:5, :8].any()                            # nothing beside the speck
    assert near[4, 13] and near[8, 11] and near[10, 18]      # beside the piece (diagonal: 1.41 cells)
    assert not near[8, 10] and not near[3, 15]               # two cells off
    assert beside_large_unknown(unknown, 0.04, 0.1)[1, 1]    # the speck is large enough for 0.04 m2
    # a speck on an edge that is not the map's goes on beyond it: large; on the map's edge: not
    edge = np.zeros((12, 20), bool)
    edge[0:2, 5:7] = True
    assert not beside_large_unknown(edge, 0.25, 0.1).any()
    assert beside_large_unknown(edge, 0.25, 0.1, (True, False, False, False))[2, 6]
    assert not beside_large_unknown(edge, 0.25, 0.1, (False, True, True, True)).any()


def test_away_from_by_hand() -> None:
    cells = np.zeros((5, 9), bool)
    cells[2, :] = True
    been = np.zeros_like(cells)
    assert np.array_equal(away_from(cells, been, 2.0), cells)        # nowhere been: all kept
    been[2, 0] = True
    assert np.array_equal(np.flatnonzero(away_from(cells, been, 2.0)[2]), np.arange(3, 9))   # 3 cells on


def test_discs_blocked_makes_the_cells_whose_centres_lie_in_a_disc_impassable_on_a_copy() -> None:
    from robotexp.planning.targets import discs_blocked

    cost = np.ones((6, 5), np.float32)          # the window of GEO's cells rows 2..7, cols 1..5
    off = (2, 1)
    # a disc about the centre of grid cell (5, 3) reaching 0.105 m: that cell and its four side neighbours
    # (centres 0.1 m away; the diagonal ones are 0.141 m away); one about the grid's corner cell (0, 0),
    # outside the window; one far outside the grid
    x, y = GEO.center_of(5, 3)
    out = discs_blocked(cost, GEO, off, np.array([[x, y, 0.105], [-0.95, 2.05, 0.15], [50.0, 50.0, 1.0]]))
    want = np.zeros((6, 5), bool)
    for r, c in [(5, 3), (4, 3), (6, 3), (5, 2), (5, 4)]:
        want[r - off[0], c - off[1]] = True
    assert (np.isinf(out) == want).all() and (out[~want] == 1.0).all()
    assert (cost == 1.0).all()                  # the window itself is left as it was
    assert (discs_blocked(cost, GEO, off, np.zeros((0, 3))) == cost).all()

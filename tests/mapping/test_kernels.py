"""Mapping kernels against hand-computed cases and slow independent references."""

from __future__ import annotations

import math
from collections import deque

import numpy as np
import pytest

from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.kernels import (
    LogOddsModel,
    clearance_mask,
    edt_sq,
    flood,
    flood8,
    frontier_mask,
    integrate_scan_himm,
    integrate_scan_logodds,
    label8,
    rasterize,
    traverse,
)
from robotexp.mapping.reference import beam_cells, integrate_scan_himm_ref, integrate_scan_logodds_ref

L_FREE = math.log(0.1 / 0.9)
L_OCC = math.log(0.9 / 0.1)
GEO5 = GridGeometry(0.0, 0.0, 1.0, 5, 5)


def _scan(grid_kind, geo, pose, angles, ranges, range_max=10.0, prior=0):
    """One scan (id 1) into a fresh grid whose cells all hold `prior`; returns (grid, seen, n)."""
    stamp = np.zeros((geo.rows, geo.cols), np.int32)
    pose = np.asarray(pose, np.float64)
    angles = np.asarray(angles, np.float64)
    ranges = np.asarray(ranges, np.float64)
    if grid_kind == "logodds":
        grid = np.full((geo.rows, geo.cols), prior, np.float32)
        model = LogOddsModel(L_FREE, L_OCC, -3.5, 3.5, range_max)
        n = integrate_scan_logodds(grid, stamp, 1, geo, pose, angles, ranges, model)
    else:
        grid = np.full((geo.rows, geo.cols), prior, np.uint8)
        n = integrate_scan_himm(grid, stamp, 1, geo, pose, angles, ranges, range_max)
    assert set(np.unique(stamp).tolist()) <= {0, 1}
    assert np.count_nonzero(stamp) == n              # n counts distinct cells, each stamped once
    return grid, stamp > 0, n


# ---------------------------------------------------------------- hand-computed cases (5 x 5, 1 m)
def test_axis_beam_hits_fourth_cell():
    grid, seen, n = _scan("logodds", GEO5, [0.5, 0.5, 0.0], [0.0], [3.2])
    expected = np.zeros((5, 5), np.float32)
    expected[0, 0:3] = np.float32(L_FREE)
    expected[0, 3] = np.float32(L_OCC)
    assert n == 4
    np.testing.assert_array_equal(grid, expected)
    np.testing.assert_array_equal(seen, expected != 0)


def test_oblique_beam_cells_by_hand():
    # From (0.2, 0.5) along (2, 1)/sqrt(5) to (2.6, 1.7): it crosses x=1 at y=0.9, y=1 at x=1.2,
    # x=2 at y=1.4, so cells (0,0) (0,1) (1,1) are free and (1,2) holds the hit.
    length = math.hypot(2.4, 1.2)
    grid, seen, n = _scan("logodds", GEO5, [0.2, 0.5, 0.0], [math.atan2(1, 2)], [length])
    assert n == 4
    free = [(0, 0), (0, 1), (1, 1)]
    for rc in free:
        assert grid[rc] == np.float32(L_FREE)
    assert grid[1, 2] == np.float32(L_OCC)
    assert np.count_nonzero(grid) == 4 and np.count_nonzero(seen) == 4


def test_max_range_and_inf_beams_are_all_free_and_clipped():
    # Up from (2.5, 2.5): inf range, range_max 10 -> free up to the top edge, no hit, 3 cells.
    grid, _, n = _scan("logodds", GEO5, [2.5, 2.5, math.pi / 2], [0.0], [math.inf])
    assert n == 3
    assert np.all(grid[2:5, 2] == np.float32(L_FREE)) and np.count_nonzero(grid) == 3
    # A 1.7 m reading with range_max 1.4 is a no-hit beam from x = 0.5 to 1.9: cols 0 and 1.
    grid, _, n = _scan("logodds", GEO5, [0.5, 0.5, 0.0], [0.0], [1.7], range_max=1.4)
    assert n == 2 and np.all(grid[0, 0:2] == np.float32(L_FREE)) and np.count_nonzero(grid) == 2
    # A hit beyond the grid edge is lost: 5 free cells, no occupied one.
    grid, _, n = _scan("logodds", GEO5, [0.5, 0.5, 0.0], [0.0], [7.0])
    assert n == 5 and np.all(grid[0] == np.float32(L_FREE))


def test_nan_and_negative_ranges_are_skipped():
    grid, seen, n = _scan("logodds", GEO5, [2.5, 2.5, 0.0], [0.0, 1.0], [math.nan, -1.0])
    assert n == 0 and not grid.any() and not seen.any()


def test_end_on_a_face_lands_behind_it():
    # Ending exactly on x = 3 moving +x: the obstacle is the cell behind the face, col 3.
    grid, _, _ = _scan("logodds", GEO5, [0.5, 0.5, 0.0], [0.0], [2.5])
    assert grid[0, 3] == np.float32(L_OCC) and grid[0, 2] == np.float32(L_FREE)
    # Moving -x onto x = 1: the obstacle is col 0.
    grid, _, _ = _scan("logodds", GEO5, [3.5, 0.5, math.pi], [0.0], [2.5])
    assert grid[0, 0] == np.float32(L_OCC) and grid[0, 1] == np.float32(L_FREE)


def test_diagonal_through_corners_steps_diagonally():
    cells = np.empty((20, 2), np.int64)
    n, ended = traverse(GEO5, 0.5, 0.5, math.cos(math.pi / 4), math.sin(math.pi / 4), 4.0, cells)
    assert ended
    assert cells[:n].tolist() == [[0, 0], [1, 1], [2, 2], [3, 3]]


def test_sensor_outside_grid_enters_it():
    cells = np.empty((20, 2), np.int64)
    n, ended = traverse(GEO5, -2.0, 1.5, 1.0, 0.0, 4.5, cells)     # ends at x = 2.5
    assert ended and cells[:n].tolist() == [[1, 0], [1, 1], [1, 2]]
    n, ended = traverse(GEO5, -2.0, 1.5, -1.0, 0.0, 4.5, cells)    # pointing away
    assert n == 0 and not ended
    n, ended = traverse(GEO5, -2.0, 1.5, 1.0, 0.0, 1.5, cells)     # ends before the grid
    assert n == 0 and not ended


def test_logodds_clamps():
    grid = np.zeros((5, 5), np.float32)
    stamp = np.zeros((5, 5), np.int32)
    model = LogOddsModel(L_FREE, L_OCC, -3.5, 3.5, 10.0)
    args = (GEO5, np.array([0.5, 0.5, 0.0]), np.array([0.0]), np.array([3.2]), model)
    integrate_scan_logodds(grid, stamp, 1, *args)
    integrate_scan_logodds(grid, stamp, 2, *args)
    # 2 * 2.197 = 4.39 and -4.39 are clamped to +-3.5.
    assert grid[0, 0] == np.float32(-3.5) and grid[0, 3] == np.float32(3.5)


def test_himm_saturates_at_15_and_0():
    cert = np.zeros((5, 5), np.uint8)
    stamp = np.zeros((5, 5), np.int32)
    hit = (GEO5, np.array([0.5, 0.5, 0.0]), np.array([0.0]), np.array([3.2]), 10.0)
    history = []
    for k in range(1, 7):
        assert integrate_scan_himm(cert, stamp, k, *hit) == 4
        history.append(int(cert[0, 3]))
    assert history == [3, 6, 9, 12, 15, 15]
    assert cert[0, :3].tolist() == [0, 0, 0]                   # floor at 0
    # A max-range beam over the hit cell takes 1 per scan.
    through = (GEO5, np.array([0.5, 0.5, 0.0]), np.array([0.0]), np.array([math.inf]), 10.0)
    assert integrate_scan_himm(cert, stamp, 7, *through) == 5
    assert cert[0].tolist() == [0, 0, 0, 14, 0]
    assert stamp[0].tolist() == [7, 7, 7, 7, 7] and np.count_nonzero(stamp) == 5


# ---------------------------------------------------------------- once per scan, a hit wins
# Sensor at (0.5, 0.5). Beam A along +x, 1.2 m: ends at x = 1.7, so (0,0) is free and X = (0,1)
# holds its hit. Beam B along (4, 1) to (3.3, 1.2): y = 0.5 + (x - 0.5) / 4 crosses x = 1 at 0.625,
# x = 2 at 0.875, y = 1 at x = 2.5 and x = 3 at 1.125, so it crosses (0,0) (0,1) (0,2) (1,2) and
# hits (1,3): it passes through X before its own hit.
_A = (0.0, 1.2)
_B = (math.atan2(1.0, 4.0), math.hypot(2.8, 0.7))


@pytest.mark.parametrize("order", [(_A, _B), (_B, _A)])
def test_logodds_hit_wins_over_a_crossing_beam(order):
    angles, ranges = zip(*order, strict=True)
    grid, seen, n = _scan("logodds", GEO5, [0.5, 0.5, 0.0], angles, ranges)
    expected = np.zeros((5, 5), np.float32)
    expected[0, 0] = np.float32(L_FREE)     # crossed by both beams: l_free once, not twice
    expected[0, 1] = np.float32(L_OCC)      # X: hit by A, crossed by B -> l_occ, not l_occ + l_free = 0
    expected[0, 2] = np.float32(L_FREE)
    expected[1, 2] = np.float32(L_FREE)
    expected[1, 3] = np.float32(L_OCC)
    np.testing.assert_array_equal(grid, expected)
    assert n == 5
    np.testing.assert_array_equal(seen, expected != 0)


@pytest.mark.parametrize("order", [(_A, _B), (_B, _A)])
def test_himm_hit_wins_over_a_crossing_beam(order):
    # From certainty 5 everywhere: hits -> 8, free cells -> 4 (once, even (0,0) crossed twice).
    angles, ranges = zip(*order, strict=True)
    cert, seen, n = _scan("himm", GEO5, [0.5, 0.5, 0.0], angles, ranges, prior=5)
    expected = np.full((5, 5), 5, np.uint8)
    expected[0, 0:3] = [4, 8, 4]
    expected[1, 2:4] = [4, 8]
    np.testing.assert_array_equal(cert, expected)
    assert n == 5 and seen.sum() == 5


def test_free_cell_crossed_by_many_beams_gets_l_free_once():
    # Eight max-range beams (each twice) from the centre of (2,2), every 45 deg: row 2, col 2 and
    # both diagonals (corners step diagonally) - 17 distinct cells; (2,2) is crossed 16 times.
    angles = np.repeat(np.arange(8) * (math.pi / 4), 2)
    grid, seen, n = _scan("logodds", GEO5, [2.5, 2.5, 0.0], angles, np.full(16, math.inf))
    lines = np.zeros((5, 5), bool)
    lines[2, :] = lines[:, 2] = True
    lines[np.arange(5), np.arange(5)] = lines[np.arange(5), 4 - np.arange(5)] = True
    np.testing.assert_array_equal(grid, np.where(lines, np.float32(L_FREE), np.float32(0)))
    assert n == 17 and lines.sum() == 17
    np.testing.assert_array_equal(seen, lines)
    # The same with HIMM from certainty 7: every line cell at 6.
    cert, _, n = _scan("himm", GEO5, [2.5, 2.5, 0.0], angles, np.full(16, math.inf), prior=7)
    np.testing.assert_array_equal(cert, np.where(lines, 6, 7))
    assert n == 17


def test_two_scans_add_and_keep_their_stamps():
    # Scan 1: A and B above. Scan 2: one beam along +x to x = 3.7, crossing (0,0) (0,1) (0,2),
    # hitting (0,3).
    grid = np.zeros((5, 5), np.float32)
    stamp = np.zeros((5, 5), np.int32)
    model = LogOddsModel(L_FREE, L_OCC, -5.0, 5.0, 10.0)
    pose = np.array([0.5, 0.5, 0.0])
    assert integrate_scan_logodds(grid, stamp, 1, GEO5, pose, np.array([_A[0], _B[0]]),
                                  np.array([_A[1], _B[1]]), model) == 5
    assert integrate_scan_logodds(grid, stamp, 2, GEO5, pose, np.array([0.0]), np.array([3.2]), model) == 4
    f, o = np.float32(L_FREE), np.float32(L_OCC)
    expected = np.zeros((5, 5), np.float32)
    expected[0, 0] = np.float32(np.float64(f) + L_FREE)       # free in both scans
    expected[0, 1] = np.float32(np.float64(o) + L_FREE)       # hit in scan 1, crossed in scan 2
    expected[0, 2] = np.float32(np.float64(f) + L_FREE)
    expected[0, 3] = o                                        # hit in scan 2 only
    expected[1, 2] = f
    expected[1, 3] = o
    np.testing.assert_array_equal(grid, expected)
    expected_stamp = np.zeros((5, 5), np.int32)
    expected_stamp[0, 0:4] = 2
    expected_stamp[1, 2:4] = 1
    np.testing.assert_array_equal(stamp, expected_stamp)
    # HIMM, the same two scans from certainty 5.
    cert = np.full((5, 5), 5, np.uint8)
    hstamp = np.zeros((5, 5), np.int32)
    integrate_scan_himm(cert, hstamp, 1, GEO5, pose, np.array([_A[0], _B[0]]), np.array([_A[1], _B[1]]), 10.0)
    integrate_scan_himm(cert, hstamp, 2, GEO5, pose, np.array([0.0]), np.array([3.2]), 10.0)
    assert cert[0].tolist() == [3, 7, 3, 8, 5] and cert[1].tolist() == [5, 5, 4, 8, 5]
    np.testing.assert_array_equal(hstamp, expected_stamp)


# ---------------------------------------------------------------- traversal vs dense sampling
def _crossings(x0, y0, dx, dy, length, cell):
    ts = []
    for p, d in ((x0, dx), (y0, dy)):
        if d != 0:
            k = np.arange(math.floor(min(p, p + length * d) / cell) - 1,
                          math.ceil(max(p, p + length * d) / cell) + 2)
            t = (k * cell - p) / d
            ts.append(t[(t >= 0) & (t <= length)])
    return np.concatenate(ts + [np.array([0.0, length])])


def test_traverse_matches_dense_sampling():
    rng = np.random.default_rng(7)
    geo = GridGeometry(0.0, 0.0, 0.1, 40, 50)
    cells = np.empty((geo.rows + geo.cols + 1, 2), np.int64)
    checked = 0
    while checked < 200:
        x0, y0 = rng.uniform(0.01, 4.99), rng.uniform(0.01, 3.99)
        a = rng.uniform(-math.pi, math.pi)
        length = rng.uniform(0.05, 6.0)
        dx, dy = math.cos(a), math.sin(a)
        t = np.sort(_crossings(x0, y0, dx, dy, length, geo.cell))
        if np.min(np.diff(t)) < 1e-3:           # keep away from corners and near-tangent ends
            continue
        checked += 1
        n, ended = traverse(geo, x0, y0, dx, dy, length, cells)
        s = np.linspace(0.0, length, int(length / 1e-4) + 2)[1:-1]
        xs, ys = x0 + s * dx, y0 + s * dy
        inside = (xs >= 0) & (xs < geo.width) & (ys >= 0) & (ys < geo.height)
        rc = np.stack([np.floor(ys[inside] / geo.cell), np.floor(xs[inside] / geo.cell)], 1).astype(int)
        keep = np.ones(len(rc), bool)
        keep[1:] = np.any(rc[1:] != rc[:-1], axis=1)
        assert cells[:n].tolist() == rc[keep].tolist()
        ex, ey = x0 + length * dx, y0 + length * dy
        assert ended == (0 <= ex < geo.width and 0 <= ey < geo.height)


# ---------------------------------------------------------------- scans vs numpy reference
def _random_scans(seed, geo, count):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        pose = np.array([rng.uniform(geo.origin_x - 1, geo.origin_x + geo.width + 1),
                         rng.uniform(geo.origin_y - 1, geo.origin_y + geo.height + 1),
                         rng.uniform(-math.pi, math.pi)])
        n = 61
        angles = np.linspace(-math.pi, math.pi, n) + rng.normal(0, 0.01, n)
        ranges = rng.uniform(0.0, 4.0, n)
        ranges[rng.random(n) < 0.15] = math.inf
        ranges[rng.random(n) < 0.05] = math.nan
        yield pose, angles, ranges


def _overlaps(geo, pose, angles, ranges, range_max):
    """(cell visits of all beams, visits of hit cells by other beams' free parts) of one scan."""
    visits, hit_cells, free_cells = 0, set(), []
    for a, r in zip(angles, ranges, strict=True):
        if math.isnan(r) or r < 0:
            continue
        cells, ended = beam_cells(geo, pose[0], pose[1], pose[2] + a, min(r, range_max))
        visits += len(cells)
        hit = r < range_max and ended
        if hit:
            hit_cells.add(tuple(cells[-1]))
        free_cells += [tuple(rc) for rc in cells[:len(cells) - hit]]
    return visits, sum(rc in hit_cells for rc in free_cells)


def test_logodds_matches_reference_on_random_scans():
    geo = GridGeometry(-1.3, 0.7, 0.1, 30, 45)
    model = LogOddsModel(L_FREE, L_OCC, -3.5, 3.5, 3.0)
    g1 = np.zeros((geo.rows, geo.cols), np.float32)
    g2 = g1.copy()
    s1 = np.zeros(g1.shape, np.int32)
    s2 = s1.copy()
    total = visits = conflicts = 0
    for k, (pose, angles, ranges) in enumerate(_random_scans(1, geo, 40), start=1):
        n1 = integrate_scan_logodds(g1, s1, k, geo, pose, angles, ranges, model)
        n2 = integrate_scan_logodds_ref(g2, s2, k, geo, pose, angles, ranges, model)
        assert n1 == n2 == np.count_nonzero(s1 == k)
        total += n1
        v, c = _overlaps(geo, pose, angles, ranges, model.range_max)
        visits += v
        conflicts += c
    # The once-per-scan and hit-wins rules were exercised (beams share cells near the sensor).
    assert total > 10000 and visits > total + 3000 and conflicts > 500
    assert (g1 > 0).any() and (g1 == np.float32(-3.5)).sum() > 50 and len(np.unique(s1)) > 10
    np.testing.assert_array_equal(g1, g2)
    np.testing.assert_array_equal(s1, s2)


def test_himm_matches_reference_on_random_scans():
    geo = GridGeometry(0.0, 0.0, 0.1, 35, 30)
    c1 = np.zeros((geo.rows, geo.cols), np.uint8)
    c2 = c1.copy()
    s1 = np.zeros(c1.shape, np.int32)
    s2 = s1.copy()
    for k, (pose, angles, ranges) in enumerate(_random_scans(2, geo, 40), start=1):
        assert (integrate_scan_himm(c1, s1, k, geo, pose, angles, ranges, 3.0)
                == integrate_scan_himm_ref(c2, s2, k, geo, pose, angles, ranges, 3.0))
    assert (c1 > 2).sum() > 10 and (c1 == 0).sum() > 100
    np.testing.assert_array_equal(c1, c2)
    np.testing.assert_array_equal(s1, s2)


# ---------------------------------------------------------------- rasterize
def _clip_area(poly, x0, y0, x1, y1):
    """Area of a convex polygon clipped to an axis-aligned square (Sutherland-Hodgman)."""
    for axis, bound, keep_ge in ((0, x0, True), (0, x1, False), (1, y0, True), (1, y1, False)):
        out = []
        for i in range(len(poly)):
            p, q = poly[i], poly[(i + 1) % len(poly)]
            pin = p[axis] >= bound if keep_ge else p[axis] <= bound
            qin = q[axis] >= bound if keep_ge else q[axis] <= bound
            if pin:
                out.append(p)
            if pin != qin:
                f = (bound - p[axis]) / (q[axis] - p[axis])
                out.append((p[0] + f * (q[0] - p[0]), p[1] + f * (q[1] - p[1])))
        poly = out
        if not poly:
            return 0.0
    xs = np.array([p[0] for p in poly])
    ys = np.array([p[1] for p in poly])
    return 0.5 * abs(np.dot(xs, np.roll(ys, -1)) - np.dot(ys, np.roll(xs, -1)))


def test_rasterize_boxes_match_exact_clipped_area():
    rng = np.random.default_rng(3)
    geo = GridGeometry(-1.0, -0.5, 0.25, 16, 20)
    boxes = np.column_stack([rng.uniform(-1.5, 4.5, 12), rng.uniform(-1, 4, 12), rng.uniform(0.05, 0.8, 12),
                             rng.uniform(0.02, 0.5, 12), rng.uniform(-math.pi, math.pi, 12)])
    # long thin walls across the grid (a row meets few of their bounding box's cells), some along the axes,
    # some on cell borders
    walls = np.column_stack([rng.uniform(0.0, 3.5, 16), rng.uniform(0.5, 3.0, 16), rng.uniform(1.0, 4.0, 16),
                             rng.uniform(0.001, 0.06, 16), rng.uniform(-math.pi, math.pi, 16)])
    walls[:4, 4] = (0.0, math.pi / 2, math.pi, -math.pi / 2)
    walls[4:6, :2] = (0.5, 1.0)
    for box in np.vstack([boxes, walls]):
        occ = np.zeros((geo.rows, geo.cols), np.bool_)
        rasterize(occ, geo, box[None, :].copy(), np.zeros((0, 3)))
        cx, cy, hx, hy, yaw = box
        u, v = np.array([math.cos(yaw), math.sin(yaw)]), np.array([-math.sin(yaw), math.cos(yaw)])
        poly = [tuple(np.array([cx, cy]) + sx * hx * u + sy * hy * v)
                for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
        ref = np.zeros_like(occ)
        for r in range(geo.rows):
            for c in range(geo.cols):
                x0, y0 = geo.origin_x + c * geo.cell, geo.origin_y + r * geo.cell
                ref[r, c] = _clip_area(poly, x0, y0, x0 + geo.cell, y0 + geo.cell) > 1e-12
        np.testing.assert_array_equal(occ, ref)


def test_rasterize_face_on_cell_border_marks_no_neighbour():
    geo = GridGeometry(0.0, 0.0, 0.1, 10, 10)
    occ = np.zeros((10, 10), np.bool_)
    # x in [0.2, 0.5], y in [0.3, 0.4]: exactly cols 2..4 of row 3; also a rotated copy (yaw pi/2).
    rasterize(occ, geo, np.array([[0.35, 0.35, 0.15, 0.05, 0.0], [0.75, 0.55, 0.15, 0.05, math.pi / 2]]),
              np.zeros((0, 3)))
    expected = np.zeros_like(occ)
    expected[3, 2:5] = True
    expected[4:7, 7] = True
    np.testing.assert_array_equal(occ, expected)


def test_rasterize_discs_match_sampling():
    rng = np.random.default_rng(4)
    geo = GridGeometry(0.0, 0.0, 0.2, 15, 15)
    discs = np.column_stack([rng.uniform(-0.3, 3.3, 10), rng.uniform(-0.3, 3.3, 10), rng.uniform(0.05, 0.7, 10)])
    occ = np.zeros((15, 15), np.bool_)
    rasterize(occ, geo, np.zeros((0, 5)), discs)
    k = 41                                  # sub-samples per side, borders included
    sub = np.linspace(0.0, 1.0, k) * geo.cell
    sx, sy = np.meshgrid(sub, sub)
    margin = geo.cell / (k - 1)
    for r in range(15):
        for c in range(15):
            px, py = sx + c * geo.cell, sy + r * geo.cell
            d = np.min(np.hypot(px[..., None] - discs[:, 0], py[..., None] - discs[:, 1]) - discs[:, 2],
                       axis=(0, 1))
            if np.any(d < -margin):         # surely overlapping some disc
                assert occ[r, c], (r, c)
            elif np.all(d > 1e-9):          # the sampled square misses every disc: no overlap
                assert not occ[r, c], (r, c)
    assert occ.sum() > 20
    # Tangent from outside: a disc touching the square x >= 0.4 at one point does not mark it.
    tangent = np.zeros((15, 15), np.bool_)
    rasterize(tangent, geo, np.zeros((0, 5)), np.array([[0.3, 0.1, 0.1]]))
    assert tangent[0].tolist()[:3] == [False, True, False]


# ---------------------------------------------------------------- frontier, labels, flood, distance
def test_frontier_mask_matches_shift_reference():
    rng = np.random.default_rng(5)
    state = rng.integers(0, 3, (23, 31))
    free, unknown = state == 0, state == 2
    pad = np.pad(unknown, 1)
    ref = free & (pad[:-2, 1:-1] | pad[2:, 1:-1] | pad[1:-1, :-2] | pad[1:-1, 2:])
    np.testing.assert_array_equal(frontier_mask(free, unknown), ref)
    assert ref.sum() > 50


def _union_find_labels(mask):
    parent = {}

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    rows, cols = mask.shape
    for r in range(rows):
        for c in range(cols):
            if mask[r, c]:
                parent[(r, c)] = (r, c)
                for dr, dc in ((-1, -1), (-1, 0), (-1, 1), (0, -1)):
                    rr, cc = r + dr, c + dc
                    if 0 <= rr < rows and 0 <= cc < cols and mask[rr, cc]:
                        parent[find((rr, cc))] = find((r, c))
    labels = np.zeros(mask.shape, np.int32)
    names = {}
    for r in range(rows):
        for c in range(cols):
            if mask[r, c]:
                labels[r, c] = names.setdefault(find((r, c)), len(names) + 1)
    return labels, len(names)


@pytest.mark.parametrize("density", [0.3, 0.45, 0.6])
def test_label8_matches_union_find(density):
    mask = np.random.default_rng(6).random((40, 37)) < density
    labels, k = label8(mask)
    ref, kr = _union_find_labels(mask)
    assert k == kr and k > 1
    np.testing.assert_array_equal(labels, ref)


def test_label8_diagonal_touch_joins():
    mask = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 0], [1, 1, 0]], bool)
    labels, k = label8(mask)
    assert k == 2 and labels.tolist() == [[1, 0, 0], [0, 1, 0], [0, 0, 0], [2, 2, 0]]


def _bfs(mask: np.ndarray, r0: int, c0: int, steps: list[tuple[int, int]]) -> np.ndarray:
    """The reference flood: the cells of `mask` a breadth-first search from (r0, c0) reaches by `steps`."""
    ref = np.zeros_like(mask)
    ref[r0, c0] = True
    queue = deque([(r0, c0)])
    while queue:
        r, c = queue.popleft()
        for dr, dc in steps:
            rr, cc = r + dr, c + dc
            if 0 <= rr < mask.shape[0] and 0 <= cc < mask.shape[1] and mask[rr, cc] and not ref[rr, cc]:
                ref[rr, cc] = True
                queue.append((rr, cc))
    return ref


def test_flood8_matches_bfs():
    rng = np.random.default_rng(8)
    mask = rng.random((30, 30)) < 0.62
    r0, c0 = np.argwhere(mask)[17]
    ref = _bfs(mask, r0, c0, [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1)])
    np.testing.assert_array_equal(flood8(mask, r0, c0), ref)
    assert 10 < ref.sum() < mask.sum()
    assert not flood8(mask, -1, 0).any() and not flood8(~mask, r0, c0).any()


@pytest.mark.parametrize("seed", [10, 11])
def test_flood_4_connected_matches_bfs(seed):
    """flood(..., diagonal=False): the 4-connected component, which a diagonal touch does not join."""
    rng = np.random.default_rng(seed)
    mask = rng.random((31, 29)) < 0.64
    r0, c0 = np.argwhere(mask)[11]
    ref = _bfs(mask, r0, c0, [(-1, 0), (1, 0), (0, -1), (0, 1)])
    np.testing.assert_array_equal(flood(mask, r0, c0, False), ref)
    assert 10 < ref.sum() < flood(mask, r0, c0, True).sum()
    corner = np.array([[1, 0], [0, 1]], bool)
    assert flood(corner, 0, 0, False).sum() == 1 and flood(corner, 0, 0, True).sum() == 2
    assert not flood(mask, 31, 0, False).any()


def test_edt_matches_brute_force():
    rng = np.random.default_rng(9)
    occ = rng.random((27, 33)) < 0.03
    pts = np.argwhere(occ)
    rr, cc = np.indices(occ.shape)
    ref = np.min((rr[..., None] - pts[:, 0]) ** 2 + (cc[..., None] - pts[:, 1]) ** 2, axis=-1)
    np.testing.assert_array_equal(edt_sq(occ), ref.astype(np.float64))
    assert np.all(np.isinf(edt_sq(np.zeros((4, 5), bool))))


@pytest.mark.parametrize("radius", [0.0, 0.4, 1.5, 2.5, 3.2, 4.0])
def test_clearance_matches_brute_force(radius):
    rng = np.random.default_rng(10)
    occ = rng.random((30, 26)) < 0.02
    occ[10:12, 5:20] = True
    pts = np.argwhere(occ)
    rr, cc = np.indices(occ.shape)
    ax = np.maximum(np.abs(cc[..., None] - pts[:, 1]) - 0.5, 0)
    ay = np.maximum(np.abs(rr[..., None] - pts[:, 0]) - 0.5, 0)
    ref = np.min(np.hypot(ax, ay), axis=-1) > radius + 1e-9
    got = clearance_mask(occ, radius)
    np.testing.assert_array_equal(got, ref)
    assert got.any() and not got.all()

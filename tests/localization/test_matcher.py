"""The scan matcher: known offsets between hand-made scans and maps, numba kernels against numpy."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.localization import HitMap, Localizer, ScanMatcher, ate, compose, relative, scan_points
from robotexp.localization import kernels as K
from robotexp.localization.reference import (
    add_hits_ref,
    bilinear_ref,
    pool_max_ref,
    refine_ref,
    search_ref,
    splat_field_ref,
)
from robotexp.mapping.geometry import GridGeometry
from robotexp.world.groundtruth import occupancy
from robotexp.robot import LaserScan, Pose
from robotexp.world.raycast import RayIndex
from robotexp.world.model import World, segment_box

CELL = 0.05
ANGLES = np.radians(np.linspace(-90.0, 90.0, 181))


def room() -> World:
    """An 8 x 6 m room with an inner corner, a pillar and a cabinet: no symmetry a scan could confuse."""
    t = 0.1
    boxes = [segment_box(0, 0, 8, 0, t), segment_box(8, 0, 8, 6, t), segment_box(8, 6, 3, 6, t),
             segment_box(3, 6, 3, 4, t), segment_box(3, 4, 0, 4, t), segment_box(0, 4, 0, 0, t),
             [5.5, 2.0, 0.3, 0.3, 0.0], [1.5, 1.0, 0.5, 0.2, 0.4], [6.5, 5.0, 0.15, 0.6, 0.0]]
    return World("room", np.array(boxes, dtype=np.float64), bounds=(-0.5, -0.5, 8.5, 6.5))


def cast(world: World, pose: Pose, reach: float = 8.0) -> LaserScan:
    index = RayIndex(world.boxes, world.discs, 1.0)
    origins = np.tile([pose.x, pose.y], (len(ANGLES), 1))
    frac = index.cast(origins, pose.theta + ANGLES, reach, 0.5)
    ranges = np.where(frac >= 1.0, np.inf, frac * reach)
    return LaserScan(ANGLES, ranges, reach, 0.0)


def true_map(world: World) -> tuple[np.ndarray, GridGeometry]:
    """The occupied cells a laser can see: obstacle cells with a free 4-neighbour (wall faces)."""
    geo = GridGeometry.covering(*world.bounds, CELL)           # type: ignore[misc]
    occ = occupancy(world, geo)
    inner = occ.copy()
    inner[1:-1, 1:-1] = occ[1:-1, 1:-1] & occ[:-2, 1:-1] & occ[2:, 1:-1] & occ[1:-1, :-2] & occ[1:-1, 2:]
    return occ & ~inner, geo


@pytest.mark.parametrize(("truth", "offset"), [
    (Pose(2.0, 2.0, 0.3), Pose(0.20, -0.15, math.radians(5.0))),
    (Pose(6.0, 1.2, 2.0), Pose(-0.25, 0.10, math.radians(-6.0))),
    (Pose(5.0, 4.0, -2.5), Pose(0.12, 0.22, math.radians(3.0))),
    (Pose(1.0, 3.0, -0.7), Pose(0.03, -0.02, math.radians(0.4))),
])
def test_known_offsets_are_recovered_within_a_cell_and_half_a_degree(truth: Pose, offset: Pose) -> None:
    world = room()
    occ, geo = true_map(world)
    px, py = scan_points(cast(world, truth))
    prediction = compose(truth, offset)
    m = ScanMatcher().match(occ, geo, px, py, prediction)
    assert m.status == "matched"
    assert math.hypot(m.pose.x - truth.x, m.pose.y - truth.y) <= CELL
    assert abs(math.degrees(m.pose.theta - truth.theta)) <= 0.5
    assert m.score > 0.5


def test_a_corridor_keeps_the_prediction_along_it() -> None:
    # two parallel walls 2 m apart, 30 m long: a scan fixes y and theta, not x
    world = World("corridor", np.array([segment_box(-15, 1, 15, 1, 0.1), segment_box(-15, -1, 15, -1, 0.1)]),
                  bounds=(-16.0, -2.0, 16.0, 2.0))
    occ, geo = true_map(world)
    truth = Pose(0.0, 0.2, 0.05)
    px, py = scan_points(cast(world, truth, reach=4.0))
    prediction = Pose(0.25, 0.05, 0.1)
    m = ScanMatcher().match(occ, geo, px, py, prediction)
    assert m.status == "degenerate"
    assert m.pose.x == pytest.approx(prediction.x, abs=0.02)       # along: the prediction
    assert m.pose.y == pytest.approx(truth.y, abs=CELL)             # across: corrected
    assert m.pose.theta == pytest.approx(truth.theta, abs=math.radians(0.5))


def test_degenerate_scans_fall_back_to_the_prediction() -> None:
    world = room()
    occ, geo = true_map(world)
    p = Pose(2.0, 2.0, 0.0)
    few = ScanMatcher().match(occ, geo, np.array([1.0, 2.0]), np.array([0.0, 0.5]), p)
    assert few.status == "few-points" and few.pose == p
    px, py = scan_points(cast(world, Pose(2.0, 2.0, 0.3)))
    empty = ScanMatcher().match(np.zeros_like(occ), geo, px, py, p)
    assert empty.status == "no-map" and empty.pose == p
    # points that fit nowhere (a scan of another building): a poor fit, the prediction is kept
    rng = np.random.default_rng(1)
    junk = ScanMatcher().match(occ, geo, rng.uniform(-0.8, 0.8, 100), rng.uniform(-0.8, 0.8, 100), p)
    assert junk.status == "poor" and junk.pose == p


def test_localizer_applies_odometry_increments_to_the_corrected_pose() -> None:
    world = room()
    occ, geo = true_map(world)
    loc = Localizer(geo)
    loc.grid.mark_occupied(occ)
    path = [Pose(2.0, 2.0, 0.0), Pose(2.4, 2.1, 0.1), Pose(2.8, 2.3, 0.25), Pose(3.3, 2.4, 0.3)]
    # odometry: 5 % long and turning 4 deg per step too much, from a frame rotated and shifted
    frame = Pose(10.0, -3.0, 1.0)
    odom = [compose(frame, path[0])]
    for a, b in zip(path, path[1:], strict=False):
        inc = relative(a, b)
        odom.append(compose(odom[-1], Pose(inc.x * 1.05, inc.y * 1.05, inc.theta + math.radians(4.0))))
    loc.reset(odom[0], path[0])
    est = [path[0]] + [loc.locate(o, cast(world, t)) for o, t in zip(odom[1:], path[1:], strict=True)]
    assert loc.counts == {"matched": 3}
    assert ate([e.as_list() for e in est], [p.as_list() for p in path]) < CELL


def test_ate_with_and_without_alignment() -> None:
    truth = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 1.0]])
    shifted = truth + [0.3, -0.4]                    # 0.5 m off everywhere
    assert ate(shifted, truth) == pytest.approx(0.5)
    assert ate(shifted, truth, align="rigid") == pytest.approx(0.0, abs=1e-12)
    th = 0.7
    rot = np.column_stack([np.cos(th) * truth[:, 0] - np.sin(th) * truth[:, 1],
                           np.sin(th) * truth[:, 0] + np.cos(th) * truth[:, 1]]) + [5.0, 2.0]
    assert ate(rot, truth, align="rigid") == pytest.approx(0.0, abs=1e-12)
    # hand-computed: errors 0, 0, 0, 1 -> sqrt(1/4)
    assert ate(truth + [[0, 0], [0, 0], [0, 0], [1, 0]], truth) == pytest.approx(0.5)


# -- kernels against their numpy references -----------------------------------------------

@pytest.fixture(scope="module")
def field_and_scan() -> tuple[np.ndarray, GridGeometry, np.ndarray, np.ndarray]:
    world = room()
    occ, geo = true_map(world)
    zero = np.zeros(occ.shape, np.float32)
    f = K.splat_field(occ, zero, zero, geo.cell, 0.05, 3)
    px, py = scan_points(cast(world, Pose(2.0, 2.0, 0.3)))
    return f, geo, px, py


def test_field_and_pooling_match_numpy(field_and_scan) -> None:   # type: ignore[no-untyped-def]
    f, geo, _, _ = field_and_scan
    occ, _ = true_map(room())
    rng = np.random.default_rng(2)
    off_x = rng.uniform(-0.5, 0.5, occ.shape).astype(np.float32)
    off_y = rng.uniform(-0.5, 0.5, occ.shape).astype(np.float32)
    for sigma, reach in ((0.05, 3), (0.08, 5)):
        assert np.allclose(K.splat_field(occ, off_x, off_y, geo.cell, sigma, reach),
                           splat_field_ref(occ, off_x, off_y, geo.cell, sigma, reach), atol=1e-12)
    assert f[occ].min() == 1.0 and f.max() <= 1.0
    # one cell from a wall (and no nearer one): exp(-cell^2 / (2 sigma^2))
    assert np.any(np.isclose(f, math.exp(-0.5)))
    for factor in (2, 3, 4):
        assert np.array_equal(K.pool_max(f, factor), pool_max_ref(f, factor))


def test_field_is_centred_on_the_mean_hit_point() -> None:
    geo = GridGeometry(0.0, 0.0, 0.1, 9, 9)
    loc_hits = HitMap(geo)
    # two hits in cell (4, 4), 0.1 and 0.3 of a cell right of its centre and 0.2 below: mean (0.2, -0.2)
    scan = LaserScan(np.array([0.0, 0.0]), np.array([0.46, 0.48]), 5.0, 0.0)
    loc_hits.add(Pose(0.0, 0.43, 0.0), scan)
    assert loc_hits.count[4, 4] == 2.0
    ox, oy = loc_hits.offsets(0, 9, 0, 9)
    # (each hit counted HIT_DEPTH = 0.1 mm beyond it, as the grid marks it: 0.001 cell further along x)
    assert ox[4, 4] == pytest.approx(0.201, abs=1e-5) and oy[4, 4] == pytest.approx(-0.2, abs=1e-5)
    ox[4, 4] = 0.2
    occ = np.zeros((9, 9), np.bool_)
    occ[4, 4] = True
    f = K.splat_field(occ, ox, oy, geo.cell, 0.1, 3)
    # at the centre of cell (4, 5), 0.8 cell right and 0.2 cell above the hit mean: d^2 = 0.68 cells^2
    assert f[4, 5] == pytest.approx(math.exp(-0.68 * 0.01 / 0.02), rel=1e-6)
    assert f[4, 5] > f[4, 3]            # the side the hits lean to is the stronger


def test_hit_sums_match_numpy() -> None:
    """`kernels.add_hits` (what `HitMap.add` runs) against `np.add.at`: bit for bit, over beams that miss, hit
    twice in one cell, end on cell borders (both directions), leave the grid, or are NaN, inf, 0 or negative."""
    rng = np.random.default_rng(5)
    ranges = rng.uniform(0.05, 2.5, 181)
    ranges[:6] = [np.nan, np.inf, 0.0, -1.0, 3.0, 2.9999]
    angles = np.radians(np.linspace(-90.0, 90.0, 181))
    angles[10:14] = [0.0, math.pi, math.pi / 2, -math.pi / 2]
    ranges[10:14] = [0.5, 0.5, 0.3, 0.3]      # from (1.0, 1.0), no offset and depth: on borders of 0.1 m cells
    for pose, offset, depth in ((Pose(1.0, 1.0, 0.0), 0.0, 0.0), (Pose(1.23, 0.87, 0.6), 0.12, 1e-4),
                                (Pose(0.1, 2.0, -2.0), 0.05, 1e-4)):
        got = [np.zeros((20, 24), np.float32) for _ in range(3)]
        ref = [np.zeros((20, 24), np.float32) for _ in range(3)]
        for _ in range(2):                            # sums over two scans
            K.add_hits(*got, 0.0, 0.0, 0.1, pose.x, pose.y, pose.theta, offset, ranges, angles, 3.0, depth)
            add_hits_ref(*ref, 0.0, 0.0, 0.1, pose.x, pose.y, pose.theta, offset, ranges, angles, 3.0, depth)
        assert got[2].sum() > 100 and np.count_nonzero(got[2] == 4.0) > 0
        for g, r in zip(got, ref, strict=True):
            assert np.array_equal(g, r)


def test_search_matches_numpy(field_and_scan) -> None:   # type: ignore[no-untyped-def]
    f, geo, px, py = field_and_scan
    for level, (x0, y0, th0) in ((1, (2.1, 1.9, 0.25)), (4, (1.8, 2.2, 0.4))):
        g = K.pool_max(f, level) if level > 1 else f
        args = (g, geo.origin_x, geo.origin_y, geo.cell * level, px, py, x0, y0, th0, 3, 1, 4, math.radians(1.0),
                x0 + 0.01, y0 - 0.02, th0 + 0.005, 50.0 * level, 300.0)
        got, ref = K.search(*args), search_ref(*args)
        assert got[:3] == pytest.approx(ref[:3], abs=1e-12) and got[3] == pytest.approx(ref[3], rel=1e-12)
    args = (f, geo.origin_x, geo.origin_y, geo.cell, px, py, 2.05, 2.0, 0.3, 2, 2, 1, math.radians(0.5),
            2.05, 2.0, 0.3, 0.0, 0.0)
    assert K.search(*args)[:3] == pytest.approx(search_ref(*args)[:3], abs=1e-12)


def test_bilinear_and_refine_match_numpy(field_and_scan) -> None:   # type: ignore[no-untyped-def]
    f, geo, px, py = field_and_scan
    rng = np.random.default_rng(0)
    gx, gy = rng.uniform(-2, f.shape[1] + 2, 500), rng.uniform(-2, f.shape[0] + 2, 500)
    ref = bilinear_ref(f, gx, gy)
    got = np.array([K.bilinear(f, a, b) for a, b in zip(gx, gy, strict=True)]).T
    assert np.allclose(got, np.array(ref), atol=1e-12)
    # at a sample centre the value is the sample
    assert K.bilinear(f, 40.5, 30.5)[0] == f[30, 40]
    args = (f, geo.origin_x, geo.origin_y, geo.cell, px, py, 2.04, 1.97, 0.31, 10, 2.04, 1.97, 0.31, 100.0, 365.0)
    got_r, ref_r = K.refine(*args), refine_ref(*args)
    assert got_r[:4] == pytest.approx(ref_r[:4], abs=1e-9)
    assert np.allclose(got_r[4], ref_r[4], rtol=1e-9, atol=1e-9)
    assert math.hypot(got_r[0] - 2.0, got_r[1] - 2.0) < CELL and abs(got_r[2] - 0.3) < math.radians(0.5)


def test_a_match_beyond_the_motion_gate_is_refused() -> None:
    world = room()
    occ, geo = true_map(world)
    start, truth = Pose(2.0, 2.0, 0.0), Pose(2.3, 2.0, 0.0)
    for gate, expected in ((4.0, "matched"), (1.0, "gated")):
        # odometry says 0.2 m where the robot went 0.3 m: 0.1 m wrong, 2.5 sigmas of a 4 cm prior
        loc = Localizer(geo, motion_noise=(0.02, 0.1, math.radians(0.5), 0.0, 0.0), gate=gate)
        loc.grid.mark_occupied(occ)
        loc.reset(start, start)
        pose = loc.locate(Pose(2.2, 2.0, 0.0), cast(world, truth))
        assert loc.counts == {expected: 1}
        if expected == "matched":
            assert math.hypot(pose.x - truth.x, pose.y - truth.y) < CELL
        else:
            assert pose == Pose(2.2, 2.0, 0.0)

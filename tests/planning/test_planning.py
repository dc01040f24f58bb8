"""Tests of robotexp.planning: kernels against plain-Python references, and hand-built scenes."""

from __future__ import annotations

import heapq
import itertools
import math
from fractions import Fraction

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.planning.grid_planner import (
    astar,
    cost_grid,
    dijkstra,
    distance_transform,
    line_of_sight,
    nearest_goal,
    path_cost,
    path_from_parents,
    simplify,
)

SEEDS = [0, 1, 2, 3, 4, 5]


# ---------------------------------------------------------------- references (plain Python)

def ref_dijkstra(cost: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    """heapq Dijkstra, 8-connected, step = length * mean cost, no corner cutting."""
    rows, cols = cost.shape
    dist = np.full(cost.shape, math.inf)
    if not math.isfinite(cost[start]):
        return dist
    dist[start] = 0.0
    pq = [(0.0, start)]
    done = set()
    while pq:
        d, (r, c) = heapq.heappop(pq)
        if (r, c) in done:
            continue
        done.add((r, c))
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                nr, nc = r + dr, c + dc
                if (dr, dc) == (0, 0) or not (0 <= nr < rows and 0 <= nc < cols):
                    continue
                if not math.isfinite(cost[nr, nc]):
                    continue
                diagonal = dr != 0 and dc != 0
                if diagonal and not (math.isfinite(cost[r, nc]) and math.isfinite(cost[nr, c])):
                    continue
                step = (math.sqrt(2) if diagonal else 1.0) * (float(cost[r, c]) + float(cost[nr, nc])) / 2
                if d + step < dist[nr, nc]:
                    dist[nr, nc] = d + step
                    heapq.heappush(pq, (d + step, (nr, nc)))
    return dist


def ref_edt(occ: np.ndarray) -> np.ndarray:
    pts = np.argwhere(occ)
    out = np.full(occ.shape, np.inf, dtype=np.float32)
    if len(pts) == 0:
        return out
    for r in range(occ.shape[0]):
        for c in range(occ.shape[1]):
            out[r, c] = np.float32(math.sqrt(min((r - pr) ** 2 + (c - pc) ** 2 for pr, pc in pts)))
    return out


def ref_touched(a: tuple[int, int], b: tuple[int, int], shape: tuple[int, int]) -> list[tuple[int, int]]:
    """Cells whose closed square meets the segment between the centres (exact slab test)."""
    (r0, c0), (r1, c1) = a, b
    half = Fraction(1, 2)
    out = []
    for r in range(shape[0]):
        for c in range(shape[1]):
            lo, hi = Fraction(0), Fraction(1)
            for p0, p1, cell in ((c0, c1, c), (r0, r1, r)):
                d = p1 - p0
                if d == 0:
                    if abs(p0 - cell) > half:
                        lo, hi = Fraction(1), Fraction(0)
                    continue
                t1, t2 = Fraction(cell - p0) - half, Fraction(cell - p0) + half
                t1, t2 = sorted((t1 / d, t2 / d))
                lo, hi = max(lo, t1), min(hi, t2)
            if lo <= hi:
                out.append((r, c))
    return out


def random_cost(rng: np.random.Generator, shape: tuple[int, int], blocked: float = 0.25) -> np.ndarray:
    cost = rng.uniform(1.0, 4.0, size=shape)
    cost[rng.random(shape) < 0.3] = 1.0
    cost[rng.random(shape) < blocked] = np.inf
    return cost


def assert_valid_path(path: np.ndarray, cost: np.ndarray, start, goal) -> None:
    assert path.dtype == np.int32 and path.ndim == 2 and path.shape[1] == 2
    assert tuple(path[0]) == tuple(start) and tuple(path[-1]) == tuple(goal)
    for r, c in path:
        assert np.isfinite(cost[r, c]), f"path crosses blocked cell {(r, c)}"
    for (r0, c0), (r1, c1) in itertools.pairwise(path):
        dr, dc = r1 - r0, c1 - c0
        assert max(abs(dr), abs(dc)) == 1, "consecutive cells are not 8-neighbours"
        if dr and dc:
            assert np.isfinite(cost[r0, c1]) and np.isfinite(cost[r1, c0]), "corner cut"


# ---------------------------------------------------------------- distance transform

@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (11, 1), (17, 23), (30, 12)])
@pytest.mark.parametrize("density", [0.0, 0.02, 0.3, 1.0])
def test_distance_transform_matches_brute_force(shape, density):
    rng = np.random.default_rng(hash((shape, density)) % 2**32)
    occ = rng.random(shape) < density
    got = distance_transform(occ)
    assert got.dtype == np.float32 and got.shape == shape
    np.testing.assert_array_equal(got, ref_edt(occ))


def test_distance_transform_single_point_by_hand():
    occ = np.zeros((4, 5), dtype=bool)
    occ[1, 2] = True
    d = distance_transform(occ)
    assert d[1, 2] == 0 and d[1, 4] == 2 and d[3, 2] == 2
    assert d[3, 4] == pytest.approx(math.sqrt(8), rel=1e-7)
    assert d[0, 0] == pytest.approx(math.sqrt(5), rel=1e-7)


def test_distance_transform_rejects_non_bool():
    with pytest.raises(ConfigError, match="bool"):
        distance_transform(np.zeros((3, 3)))


# ---------------------------------------------------------------- cost grid

def test_cost_grid_values_by_hand():
    d = np.array([[0.0, 1.0, 1.5, 2.0], [3.0, 3.5, 5.0, np.inf]])
    cost = cost_grid(d, robot_radius_cells=1, danger_radius_cells=4, danger_cost=8.0)
    assert cost.dtype == np.float32
    # R=1, D=4: 1.5 -> 1 + 8*(1 - 0.5/4) = 8; 2 -> 7; 3 -> 5; 3.5 -> 4; 5 = R+D -> 1
    np.testing.assert_array_equal(cost, [[np.inf, np.inf, 8.0, 7.0], [5.0, 4.0, 1.0, 1.0]])


def test_cost_grid_without_danger_zone_and_blocked_mask():
    d = np.array([[0.0, 0.5, 2.0, 9.0]])
    blocked = np.array([[False, False, False, True]])
    cost = cost_grid(d, robot_radius_cells=0.5, blocked=blocked)
    np.testing.assert_array_equal(cost, [[np.inf, np.inf, 1.0, np.inf]])


@pytest.mark.parametrize("kw", [{"robot_radius_cells": -1}, {"robot_radius_cells": 1, "danger_cost": -2},
                                {"robot_radius_cells": 1, "danger_radius_cells": math.nan}])
def test_cost_grid_rejects_bad_parameters(kw):
    with pytest.raises(ConfigError, match="cost_grid"):
        cost_grid(np.ones((2, 2)), **kw)


# ---------------------------------------------------------------- Dijkstra

@pytest.mark.parametrize("seed", SEEDS)
def test_dijkstra_field_matches_reference(seed):
    rng = np.random.default_rng(seed)
    cost = random_cost(rng, (23, 31))
    start = (int(rng.integers(23)), int(rng.integers(31)))
    cost[start] = 1.0
    dist, parent = dijkstra(cost, start)
    ref = ref_dijkstra(cost, start)
    assert dist.shape == cost.shape and dist.dtype == np.float64 and parent.dtype == np.int32
    np.testing.assert_array_equal(np.isinf(dist), np.isinf(ref))
    np.testing.assert_allclose(dist[np.isfinite(ref)], ref[np.isfinite(ref)], rtol=0, atol=1e-9)
    assert parent[start[0] * 31 + start[1]] == -1
    assert (parent[np.isinf(ref).ravel()] == -1).all()
    for r, c in np.argwhere(np.isfinite(ref))[::7]:  # parents give shortest paths
        path = path_from_parents(parent, 31, (r, c))
        assert_valid_path(path, cost, start, (r, c))
        assert path_cost(cost, path) == pytest.approx(ref[r, c], abs=1e-9)


@pytest.mark.parametrize("seed", SEEDS[:3])
def test_dijkstra_max_dist(seed):
    rng = np.random.default_rng(seed)
    cost = random_cost(rng, (20, 20))
    cost[10, 10] = 1.0
    ref = ref_dijkstra(cost, (10, 10))
    dist, parent = dijkstra(cost, (10, 10), max_dist=7.3)
    inside = ref <= 7.3
    np.testing.assert_allclose(dist[inside], ref[inside], rtol=0, atol=1e-9)
    assert np.isinf(dist[~inside]).all() and (parent[~inside.ravel()] == -1).all()


@pytest.mark.parametrize("seed", SEEDS)
def test_dijkstra_early_exit_and_nearest_goal(seed):
    rng = np.random.default_rng(100 + seed)
    cost = random_cost(rng, (25, 27))
    start = (12, 13)
    cost[start] = 1.0
    goals = rng.random(cost.shape) < 0.01
    goals[start] = False
    ref = ref_dijkstra(cost, start)
    best = ref[goals].min() if goals.any() else math.inf
    dist, _ = dijkstra(cost, start, goal_mask=goals)
    finite = np.isfinite(dist)
    np.testing.assert_allclose(dist[finite], ref[finite], rtol=0, atol=1e-9)  # settled = exact
    got = nearest_goal(cost, start, goals)
    if math.isinf(best):
        assert got is None and not (finite & goals).any()
        return
    assert np.count_nonzero(finite & goals) == 1
    goal, path, length = got
    assert goals[goal] and tuple(np.argwhere(finite & goals)[0]) == goal
    assert length == pytest.approx(best, abs=1e-9) and ref[goal] == pytest.approx(best, abs=1e-9)
    assert_valid_path(path, cost, start, goal)
    assert path_cost(cost, path) == pytest.approx(length, abs=1e-9)


# ---------------------------------------------------------------- A*

@pytest.mark.parametrize("seed", SEEDS)
def test_astar_matches_dijkstra(seed):
    rng = np.random.default_rng(200 + seed)
    shape = (26, 34)
    cost = random_cost(rng, shape, blocked=0.2)
    start = (int(rng.integers(shape[0])), int(rng.integers(shape[1])))
    cost[start] = rng.uniform(1, 3)
    ref = ref_dijkstra(cost, start)
    found = 0
    for _ in range(12):
        goal = (int(rng.integers(shape[0])), int(rng.integers(shape[1])))
        path = astar(cost, start, goal)
        if math.isinf(ref[goal]):
            assert path is None
            continue
        found += 1
        assert_valid_path(path, cost, start, goal)
        assert path_cost(cost, path) == pytest.approx(ref[goal], abs=1e-9)
    assert found > 0


def test_astar_uniform_cost_is_octile():
    cost = np.ones((10, 15))
    path = astar(cost, (1, 2), (8, 13))
    assert path_cost(cost, path) == pytest.approx(11 + 7 * (math.sqrt(2) - 1), abs=1e-12)
    assert len(path) == 12


def wall_scene(*, wide_gap: bool) -> tuple[np.ndarray, np.ndarray]:
    """A wall at col 20 with a narrow gap (rows 5-7) on the straight line, and a wide one (rows 14-24)."""
    occ = np.zeros((31, 41), dtype=bool)
    occ[:, 20] = True
    occ[5:8, 20] = False
    if wide_gap:
        occ[14:25, 20] = False
    return occ, distance_transform(occ)


def test_astar_avoids_danger_zone_when_a_clear_way_exists():
    _occ, dist = wall_scene(wide_gap=True)
    # the narrow gap is passable (distance 2 > radius 1) but deep in the danger zone
    cost = cost_grid(dist, robot_radius_cells=1, danger_radius_cells=3, danger_cost=10.0)
    assert np.isfinite(cost[6, 20]) and cost[6, 20] > 7
    path = astar(cost, (6, 5), (6, 35))
    assert_valid_path(path, cost, (6, 5), (6, 35))
    crossing = path[path[:, 1] == 20]
    assert len(crossing) == 1 and 14 <= crossing[0, 0] <= 24, "did not take the wide gap"
    assert cost[path[:, 0], path[:, 1]].max() < 2.0
    # without danger costs the straight way through the narrow gap is shortest
    plain = cost_grid(dist, robot_radius_cells=1)
    straight = astar(plain, (6, 5), (6, 35))
    assert (straight[:, 0] == 6).all() and path_cost(plain, straight) == 30
    assert path_cost(plain, path) > 30  # the clear way is longer in plain length


def test_astar_goes_through_danger_zone_when_no_other_way():
    _occ, dist = wall_scene(wide_gap=False)
    cost = cost_grid(dist, robot_radius_cells=1, danger_radius_cells=3, danger_cost=10.0)
    path = astar(cost, (6, 5), (6, 35))
    assert_valid_path(path, cost, (6, 5), (6, 35))
    assert [6, 20] in path.tolist()
    assert path_cost(cost, path) == pytest.approx(ref_dijkstra(cost, (6, 5))[6, 35], abs=1e-9)


def test_unreachable_and_blocked_ends():
    cost = np.ones((9, 9))
    cost[3:6, 3:6] = np.inf
    cost[4, 4] = 1.0  # a free cell enclosed by blocked ones
    assert astar(cost, (0, 0), (4, 4)) is None
    assert nearest_goal(cost, (0, 0), np.pad(np.ones((1, 1), bool), 4)) is None
    assert astar(cost, (0, 0), (3, 3)) is None  # blocked goal
    assert astar(cost, (3, 3), (0, 0)) is None  # blocked start
    dist, parent = dijkstra(cost, (3, 3))
    assert np.isinf(dist).all() and (parent == -1).all()


def test_no_corner_cutting():
    cost = np.ones((2, 2))
    cost[0, 1] = cost[1, 0] = np.inf
    assert astar(cost, (0, 0), (1, 1)) is None
    cost[1, 0] = 1.0
    assert astar(cost, (0, 0), (1, 1)).tolist() == [[0, 0], [1, 0], [1, 1]]


def test_start_equals_goal():
    cost = np.ones((5, 5))
    assert astar(cost, (2, 3), (2, 3)).tolist() == [[2, 3]]
    goals = np.zeros((5, 5), bool)
    goals[2, 3] = goals[0, 0] = True
    goal, path, length = nearest_goal(cost, (2, 3), goals)
    assert goal == (2, 3) and path.tolist() == [[2, 3]] and length == 0.0


def test_bad_inputs_raise_config_error():
    cost = np.ones((4, 5))
    with pytest.raises(ConfigError, match=r"astar: start_rc: cell \(4, 0\) is outside the 4 x 5 grid"):
        astar(cost, (4, 0), (0, 0))
    bad = cost.copy()
    bad[1, 2] = math.nan
    with pytest.raises(ConfigError, match=r"cost\[1, 2\]"):
        dijkstra(bad, (0, 0))
    with pytest.raises(ConfigError, match="goal_mask"):
        nearest_goal(cost, (0, 0), np.zeros((5, 4), bool))


# ---------------------------------------------------------------- line of sight, simplify

def test_line_of_sight_by_hand():
    free = np.ones((3, 3), bool)
    free[0, 1] = False
    assert not line_of_sight(free, (0, 0), (1, 1))  # the segment touches the corner of (0, 1)
    assert line_of_sight(free, (0, 0), (2, 0))
    knight = np.ones((2, 3), bool)
    knight[1, 0] = False  # (0,0)->(1,2) touches (0,0), (0,1), (1,1), (1,2) only
    assert line_of_sight(knight, (0, 0), (1, 2))
    knight[1, 0], knight[0, 1] = True, False
    assert not line_of_sight(knight, (0, 0), (1, 2))


@pytest.mark.parametrize("seed", SEEDS[:3])
def test_line_of_sight_matches_exact_supercover(seed):
    rng = np.random.default_rng(300 + seed)
    shape = (9, 11)
    free = rng.random(shape) > 0.12
    for _ in range(120):
        a = (int(rng.integers(shape[0])), int(rng.integers(shape[1])))
        b = (int(rng.integers(shape[0])), int(rng.integers(shape[1])))
        expected = all(free[cell] for cell in ref_touched(a, b, shape))
        assert line_of_sight(free, a, b) == expected, (a, b)
        assert line_of_sight(free, b, a) == expected


def test_simplify_by_hand():
    free = np.ones((6, 6), bool)
    straight = np.array([[0, 0], [1, 1], [2, 2], [3, 3], [4, 4]], dtype=np.int32)
    assert simplify(straight, free).tolist() == [[0, 0], [4, 4]]
    free[1:6, 1] = False  # a wall along col 1: the path goes down col 0, then along row 0
    el = np.array([[5, 0], [4, 0], [3, 0], [2, 0], [1, 0], [0, 0], [0, 1], [0, 2], [0, 3]], dtype=np.int32)
    assert simplify(el, free).tolist() == [[5, 0], [0, 0], [0, 3]]
    assert simplify(el[:1], free).tolist() == [[5, 0]]


@pytest.mark.parametrize("seed", SEEDS)
def test_simplify_keeps_visible_subsequence(seed):
    rng = np.random.default_rng(400 + seed)
    cost = random_cost(rng, (30, 30), blocked=0.15)
    cost[0, 0] = cost[29, 29] = 1.0
    path = astar(cost, (0, 0), (29, 29))
    if path is None:
        pytest.skip("seed gives no path")
    free = np.isfinite(cost)
    short = simplify(path, free)
    assert short.tolist()[0] == [0, 0] and short.tolist()[-1] == [29, 29] and len(short) < len(path)
    rows = path.tolist()
    idx = [rows.index(p) for p in short.tolist()]
    assert idx == sorted(idx)
    for a, b in itertools.pairwise(short):
        assert line_of_sight(free, a, b)
        assert all(free[c] for c in ref_touched(tuple(a), tuple(b), free.shape))


@pytest.mark.parametrize("seed", SEEDS[:3])
def test_searches_in_a_large_grid_cost_what_they_reach_and_find_the_same_paths(seed):
    """A* and nearest_goal set up only the cells they reach: the same scene inside a large blocked grid gives
    the same paths, cell for cell, and nearest_goal the goal and path of the eager early-exit Dijkstra."""
    rng = np.random.default_rng(300 + seed)
    cost = random_cost(rng, (21, 24), blocked=0.15)
    start, goal = (3, 4), (17, 20)
    cost[start] = cost[goal] = 1.0
    goals = np.zeros(cost.shape, bool)
    goals[goal] = goals[15, 2] = True
    shift = np.array([200, 300])
    big = np.full((400, 500), np.inf)
    big[200:221, 300:324] = cost
    big_goals = np.zeros(big.shape, bool)
    big_goals[200:221, 300:324] = goals
    small_path = astar(cost, start, goal)
    big_path = astar(big, tuple(shift + start), tuple(shift + goal))
    assert small_path is not None and big_path is not None
    np.testing.assert_array_equal(big_path - shift, small_path)
    found = []
    for c, g, s in ((cost, goals, start), (big, big_goals, tuple(shift + start))):
        got = nearest_goal(c, s, g)
        dist, parent = dijkstra(c, s, goal_mask=g)
        reached = np.argwhere(np.isfinite(dist) & g)
        assert got is not None and len(reached) == 1
        assert tuple(reached[0]) == got[0] and got[2] == dist[got[0]]
        np.testing.assert_array_equal(got[1], path_from_parents(parent, c.shape[1], got[0]))
        found.append(got)
    assert tuple(np.array(found[1][0]) - shift) == found[0][0] and found[1][2] == found[0][2]
    np.testing.assert_array_equal(found[1][1] - shift, found[0][1])

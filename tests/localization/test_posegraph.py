"""The pose graph (loop closure's optimiser): the sparse solver against the dense edge-by-edge reference,
a graph whose edges agree recovered exactly, and a wrong loop edge held off by the Cauchy kernel."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.localization.matcher import relative
from robotexp.localization.posegraph import Edge, optimize
from robotexp.localization.reference import optimize_ref
from robotexp.robot import Pose

INFO = np.diag([0.05 ** -2, 0.05 ** -2, math.radians(0.5) ** -2])


def _square(n_side: int = 5, side: float = 4.0) -> np.ndarray:
    """Poses around a square, counter-clockwise from the origin, heading along each side."""
    out = []
    for k in range(4):
        th = k * math.pi / 2
        x0, y0 = [(0, 0), (side, 0), (side, side), (0, side)][k]
        for m in range(n_side):
            d = side * m / n_side
            out.append((x0 + d * math.cos(th), y0 + d * math.sin(th), th))
    return np.array(out)


def _edges(truth: np.ndarray, loops: list[tuple[int, int]]) -> list[Edge]:
    chain = [Edge(k, k + 1, relative(Pose(*truth[k]), Pose(*truth[k + 1])), INFO) for k in range(len(truth) - 1)]
    return chain + [Edge(i, j, relative(Pose(*truth[i]), Pose(*truth[j])), INFO, loop=True) for i, j in loops]


def _drifted(truth: np.ndarray, per_node: float) -> np.ndarray:
    """The path as odometry with a heading error of `per_node` rad at every step would give it."""
    out = [truth[0]]
    for k in range(1, len(truth)):
        inc = relative(Pose(*truth[k - 1]), Pose(*truth[k]))
        p = out[-1]
        th = p[2] + per_node
        c, s = math.cos(th), math.sin(th)
        out.append((p[0] + c * inc.x - s * inc.y, p[1] + s * inc.x + c * inc.y, p[2] + inc.theta + per_node))
    return np.array(out)


def test_agreeing_edges_give_back_the_true_path():
    truth = _square()
    start = _drifted(truth, math.radians(2.0))
    assert np.hypot(*(start[-1, :2] - truth[-1, :2])) > 0.5       # 2 deg a step: metres off at the end
    out = optimize(start, _edges(truth, [(0, 19), (2, 17)]), iterations=20)
    np.testing.assert_allclose(out[:, :2], truth[:, :2], atol=1e-6)
    np.testing.assert_allclose(np.cos(out[:, 2] - truth[:, 2]), 1.0, atol=1e-9)


def test_sparse_solver_matches_the_dense_reference():
    rng = np.random.default_rng(3)
    truth = _square(8)
    edges = _edges(truth, [(0, 31), (3, 27), (5, 20)])
    noisy = [Edge(e.i, e.j, Pose(e.z.x + rng.normal(0, 0.05), e.z.y + rng.normal(0, 0.05),
                                 e.z.theta + rng.normal(0, 0.01)), e.info, e.loop) for e in edges]
    noisy.append(Edge(1, 30, Pose(3.0, -2.0, 1.0), INFO, loop=True))       # a wrong loop edge
    start = _drifted(truth, math.radians(1.5))
    np.testing.assert_allclose(optimize(start, noisy), optimize_ref(start, noisy), atol=1e-9)


def test_a_wrong_loop_edge_pulls_little():
    truth = _square()
    good = _edges(truth, [(0, 19)])
    bad = good + [Edge(5, 15, Pose(1.0, 2.0, 0.3), INFO, loop=True)]           # the truth is (0, 4, pi)
    out = optimize(truth, bad, iterations=30)
    err = np.hypot(*(out[:, :2] - truth[:, :2]).T)
    assert err.max() < 0.05                     # 2.5 m of wrong loop edge: a few centimetres at most
    plain = optimize(truth, [*good, Edge(5, 15, Pose(1.0, 2.0, 0.3), INFO)], iterations=30)
    assert np.hypot(*(plain[:, :2] - truth[:, :2]).T).max() > 0.5               # without the kernel: metres


def test_thousands_of_poses_and_bad_edges():
    n = 6000                                    # a dense system would be 18000 x 18000 (2.6 GB)
    truth = np.column_stack([np.arange(n) * 0.1, np.zeros(n), np.zeros(n)])
    edges = _edges(truth, [(0, n - 1)])
    out = optimize(truth + np.array([0.0, 0.01, 0.0]) * (np.arange(n) > 0)[:, None], edges)
    np.testing.assert_allclose(out, truth, atol=1e-6)
    with pytest.raises(ConfigError, match="outside the 3 nodes"):
        optimize(np.zeros((3, 3)), [Edge(0, 3, Pose(1, 0, 0), INFO)])

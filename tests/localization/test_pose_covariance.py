"""The localizer's covariance of (x, y, theta, k): carried along odometry and updated by matches, against
hand-computed values (sparse: a lone pillar fixes the position, not the turn about itself)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.localization import Localizer, Match
from robotexp.localization import covariance as C
from robotexp.localization.calibration import OdometryCalibration
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import Pose

GEO = GridGeometry.covering(-5.0, -5.0, 5.0, 5.0, 0.05)


def test_driving_carries_a_heading_bias_into_heading_and_sideways_position() -> None:
    q_xy, q_th, k0, q_k = 1e-4, 2e-5, 0.05, 1e-7
    loc = Localizer(GEO, calibration=OdometryCalibration(), covariance=(q_xy, q_th, k0, q_k))
    loc.reset(Pose(0.0, 0.0, 0.0), Pose(0.0, 0.0, 0.0))
    loc.cov = np.diag([0.0, 0.0, 0.0, k0 * k0])
    d = 2.0
    loc.locate(Pose(d, 0.0, 0.0), None)                  # 2 m straight along x, one step
    p = loc.cov
    s2 = k0 * k0
    # the heading turns by k d, the end moves sideways by k d^2 / 2 (the chord of the arc)
    assert p[2, 2] == pytest.approx(d * d * s2 + q_th * d)
    assert p[1, 1] == pytest.approx((d * d / 2) ** 2 * s2 + q_xy * d)
    assert p[1, 2] == pytest.approx(d * d / 2 * d * s2)
    assert p[2, 3] == pytest.approx(d * s2)
    assert p[1, 3] == pytest.approx(d * d / 2 * s2)
    assert p[3, 3] == pytest.approx(s2 + q_k * d)
    assert p[0, 0] == pytest.approx(q_xy * d) and p[0, 2] == pytest.approx(0.0, abs=1e-15)


def test_a_match_that_fixes_only_the_position_corrects_the_heading_through_the_covariance() -> None:
    cal = OdometryCalibration()
    loc = Localizer(GEO, calibration=cal, covariance=(1e-4, 2e-5, 0.05, 1e-7))
    cov = np.zeros((4, 4))
    cov[0, 0], cov[1, 1], cov[2, 2], cov[3, 3] = 0.01, 0.01, 0.001, 0.0025
    cov[1, 2] = cov[2, 1] = 0.002                        # a heading error went with a sideways one
    cov[1, 3] = cov[3, 1] = 0.0005                       # ... and so did the heading bias
    loc.cov = cov.copy()
    h = 1e4
    info = np.diag([h, h, 0.0])                          # the scan fixes x and y, not the heading
    prediction = Pose(0.0, 0.0, 0.0)
    m = Match(Pose(0.0, 0.1, 0.0), 0.9, 30, "matched", 1.0, info, 2.0)
    pose = loc._fuse(prediction, m)
    # the position is the match's; the heading follows the y correction by its covariance with y
    # (Kalman gain cov[., y] / (cov[y, y] + 1 / h); the heading's RMS-range scale cancels)
    assert pose.x == pytest.approx(0.0, abs=1e-12) and pose.y == pytest.approx(0.1)
    assert pose.theta == pytest.approx(0.002 / (0.01 + 1 / h) * 0.1)
    assert cal.k == 0.0                                  # k's estimate stays the calibration's
    # ... the kernel's update of k, by the same gain
    assert C.fuse(cov.copy(), info, 2.0, 0.03, 0.2, 0.0, 0.1, 0.0)[3] == pytest.approx(0.0005 / (0.01 + 1 / h) * 0.1)
    # the covariance shrinks: y to about the scan's own, the heading by what y told of it
    assert loc.cov[1, 1] == pytest.approx(0.01 - 0.01 ** 2 / (0.01 + 1 / h))
    assert loc.cov[2, 2] == pytest.approx(0.001 - 0.002 ** 2 / (0.01 + 1 / h))
    # a match that fixes everything keeps its own pose (the update only moves k and the covariance)
    loc.cov = cov.copy()
    full = Match(Pose(0.05, 0.1, math.radians(1.0)), 0.9, 100, "matched", 1.0, np.diag([h, h, h]), 2.0)
    assert loc._fuse(prediction, full).as_list() == pytest.approx(full.pose.as_list())


@pytest.mark.parametrize("rank", [3, 2, 1, 0])
def test_kernels_match_numpy(rank: int) -> None:
    rng = np.random.default_rng(rank)
    a = rng.normal(size=(4, 4))
    cov = a @ a.T * 0.01 + np.eye(4) * 1e-4
    got, ref = cov.copy(), cov.copy()
    C.propagate(got, 0.03, -0.02, 0.036, 1e-4, 2e-5, 1e-7)
    C.propagate_ref(ref, 0.03, -0.02, 0.036, 1e-4, 2e-5, 1e-7)
    assert np.allclose(got, ref, rtol=1e-12, atol=1e-15)
    # a scan's normal matrix of the given rank (a room, a corridor or a pillar, one wall point, nothing)
    j = rng.normal(size=(rank, 3)) * [30.0, 30.0, 60.0]
    info = j.T @ j
    got, ref = cov.copy(), cov.copy()
    out = C.fuse(got, info, 2.1, 0.03, 0.2, 0.04, -0.03, 0.01)
    expected = C.fuse_ref(ref, info, 2.1, 0.03, 0.2, 0.04, -0.03, 0.01)
    assert out == pytest.approx(expected, rel=1e-9, abs=1e-12)
    assert np.allclose(got, ref, rtol=1e-9, atol=1e-15)
    if rank == 0:
        assert out == (0.04, -0.03, 0.01, 0.0) and np.array_equal(got, cov)

"""Scan-to-map matching and the `Localizer` stage that sits between a robot's odometry and the mapper.

`ScanMatcher.match` aligns one scan with an occupancy grid: a likelihood field of the grid's occupied
cells near the predicted pose, a correlative search on a max-pooled copy of it (coarse), another on
the field itself around the coarse winner (fine), and Gauss-Newton on the bilinearly interpolated
field (`robotexp.localization.kernels`). Degenerate cases fall back to the prediction and are
counted: too few points, no map near the robot, a poor fit, or a corridor (the normal matrix's
translation block is ill-conditioned: the correction along the corridor is dropped, the rest kept).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.localization import kernels as K
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.mapping.kernels import edt_sq
from robotexp.robot import LaserScan, Pose, wrap_angle

__all__ = ["MatcherConfig", "Match", "ScanMatcher", "Localizer", "compose", "relative", "scan_points"]

Status = Literal["matched", "degenerate", "few-points", "no-map", "poor"]


@dataclass(frozen=True)
class MatcherConfig:
    """Settings of the scan matcher (SI units).

    Attributes:
        sigma: [m] standard deviation of the likelihood field around occupied cells.
        window_xy: [m] half-width of the x and y search window around the prediction.
        window_theta: [rad] half-width of the heading search window.
        coarse: pooling factor of the coarse level (cells of coarse * cell).
        iterations: Gauss-Newton iterations at most.
        range_max: [m] points farther than this from the sensor are not matched (the map still
            takes them).
        min_points: fewer matched points than this: keep the prediction ("few-points").
        min_score: a mean field value under the points below this after matching: keep the
            prediction ("poor").
        degenerate_ratio: smallest / largest eigenvalue of the translation block of the normal matrix
            below this: a corridor; the correction along the weak direction is dropped ("degenerate").
    """

    sigma: float = 0.05
    window_xy: float = 0.3
    window_theta: float = math.radians(8.0)
    coarse: int = 4
    iterations: int = 10
    range_max: float = 12.0
    min_points: int = 20
    min_score: float = 0.2
    degenerate_ratio: float = 0.03

    def __post_init__(self) -> None:
        if not (self.sigma > 0 and self.window_xy >= 0 and self.window_theta >= 0 and self.range_max > 0):
            raise ConfigError(f"scan matcher: sigma and range_max must be > 0 m and the windows >= 0, got {self}")
        if self.coarse < 1 or self.iterations < 0 or self.min_points < 1:
            raise ConfigError(f"scan matcher: coarse >= 1, iterations >= 0 and min_points >= 1 expected, got {self}")


@dataclass(frozen=True)
class Match:
    """The outcome of one match: the pose, the mean field value under the points there, how many points
    were matched, and what happened (`status`)."""

    pose: Pose
    score: float
    points: int
    status: Status


def compose(a: Pose, b: Pose) -> Pose:
    """a (+) b: pose `b`, given in the frame of `a`, in the world frame."""
    c, s = math.cos(a.theta), math.sin(a.theta)
    return Pose(a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, wrap_angle(a.theta + b.theta))


def relative(a: Pose, b: Pose) -> Pose:
    """(-a) (+) b: pose `b` in the frame of `a` (so compose(a, relative(a, b)) == b)."""
    c, s = math.cos(a.theta), math.sin(a.theta)
    dx, dy = b.x - a.x, b.y - a.y
    return Pose(c * dx + s * dy, -s * dx + c * dy, wrap_angle(b.theta - a.theta))


def scan_points(scan: LaserScan, range_max: float = math.inf
                ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The scan's hits as points in the robot frame [m]: finite ranges below the scan's and `range_max`."""
    r = np.asarray(scan.ranges, np.float64)
    a = np.asarray(scan.angles, np.float64)
    ok = np.isfinite(r) & (r > 0.0) & (r < min(scan.range_max, range_max))
    r, a = r[ok], a[ok]
    return (np.ascontiguousarray(scan.offset_x + r * np.cos(a)), np.ascontiguousarray(r * np.sin(a)))


class ScanMatcher:
    """Aligns scans with occupancy maps (see the module docstring)."""

    def __init__(self, config: MatcherConfig | None = None) -> None:
        self.config = config or MatcherConfig()

    def field(self, occupied: npt.NDArray[np.bool_], geo: GridGeometry, x: float, y: float, radius: float
              ) -> tuple[npt.NDArray[np.float64], float, float] | None:
        """The likelihood field of `occupied` over the cells within `radius` [m] of (x, y) (a square),
        as (field, origin_x, origin_y); None when that square holds no occupied cell."""
        r0, c0 = geo.cell_of(x - radius, y - radius)
        r1, c1 = geo.cell_of(x + radius, y + radius)
        r0, c0 = max(r0, 0), max(c0, 0)
        r1, c1 = min(r1 + 1, geo.rows), min(c1 + 1, geo.cols)
        if r0 >= r1 or c0 >= c1:
            return None
        sub = np.ascontiguousarray(occupied[r0:r1, c0:c1])
        if not sub.any():
            return None
        f = K.likelihood_field(edt_sq(sub), geo.cell, self.config.sigma)
        return f, geo.origin_x + c0 * geo.cell, geo.origin_y + r0 * geo.cell

    def match(self, occupied: npt.NDArray[np.bool_], geo: GridGeometry, px: npt.NDArray[np.float64],
              py: npt.NDArray[np.float64], prediction: Pose) -> Match:
        """Align the points (robot frame [m]) with the occupied cells, starting at `prediction`.

        Raises:
            ConfigError: `occupied` does not match `geo`, or px, py differ in shape.
        """
        cfg = self.config
        if occupied.shape != (geo.rows, geo.cols):
            raise ConfigError(f"scan matcher: map shape {occupied.shape} does not match its geometry {geo}")
        if px.shape != py.shape:
            raise ConfigError(f"scan matcher: point arrays differ in shape: {px.shape} and {py.shape}")
        n = len(px)
        if n < cfg.min_points:
            return Match(prediction, 0.0, n, "few-points")
        reach = float(np.sqrt(px * px + py * py).max())
        made = self.field(occupied, geo, prediction.x, prediction.y, reach + cfg.window_xy + 4 * cfg.sigma + geo.cell)
        if made is None:
            return Match(prediction, 0.0, n, "no-map")
        f, ox, oy = made
        cell = geo.cell
        fc = cfg.coarse
        px = np.ascontiguousarray(px, np.float64)
        py = np.ascontiguousarray(py, np.float64)
        # heading steps that move the farthest point by about one cell of each level
        dth_c = math.atan2(cell * fc, max(reach, cell))
        dth_f = math.atan2(cell, max(reach, cell))
        x, y, th = prediction.x, prediction.y, prediction.theta
        if fc > 1:
            coarse = K.pool_max(f, fc)
            x, y, th, _ = K.search(coarse, ox, oy, cell * fc, px, py, x, y, th,
                                   math.ceil(cfg.window_xy / (cell * fc)), 1,
                                   math.ceil(cfg.window_theta / dth_c), dth_c)
            x, y, th, _ = K.search(f, ox, oy, cell, px, py, x, y, th, fc, 1, math.ceil(dth_c / dth_f), dth_f)
        else:
            x, y, th, _ = K.search(f, ox, oy, cell, px, py, x, y, th, math.ceil(cfg.window_xy / cell), 1,
                                   math.ceil(cfg.window_theta / dth_f), dth_f)
        # the correlative search looks up whole cells; Gauss-Newton takes it to the interpolated optimum
        x, y, th, score, h = K.refine(f, ox, oy, cell, px, py, x, y, th, cfg.iterations)
        if score < cfg.min_score:
            return Match(prediction, score, n, "poor")
        pose = Pose(x, y, wrap_angle(th))
        status: Status = "matched"
        block = h[:2, :2]
        eig, vec = np.linalg.eigh(block)
        if eig[1] <= 0 or eig[0] < cfg.degenerate_ratio * eig[1]:
            # a corridor: keep the correction across it (and in heading), not along it
            weak = vec[:, 0]
            d = np.array([x - prediction.x, y - prediction.y])
            d -= weak * float(weak @ d)
            pose = Pose(prediction.x + d[0], prediction.y + d[1], pose.theta)
            status = "degenerate"
        return Match(pose, score, n, status)


@dataclass
class Localizer:
    """Corrects odometry with scan matching: each odometry increment is applied to the last corrected
    pose, and the result matched against the map (the caller's grid, read, never written here).

    Attributes:
        grid: the map to match against (the mapper's grid, updated by the caller with the pose
            `locate` returns).
        matcher: the scan matcher.
        counts: how many scans ended in each `Match.status`.
    """

    grid: OccupancyGrid
    matcher: ScanMatcher = field(default_factory=ScanMatcher)
    counts: dict[str, int] = field(default_factory=dict)
    _odom: Pose | None = None
    _pose: Pose | None = None

    def reset(self, odom: Pose, pose: Pose) -> None:
        """Restart from `pose` (the corrected pose) with odometry reading `odom` there."""
        self._odom, self._pose = odom, pose

    def predict(self, odom: Pose) -> Pose:
        """The last corrected pose moved by the odometry increment since then (odom itself at first)."""
        if self._odom is None or self._pose is None:
            return odom
        return compose(self._pose, relative(self._odom, odom))

    def locate(self, odom: Pose, scan: LaserScan | None) -> Pose:
        """The corrected pose for odometry `odom` and the scan taken there (None: prediction only)."""
        prediction = self.predict(odom)
        if scan is None:
            status, pose = "no-scan", prediction
        else:
            px, py = scan_points(scan, self.matcher.config.range_max)
            m = self.matcher.match(self.grid.occupied(), self.grid.geo, px, py, prediction)
            status, pose = m.status, m.pose
        self.counts[status] = self.counts.get(status, 0) + 1
        self._odom, self._pose = odom, pose
        return pose

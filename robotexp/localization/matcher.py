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
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.localization import covariance as C
from robotexp.localization import kernels as K
from robotexp.localization.calibration import OdometryCalibration
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import HIT_DEPTH, OccupancyGrid
from robotexp.robot import LaserScan, Pose, compose_pose, relative_pose, wrap_angle

__all__ = ["MatcherConfig", "Match", "HitMap", "ScanMatcher", "Localizer", "compose", "relative", "scan_points",
           "fill_walls"]

WINDOW_CAP = (1.5, math.radians(12.0))   # [m], [rad]: the widest search after a stretch without matches
CALIBRATION_POINTS = 60   # matches with fewer points do not calibrate odometry (in an open hall they turned it wrong)
CACHE_MARGIN = 1.0   # [m] a cached likelihood field reaches this much beyond the box a match needs
FLAT = 0.01   # a corridor's correction along it is dropped only if the mean field loses less than this
# `fill_walls`: the chord between two neighbouring beams' hits is a surface when it is at most FILL_ARC times the
# arc between the beams at the nearer range (a surface seen up to ~70 deg off square-on) and at most FILL_CAP [m]
FILL_ARC = 3.0
FILL_CAP = 0.5

Status = Literal["matched", "degenerate", "few-points", "no-map", "unseen", "poor"]
# a likelihood field over a box: (field, origin_x [m], origin_y [m], hit points or None; see `ScanMatcher.field`)
Field = tuple[npt.NDArray[np.float64], float, float, K.HitSegments | None]


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
        fuse_ratio: with a pose covariance (`Localizer(covariance=...)`), a direction of the position whose
            eigenvalue in the translation block of the normal matrix is below this share of the block's
            largest takes the Kalman update's step instead of the match's correction (`covariance.fuse`;
            Zhang, Kaess and Singh 2016, "On degeneracy of optimization-based state estimation problems",
            leave such a direction to the prior). Without it (0) a corridor's few features (a door frame, a
            bump in a wall) counted as fixing the position along it, and each match moved the pose along it
            by a centimetre or two: with error-free odometry, the ring corridor eb_loop (frontier, 3 m laser)
            came out 2.9 m short over 153 m.
        prior: weight of the prediction in the correlative search: a pose at the edge of the x, y
            or heading window loses this much of the mean field value (0: no prior).
        motion_sigma_xy: [m] the motion prior of the Gauss-Newton step: a pose this far from the
            prediction costs as much as one scan point entirely off the map; it holds what the scan
            does not fix (along a corridor) near the prediction.
        motion_sigma_theta: [rad] the same for heading.
        accept_score: Gauss-Newton from the prediction that ends at a mean field value at least this
            is the match (no correlative search); > 1: always search. (On the exact field a scan matched
            against a map of itself scores 0.99-1.0, and a local optimum 1.3 cm and 0.8 deg off scored
            0.915: 0.9 before the exact field, 0.95 with it.)
        exact_field: with the hit points (`match`'s `hits`), Gauss-Newton on the field of their wall
            segments evaluated exactly at each scan point (`kernels.refine_hits`), not interpolated
            bilinearly between cell centres (`kernels.refine`): interpolated, the optimum is biased by up
            to half a cell (a scan matched against a map made of itself ended 0.5-2.5 cm off). The
            correlative search uses the sampled field either way. On for whole simulated runs
            (`robotexp.localization.robot.RUN_MATCHER`: dense frontier 0.81 map IoU against 0.24, stalled,
            without it); off by default: on the three CARMEN logs (range noise, loop closure) the
            bilinear field did better (ATE 0.090 / 0.119 / 0.067 m against 0.136 / 0.227 / 0.100 m).
        drop_unseen: with `known` (see `match`), the points on never-seen cells are left out of the
            correlative search too, whatever their number (fewer than min_points left: "few-points", or
            "unseen" when more were left out than kept: the map has not seen where the scan falls).
            They carry no information, and where a robot turning in a corridor saw new parts of it,
            the search fitted them to the mapped walls: 8-18 cm off along the corridor.
        seen_free: [log-odds] with the exact field, a map given as log-odds and `known`: a wall segment's end
            is where the wall ends only when the map has seen a cell beyond it along the wall, occupied or
            free at or below this value (one pass of the `Localizer`'s p_free 0.4 makes -0.405); else it is
            where the map stopped seeing the wall (the laser's reach), and scan points just past it are not
            pulled back to it (`kernels.hit_points`). Pulled back, a robot driving along a featureless
            corridor came out short on every metre (eb_loop, 3 m laser, P3-DX preset, scan matching: 1.07 m
            short after 70 m; 0.50 m with this test). -1.2 (three passes) left 0.27 m there but cost
            furniture ends the map had seen past once (dense frontier, seeds 0-1: tolerant map IoU 0.90-0.92
            against 0.94-0.96).
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
    fuse_ratio: float = 0.2
    prior: float = 0.1
    motion_sigma_xy: float = 0.1
    motion_sigma_theta: float = math.radians(3.0)
    accept_score: float = 0.95
    exact_field: bool = False
    drop_unseen: bool = False
    seen_free: float = -0.4

    def __post_init__(self) -> None:
        if not (self.motion_sigma_xy > 0 and self.motion_sigma_theta > 0):
            raise ConfigError(f"scan matcher: the motion prior's sigmas must be > 0, got {self}")
        if not (self.sigma > 0 and self.window_xy >= 0 and self.window_theta >= 0 and self.range_max > 0):
            raise ConfigError(f"scan matcher: sigma and range_max must be > 0 m and the windows >= 0, got {self}")
        if not 0.0 <= self.fuse_ratio < 1.0:
            raise ConfigError(f"scan matcher: fuse_ratio must be in [0, 1), got {self.fuse_ratio}")
        if not self.seen_free < 0:
            raise ConfigError(f"scan matcher: seen_free must be a negative log-odds, got {self.seen_free}")
        if self.coarse < 1 or self.iterations < 0 or self.min_points < 1 or self.prior < 0:
            raise ConfigError(f"scan matcher: coarse >= 1, iterations >= 0, min_points >= 1 and prior >= 0 "
                              f"expected, got {self}")


@dataclass(frozen=True)
class Match:
    """The outcome of one match: the pose, the mean field value under the points there, how many points
    were matched, what happened (`status`), and how well the scan fixes the position (`conditioning`:
    near 0 in a corridor, near 1 in a room)."""

    pose: Pose
    score: float
    points: int
    status: Status
    conditioning: float = 0.0      # smallest / largest eigenvalue of the fit's translation information
    info: npt.NDArray[np.float64] | None = None   # the fit's 3x3 normal matrix (x, y [m], theta [rad])
    lever: float = 0.0             # [m] the matched points' RMS range


# the pose algebra of the whole project, under the short names this module has always used
compose, relative = compose_pose, relative_pose


def scan_points(scan: LaserScan, range_max: float = math.inf
                ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The scan's hits as points in the robot frame [m]: finite ranges below the scan's and `range_max`."""
    r = np.asarray(scan.ranges, np.float64)
    a = np.asarray(scan.angles, np.float64)
    ok = np.isfinite(r) & (r > 0.0) & (r < min(scan.range_max, range_max))
    r, a = r[ok], a[ok]
    return (np.ascontiguousarray(scan.offset_x + r * np.cos(a)), np.ascontiguousarray(r * np.sin(a)))


def fill_walls(scan: LaserScan, cell: float, arc: float = FILL_ARC, cap: float = FILL_CAP) -> LaserScan:
    """`scan` with points added every `cell` [m] along the chord between neighbouring beams' hits where the
    chord is short enough to be one surface (at most `arc` times the arc between the two beams at the nearer
    range, and `cap` metres): the beams of an added point are the straight lines from the sensor to it.

    What a matching map is made of: a laser 1 deg a beam hits a wall 8 m away every 14 cm, every third
    5 cm cell, and a map made of such scans holds the wall as a row of dots, not a line. A scan turned by a
    fraction of a beam against it is drawn to the dots (its points towards the old beams' points): matched
    against a map of one scan of the 30 x 20 m hall, taken at the same spot and turned by 4.6, 9.2, 13.8 ...
    deg, the heading came out 0.2-0.4 deg off; with the walls filled in, under 0.01 deg in most and 0.08
    deg at most. Beams with no hit, and a depth jump between neighbours (a door post against the room
    behind it), add nothing."""
    r = np.asarray(scan.ranges, np.float64)
    a = np.asarray(scan.angles, np.float64)
    if len(r) < 2 or not cell > 0:
        return scan
    ok = np.isfinite(r) & (r > 0.0) & (r < scan.range_max)
    rr = np.where(ok, r, 0.0)
    x = scan.offset_x + rr * np.cos(a)
    y = rr * np.sin(a)
    chord = np.hypot(np.diff(x), np.diff(y))
    near = np.minimum(rr[:-1], rr[1:])
    surface = ok[:-1] & ok[1:] & (chord <= np.minimum(cap, np.maximum(arc * near * np.abs(np.diff(a)), 2 * cell)))
    n = np.where(surface, np.ceil(chord / cell) - 1.0, 0.0).astype(np.int64)
    total = int(n.sum())
    if total == 0:
        return scan
    i = np.repeat(np.arange(len(n)), n)                       # the beam each added point follows
    first = np.repeat(np.cumsum(n) - n, n)                    # where its chord's points start
    f = (np.arange(total) - first + 1) / np.repeat(n + 1, n)  # 1/(n+1) ... n/(n+1) along the chord
    px = x[i] + f * (x[i + 1] - x[i]) - scan.offset_x
    py = y[i] + f * (y[i + 1] - y[i])
    angles = np.concatenate([a, np.arctan2(py, px)])
    ranges = np.concatenate([r, np.hypot(px, py)])
    order = np.argsort(angles, kind="stable")
    return LaserScan(angles[order], ranges[order], scan.range_max, scan.offset_x, scan.stamp)


class HitMap:
    """Where in each cell the laser hits fell: running sums of the hit points' offsets from the cell
    centre [cells] and their count, over a `GridGeometry`; float32 (12 bytes a cell)."""

    def __init__(self, geo: GridGeometry) -> None:
        self.geo = geo
        self.sum_x = np.zeros((geo.rows, geo.cols), np.float32)
        self.sum_y = np.zeros((geo.rows, geo.cols), np.float32)
        self.count = np.zeros((geo.rows, geo.cols), np.float32)

    def add(self, pose: Pose, scan: LaserScan, range_max: float = math.inf) -> None:
        """Record the hits of `scan` taken at robot pose `pose` (ranges below `range_max` and the scan's), each
        in the cell `OccupancyGrid.update` marks for it: HIT_DEPTH beyond the hit, a point on a cell border
        in the cell the beam goes on into. (With the cell under the point, a wall face on a border had its
        hits counted in the free cell in front of it and its occupied cell matched at its centre, half a
        cell behind the face.)"""
        g = self.geo
        K.add_hits(self.sum_x, self.sum_y, self.count, g.origin_x, g.origin_y, g.cell, pose.x, pose.y, pose.theta,
                   scan.offset_x, np.ascontiguousarray(scan.ranges, np.float64),
                   np.ascontiguousarray(scan.angles, np.float64), min(scan.range_max, range_max), HIT_DEPTH)

    def offsets(self, r0: int, r1: int, c0: int, c1: int) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """Mean hit offsets [cells] of the cells [r0, r1) x [c0, c1) (0 where no hit was recorded)."""
        n = np.maximum(self.count[r0:r1, c0:c1], np.float32(1.0))
        return (np.ascontiguousarray(self.sum_x[r0:r1, c0:c1] / n), np.ascontiguousarray(self.sum_y[r0:r1, c0:c1] / n))


def _eig2(a: float, b: float, c: float) -> tuple[tuple[float, float], npt.NDArray[np.float64]]:
    """The eigenvalues (smaller first) of the symmetric [[a, b], [b, c]] and the unit eigenvector of the
    smaller (np.linalg.eigh's, in closed form: it ran once a match)."""
    m, r = (a + c) / 2, math.hypot((a - c) / 2, b)
    lo = m - r
    v = (b, lo - a) if abs(lo - a) >= abs(lo - c) else (lo - c, b)
    n = math.hypot(*v)
    vec = np.array([1.0, 0.0] if a <= c else [0.0, 1.0]) if n == 0 else np.array(v) / n
    return (lo, m + r), vec


class ScanMatcher:
    """Aligns scans with occupancy maps (see the module docstring)."""

    def __init__(self, config: MatcherConfig | None = None) -> None:
        self.config = config or MatcherConfig()
        self._cache: tuple[int, tuple[float, float, float, float], Field | None] | None = None

    def field(self, occupied: npt.NDArray[Any], geo: GridGeometry, box: tuple[float, float, float, float],
              hits: HitMap | None = None, known: npt.NDArray[Any] | None = None) -> Field | None:
        """The likelihood field of `occupied` (bool, or numbers with > 0 occupied, e.g. log-odds) over
        the cells of `box` (xmin, ymin, xmax, ymax) [m], as (field, origin_x, origin_y, points), centred on
        the mean hit point of each occupied cell when `hits` knows it (else on its centre), with those
        points (`kernels.hit_points`; None unless `exact_field` and `hits`: cell centres are no wall
        points); None when that box holds no occupied cell. `known` (> 0 where the map has seen a cell;
        None: everywhere) tells the wall ends the map saw from those where it stopped seeing the wall."""
        r0, c0 = geo.cell_of(box[0], box[1])
        r1, c1 = geo.cell_of(box[2], box[3])
        r0, c0 = max(r0, 0), max(c0, 0)
        r1, c1 = min(r1 + 1, geo.rows), min(c1 + 1, geo.cols)
        if r0 >= r1 or c0 >= c1:
            return None
        sub = occupied[r0:r1, c0:c1]
        sub = np.ascontiguousarray(sub if sub.dtype == np.bool_ else sub > 0)
        if not sub.any():
            return None
        if hits is not None:
            off_x, off_y = hits.offsets(r0, r1, c0, c1)
        else:
            off_x = off_y = np.zeros(sub.shape, np.float32)
        reach = math.ceil(3.0 * self.config.sigma / geo.cell)
        f = K.splat_field(sub, off_x, off_y, geo.cell, self.config.sigma, reach)
        points = None
        if self.config.exact_field and hits is not None:
            if known is None:
                seen = np.ones(sub.shape, np.bool_)
            else:
                seen = known[r0:r1, c0:c1] > 0
                if occupied.dtype != np.bool_:         # log-odds: free only where passes add up to seen_free
                    values = occupied[r0:r1, c0:c1]
                    seen &= (values <= self.config.seen_free) | (values > 0)
                seen = np.ascontiguousarray(seen)
            points = K.hit_points(sub, off_x, off_y, seen)
        return f, geo.origin_x + c0 * geo.cell, geo.origin_y + r0 * geo.cell, points

    def match(self, occupied: npt.NDArray[Any], geo: GridGeometry, px: npt.NDArray[np.float64],  # noqa: C901
              py: npt.NDArray[np.float64], prediction: Pose, hits: HitMap | None = None,
              known: npt.NDArray[Any] | None = None, motion: tuple[float, float] | None = None,
              window: tuple[float, float] | None = None, version: int | None = None) -> Match:
        """Align the points (robot frame [m]) with the occupied cells (bool, or > 0), starting at `prediction`
        (with `hits`, the field is centred on the cells' mean hit points).

        With `known` ((rows, cols), > 0 where the map has seen the cell, e.g. a grid's `stamp`), the
        Gauss-Newton step leaves out the points that fall on cells the map has never seen, placed at the
        prediction (when at least half of them, and min_points, remain): where a wall runs on beyond
        the part mapped so far, the end of the mapped part pulls them back along it and turns the scan.
        The correlative search still uses every point (unless `drop_unseen`). `motion` (sigma_xy [m], sigma_theta [rad])
        replaces the config's motion prior (the `Localizer` scales it with the motion since the last
        match). `window` (xy [m], theta [rad]) replaces the config's search window. `version` names the
        state of the map (a number the caller changes whenever the map changes): with it the likelihood
        field is computed over a box CACHE_MARGIN wider and reused while the version stays and the
        box it needs lies inside.

        Raises:
            ConfigError: `occupied` does not match `geo`, or px, py differ in shape.
        """
        cfg = self.config
        if occupied.shape != (geo.rows, geo.cols):
            raise ConfigError(f"scan matcher: map shape {occupied.shape} does not match its geometry {geo}")
        if px.shape != py.shape:
            raise ConfigError(f"scan matcher: point arrays differ in shape: {px.shape} and {py.shape}")
        if known is not None and len(px):
            c, s_ = math.cos(prediction.theta), math.sin(prediction.theta)
            col = np.floor((prediction.x + c * px - s_ * py - geo.origin_x) / geo.cell).astype(np.intp)
            row = np.floor((prediction.y + s_ * px + c * py - geo.origin_y) / geo.cell).astype(np.intp)
            inside = (row >= 0) & (row < geo.rows) & (col >= 0) & (col < geo.cols)
            keep = np.zeros(len(px), np.bool_)
            keep[inside] = known[row[inside], col[inside]] > 0
            if cfg.drop_unseen:
                unseen = len(px) - int(np.count_nonzero(keep))
                px, py = np.ascontiguousarray(px[keep]), np.ascontiguousarray(py[keep])
                gx, gy = px, py
                if len(px) < cfg.min_points and unseen > len(px):
                    return Match(prediction, 0.0, len(px), "unseen")
            elif np.count_nonzero(keep) >= max(cfg.min_points, len(px) // 2):
                gx, gy = np.ascontiguousarray(px[keep]), np.ascontiguousarray(py[keep])
            else:
                gx, gy = px, py
        else:
            gx, gy = px, py
        n = len(px)
        if n < cfg.min_points:
            return Match(prediction, 0.0, n, "few-points")
        reach = float(np.sqrt(px * px + py * py).max())
        # the field covers the points at the prediction, moved anywhere in the search window
        c, s_ = math.cos(prediction.theta), math.sin(prediction.theta)
        wx, wy = prediction.x + c * px - s_ * py, prediction.y + s_ * px + c * py
        win_xy, win_th = window if window is not None else (cfg.window_xy, cfg.window_theta)
        pad = win_xy + reach * math.sin(min(win_th, math.pi / 2)) + 4 * cfg.sigma + geo.cell
        box = (min(float(wx.min()), prediction.x) - pad, min(float(wy.min()), prediction.y) - pad,
               max(float(wx.max()), prediction.x) + pad, max(float(wy.max()), prediction.y) + pad)
        made: Field | None = None
        cached = self._cache
        if version is not None and cached is not None and cached[0] == version and cached[1][0] <= box[0] \
                and cached[1][1] <= box[1] and cached[1][2] >= box[2] and cached[1][3] >= box[3]:
            made = cached[2]                 # the map has not changed and its field covers the box
        else:
            if version is not None:          # a field over a wider box serves the next matches too
                box = (box[0] - CACHE_MARGIN, box[1] - CACHE_MARGIN, box[2] + CACHE_MARGIN, box[3] + CACHE_MARGIN)
            made = self.field(occupied, geo, box, hits, known)
            if version is not None:
                self._cache = (version, box, made)
        if made is None:
            return Match(prediction, 0.0, n, "no-map")
        f, ox, oy, points = made
        cell = geo.cell
        fc = cfg.coarse
        px = np.ascontiguousarray(px, np.float64)
        py = np.ascontiguousarray(py, np.float64)
        # heading steps that move the farthest point by about one cell of each level
        dth_c = math.atan2(cell * fc, max(reach, cell))
        dth_f = math.atan2(cell, max(reach, cell))
        x0, y0, th0 = prediction.x, prediction.y, prediction.theta
        gx = np.ascontiguousarray(gx, np.float64)
        gy = np.ascontiguousarray(gy, np.float64)
        sxy, sth = motion if motion is not None else (cfg.motion_sigma_xy, cfg.motion_sigma_theta)
        wxy, wth = sxy ** -2, sth ** -2
        # Gauss-Newton from the prediction first: where it fits well (mean field >= accept_score) the
        # correlative search ends at the same pose (on a sparse run: within 8 mm and 0.26 deg in 99.9 %
        # of the matches) and is skipped
        if points is not None:      # Gauss-Newton on the field evaluated exactly at the points
            sig, reach_cells = cfg.sigma, math.ceil(3.0 * cfg.sigma / cell)
            assert points is not None

            def refine(x: float, y: float, th: float) -> tuple[float, float, float, float, npt.NDArray[np.float64]]:
                return K.refine_hits(points, ox, oy, cell, sig, reach_cells, gx, gy, x, y, th, cfg.iterations,
                                     x0, y0, th0, wxy, wth)

            def objective(x: float, y: float, th: float) -> float:
                return K.objective_hits(points, ox, oy, cell, sig, reach_cells, gx, gy, x, y, th, x0, y0, th0,
                                        wxy, wth)

            def mean(x: float, y: float, th: float) -> float:
                return K.mean_hits(points, ox, oy, cell, sig, reach_cells, gx, gy, x, y, th)
        else:                       # ... or on the bilinear field
            def refine(x: float, y: float, th: float) -> tuple[float, float, float, float, npt.NDArray[np.float64]]:
                return K.refine(f, ox, oy, cell, gx, gy, x, y, th, cfg.iterations, x0, y0, th0, wxy, wth)

            def objective(x: float, y: float, th: float) -> float:
                return K.objective(f, ox, oy, cell, gx, gy, x, y, th, x0, y0, th0, wxy, wth)

            def mean(x: float, y: float, th: float) -> float:
                return K.mean_field(f, ox, oy, cell, gx, gy, x, y, th)

        r = refine(x0, y0, th0)
        best = (objective(r[0], r[1], r[2]), r)
        if r[3] < cfg.accept_score:
            kxy = cfg.prior * n / max(win_xy, cell) ** 2
            kth = cfg.prior * n / max(win_th, dth_f) ** 2
            if fc > 1:
                coarse = K.pool_max(f, fc)
                x, y, th, _ = K.search(coarse, ox, oy, cell * fc, px, py, x0, y0, th0,
                                       math.ceil(win_xy / (cell * fc)), 1,
                                       math.ceil(win_th / dth_c), dth_c, x0, y0, th0, kxy, kth)
                x, y, th, _ = K.search(f, ox, oy, cell, px, py, x, y, th, fc, 1, math.ceil(dth_c / dth_f), dth_f,
                                       x0, y0, th0, kxy, kth)
            else:
                x, y, th, _ = K.search(f, ox, oy, cell, px, py, x0, y0, th0, math.ceil(win_xy / cell), 1,
                                       math.ceil(win_th / dth_f), dth_f, x0, y0, th0, kxy, kth)
            # the correlative search looks up whole cells; Gauss-Newton takes it to the interpolated optimum
            # (the search's whole cells can step off a pose that was right, where the field is flat: the
            # better end by fit and prior, from the search's pose or from the prediction, wins)
            r = refine(x, y, th)
            total = objective(r[0], r[1], r[2])
            if total < best[0]:
                best = (total, r)
        x, y, th, score, h = best[1]
        if score < cfg.min_score:
            return Match(prediction, score, n, "poor")
        pose = Pose(x, y, wrap_angle(th))
        status: Status = "matched"
        eig, weak = _eig2(float(h[0, 0]), float(h[0, 1]), float(h[1, 1]))
        if eig[1] <= 0 or eig[0] < cfg.degenerate_ratio * eig[1]:
            # a corridor: keep the correction across it (and in heading), not along it
            d = np.array([x - prediction.x, y - prediction.y])
            d -= weak * float(weak @ d)
            kept = Pose(prediction.x + d[0], prediction.y + d[1], pose.theta)
            # only where the field really is flat along that direction: the fit must stay as good
            if mean(kept.x, kept.y, kept.theta) >= score - FLAT:
                pose = kept
                status = "degenerate"
        lever = float(np.sqrt(np.mean(gx * gx + gy * gy)))
        return Match(pose, score, n, status, float(max(eig[0], 0.0) / eig[1]) if eig[1] > 0 else 0.0, h, lever)


class Localizer:
    """Corrects odometry with scan matching: each odometry increment is applied to the last corrected
    pose, the scan is matched there against the localizer's own map, and then integrated into it at
    the corrected pose.

    The matching map is a log-odds grid with Hector SLAM's sensor model (p_occ 0.9, p_free 0.4: a
    wall hit once survives a few grazing beams), separate from the explorer's map, whose model the
    method chooses (HIMM for BVP, UFMG log-odds).

    Args:
        geo: the matching map's extent and cells.
        matcher: the scan matcher (default settings when None).
        p_occ: the matching map's occupancy after a hit.
        p_free: the matching map's occupancy of a crossed cell.
        range_max: [m] beams at or beyond this record no hit in the matching map (default the
            scan's range_max).
        use_hits: centre the likelihood field on the cells' mean hit points (`HitMap`), not their
            centres (on the three CARMEN logs with loop closure: ATE 0.145 / 0.198 / 0.183 m against
            0.149 / 0.267 / 0.175 m; see docs/localization).
        min_travel: [m] match (and update the map) only once odometry has moved this far since the
            last match ...
        min_turn: [rad] ... or turned this much.
        motion_noise: (a_xy [m], b_xy [m/m], a_th [rad], b_th [rad/m], c_th [rad/rad]): the motion
            prior of a match after odometry moved d and turned dth since the last one has sigmas
            a_xy + b_xy d and a_th + b_th d + c_th |dth| (None: the matcher's fixed ones).
        gate: with `motion_noise`, a match that moves the pose more than `gate` sigmas of it from the
            prediction is refused ("gated": the prediction is kept); 0: no gate.
        skip_unseen: pass the grid's `stamp` as `known` to `ScanMatcher.match` (Gauss-Newton without the
            points on never-seen cells). On a simulated log it halves the heading drift (ATE 0.26 ->
            0.15 m without noise), on the CARMEN logs it did worse (ACES 0.307 m against 0.198 m with
            loop closure), so it is off by default.
        calibration: estimate odometry's systematic heading error online from the matches and correct
            every increment with it (`OdometryCalibration`; None: odometry as it is).
        max_turn_rate: [rad/s] a scan taken while the robot turns faster than this is neither matched nor
            mapped ("turning": the prediction is kept). A real laser's beams and its stamp are never
            exactly in step with odometry: on the Kobuki emulator, turning at 2.6 rad/s, a 10 ms skew
            is 1.5 deg, and matches pulled the heading by up to 2 deg there and back (its explored map
            smeared and frontier exploration stopped at 0.81 coverage); odometry (or a gyro) turns in
            place better than that.
        map_uncertain: [m] once odometry has gone this far since the last match, an unmatched scan
            ("few-points", "poor", "gated") no longer goes into the matching map (where nothing is
            mapped yet, "no-map", or the scan falls mostly on never-seen cells, "unseen", it still does):
            mapped at a drifting pose, the walls of an open hall seen by a few beams made a second,
            turned copy of the map that later scans matched. (Without the "unseen" exception the map
            froze in `sparse` once the pose was uncertain: every later scan of new ground was
            "few-points" with `drop_unseen`, and the localizer never matched again.)
        map_travel: [m] a matched scan goes into the matching map only once odometry has moved this far
            since the last one that did ...
        map_turn: [rad] ... or turned this much (or where nothing is mapped yet): Hector SLAM's map
            update thresholds; the scans between are matched against the same map (and its cached
            likelihood field, `ScanMatcher.match`'s `version`).
        covariance: (q_xy [m^2/m], q_th [rad^2/m], k0 [rad/m], q_k [rad^2/m^3]): keep a covariance of
            (x, y, theta, k), k the odometry heading bias per metre of `calibration` (without it, k is
            left out), carried along odometry (position and heading random walks of q_xy and q_th per
            metre, k's of q_k; k uncertain by k0 at the start: the heading's uncertainty grows with
            the distance driven since the calibration's k may be off), and update it by each match
            (`_fuse`): the match's correction stands where its scan fixes the pose, and where it does
            not (a lone pillar fixes the position, not the turn about itself) the correction follows
            from the covariance. None: no covariance (matches as they are).
        fill: put scans into the matching map with their walls filled in between neighbouring beams
            (`fill_walls`): walls seen at range are lines there, not rows of dots one beam apart, which the
            exact field's wall segments (`MatcherConfig.exact_field`) need. None: on with the exact field.
            In `sparse` (8 m laser, P3-DX preset, loop closure) the loop-closure study's 15 runs there met
            the targets in 12 against 6 without. With the bilinear field (the CARMEN logs) it stays off:
            there it gave 33 against 30 of 44 log runs within 0.3 m, but turned a simulated corridor log by
            0.036 deg a match on average and took its ATE from 0.09-0.17 m to 0.20-0.38 m
            (docs/how-to/localization.md).

    Attributes:
        grid: the matching map.
        hits: where the hits fell in its cells.
        counts: how many scans ended in each `Match.status` (and "no-scan", "odometry", "turning", "gated").
        status: the last `locate`'s outcome.
        cov: the 4x4 covariance of (x, y [m], theta [rad], k [rad/m]) with `covariance`.
    """

    def __init__(self, geo: GridGeometry, matcher: ScanMatcher | None = None, *, p_occ: float = 0.9,  # noqa: PLR0913
                 p_free: float = 0.4, range_max: float | None = None, use_hits: bool = True,
                 skip_unseen: bool = False, min_travel: float = 0.0, min_turn: float = 0.0,
                 motion_noise: tuple[float, float, float, float, float] | None = None, gate: float = 0.0,
                 calibration: OdometryCalibration | None = None, max_turn_rate: float = math.inf,
                 map_uncertain: float = math.inf, map_travel: float = 0.0, map_turn: float = 0.0,
                 covariance: tuple[float, float, float, float] | None = None, fill: bool | None = None) -> None:
        if min_travel < 0 or min_turn < 0:
            raise ConfigError(f"localizer: min_travel and min_turn must be >= 0, got {min_travel} and {min_turn}")
        self.grid = OccupancyGrid(geo, p_occ=p_occ, p_free=p_free, range_max=range_max)
        self.min_travel, self.min_turn = min_travel, min_turn
        self.motion_noise = motion_noise
        self.gate = gate
        self._matched: Pose | None = None
        self.hits = HitMap(geo)
        self.use_hits = use_hits
        self.skip_unseen = skip_unseen
        self.matcher = matcher or ScanMatcher()
        self.counts: dict[str, int] = {}
        self.calibration = calibration
        self.max_turn_rate = max_turn_rate
        self.map_uncertain = map_uncertain
        self.map_travel, self.map_turn = map_travel, map_turn
        self.version = 0                 # changes with every scan put into the matching map
        self.status = ""                 # what the last `locate` did (a `counts` key)
        self._mapped: Pose | None = None  # odometry at the last scan put into it
        self._last_status = ""
        self._free = (0.0, 0.0)    # odometry's distance [m] and turn [rad] since the last correction
        self._odom: Pose | None = None
        self._pose: Pose | None = None
        self.prediction: Pose | None = None     # the last `locate`'s prediction
        self.covariance = covariance
        self.cov = self._cov0()
        self.fill = self.matcher.config.exact_field if fill is None else fill

    def reset(self, odom: Pose, pose: Pose) -> None:
        """Restart from `pose` (the corrected pose) with odometry reading `odom` there."""
        self._odom, self._pose, self._matched = odom, pose, odom
        self._last_status = ""
        self._mapped = None
        self._free = (0.0, 0.0)
        self.cov = self._cov0()

    def _cov0(self) -> npt.NDArray[np.float64]:
        k0 = 0.0 if self.covariance is None or self.calibration is None else self.covariance[2]
        return np.diag([1e-4, 1e-4, math.radians(0.5) ** 2, k0 * k0])

    def _propagate(self, prediction: Pose, distance: float) -> None:
        """Carry the covariance of (x, y, theta, k) from the last pose to `prediction`, `distance` [m] of
        odometry on (`robotexp.localization.covariance.propagate`)."""
        if self.covariance is None or self._pose is None:
            return
        q_xy, q_th, _, q_k = self.covariance
        C.propagate(self.cov, prediction.x - self._pose.x, prediction.y - self._pose.y, distance, q_xy, q_th,
                    q_k if self.calibration is not None else 0.0)

    def _fuse(self, prediction: Pose, m: Match) -> Pose:
        """The match's pose after a Kalman update of (x, y, theta, k) by it
        (`robotexp.localization.covariance.fuse`): its correction where its scan fixes the pose, the
        update's where it does not (a lone pillar: the turn about itself). k's estimate stays the
        odometry calibration's: taking the update's k as well moved it by 0.2-0.3 deg/m in the sparse
        hall (a pillar's heading error taken for bias), and the update's k alone, without the
        calibration's fit, made frontier's ATE 10.6-13.0 m there (3.3-5.5 m without it)."""
        if m.info is None:
            return m.pose
        cfg = self.matcher.config
        sx, sy, sth, _ = C.fuse(self.cov, m.info, m.lever, cfg.degenerate_ratio, cfg.fuse_ratio,
                                m.pose.x - prediction.x, m.pose.y - prediction.y,
                                wrap_angle(m.pose.theta - prediction.theta))
        return Pose(prediction.x + sx, prediction.y + sy, wrap_angle(prediction.theta + sth))

    def mapped(self, scan: LaserScan) -> LaserScan:
        """The scan as the matching map takes it (its walls filled in with `fill`)."""
        return fill_walls(scan, self.grid.geo.cell) if self.fill else scan

    def integrate(self, pose: Pose, scan: LaserScan) -> None:
        """Put `scan`, taken at `pose`, into the matching map (`locate` does this itself)."""
        scan = self.mapped(scan)
        self.grid.update(pose, scan)
        rmax = self.grid.range_max if self.grid.range_max is not None else math.inf
        self.hits.add(pose, scan, rmax)
        self.version += 1

    @property
    def pose(self) -> Pose | None:
        """The last corrected pose (None before `reset`)."""
        return self._pose

    def predict(self, odom: Pose) -> Pose:
        """The last corrected pose moved by the odometry increment since then (odom itself at first)."""
        if self._odom is None or self._pose is None:
            return odom
        inc = relative(self._odom, odom)
        return compose(self._pose, inc if self.calibration is None else self.calibration.apply(inc))

    def locate(self, odom: Pose, scan: LaserScan | None, turn_rate: float = 0.0) -> Pose:
        """The corrected pose for odometry `odom` and the scan taken there (None: prediction only); the
        scan then goes into the matching map at that pose. While odometry has moved less than
        `min_travel` and turned less than `min_turn` since the last match, the prediction is the pose
        ("odometry") and the map is left as it is (Hector SLAM's map update thresholds): the pose
        follows odometry smoothly between matches and the scans cost nothing. While `turn_rate`
        [rad/s] exceeds `max_turn_rate` the same holds ("turning")."""
        prediction = self.predict(odom)
        self.prediction = prediction
        moved = relative(self._matched, odom) if self._matched is not None else None
        if self._odom is not None:
            step = relative(self._odom, odom)
            self._free = (self._free[0] + math.hypot(step.x, step.y), self._free[1] + abs(step.theta))
            self._propagate(prediction, math.hypot(step.x, step.y))
        if scan is None:
            status, pose = "no-scan", prediction
        elif abs(turn_rate) > self.max_turn_rate:
            status, pose = "turning", prediction
        elif moved is not None and math.hypot(moved.x, moved.y) < self.min_travel and \
                abs(moved.theta) < self.min_turn:
            status, pose = "odometry", prediction
        else:
            self._matched = odom
            px, py = scan_points(scan, self.matcher.config.range_max)
            motion = window = None
            if self.motion_noise is not None and moved is not None:
                a_xy, b_xy, a_th, b_th, c_th = self.motion_noise
                d, turn = self._free       # since the last correction: a stretch without one widens the prior
                motion = (a_xy + b_xy * d, a_th + b_th * d + c_th * turn)
                cfg = self.matcher.config       # the search window covers 3 sigmas of the prior (up to a cap)
                window = (min(max(cfg.window_xy, 3 * motion[0]), WINDOW_CAP[0]),
                          min(max(cfg.window_theta, 3 * motion[1]), WINDOW_CAP[1]))
            m = self.matcher.match(self.grid.values, self.grid.geo, px, py, prediction,
                                   self.hits if self.use_hits else None, self.grid.stamp if self.skip_unseen else None,
                                   motion, window, self.version)
            status, pose = m.status, m.pose
            if motion is not None and self.gate > 0:
                dev = relative(prediction, pose)
                cfg = self.matcher.config
                if math.hypot(dev.x, dev.y) > self.gate * motion[0] or abs(dev.theta) > self.gate * motion[1]:
                    status, pose = "gated", prediction      # farther than odometry can be wrong: a false match
                elif (math.hypot(dev.x, dev.y) > cfg.window_xy or abs(dev.theta) > cfg.window_theta) and not (
                        status == "matched" and m.score >= cfg.accept_score and m.points >= 3 * cfg.min_points):
                    # a jump beyond the usual window (after a stretch without matches) needs a scan that
                    # fixes the pose well: a few points on a wall in an open hall turned the pose by 15 deg
                    status, pose = "gated", prediction
            if self.covariance is not None and status in ("matched", "degenerate"):
                pose = self._fuse(prediction, m)
            if self.calibration is not None and moved is not None and status == "matched" \
                    and m.points >= CALIBRATION_POINTS and self._last_status in ("matched", "degenerate"):
                self.calibration.observe(moved.x, moved.theta, wrap_angle(pose.theta - prediction.theta))
            self._last_status = status
            if status in ("matched", "degenerate"):
                self._free = (0.0, 0.0)
            since = relative(self._mapped, odom) if self._mapped is not None else None
            due = since is None or math.hypot(since.x, since.y) >= self.map_travel or \
                abs(since.theta) >= self.map_turn or status in ("no-map", "unseen")
            if due and (status in ("matched", "degenerate", "no-map", "unseen") or self._free[0] < self.map_uncertain):
                self.integrate(pose, scan)
                self._mapped = odom
        self.counts[status] = self.counts.get(status, 0) + 1
        self.status = status
        self._odom, self._pose = odom, pose
        return pose

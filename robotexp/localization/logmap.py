"""Maps from laser logs: perturb a log's poses as drifting odometry would, recover them by scan matching,
build the occupancy grid, and measure the absolute trajectory error against the logged poses."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.localization.carmen import CarmenLog
from robotexp.localization.matcher import Localizer, MatcherConfig, ScanMatcher, compose, relative
from robotexp.localization.metrics import ate
from robotexp.localization.posegraph import LoopConfig, close_loops
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import LaserScan, Pose

__all__ = ["OdometryNoise", "parse_noise", "perturb_path", "LogMap", "map_log"]


@dataclass(frozen=True)
class OdometryNoise:
    """Odometry error proportional to distance: over an increment of length d, the translation is
    read (1 + dist (1 + n1)) d long and the heading turns by heading (1 + n2) d too much, n1, n2
    standard normal: a systematic error of `dist` (a fraction) and `heading` [rad/m], plus random
    errors of the same size."""

    dist: float = 0.0
    heading: float = 0.0

    @property
    def active(self) -> bool:
        """True when the noise changes anything."""
        return bool(self.dist or self.heading)


def parse_noise(text: str) -> OdometryNoise:
    """Parse `DIST,DEG_PER_M` (e.g. "0.02,1": 2 % of distance, 1 deg per metre).

    Raises:
        ConfigError: not two finite numbers, or one out of range ([0, 0.5] and [0, 45]).
    """
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        dist, deg = float(parts[0]), float(parts[1])
    except ValueError:
        raise ConfigError(f"--odometry-noise: {text!r} is not DIST,DEG_PER_M (e.g. 0.02,1)") from None
    if not (0.0 <= dist <= 0.5 and 0.0 <= deg <= 45.0):
        raise ConfigError(f"--odometry-noise: {text!r}: DIST must be in [0, 0.5] and DEG_PER_M in [0, 45]")
    return OdometryNoise(dist, math.radians(deg))


def perturb_path(truth: list[Pose], noise: OdometryNoise, seed: int) -> list[Pose]:
    """Odometry poses that drift from `truth` as `noise` says, starting at truth[0]."""
    if not truth:
        return []
    rng = np.random.default_rng(seed)
    out = [truth[0]]
    for a, b in zip(truth, truth[1:], strict=False):
        inc = relative(a, b)
        d = math.hypot(inc.x, inc.y)
        n1, n2 = rng.normal(0.0, 1.0, 2)
        k = 1.0 + noise.dist * (1.0 + n1)
        out.append(compose(out[-1], Pose(inc.x * k, inc.y * k, inc.theta + noise.heading * (1.0 + n2) * d)))
    return out


@dataclass
class LogMap:
    """What `map_log` made: the grid, the estimated, odometry and logged paths ((n, 3) arrays), the
    matcher's outcome counts, and the ATE [m] of the estimate and of the raw odometry (no alignment:
    every path starts at the logged first pose)."""

    grid: OccupancyGrid
    estimate: npt.NDArray[np.float64]
    odometry: npt.NDArray[np.float64]
    truth: npt.NDArray[np.float64]
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def ate_m(self) -> float:
        """[m] RMSE of the estimated positions against the logged ones, no alignment."""
        return ate(self.estimate, self.truth)

    @property
    def ate_rigid_m(self) -> float:
        """[m] the same after the best rigid alignment."""
        return ate(self.estimate, self.truth, align="rigid")

    @property
    def odometry_ate_m(self) -> float:
        """[m] ATE of the perturbed odometry itself, no alignment."""
        return ate(self.odometry, self.truth)


COARSER_CELLS = (0.1, 0.2, 0.5, 1.0)   # [m] the cells a log too large for its --cell is offered (and benchmarked at)


def _fits(box: tuple[float, float, float, float], cell: float, margin: float) -> bool:
    try:
        GridGeometry.covering(*box, cell, margin=margin)
    except ConfigError:
        return False
    return True


def map_log(log: CarmenLog, *, cell: float = 0.05, noise: OdometryNoise | None = None,
            localize: Literal["none", "scan-match"] = "scan-match", seed: int = 0, range_max: float = 20.0,
            matcher: MatcherConfig | None = None, margin: float = 2.0,
            loops: LoopConfig | None = None) -> LogMap:
    """Build a map from a log's laser readings placed at (perturbed and then corrected) poses.

    The logged laser poses are the truth. Odometry is the truth perturbed by `noise` from the first
    pose (the start is known, as on a robot). With `localize="scan-match"` each reading's pose is the
    odometry increment applied to the last corrected pose, then matched against the map so far.

    Args:
        log: the parsed log (at least one laser reading).
        cell: [m] grid cell size.
        noise: odometry noise (default none).
        localize: "none" maps on odometry, "scan-match" corrects it first.
        seed: seed of the noise.
        range_max: [m] readings beyond this are free up to it and mark no hit.
        matcher: scan matcher settings (default `MatcherConfig()`).
        margin: [m] beyond the logged path's bounds (and the perturbed odometry's with `localize="none"`)
            plus `range_max`, the grid's extent.
        loops: with scan matching, also close loops (`robotexp.localization.posegraph`) with these
            settings, then build the map on the corrected path; None: no loop closure.

    Raises:
        ConfigError: no laser reading, no beam in any of them, or a parameter out of range.
    """
    if not log.scans:
        raise ConfigError(f"{log.path}: no FLASER, ROBOTLASER1 or RAWLASER1 line: nothing to map")
    if not any(len(s.ranges) for s in log.scans):
        raise ConfigError(f"{log.path}: no laser beams to map: its {len(log.scans)} laser readings have 0 beams "
                          "each; give a log whose laser lines carry ranges")
    if not (cell > 0 and range_max > 0):
        raise ConfigError(f"map_log: cell and range_max must be > 0 m, got {cell} and {range_max}")
    if localize not in ("none", "scan-match"):
        raise ConfigError(f"--localize must be 'none' or 'scan-match', got {localize!r}")
    truth = [s.pose for s in log.scans]
    odom = perturb_path(truth, noise or OdometryNoise(), seed)
    # the logged path bounds the map, and odometry's too where the map is built on it: with scan matching a
    # perturbed path that drifts tens of metres away (Freiburg campus: 614 x 445 m against 216 x 180 m)
    # would only make the grid larger than the memory limit
    xy = np.array([[p.x, p.y] for p in (odom + truth if localize == "none" else truth)])
    reach = range_max + margin
    box = (float(xy[:, 0].min()), float(xy[:, 1].min()), float(xy[:, 0].max()), float(xy[:, 1].max()))
    try:
        geo = GridGeometry.covering(*box, cell, margin=reach)
    except ConfigError as e:
        fits = next((c for c in COARSER_CELLS if c > cell and _fits(box, c, reach)), None)
        msg = str(e)
        if fits is not None:
            msg = msg.replace("use a larger cell or smaller bounds", f"use a larger --cell ({fits:g} m fits)")
        raise ConfigError(f"{log.path}: {msg}") from None
    if geo.rows * geo.cols > 200_000_000:
        raise ConfigError(f"{log.path}: the map would have {geo.rows} x {geo.cols} cells: use a larger --cell")
    grid = OccupancyGrid(geo, range_max=range_max)
    loc = Localizer(geo, ScanMatcher(matcher), range_max=range_max) if localize == "scan-match" else None
    no_echo = log.no_echo()
    keep = loc is not None and loops is not None     # loop closure maps the scans again: kept; else made one by one
    scans: list[LaserScan] = []
    estimate: list[Pose] = []
    for i, reading in enumerate(log.scans):
        scan = reading.scan(range_max, no_echo)
        if keep:
            scans.append(scan)
        if i == 0:
            pose = truth[0]
            if loc is not None:
                loc.reset(odom[0], pose)
                loc.integrate(pose, scan)
        elif loc is not None:
            pose = loc.locate(odom[i], scan)
        else:
            pose = odom[i]
        grid.update(pose, scan)
        estimate.append(pose)
    path = np.array([[p.x, p.y, p.theta] for p in estimate])
    counts = dict(loc.counts) if loc else {}
    if loc is not None and loops is not None:
        path, found = close_loops(path, scans, cell=cell, matcher=loc.matcher.config, cfg=loops)
        counts["loop-edges"] = found
        grid = OccupancyGrid(geo, range_max=range_max)
        for row, scan in zip(path, scans, strict=True):
            grid.update(Pose(*row), scan)
    arr = lambda poses: np.array([[p.x, p.y, p.theta] for p in poses])   # noqa: E731
    return LogMap(grid, path, arr(odom), arr(truth), counts)

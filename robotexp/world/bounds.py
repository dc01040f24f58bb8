"""Exploration bounds: the area a run explores, and the means that keep every explorer inside it.

A run's exploration area is the user's (`--bounds`, `exploration.setMapLimits`, a campaign's
`bounds_mm`) or else what the map declares (`World.declared`: a `.map`'s MinPos..MaxPos and
LineMinPos..LineMaxPos, a ROS map's image extent); built-in worlds declare none and keep their map
(the world's box plus a margin). Inside the run:

- the occupancy grid is the area, so no frontier, target or plan lies beyond it (the grid planners
  and the shared frontier helpers never leave their grid), and ground truth and coverage are
  computed on that grid, inside it;
- explorers see the area's edge as a wall: `clip_scan` shortens every beam that would leave it to
  where it leaves (an explorer steering by its scans, such as SRT, stays inside; the map itself
  integrates the real scan);
- optionally the simulator gets real walls there (`with_boundary_walls`), for maps whose outline
  is open.

Unknown cells of a ROS map are obstacles to the simulator (`load_ros_world`): most real maps are
unknown outside the building, where a simulated robot must neither drive nor see.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from robotexp.errors import ConfigError
from robotexp.robot import LaserScan, Pose
from robotexp.world.model import World

__all__ = ["Area", "BOUNDARY_THICKNESS", "clip_scan", "exploration_area", "inside", "parse_bounds",
           "with_boundary_walls"]

Area = tuple[float, float, float, float]        # [m] xmin, ymin, xmax, ymax
BOUNDARY_THICKNESS = 0.05                       # [m] the simulator's walls along the area's edge


def exploration_area(world: World, given: Area | None) -> Area | None:
    """The run's exploration area: `given`, else the map's declared area (None: the world's box)."""
    return given if given is not None else world.declared


def parse_bounds(text: str, what: str = "--bounds") -> Area:
    """`xmin,ymin,xmax,ymax` in mm -> an area in m.

    Raises:
        ConfigError: not four finite numbers with xmin < xmax and ymin < ymax (one line, says the form).
    """
    parts = text.split(",")
    try:
        if len(parts) != 4:
            raise ValueError
        x0, y0, x1, y1 = (float(p) for p in parts)
    except ValueError:
        raise ConfigError(f"{what} {text!r}: expected xmin,ymin,xmax,ymax in mm (e.g. -1000,-1000,20000,15000)") \
            from None
    if not all(math.isfinite(v) for v in (x0, y0, x1, y1)) or not (x0 < x1 and y0 < y1):
        raise ConfigError(f"{what} {text!r}: expected finite xmin < xmax and ymin < ymax in mm")
    return (x0 / 1000.0, y0 / 1000.0, x1 / 1000.0, y1 / 1000.0)


def inside(area: Area, x: float, y: float, tol: float = 0.0) -> bool:
    """True when (x, y) [m] lies in `area` grown by `tol` [m]."""
    x0, y0, x1, y1 = area
    return x0 - tol <= x <= x1 + tol and y0 - tol <= y <= y1 + tol


def with_boundary_walls(world: World, area: Area, thickness: float = BOUNDARY_THICKNESS) -> World:
    """`world` with four walls of `thickness` [m] just outside `area` (their inner faces on its edge)."""
    x0, y0, x1, y1 = area
    t = thickness / 2
    w, h = (x1 - x0) / 2 + thickness, (y1 - y0) / 2 + thickness
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    walls = np.array([[cx, y0 - t, w, t, 0.0], [cx, y1 + t, w, t, 0.0],
                      [x0 - t, cy, t, h, 0.0], [x1 + t, cy, t, h, 0.0]])
    bounds = world.bounds or area
    grown = (min(bounds[0], x0 - thickness), min(bounds[1], y0 - thickness),
             max(bounds[2], x1 + thickness), max(bounds[3], y1 + thickness))
    return replace(world, boxes=np.vstack([world.boxes, walls]), bounds=grown,
                   description=world.description + f"; walls along the exploration bounds "
                   f"{x0 * 1000:.0f},{y0 * 1000:.0f},{x1 * 1000:.0f},{y1 * 1000:.0f} mm")


def clip_scan(scan: LaserScan, pose: Pose, area: Area) -> LaserScan:
    """`scan` taken at `pose` with every beam that would leave `area` ending where it leaves it.

    A beam whose reading (or, with no echo, whose range_max) lies beyond the area's edge reads the
    distance to that edge instead, as if a wall stood there; beams inside are unchanged (the same
    array when none changes). A sensor outside the area sees the edge at distance 0 in every
    direction that leaves it.
    """
    x0, y0, x1, y1 = area
    sx, sy = scan.origin(pose)
    # a beam leaves the area no nearer than its nearest edge: readings all short of it change nothing (a
    # robot inside the area, away from its edges: most control periods, at the cost of one comparison); a
    # beam without an echo (inf) reads range_max below, short of the edge as well
    edge = min(sx - x0, x1 - sx, sy - y0, y1 - sy) - 1e-9
    if scan.range_max < edge and not bool(np.any((scan.ranges >= edge) & (scan.ranges != math.inf))):
        return scan
    a = pose.theta + scan.angles
    dx, dy = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(dx > 0, (x1 - sx) / dx, np.where(dx < 0, (x0 - sx) / dx, np.inf))
        ty = np.where(dy > 0, (y1 - sy) / dy, np.where(dy < 0, (y0 - sy) / dy, np.inf))
    exit_t = np.maximum(np.minimum(tx, ty), 0.0)
    reading = np.where(np.isfinite(scan.ranges), scan.ranges, scan.range_max)
    cut = exit_t < reading
    if not cut.any():
        return scan
    ranges = scan.ranges.copy()
    ranges[cut] = exit_t[cut]
    return replace(scan, ranges=ranges)

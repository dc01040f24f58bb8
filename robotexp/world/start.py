"""`default_start`: where a run starts on a map that names no start pose.

The free place nearest a map's centre can be a closet, a pocket between furniture or the unknown
outside of a laser-built map. Instead: the places where the robot fits (cells whose centre is
farther than its radius plus `START_MARGIN` from every occupied cell, the ground truth's C-free
with a margin) are split into 8-connected regions; regions touching the edge of the map's box are
left out when another exists (they leak out of an unclosed outline); the largest region left is
the one the run explores, and the start is a point well inside it: among its cells with the most
clearance (at least `WELL_INSIDE`, or the region's best when it has none that clear), the one
nearest the region's centroid. Ground truth and coverage then count what the robot can reach from
there (`ground_truth`: reachable is the start's C-free region).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robotexp.errors import WorldError
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import Pose
from robotexp.world.model import World

__all__ = ["START_MARGIN", "StartChoice", "WELL_INSIDE", "default_start"]

START_MARGIN = 0.05         # [m] clearance beyond the robot radius at the start
WELL_INSIDE = 0.75          # [m] clearance of a start "well inside" its region
MAX_CELLS = 4_000_000       # the search grid is coarsened beyond this many cells


@dataclass(frozen=True)
class StartChoice:
    """The default start and why: `area` [m^2] of its region, `regions` found, `edge` True when every
    region touched the map's edge (the map's outline is not closed where the robot fits)."""

    pose: Pose
    area: float
    regions: int
    edge: bool

    def describe(self) -> str:
        """One line: where and why."""
        where = f"({self.pose.x:.2f}, {self.pose.y:.2f}) m"
        why = f"largest of {self.regions} regions where the robot fits, {self.area:.1f} m2"
        if self.edge:
            why += "; every region reaches the map's edge (outline not closed)"
        return f"default start {where}: {why}"


def default_start(world: World, radius: float, *, cell: float = 0.05) -> StartChoice:
    """The start pose of `world` for a robot of `radius` [m] when the map names none (see the module).

    Args:
        world: the world (its static boxes and discs).
        radius: [m] the robot's radius, >= 0.
        cell: [m] the search grid's cell (coarsened so the grid stays under MAX_CELLS).

    Returns:
        The choice: pose (heading 0), region area and count.

    Raises:
        WorldError: nowhere in the map does the robot fit (says the radius).
        ConfigError: the map is too large for any grid (`check_grid_size`).
    """
    from robotexp.mapping.groundtruth import occupancy
    from robotexp.mapping.kernels import clearance_mask, edt_sq, label8

    assert world.bounds is not None
    x0, y0, x1, y1 = world.bounds
    cell = max(cell, math.sqrt(max(x1 - x0, 0.0) * max(y1 - y0, 0.0) / MAX_CELLS))
    geo = GridGeometry.covering(x0, y0, x1, y1, cell)
    occ = occupancy(world, geo)
    fits = clearance_mask(occ, (radius + START_MARGIN) / geo.cell)
    labels, n = label8(fits)
    if n == 0:
        raise WorldError(f"world {world.name!r}: no place where a robot of radius {radius:g} m fits "
                         f"(with {START_MARGIN:g} m to spare): give a start pose or a larger map")
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    sizes[0] = 0
    edge_labels = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    inner = sizes.copy()
    inner[edge_labels] = 0
    edge = not inner.any()
    best = int(np.argmax(sizes if edge else inner))
    region = labels == best
    clear = np.sqrt(edt_sq(occ)) * geo.cell          # [m] to the nearest occupied centre
    clear[~region] = -1.0
    enough = min(WELL_INSIDE, float(clear.max()))
    rows, cols = np.nonzero(clear >= enough)
    rr, cc = np.nonzero(region)
    cr, ccol = rr.mean(), cc.mean()
    k = int(np.argmin((rows - cr) ** 2 + (cols - ccol) ** 2))
    x, y = geo.center_of(int(rows[k]), int(cols[k]))
    return StartChoice(Pose(x, y, 0.0), float(sizes[best]) * geo.cell ** 2, n, edge)

"""`default_start`: where a run starts on a map that names no start pose.

The free place nearest a map's centre can be a closet, a pocket between furniture or the unknown
outside of a laser-built map. Instead: the places where the robot fits, by the ground truth's own
definition (`robotexp.world.clearance.reach_regions`: exact clearance from the obstacle shapes
greater than the robot radius, connected through passages it fits through), are split into their
connected regions; regions touching the edge of the map's box are left out when a closed one of some
size exists (they leak out of an unclosed outline): one of at least `INNER_SHARE` of the largest
region's area or `INNER_AREA` (a pocket among the clutter or noise of a laser map whose building runs
off the image's edge is no building to explore); the largest region left (by area) is the one the run
explores, and the start is a point well inside it: among its cells with the most clearance (at least
`WELL_INSIDE`, or the region's best when it has none that clear), the one nearest the region's
centroid. Ground truth and coverage then count what the robot can reach from there: that region.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robotexp.errors import WorldError
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import Pose
from robotexp.world.model import World
from robotexp.world.rosmap import READ_WRONG

__all__ = ["INNER_AREA", "INNER_SHARE", "StartChoice", "WELL_INSIDE", "chosen_start", "default_start"]

WELL_INSIDE = 0.75          # [m] clearance of a start "well inside" its region
INNER_SHARE = 0.05          # a closed region this share of the largest region's area is preferred to the
INNER_AREA = 100.0          # [m^2] ... or this large: regions that reach the map's edge
MAX_CELLS = 4_000_000       # the search grid is coarsened beyond this many cells
FEW_FREE = 0.1             # a ROS map with less of its area free than this and no room: its image may be read wrong


@dataclass(frozen=True)
class StartChoice:
    """The default start and why: `area` [m^2] of its region, `regions` found, `edge` True when its
    region touches the map's edge (the map's outline is not closed where the robot fits, and no closed region
    large enough exists)."""

    pose: Pose
    area: float
    regions: int
    edge: bool

    def describe(self) -> str:
        """One line: where and why."""
        where = f"({self.pose.x:.2f}, {self.pose.y:.2f}) m"
        why = f"largest of {self.regions} regions where the robot fits, {self.area:.1f} m2"
        if self.edge:
            why += "; it reaches the map's edge (outline not closed)"
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
    from robotexp.world.clearance import clearance, reach_regions, world_index
    from robotexp.world.groundtruth import occupancy

    assert world.bounds is not None
    x0, y0, x1, y1 = world.bounds
    cell = max(cell, math.sqrt(max(x1 - x0, 0.0) * max(y1 - y0, 0.0) / MAX_CELLS))
    geo = GridGeometry.covering(x0, y0, x1, y1, cell)
    occ = occupancy(world, geo)
    index = world_index(world)
    regions = reach_regions(world, geo, radius, occupied=occ, index=index)
    labels = regions.centre_labels()
    n = regions.count
    sizes = regions.area.copy()
    sizes[np.bincount(labels.ravel(), minlength=n + 1) == 0] = 0.0       # no cell centre: no start there
    if n == 0 or not sizes.any():
        free = 1.0 - float(np.count_nonzero(occ)) / max(occ.size, 1)
        hint, ros = "", str(world.source or "").endswith((".yaml", ".yml"))
        if min(x1 - x0, y1 - y0) < 2 * radius:
            hint = f" (the map is {x1 - x0:.3g} x {y1 - y0:.3g} m" + (": is its resolution right?)" if ros else ")")
        elif free < FEW_FREE and ros:
            hint = f" (only {100 * free:.1f} % of the map is free: {READ_WRONG})"
        raise WorldError(f"world {world.name!r}: no place where a robot of radius {radius:g} m fits: "
                         f"give a start pose or a larger map{hint}")
    rim = np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1],
                          regions.coarse[0], regions.coarse[-1], regions.coarse[:, 0], regions.coarse[:, -1]])
    inner = sizes.copy()
    inner[np.unique(rim)] = 0.0
    inner[inner < min(INNER_SHARE * float(sizes.max()), INNER_AREA)] = 0.0
    edge = not inner.any()
    best = int(np.argmax(sizes if edge else inner))
    region = labels == best
    clear = clearance(world, geo, WELL_INSIDE + geo.cell, index=index, occupied=occ, floor=radius)  # region: > radius
    clear[~region] = -1.0
    enough = min(WELL_INSIDE, float(clear.max()))
    rows, cols = np.nonzero(clear >= enough)
    rr, cc = np.nonzero(region)
    cr, ccol = rr.mean(), cc.mean()
    k = int(np.argmin((rows - cr) ** 2 + (cols - ccol) ** 2))
    x, y = geo.center_of(int(rows[k]), int(cols[k]))
    choice = StartChoice(Pose(x, y, 0.0), float(sizes[best]), int(np.count_nonzero(sizes[1:])), edge)
    _CHOSEN[world.name] = choice
    while len(_CHOSEN) > 16:
        del _CHOSEN[next(iter(_CHOSEN))]
    return choice


_CHOSEN: dict[str, StartChoice] = {}


def chosen_start(world_name: str) -> StartChoice | None:
    """The last default start chosen in the world called `world_name` (None: none chosen), to say why."""
    return _CHOSEN.get(world_name)

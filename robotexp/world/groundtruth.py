"""Ground truth of a world on a grid: what is occupied, where the robot can go, what it can see.

`ground_truth()` rasterises a `World` and derives the reachable and explorable cells; `coverage()`
and `map_iou()` score an occupancy grid against it. A cell is reachable when the robot, a disc of
`robot_radius`, fits at some point of the cell (its exact clearance from the world's obstacle shapes
exceeds the radius) connected to the start by such points (`robotexp.world.clearance`: exact
clearance, the free space's border sampled every centimetre). A cell is explorable when it is free and
a laser of `laser_range` sees it from some reachable position (see `ground_truth` for the sampling).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError, WorldError
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.kernels import rasterize, traverse, view_free
from robotexp.robot import Pose
from robotexp.world.clearance import TOL, Regions, clearance_points, reach_regions, world_index
from robotexp.world.model import World
from robotexp.world.raycast import RayIndex, box_extents, parts

if TYPE_CHECKING:
    from robotexp.mapping.grid import OccupancyGrid

__all__ = ["GroundTruth", "coverage", "coverage_inside", "map_iou_tolerant",
           "grid_coverage", "ground_truth", "map_iou", "map_iou_parts", "occupancy",
           "ray_tree"]

RASTER_PART = 1 << 24     # bounding-box cells rasterised per kernel call (`occupancy`)


@dataclass(frozen=True)
class GroundTruth:
    """Bool (rows, cols) grids over `geo` describing one world for one robot and laser.

    Attributes:
        geo: the grid.
        occupied: cells whose square overlaps an obstacle.
        reachable: cells the robot centre can reach from the start (a subset of the free cells).
        explorable: free cells a laser sees from some reachable cell (includes `reachable`).
    """

    geo: GridGeometry
    occupied: npt.NDArray[np.bool_]
    reachable: npt.NDArray[np.bool_]
    explorable: npt.NDArray[np.bool_]

    @property
    def free(self) -> npt.NDArray[np.bool_]:
        """Bool (rows, cols): cells overlapping no obstacle."""
        return ~self.occupied

    @functools.cached_property
    def explorable_cells(self) -> int:
        """How many cells are explorable (counted once)."""
        return int(np.count_nonzero(self.explorable))


def _geo64(geo: GridGeometry) -> GridGeometry:
    """`geo` with float fields as float and counts as int, so kernels compile once."""
    return GridGeometry(float(geo.origin_x), float(geo.origin_y), float(geo.cell), int(geo.rows),
                        int(geo.cols))


def occupancy(world: World, geo: GridGeometry) -> npt.NDArray[np.bool_]:
    """Bool (rows, cols): cells whose square overlaps a static obstacle of `world` with positive area."""
    occ = np.zeros((geo.rows, geo.cols), np.bool_)
    boxes = np.ascontiguousarray(world.boxes, np.float64).reshape(-1, 5)
    discs = np.ascontiguousarray(world.discs, np.float64).reshape(-1, 3)
    # in parts of about RASTER_PART bounding-box cells (long diagonal walls have large boxes): Ctrl-C and
    # signals are handled between them
    ex, ey = box_extents(boxes)
    cells = np.minimum(2 * ex / geo.cell + 2, geo.cols) * np.minimum(2 * ey / geo.cell + 2, geo.rows)
    g64 = _geo64(geo)
    for first, last in parts(np.nan_to_num(cells, nan=1.0, posinf=RASTER_PART), RASTER_PART):
        rasterize(occ, g64, boxes[first:last], discs[:0])
    rasterize(occ, g64, boxes[:0], discs)
    return occ


def _border(region: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """Cells of `region` with a 4-neighbour outside it (or on the grid edge)."""
    padded = np.pad(region, 1, constant_values=False)
    inner = padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:]
    return region & ~inner


def _near(mask: npt.NDArray[np.bool_], reach: int) -> npt.NDArray[np.bool_]:
    """Cells within `reach` cells (Chebyshev distance) of a True cell of `mask`: a box filter done as
    two running sums, linear in the cells whatever `reach` is."""
    out = mask
    for axis in (0, 1):
        n = out.shape[axis]
        sums = np.concatenate([np.zeros_like(out.take([0], axis), np.int32), np.cumsum(out, axis, dtype=np.int32)],
                              axis)
        hi = np.minimum(np.arange(n) + reach + 1, n)
        lo = np.maximum(np.arange(n) - reach, 0)
        out = (sums.take(hi, axis) - sums.take(lo, axis)) > 0
    return out


@functools.lru_cache(maxsize=8)
def ray_tree(n_rays: int, range_cells: float) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """The rays of a laser at a cell centre as a prefix tree of cell offsets, for `view_free`.

    Ray i leaves at angle 2*pi*i/n_rays and runs `range_cells` [cells]; it crosses the cells that
    `traverse` gives. Rays sharing their first cells share those nodes.

    Returns:
        (offsets, skip): int64 (n, 2) (drow, dcol) of the nodes in depth-first order, node 0 being
        (0, 0), and int64 (n,) index of the first node after each node's subtree.
    """
    m = math.ceil(range_cells) + 2
    side = 2 * m + 1
    geo = GridGeometry(float(-m), float(-m), 1.0, side, side)     # viewpoint cell (m, m)
    cells = np.empty((2 * side + 1, 2), np.int64)
    offset: list[tuple[int, int]] = [(0, 0)]
    kids: list[list[int]] = [[]]
    child_of: dict[tuple[int, int, int], int] = {}
    for i in range(n_rays):
        angle = 2.0 * math.pi * i / n_rays
        n, _ = traverse(geo, 0.5, 0.5, math.cos(angle), math.sin(angle), float(range_cells), cells)
        node = 0
        for j in range(1, n):
            key = (node, int(cells[j, 0]) - m, int(cells[j, 1]) - m)
            child = child_of.get(key)
            if child is None:
                child = len(offset)
                child_of[key] = child
                offset.append(key[1:])
                kids.append([])
                kids[node].append(child)
            node = child
    size = [1] * len(offset)
    for node in range(len(offset) - 1, 0, -1):       # children are created after their parents
        for kid in kids[node]:
            size[node] += size[kid]
    size[0] += sum(size[kid] for kid in kids[0])
    offsets = np.empty((len(offset), 2), np.int64)
    skip = np.empty(len(offset), np.int64)
    stack = [0]
    pos = 0
    while stack:
        node = stack.pop()
        offsets[pos] = offset[node]
        skip[pos] = pos + size[node]
        pos += 1
        stack.extend(reversed(kids[node]))
    offsets.flags.writeable = False
    skip.flags.writeable = False
    return offsets, skip


def ground_truth(world: World, geo: GridGeometry, *, robot_radius: float, laser_range: float,
                 start: Pose, n_rays: int = 720, sample_step: float | None = None) -> GroundTruth:
    """Rasterise `world` on `geo` and find the cells reachable and explorable from `start`.

    Reachable is where the robot fits (a disc of `robot_radius` whose centre is farther than the radius
    from every obstacle shape: exact distances, no cell quantisation) connected to the start
    (`robotexp.world.clearance.reach_regions`): the cells whose centre is such a point, and the start
    cell (a cell overlapping an obstacle never counts). A door the robot fits through with a centimetre
    to spare joins the rooms, whatever the cell size. Explorable is the reachable cells plus the
    free cells seen by `n_rays` rays over 360 deg, each stopped by the first occupied cell or at
    `laser_range`, cast from the centres of the viewpoints: the reachable cells whose row and
    column are multiples of k = max(1, round(sample_step / cell)), every reachable cell with a
    4-neighbour outside the reachable region, and the start cell.

    Args:
        world: the world; only its static boxes and discs count.
        geo: the grid.
        robot_radius: [m] radius of the robot footprint (>= 0).
        laser_range: [m] range of the laser (> 0).
        start: the start pose (its heading is ignored).
        n_rays: rays per viewpoint (>= 1).
        sample_step: [m] viewpoint lattice spacing; default 2 cells, rounded to whole cells (>= 1).

    Returns:
        The ground truth.

    Raises:
        ConfigError: a parameter out of range.
        WorldError: the start lies outside the grid, in an obstacle or closer than the radius to one.
    """
    if not robot_radius >= 0:
        raise ConfigError(f"ground truth: robot_radius must be >= 0 m, got {robot_radius}")
    if not laser_range > 0:
        raise ConfigError(f"ground truth: laser_range must be > 0 m, got {laser_range}")
    if n_rays < 1:
        raise ConfigError(f"ground truth: n_rays must be >= 1, got {n_rays}")
    if sample_step is not None and not sample_step > 0:
        raise ConfigError(f"ground truth: sample_step must be > 0 m, got {sample_step}")
    geo = _geo64(geo)
    step = 2 if sample_step is None else max(1, round(sample_step / geo.cell))
    base = _world_grid(world, geo, float(robot_radius))
    occ = base.occupied
    row, col = geo.cell_of(start.x, start.y)
    where = f"world {world.name!r}: start pose ({start.x:g}, {start.y:g}) m"
    if not geo.contains(row, col):
        x1, y1 = geo.origin_x + geo.width, geo.origin_y + geo.height
        raise WorldError(f"{where} is outside the map (x {geo.origin_x:g}..{x1:g} m, "
                         f"y {geo.origin_y:g}..{y1:g} m): pick a start inside it")
    here = np.empty(1)
    index = base.index
    clearance_points(index.shapes, index.starts, index.items, index.origin[0], index.origin[1], index.bucket,
                     index.rows, index.cols, np.array([float(start.x)]), np.array([float(start.y)]),
                     float(robot_radius) + 1.0, here)
    label = base.regions.region_at(start.x, start.y) if here[0] > robot_radius + TOL else 0
    if label == 0:
        raise WorldError(f"{where} is inside an obstacle or closer than the robot radius "
                         f"({robot_radius:g} m) to one: pick a start in open space")
    offsets, skip = ray_tree(int(n_rays), float(laser_range) / geo.cell)
    sight = (step, int(n_rays), float(laser_range))
    part = next((c for c in base.components if c.sight == sight and c.label == label), None)
    if part is None:
        reachable = (base.centres == label) & ~occ
        reachable[row, col] = not occ[row, col]
        views = _border(reachable)
        views[::step, ::step] |= reachable[::step, ::step]
        # a viewpoint sees no further than its rays reach: one with no free cell the robot cannot reach
        # that near adds nothing to the reachable cells (explorable anyway), so it is not cast from
        # (the same ground truth bit for bit; a large open floor costs its border, not its area)
        views &= _near(~occ & ~reachable, int(np.abs(offsets).max()) + 1)
        part = _Component(sight, label, reachable, views,
                          view_free(occ, np.argwhere(views).astype(np.int64), offsets, skip))
        base.components.append(part)
    seen = part.seen
    if not part.views[row, col]:        # the start cell is a viewpoint too: what it sees joins the rest
        seen = seen | view_free(occ, np.array([[row, col]], np.int64), offsets, skip)
    return GroundTruth(geo, occ.copy(), part.reachable.copy(), seen | part.reachable)


@dataclass
class _Component:
    """A reachable region of a world's grid and the free cells seen from its viewpoints (the lattice
    and the border of `ground_truth`, without a start cell)."""

    sight: tuple[int, int, float]           # (lattice step, rays, laser range) they were seen with
    label: int                              # the region's label in `_WorldGrid.regions`
    reachable: npt.NDArray[np.bool_]
    views: npt.NDArray[np.bool_]
    seen: npt.NDArray[np.bool_]


@dataclass
class _WorldGrid:
    """A world rasterised on a grid for one robot radius: its occupied cells, the regions where the
    robot fits, and the reachable regions' sight found so far."""

    occupied: npt.NDArray[np.bool_]
    index: RayIndex
    regions: Regions
    centres: npt.NDArray[np.int32]          # `regions.centre_labels()`
    components: list[_Component]


_GRIDS: dict[tuple[object, ...], _WorldGrid] = {}
_GRIDS_KEPT = 4


def _world_grid(world: World, geo: GridGeometry, robot_radius: float) -> _WorldGrid:
    """The world's occupied cells and regions on `geo`, kept for the next runs in the same world (a
    campaign makes many runs per world: rasterising, the clearance and the sight from a region's
    viewpoints are the same for every start in that region; only the start cell's own view differs,
    and `view_free` of a set of viewpoints is the union of theirs, so the result is the same bit for bit)."""
    boxes = np.ascontiguousarray(world.boxes, np.float64)
    discs = np.ascontiguousarray(world.discs, np.float64)
    key = (tuple(geo), robot_radius, boxes.shape, boxes.tobytes(), discs.shape, discs.tobytes())
    grid = _GRIDS.pop(key, None)
    if grid is None:
        occ = occupancy(world, geo)
        index = world_index(world)
        regions = reach_regions(world, geo, robot_radius, occupied=occ, index=index)
        grid = _WorldGrid(occ, index, regions, regions.centre_labels(), [])
    _GRIDS[key] = grid                      # most recently used last
    while len(_GRIDS) > _GRIDS_KEPT:
        del _GRIDS[next(iter(_GRIDS))]
    return grid


def _check_shape(name: str, grid: npt.NDArray[np.generic], gt: GroundTruth) -> None:
    """Raise ConfigError when `grid` is not (rows, cols) of the ground truth."""
    if grid.shape != gt.occupied.shape:
        raise ConfigError(f"{name}: the map is {grid.shape} cells but the ground truth is "
                          f"{gt.occupied.shape}: build both on the same GridGeometry")


def coverage(grid_free: npt.NDArray[np.bool_], gt: GroundTruth) -> float:
    """Share in [0, 1] of the explorable cells that `grid_free` (rows, cols) bool marks free.

    1.0 when nothing is explorable. Raises ConfigError when the shapes differ.
    """
    _check_shape("coverage", grid_free, gt)
    total = int(np.count_nonzero(gt.explorable))
    if total == 0:
        return 1.0
    return int(np.count_nonzero(grid_free & gt.explorable)) / total


def coverage_inside(grid_free: npt.NDArray[np.bool_], gt: GroundTruth, cells: int = 1) -> float:
    """`coverage` of the explorable cells farther than `cells` cells (chessboard distance) from every
    obstacle cell: how much of the floor was explored, with the cells along the faces left out. A
    diagnostic for maps made from coarser or later scans than the simulator's (whole-centimetre ranges,
    a pose a packet behind the scan): on a world whose faces lie on cell borders their hits land a cell
    short of a face, and the free cell in front of it reads occupied however small the error.

    1.0 when no such cell is explorable. Raises ConfigError when the shapes differ.
    """
    _check_shape("coverage", grid_free, gt)
    inside = gt.explorable & ~_grow(gt.occupied, cells)
    total = int(np.count_nonzero(inside))
    if total == 0:
        return 1.0
    return int(np.count_nonzero(grid_free & inside)) / total


def grid_coverage(grid: OccupancyGrid, gt: GroundTruth) -> float:
    """`coverage` of the free cells of `grid`, counted in the window of the cells scans touched
    (`OccupancyGrid.touched_box`; every cell outside it is unknown): the same share at a cost that
    follows the explored part of the map, not its size.

    Raises:
        ConfigError: the shapes differ.
    """
    _check_shape("coverage", grid.values, gt)
    total = gt.explorable_cells
    if total == 0:
        return 1.0
    box = grid.touched_box()
    if box is None:
        return 0.0
    r0, r1, c0, c1 = box
    return int(np.count_nonzero(grid.window(r0, r1, c0, c1).free() & gt.explorable[r0:r1, c0:c1])) / total


def _iou(hits: int, union: int) -> float:
    return 1.0 if union == 0 else hits / union


def map_iou(grid_states: npt.NDArray[np.int8], gt: GroundTruth) -> float:
    """Mean of the occupied and free intersection-over-union of a map against the ground truth.

    The targets are what a laser can observe: free target F = `gt.explorable`, occupied target
    O = occupied cells with an 8-neighbour in F. With M_occ = (states == 100), M_free = (states == 0):

        IoU_occ  = |M_occ ∩ occupied| / |M_occ ∪ O|
        IoU_free = |M_free ∩ free|    / |M_free ∪ F|
        map_iou  = (IoU_occ + IoU_free) / 2

    A right mark outside the target (say, the inside of a thick wall) counts in both numerator and
    denominator, a wrong one only in the denominator; an empty union scores 1. The result is 1
    exactly when every target is mapped and no mark is wrong.

    Args:
        grid_states: int8 (rows, cols) map states: -1 unknown, 0 free, 100 occupied.
        gt: the ground truth.

    Returns:
        The score in [0, 1].

    Raises:
        ConfigError: the shapes differ.
    """
    iou_occ, iou_free = map_iou_parts(grid_states, gt)
    return 0.5 * (iou_occ + iou_free)


def map_iou_parts(grid_states: npt.NDArray[np.int8], gt: GroundTruth) -> tuple[float, float]:
    """The two halves of `map_iou`: (IoU_occ, IoU_free), as defined there.

    Raises:
        ConfigError: the shapes differ.
    """
    return _parts(grid_states, gt, 0, "map_iou")


def _grow(mask: npt.NDArray[np.bool_], cells: int) -> npt.NDArray[np.bool_]:
    """`mask` grown by `cells` in the chessboard metric (a (2 cells + 1)-square around each cell)."""
    if cells == 0:
        return mask
    padded = np.pad(mask, cells, constant_values=False)
    rows, cols = mask.shape
    out = np.zeros_like(mask)
    for dr in range(2 * cells + 1):
        for dc in range(2 * cells + 1):
            out |= padded[dr:dr + rows, dc:dc + cols]
    return out


def _parts(grid_states: npt.NDArray[np.int8], gt: GroundTruth, cells: int, name: str) -> tuple[float, float]:
    """(IoU_occ, IoU_free) with a tolerance of `cells` cells (`map_iou_tolerant`; 0: `map_iou`'s)."""
    _check_shape(name, grid_states, gt)
    m_occ = grid_states == 100
    m_free = grid_states == 0
    target_occ = gt.occupied & _grow(gt.explorable, 1)     # occupied cells with an explorable 8-neighbour
    iou_occ = _iou(int(np.count_nonzero(m_occ & _grow(gt.occupied, cells))),
                   int(np.count_nonzero(m_occ)) + int(np.count_nonzero(target_occ & ~_grow(m_occ, cells))))
    iou_free = _iou(int(np.count_nonzero(m_free & _grow(~gt.occupied, cells))),
                    int(np.count_nonzero(m_free)) + int(np.count_nonzero(gt.explorable & ~_grow(m_free, cells))))
    return iou_occ, iou_free


def map_iou_tolerant(grid_states: npt.NDArray[np.int8], gt: GroundTruth, cells: int = 1) -> tuple[float, float, float]:
    r"""`map_iou` with a tolerance of `cells` cells: a mark is right when the truth it claims lies within
    `cells` cells of it (chessboard distance), and a target is found when a mark of its kind lies that
    close. A diagnostic for maps made at an estimated pose: on a world whose faces lie on cell borders
    a pose a few millimetres off moves a face's hits into the free cell in front of it, which `map_iou`
    counts twice (a wrong mark, a missed target) however small the error (docs/localization).

    With M_occ, M_free, O and F as in `map_iou`, G the occupied cells and D(X) the cells within `cells`
    of X:

        IoU_occ  = |M_occ ∩ D(G)|  / (|M_occ|  + |O \ D(M_occ)|)
        IoU_free = |M_free ∩ D(~G)| / (|M_free| + |F \ D(M_free)|)

    With `cells` = 0 these are `map_iou_parts` (|A ∪ B| = |A| + |B \ A|): both are `_parts`.

    Returns:
        (mean, IoU_occ, IoU_free), each in [0, 1].

    Raises:
        ConfigError: the shapes differ, or `cells` < 0.
    """
    _check_shape("map_iou_tolerant", grid_states, gt)
    if cells < 0:
        raise ConfigError(f"map_iou_tolerant: cells must be >= 0, got {cells}")
    iou_occ, iou_free = _parts(grid_states, gt, cells, "map_iou_tolerant")
    return 0.5 * (iou_occ + iou_free), iou_occ, iou_free

"""`GridGeometry`: where a grid lies in the world. Shared by maps, ground truth and planners."""

from __future__ import annotations

import math
import os
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError

__all__ = ["BYTES_PER_CELL", "MAX_CELLS", "GridGeometry", "check_grid_size", "memory_limit"]

# [bytes] what a run holds per map cell, about: the occupancy grid (values, stamps, states), the
# ground truth (occupied, clearance, reachable, explorable, viewpoints) and a planner's float64
# cost and distance grids with their temporaries
BYTES_PER_CELL = 64
MAX_CELLS = 25_000_000      # 50 x 50 m at 1 cm: beyond, the ground truth alone takes many minutes


def memory_limit() -> int:
    """[bytes] the most a run's grids may take: half of this machine's physical memory."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")) // 2
    except (ValueError, OSError, AttributeError):
        return 4 << 30


def _human(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} TB"    # pragma: no cover


def check_grid_size(width: float, height: float, cell: float, what: str = "map") -> None:
    """Refuse, before anything is allocated, a grid of `cell` [m] over `width` x `height` [m] of more
    than `MAX_CELLS` cells or that cannot fit in `memory_limit()` at `BYTES_PER_CELL`.

    Raises:
        ConfigError: one line with the cell count and the memory it would need.
    """
    if not (math.isfinite(width) and math.isfinite(height) and width >= 0 and height >= 0):
        raise ConfigError(f"{what}: extent {width:g} x {height:g} m is not finite, expected a map of "
                          "finite size (check the map's coordinates, origin and resolution)")
    if not (math.isfinite(cell) and cell > 0):
        raise ConfigError(f"{what}: cell size {cell:g} m, expected a positive size")
    cells = max(math.ceil(width / cell), 1.0) * max(math.ceil(height / cell), 1.0) if width / cell < 1e150 \
        and height / cell < 1e150 else math.inf
    need, memory = cells * BYTES_PER_CELL, memory_limit()
    if need > memory or cells > MAX_CELLS:
        limit = (f"limit {MAX_CELLS:.3g} cells" if need <= memory else
                 f"limit {_human(memory)}, half of this machine's")
        raise ConfigError(f"{what}: {width:.6g} x {height:.6g} m at cells of {cell * 1000:g} mm is {cells:.3g} "
                          f"cells, which would need about {_human(need)} of memory ({limit}): use a larger "
                          "cell or smaller bounds")


class GridGeometry(NamedTuple):
    """A rows x cols grid of square cells; row 0 is the bottom (smallest y), col 0 the left.

    Cell (r, c) covers x in [origin_x + c*cell, origin_x + (c+1)*cell) and
    y in [origin_y + r*cell, origin_y + (r+1)*cell). A NamedTuple so numba kernels take it as is.
    """

    origin_x: float  # [m] world x of the lower-left corner of cell (0, 0)
    origin_y: float  # [m]
    cell: float      # [m] side of one cell
    rows: int
    cols: int

    @classmethod
    def covering(cls, xmin: float, ymin: float, xmax: float, ymax: float, cell: float,
                 margin: float = 0.0) -> GridGeometry:
        """The smallest grid of `cell`-sized cells, aligned on multiples of `cell`, over the box.

        Raises:
            ConfigError: the box is not finite or the grid cannot fit in memory (`check_grid_size`).
        """
        check_grid_size(xmax - xmin + 2 * margin, ymax - ymin + 2 * margin, cell)
        if not all(math.isfinite(v) for v in (xmin, ymin, xmax, ymax, margin)):
            raise ConfigError(f"map: bounds ({xmin:g}, {ymin:g}, {xmax:g}, {ymax:g}) m are not finite, "
                              "expected finite coordinates")
        ox = math.floor((xmin - margin) / cell) * cell
        oy = math.floor((ymin - margin) / cell) * cell
        cols = int(math.ceil((xmax + margin - ox) / cell - 1e-9))
        rows = int(math.ceil((ymax + margin - oy) / cell - 1e-9))
        return cls(float(ox), float(oy), float(cell), max(rows, 1), max(cols, 1))

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell holding world point (x, y); may lie outside the grid."""
        return (int(math.floor((y - self.origin_y) / self.cell)),
                int(math.floor((x - self.origin_x) / self.cell)))

    def center_of(self, row: int, col: int) -> tuple[float, float]:
        """World (x, y) [m] of the centre of cell (row, col)."""
        return (self.origin_x + (col + 0.5) * self.cell, self.origin_y + (row + 0.5) * self.cell)

    def cells_of(self, points: npt.ArrayLike) -> npt.NDArray[np.intp]:
        """(k, 2) int (row, col) of the cells holding the (k, 2) world points [m]; may lie outside."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        return np.column_stack([np.floor((p[:, 1] - self.origin_y) / self.cell),
                                np.floor((p[:, 0] - self.origin_x) / self.cell)]).astype(np.intp)

    def centers_of(self, cells: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """(k, 2) world (x, y) [m] of the centres of the (k, 2) (row, col) cells."""
        rc = np.asarray(cells).reshape(-1, 2)
        return np.column_stack([self.origin_x + (rc[:, 1] + 0.5) * self.cell,
                                self.origin_y + (rc[:, 0] + 0.5) * self.cell])

    def disc_box(self, x: float, y: float, radius: float,
                 within: tuple[int, int, int, int] | None = None) -> tuple[int, int, int, int] | None:
        """(r0, r1, c0, c1): the rows r0..r1-1 and columns c0..c1-1 of the cells holding the square around the
        disc of `radius` [m] about (`x`, `y`) [m], cut to `within` (r0, r1, c0, c1; default the whole grid);
        None when nothing is left."""
        b0, b1, d0, d1 = within if within is not None else (0, self.rows, 0, self.cols)
        r0, c0 = self.cell_of(x - radius, y - radius)
        r1, c1 = self.cell_of(x + radius, y + radius)
        r0, c0, r1, c1 = max(r0, b0), max(c0, d0), min(r1 + 1, b1), min(c1 + 1, d1)
        return None if r1 <= r0 or c1 <= c0 else (r0, r1, c0, c1)

    def reach_box(self, xy: npt.ArrayLike, reach: float) -> tuple[int, int, int, int] | None:
        """(r0, r1, c0, c1): the rows r0..r1-1 and columns c0..c1-1 of the cells within `reach` [m] of the (k, 2)
        world points `xy` [m] (their bounding box grown by `reach` and a cell of slack), cut to the grid; None
        when nothing is left."""
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        c0 = max(math.floor((p[:, 0].min() - reach - self.origin_x) / self.cell) - 1, 0)
        c1 = min(math.ceil((p[:, 0].max() + reach - self.origin_x) / self.cell) + 1, self.cols)
        r0 = max(math.floor((p[:, 1].min() - reach - self.origin_y) / self.cell) - 1, 0)
        r1 = min(math.ceil((p[:, 1].max() + reach - self.origin_y) / self.cell) + 1, self.rows)
        return None if r1 <= r0 or c1 <= c0 else (r0, r1, c0, c1)

    def part(self, box: tuple[int, int, int, int]) -> GridGeometry:
        """The geometry of the cells of `box` (r0, r1, c0, c1) alone: their cell (0, 0) is this grid's (r0, c0)."""
        r0, r1, c0, c1 = box
        return GridGeometry(self.origin_x + c0 * self.cell, self.origin_y + r0 * self.cell, self.cell, r1 - r0, c1 - c0)

    def disc_mask(self, box: tuple[int, int, int, int], x: float, y: float, radius: float) -> npt.NDArray[np.bool_]:
        """Bool (r1 - r0, c1 - c0): the cells of `box` (r0, r1, c0, c1, e.g. `disc_box`'s) whose centres lie
        within `radius` [m] of (`x`, `y`) [m]."""
        r0, r1, c0, c1 = box
        cy = self.origin_y + (np.arange(r0, r1) + 0.5) * self.cell
        cx = self.origin_x + (np.arange(c0, c1) + 0.5) * self.cell
        return np.asarray(np.hypot(cx[None, :] - x, cy[:, None] - y) <= radius)

    def contains(self, row: int, col: int) -> bool:
        """True when (row, col) is inside the grid."""
        return 0 <= row < self.rows and 0 <= col < self.cols

    def contains_cells(self, cells: npt.ArrayLike) -> npt.NDArray[np.bool_]:
        """Bool (k,): which of the (k, 2) (row, col) cells are inside the grid."""
        rc = np.asarray(cells).reshape(-1, 2)
        return np.asarray((rc[:, 0] >= 0) & (rc[:, 0] < self.rows) & (rc[:, 1] >= 0) & (rc[:, 1] < self.cols))

    @property
    def width(self) -> float:
        """[m] extent along x."""
        return self.cols * self.cell

    @property
    def height(self) -> float:
        """[m] extent along y."""
        return self.rows * self.cell

"""`GridGeometry`: where a grid lies in the world. Shared by maps, ground truth and planners."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

__all__ = ["GridGeometry"]


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
        """The smallest grid of `cell`-sized cells, aligned on multiples of `cell`, over the box."""
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

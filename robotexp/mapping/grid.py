"""`OccupancyGrid`: the map a robot builds from its laser, as log-odds (UFMG) or HIMM (BVP).

Log-odds: prior 0 (p = 0.5); a beam adds l_free = logit(p_free) to the cells it crosses and
l_occ = logit(p_occ) to its end cell when it hit something; values are clamped to +-l_clamp.
A cell is occupied when l > 0, free when l < 0, unknown when l == 0 (never seen, or cancelled:
with p_free = 1 - p_occ one hit and one pass cancel exactly). Within one scan each cell is
updated at most once and a hit wins over the beams crossing its cell (see the kernels).

HIMM (Borenstein & Koren 1991): certainty 0..15 (uint8), -1 on the beam (floor 0), +3 at a hit
(cap 15). A cell is occupied when its certainty is > 2, free when seen and <= 2, unknown when
never seen.
"""

from __future__ import annotations

import math
from typing import Literal, Self, cast

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.kernels import (
    LogOddsModel,
    frontier_mask,
    integrate_scan_himm,
    integrate_scan_logodds,
    label8,
    merge_boxes,
    note_hits,
    nudged_ranges,
)
from robotexp.robot import LaserScan, Pose

__all__ = ["HIMM_MAX", "HIMM_OCCUPIED", "OccupancyGrid"]

HIMM_MAX = 15        # certainty cap
HIMM_OCCUPIED = 2    # a certainty above this is occupied

# HIMM certainty -> probability: free 0..2 -> 0, 0.05, 0.10; occupied 3..15 -> 0.70..1.00 linearly,
# so the ROS thresholds (free < 0.196, occupied > 0.65) give back the same three states.
_HIMM_P = np.array([0.0, 0.05, 0.10] + [0.7 + 0.3 * (c - 3) / 12 for c in range(3, 16)], np.float32)


HIT_DEPTH = 1e-4   # [m] see OccupancyGrid.update


def _logit(p: float) -> float:
    return math.log(p / (1.0 - p))


class OccupancyGrid:
    """An occupancy grid over `geo`, updated in place by laser scans.

    Attributes:
        geo: the grid geometry (row 0 at the bottom).
        model: "logodds" or "himm".
        values: the cell values, (rows, cols): float32 log-odds, or uint8 HIMM certainty.
        stamp: int32 (rows, cols), the last scan (or mark) that touched each cell, 0 = never;
            `seen` is stamp > 0.
        hit_box: uint8 (rows, cols, 4), per cell the box of the laser endpoints that fell in it
            (x_lo, x_hi, y_lo, y_hi in 1/255 of the cell's side from its lower-left corner, rounded
            outwards; x_lo > x_hi: none yet): where in an occupied cell the obstacle's surface lies,
            finer than the cell (`robotexp.planning.targets.WallDistance` measures to it).
        scans: the number of scans and marks so far, which is also the id of the last one.
        cells_updated: cell updates so far (a cell counts once per scan or mark that touched it).
        range_max: [m] cap on the sensor model's range, or None to use each scan's `range_max`.
        l_occ: log-odds added at a hit, logit(p_occ) rounded to float32.
        l_free: log-odds added on a crossed cell, logit(p_free) rounded to float32.
        l_clamp: log-odds bound (values stay in [-l_clamp, l_clamp]).
    """

    def __init__(self, geo: GridGeometry, *, model: Literal["logodds", "himm"] = "logodds",
                 p_occ: float = 0.9, p_free: float = 0.1, l_clamp: float = 3.5,
                 range_max: float | None = None) -> None:
        """Make an empty grid (every cell unknown).

        Args:
            geo: the grid geometry; cell > 0, rows and cols >= 1.
            model: "logodds" or "himm".
            p_occ: log-odds model: probability of occupancy after a hit, in (0.5, 1).
            p_free: log-odds model: probability of occupancy of a crossed cell, in (0, 0.5).
            l_clamp: log-odds model: values stay in [-l_clamp, l_clamp]; > 0.
            range_max: [m] beams at or beyond min(range_max, scan.range_max) record no hit;
                None uses the scan's own range_max; > 0.

        Raises:
            ConfigError: a parameter out of range.
        """
        if not (geo.cell > 0 and geo.rows >= 1 and geo.cols >= 1):
            raise ConfigError(f"occupancy grid: need cell > 0 m and rows, cols >= 1, got {geo}")
        if model not in ("logodds", "himm"):
            raise ConfigError(f"occupancy grid: model must be 'logodds' or 'himm', got {model!r}")
        if not 0.5 < p_occ < 1.0:
            raise ConfigError(f"occupancy grid: p_occ must be in (0.5, 1), got {p_occ}")
        if not 0.0 < p_free < 0.5:
            raise ConfigError(f"occupancy grid: p_free must be in (0, 0.5), got {p_free}")
        if not l_clamp > 0:
            raise ConfigError(f"occupancy grid: l_clamp must be > 0, got {l_clamp}")
        if range_max is not None and not range_max > 0:
            raise ConfigError(f"occupancy grid: range_max must be > 0 m or None, got {range_max}")
        self.geo = GridGeometry(float(geo.origin_x), float(geo.origin_y), float(geo.cell),
                                int(geo.rows), int(geo.cols))
        self.model = model
        self.range_max = range_max
        self.p_free = float(p_free)      # as given (a recording keeps it, to map its scans again alike)
        # Rounded to float32, the grid's type, so that with p_free = 1 - p_occ a hit and a pass
        # cancel exactly and the cell is unknown again.
        self.l_occ = float(np.float32(_logit(p_occ)))
        self.l_free = float(np.float32(_logit(p_free)))
        self.l_clamp = float(np.float32(l_clamp))
        shape = (self.geo.rows, self.geo.cols)
        self.values: npt.NDArray[np.float32] | npt.NDArray[np.uint8]
        if model == "logodds":
            self.values = np.zeros(shape, np.float32)
        else:
            self.values = np.zeros(shape, np.uint8)
        self.stamp: npt.NDArray[np.int32] = np.zeros(shape, np.int32)   # last scan id per cell, 0 = never
        self.hit_box: npt.NDArray[np.uint8] = np.zeros(shape + (4,), np.uint8)
        self.hit_box[:, :, 0] = 255                      # no endpoint yet (x_lo > x_hi)
        self.scans = 0
        self.cells_updated = 0
        self.box: tuple[int, int, int, int] | None = None   # see touched_box
        self._changes = np.zeros((64, 4), np.int32)   # per scan or mark (row scans - 1): the box it touched, grown
        #                                                by doubling (see changed_box)

    @property
    def seen(self) -> npt.NDArray[np.bool_]:
        """(rows, cols) bool: cells some beam has touched."""
        return self.stamp > 0

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols)."""
        return (self.geo.rows, self.geo.cols)

    def update(self, pose: Pose, scan: LaserScan) -> int:
        """Integrate one laser scan taken at robot pose `pose`; return the cell updates it made.

        The sensor sits `scan.offset_x` [m] ahead of the robot centre along the heading; beam
        angles are relative to the heading. NaN ranges are skipped; a scan from a pose not finite changes
        nothing (it is counted in `scans`).

        Raises:
            ConfigError: `scan.angles` and `scan.ranges` differ in shape.
        """
        angles = np.ascontiguousarray(scan.angles, np.float64)
        ranges = np.ascontiguousarray(scan.ranges, np.float64)
        if angles.shape != ranges.shape or angles.ndim != 1:
            raise ConfigError(f"occupancy grid update: scan angles {angles.shape} and ranges "
                              f"{ranges.shape} must be equal 1-D shapes")
        rmax = float(scan.range_max if self.range_max is None else min(self.range_max, scan.range_max))
        # A hit lies on the obstacle's surface; when that surface is a cell border, rounding in the
        # sensor's arithmetic puts half the hits in the free cell in front of it. Nudging hits
        # HIT_DEPTH [m] into the obstacle puts them in the obstacle's cell.
        measured = ranges
        ranges = nudged_ranges(ranges, rmax, HIT_DEPTH)
        sensor = np.array([*scan.origin(pose), pose.theta], np.float64)
        self.scans += 1
        if not (math.isfinite(sensor[0]) and math.isfinite(sensor[1]) and math.isfinite(sensor[2])):
            self._note(0, 0, 0, 0)          # a pose not known: the scan changes nothing
            return 0
        self._note(*note_hits(self.hit_box, self.geo, sensor, angles, measured, ranges, rmax))
        if self.model == "logodds":
            lm = LogOddsModel(self.l_free, self.l_occ, -self.l_clamp, self.l_clamp, rmax)
            logodds = cast("npt.NDArray[np.float32]", self.values)
            n = integrate_scan_logodds(logodds, self.stamp, self.scans, self.geo, sensor, angles, ranges, lm)
        else:
            cert = cast("npt.NDArray[np.uint8]", self.values)
            n = integrate_scan_himm(cert, self.stamp, self.scans, self.geo, sensor, angles, ranges, rmax)
        self.cells_updated += int(n)
        return int(n)

    def touched_box(self) -> tuple[int, int, int, int] | None:
        """Rows r0..r1 and columns c0..c1 (half-open) that hold every cell a scan or mark has touched so far
        (a scan's box is the box of its beams, so the box may be a little larger); None before the first.

        Every cell outside it is unknown: whole-map work (planning, frontier, potentials) can be done
        on `window` of this box grown by a margin, at a cost that follows the explored part of the
        map, not the map.
        """
        return self.box

    def changed_box(self, since: int) -> tuple[int, int, int, int] | None:
        """Rows r0..r1 and columns c0..c1 (half-open) holding every cell the scans and marks after the
        `since`-th (`scans` counts them) may have changed; None when none did.

        A consumer that keeps something derived from the map (costs, an inflation) remembers `scans`
        and recomputes only near this box at its next update.
        """
        since = max(since, 0)
        if since == self.scans - 1:         # one scan (every step of a run): no array reductions
            r0, r1, c0, c1 = self._changes[since].tolist()
            return (r0, r1, c0, c1) if r1 > r0 else None
        a = self._changes[since:self.scans]
        a = a[a[:, 1] > a[:, 0]]
        if len(a) == 0:
            return None
        return int(a[:, 0].min()), int(a[:, 1].max()), int(a[:, 2].min()), int(a[:, 3].max())

    def changed_boxes(self, since: int, grow: int = 0) -> list[tuple[int, int, int, int]]:
        """The cells `changed_box` holds, as separate boxes: each scan's or mark's box after the `since`-th,
        those whose boxes grown by `grow` cells overlap or touch merged into their bounding box (repeatedly,
        so no two of the boxes returned do); [] when none changed.

        Several robots mapping one grid far apart change a few small boxes; their single bounding box
        would be most of the map. A consumer that recomputes near what changed, `grow` cells around it,
        does the work of these boxes instead.
        """
        since = max(since, 0)
        if since == self.scans - 1:
            box = self.changed_box(since)
            return [] if box is None else [box]
        return [(r0, r1, c0, c1) for r0, r1, c0, c1 in merge_boxes(self._changes[since:self.scans], int(grow)).tolist()]

    def window(self, r0: int, r1: int, c0: int, c1: int) -> OccupancyGrid:
        """The rows r0..r1 and columns c0..c1 (half-open, clipped to the grid) as an `OccupancyGrid` that
        shares this grid's arrays (views, not copies): its cell (0, 0) is this grid's (r0, c0).

        Use it for the states (`occupied`, `free`, `frontier`, ...) of a part of the map; convert world
        points to cells with this grid's `geo` and subtract (r0, c0): the window's `geo.origin_*` are
        rounded sums and may place a point on a cell border in the other cell.

        Raises:
            ConfigError: the clipped window is empty.
        """
        rows, cols = self.shape
        r0, r1, c0, c1 = max(r0, 0), min(r1, rows), max(c0, 0), min(c1, cols)
        if r1 <= r0 or c1 <= c0:
            raise ConfigError(f"occupancy grid window: rows {r0}..{r1}, cols {c0}..{c1} hold no cell of the "
                              f"{rows} x {cols} grid")
        other = object.__new__(type(self))
        other.__dict__.update(self.__dict__)
        g = self.geo
        other.geo = GridGeometry(g.origin_x + c0 * g.cell, g.origin_y + r0 * g.cell, g.cell, r1 - r0, c1 - c0)
        other.values = self.values[r0:r1, c0:c1]
        other.stamp = self.stamp[r0:r1, c0:c1]
        other.hit_box = self.hit_box[r0:r1, c0:c1]
        other._changes = np.zeros((64, 4), np.int32)   # a window keeps no history: ask the grid (its numbers)
        other.box = None if self.box is None else (
            max(self.box[0] - r0, 0), max(min(self.box[1] - r0, r1 - r0), 0),
            max(self.box[2] - c0, 0), max(min(self.box[3] - c0, c1 - c0), 0))
        return other

    def _note(self, r0: int, r1: int, c0: int, c1: int) -> None:
        """Log rows r0..r1, columns c0..c1 (half-open; clipped to the grid) as the box of the latest scan
        or mark, and grow `box` by it."""
        rows, cols = self.shape
        r0, r1, c0, c1 = max(r0, 0), min(r1, rows), max(c0, 0), min(c1, cols)
        if self.scans > len(self._changes):
            self._changes = np.concatenate([self._changes, np.zeros_like(self._changes)])
        if r1 <= r0 or c1 <= c0:
            self._changes[self.scans - 1] = 0
            return
        self._changes[self.scans - 1] = (r0, r1, c0, c1)
        if self.box is not None:
            b = self.box
            r0, r1, c0, c1 = min(r0, b[0]), max(r1, b[1]), min(c0, b[2]), max(c1, b[3])
        self.box = (r0, r1, c0, c1)

    def occupied(self) -> npt.NDArray[np.bool_]:
        """Bool (rows, cols): occupied cells (log-odds > 0; HIMM certainty > 2)."""
        if self.model == "logodds":
            return self.values > 0
        return self.values > HIMM_OCCUPIED

    def firmly_occupied(self, box: tuple[int, int, int, int] | None = None) -> npt.NDArray[np.bool_]:
        """Bool (rows, cols): cells occupied by at least two hits more than crossing beams
        (log-odds >= min(2 l_occ, l_clamp); HIMM certainty >= 6). A hit that a scan taken from a
        slightly wrong pose put beside a wall is one hit, which the next beams through it undo.
        With `box` = (r0, r1, c0, c1) (half-open), only those rows and columns."""
        v = self.values if box is None else self.values[box[0]:box[1], box[2]:box[3]]
        if self.model == "logodds":
            return v >= np.float32(min(2.0 * self.l_occ, self.l_clamp))
        return v >= 2 * 3

    def near_occupied(self) -> npt.NDArray[np.bool_]:
        """Bool (rows, cols): occupied cells and their 8-neighbours (a frontier cell here is the face
        of a wall, not an opening)."""
        occ = self.occupied()
        near = occ.copy()
        near[1:, :] |= occ[:-1, :]
        near[:-1, :] |= occ[1:, :]
        near[:, 1:] |= near[:, :-1].copy()
        near[:, :-1] |= near[:, 1:].copy()
        return near

    def free(self) -> npt.NDArray[np.bool_]:
        """Bool (rows, cols): free cells (log-odds < 0; HIMM seen with certainty <= 2)."""
        if self.model == "logodds":
            return self.values < 0
        return self.seen & (self.values <= HIMM_OCCUPIED)

    def unknown(self) -> npt.NDArray[np.bool_]:
        """Bool (rows, cols): unknown cells (log-odds == 0; HIMM never seen)."""
        if self.model == "logodds":
            return self.values == 0
        return ~self.seen

    def states(self) -> npt.NDArray[np.int8]:
        """Int8 (rows, cols) in the ROS convention: -1 unknown, 0 free, 100 occupied."""
        out = np.full(self.shape, -1, np.int8)
        out[self.free()] = 0
        out[self.occupied()] = 100
        return out

    def probability(self) -> npt.NDArray[np.float32]:
        """Float32 (rows, cols) probability of occupancy; 0.5 for unknown cells.

        Log-odds: 1 / (1 + exp(-l)). HIMM: certainty 0, 1, 2 -> 0, 0.05, 0.10 and 3..15 ->
        0.70..1.00 linearly, so the ROS map thresholds (0.196, 0.65) give back `states()`.
        """
        if self.model == "logodds":
            return (1.0 / (1.0 + np.exp(-self.values))).astype(np.float32)
        return np.where(self.seen, _HIMM_P[self.values], np.float32(0.5)).astype(np.float32)

    def frontier(self) -> npt.NDArray[np.bool_]:
        """Bool (rows, cols): free cells with an unknown 4-neighbour."""
        return frontier_mask(self.free(), self.unknown())

    def frontier_groups(self, min_cells: int = 1) -> list[npt.NDArray[np.int64]]:
        """The 8-connected groups of frontier cells with at least `min_cells` cells.

        Returns:
            One int64 (k, 2) array of (row, col) per group, in row-major order inside a group;
            groups ordered by their first cell in row-major order.

        Raises:
            ConfigError: `min_cells` < 1.
        """
        if min_cells < 1:
            raise ConfigError(f"frontier_groups: min_cells must be >= 1, got {min_cells}")
        labels, k = label8(self.frontier())
        if k == 0:
            return []
        cells = np.argwhere(labels > 0)
        order = labels[cells[:, 0], cells[:, 1]]
        sort = np.argsort(order, kind="stable")
        cells, order = cells[sort], order[sort]
        bounds = np.searchsorted(order, np.arange(1, k + 2))
        groups = [cells[bounds[i]:bounds[i + 1]].astype(np.int64) for i in range(k)]
        return [g for g in groups if len(g) >= min_cells]

    def _mask(self, mask: npt.NDArray[np.bool_], what: str) -> npt.NDArray[np.bool_]:
        m = np.asarray(mask)
        if m.shape != self.shape or m.dtype != np.bool_:
            raise ConfigError(f"occupancy grid {what}: mask must be bool {self.shape}, "
                              f"got {m.dtype} {m.shape}")
        return m

    def mark_free(self, mask: npt.NDArray[np.bool_]) -> None:
        """Set the cells of `mask` (rows, cols) bool to certainly free (-l_clamp; HIMM 0).

        Raises:
            ConfigError: `mask` is not a bool array of the grid's shape.
        """
        self._mark(0, 0, self._mask(mask, "mark_free"), -self.l_clamp if self.model == "logodds" else 0)

    def mark_free_disc(self, x: float, y: float, radius: float) -> int:
        """Set the unknown cells whose centres lie within `radius` [m] of (`x`, `y`) [m] to certainly free (as
        `mark_free`): where a robot stands is free space, though no beam may have crossed it (the robot's
        body hides it from its teammates' lasers). Counted as a mark only when some cell was unknown;
        returns how many cells it set."""
        if not (math.isfinite(x) and math.isfinite(y) and radius > 0):
            return 0
        box = self.geo.disc_box(x, y, radius)
        if box is None:
            return 0
        r0, r1, c0, c1 = box
        unknown = self.values[r0:r1, c0:c1] == 0 if self.model == "logodds" else self.stamp[r0:r1, c0:c1] == 0
        if not unknown.any():
            return 0
        cells = unknown & self.geo.disc_mask(box, x, y, radius)
        if not cells.any():
            return 0
        return self._mark(r0, c0, cells, -self.l_clamp if self.model == "logodds" else 0)

    def mark_occupied(self, mask: npt.NDArray[np.bool_]) -> None:
        """Set the cells of `mask` (rows, cols) bool to certainly occupied (+l_clamp; HIMM 15).

        Raises:
            ConfigError: `mask` is not a bool array of the grid's shape.
        """
        self._mark(0, 0, self._mask(mask, "mark_occupied"), self.l_clamp if self.model == "logodds" else HIMM_MAX)

    def copy(self) -> Self:
        """An independent copy (arrays copied)."""
        other = object.__new__(type(self))
        other.__dict__.update(self.__dict__)
        other.values = self.values.copy()
        other.stamp = self.stamp.copy()
        other.hit_box = self.hit_box.copy()
        other._changes = self._changes.copy()
        return other

    def blank(self, geo: GridGeometry) -> OccupancyGrid:
        """An empty grid over `geo` that maps scans as this one does (its model, range and sensor model): a box to
        map again and `replace_box` with."""
        out = OccupancyGrid(geo, model=self.model, range_max=self.range_max)
        out.l_occ, out.l_free, out.l_clamp = self.l_occ, self.l_free, self.l_clamp
        return out

    def replace_box(self, r0: int, c0: int, other: OccupancyGrid) -> None:
        """Set the cells of the box whose cell (0, 0) is the grid's (`r0`, `c0`) to those of `other` (a grid
        of the box alone, of the same model), counted as one mark that touched the box (`scans`, the stamps
        of the cells `other` has seen, the changed box); the box must lie inside the grid.

        Raises:
            ConfigError: the box does not fit, or the models differ.
        """
        rows, cols = other.shape
        if other.model != self.model or r0 < 0 or c0 < 0 or r0 + rows > self.shape[0] or c0 + cols > self.shape[1]:
            raise ConfigError(f"occupancy grid: a {other.model} box of {rows} x {cols} cells at ({r0}, {c0}) does "
                              f"not fit the {self.model} grid of {self.shape[0]} x {self.shape[1]}")
        self.values[r0:r0 + rows, c0:c0 + cols] = other.values
        self.hit_box[r0:r0 + rows, c0:c0 + cols] = other.hit_box
        self.scans += 1
        self.stamp[r0:r0 + rows, c0:c0 + cols] = np.where(other.stamp > 0, self.scans, 0)
        self._note(r0, r0 + rows, c0, c0 + cols)
        self.cells_updated += rows * cols

    def _mark(self, r0: int, c0: int, cells: npt.NDArray[np.bool_], value: float) -> int:
        """Set `cells` (a bool mask of the box whose cell (0, 0) is the grid's (`r0`, `c0`)) to `value`,
        counted as one scan that touched them (a mark: `scans`, their stamps, its changed box); gives how
        many cells it set."""
        rows, cols = cells.shape
        self.values[r0:r0 + rows, c0:c0 + cols][cells] = value
        self.scans += 1
        self.stamp[r0:r0 + rows, c0:c0 + cols][cells] = self.scans
        hit_rows = np.flatnonzero(cells.any(axis=1))
        if hit_rows.size:
            hit_cols = np.flatnonzero(cells.any(axis=0))
            self._note(r0 + int(hit_rows[0]), r0 + int(hit_rows[-1]) + 1, c0 + int(hit_cols[0]),
                       c0 + int(hit_cols[-1]) + 1)
        else:
            self._note(0, 0, 0, 0)
        n = int(np.count_nonzero(cells))
        self.cells_updated += n
        return n

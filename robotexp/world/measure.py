"""What a map of a building is like, measured on its occupancy grid: doors, corridors, rooms, clutter,
wall noise, unknown space, open outline.

`measure_grid(values, cell)` reads a grid (0 free, 100 occupied, -1 unknown; values 1..49 count as
free, 50..100 as occupied) and returns a `BuildingMeasure`. Everything is in metres and square metres.

- Clearance: the distance from each free cell to the nearest cell that is not free (the image edge
  counts as not free), from scipy's exact Euclidean distance transform.
- Doors: the narrowest passages between regions. The free cells with clearance above a level t form
  connected parts; raising t (in steps of half a cell) splits a part in two where a passage of
  half-width t joins them. A split counts as a door when both sides are regions of their own: each
  holds a place with at least `PERSISTENCE` more clearance than the passage (a room wider than its
  door, not a bump of a noisy wall). The door's width is twice the passage's clearance (mid-way between
  the two levels) minus half a cell: a passage of k free cells along the grid has its middle cell k/2
  or (k+1)/2 cells from the walls, so the width is k cells within half a cell (a slanted one within a cell).
- Rooms: the regions the doors separate, grown from the last parts (those that never split again)
  over the free space by a watershed on clearance; their areas. A region longer than `CORRIDOR_RATIO`
  times its width and at most `CORRIDOR_MAX` wide is a corridor; its width is twice the median
  clearance on its medial axis (the cells whose clearance is a local maximum across one of the four
  directions), less half a cell.
- Clutter: occupied 8-connected parts surrounded by free space alone (not the largest part, the
  building's walls, nor parts touching unknown space or the image edge): furniture, pillars, specks of
  laser noise (at most `SPECK` m2).
- Walls: thickness (twice the median clearance inside the walls on their medial axis, less half a cell),
  corners of the wall face per metre of it (2 x 2 windows of known cells holding one or three occupied
  ones: a straight drawn wall has none but at its ends, a laser-built one many), gaps of one cell.
- Unknown: its share of the image and of the building's box (the box around free and occupied cells);
  pockets: unknown parts of at least `MIN_POCKET` inside the building (not touching the image edge), and
  the area of all of them.
- Open outline: the length of the boundary between free cells and the outside (unknown parts touching
  the image edge) or the image edge.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["BuildingMeasure", "CORRIDOR_MAX", "CORRIDOR_RATIO", "MIN_POCKET", "PERSISTENCE", "SPECK", "measure_grid"]

PERSISTENCE = 0.2       # [m] clearance a region needs beyond its door's half-width
CORRIDOR_RATIO = 4.0    # a corridor is this many times longer than wide
CORRIDOR_MAX = 3.5      # [m] widest corridor
SPECK = 0.01            # [m2] clutter up to this size is laser noise
MIN_ROOM = 1.0          # [m2] smaller regions are alcoves, not rooms
MIN_HALF = 0.15         # [m] narrowest half-width looked at (a 0.3 m passage)
MAX_HALF = 3.0          # [m] widest half-width looked at
MIN_POCKET = 0.25       # [m2] smallest unknown pocket counted

_EIGHT = np.ones((3, 3), dtype=bool)


@dataclass
class BuildingMeasure:
    """The measures of one map; lists are one entry per door, room, corridor, clutter piece."""

    cell: float
    free_area: float                      # [m2]
    door_widths: list[float] = field(default_factory=list)        # [m]
    room_areas: list[float] = field(default_factory=list)         # [m2], corridors excluded
    corridor_widths: list[float] = field(default_factory=list)    # [m]
    corridor_areas: list[float] = field(default_factory=list)     # [m2]
    clutter_areas: list[float] = field(default_factory=list)      # [m2], specks included
    specks: int = 0
    wall_thickness: float = 0.0           # [m] median
    corners_per_m: float = 0.0            # corners of the wall face per m of it
    wall_gaps_per_10m: float = 0.0        # one-cell gaps per 10 m of wall face
    unknown_share: float = 0.0            # of the image
    unknown_share_box: float = 0.0        # of the box around the known cells
    pockets: int = 0
    pocket_area: float = 0.0              # [m2]
    open_length: float = 0.0              # [m] of free boundary onto unknown or the image edge

    @property
    def clutter_per_100m2(self) -> float:
        """Clutter pieces other than specks per 100 m2 of free space."""
        return 100.0 * (len(self.clutter_areas) - self.specks) / max(self.free_area, 1e-9)

    @property
    def specks_per_100m2(self) -> float:
        return 100.0 * self.specks / max(self.free_area, 1e-9)


def _ndimage() -> Any:
    """scipy.ndimage (imported on first use)."""
    from scipy import ndimage  # type: ignore[import-untyped]  # scipy: a dependency (statistics)
    return ndimage


def _clearance(free: npt.NDArray[np.bool_], cell: float) -> npt.NDArray[np.float64]:
    """[m] from each free cell to the nearest cell that is not free, the image edge not free."""
    padded = np.pad(free, 1, constant_values=False)
    d: npt.NDArray[np.float64] = _ndimage().distance_transform_edt(padded)[1:-1, 1:-1] * cell
    return d


def _ridge(d: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    """Cells whose value is a local maximum across one of the four directions (not below either neighbour,
    above one of them), and > 0."""
    p = np.pad(d, 1, constant_values=0.0)
    c = p[1:-1, 1:-1]
    ridge = np.zeros(d.shape, dtype=bool)
    for (a, b), (e, f) in (((0, 1), (2, 1)), ((1, 0), (1, 2)), ((0, 0), (2, 2)), ((0, 2), (2, 0))):
        one, two = p[a:a + d.shape[0], b:b + d.shape[1]], p[e:e + d.shape[0], f:f + d.shape[1]]
        ridge |= (c >= one) & (c >= two) & ((c > one) | (c > two))
    return ridge & (d > 0)


def _holds(labels: npt.NDArray[np.int32], n: int, mask: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """(n + 1,) True for the labels with a cell in `mask` (label 0 never)."""
    out = np.zeros(n + 1, dtype=bool)
    out[labels[mask]] = True
    out[0] = False
    return out


def _doors(d: npt.NDArray[np.float64], cell: float) -> tuple[list[float], npt.NDArray[np.int32]]:
    """Door widths [m] and the seeds of the regions (labels > 0) they separate: the parts that never
    split again (a part that splits hands its seed on to its significant parts)."""
    nd = _ndimage()
    step = cell / 2
    # levels a quarter cell off the half cells: the clearance of an axis-aligned passage, a whole number
    # of cells, lies mid-way between two levels
    first = np.ceil(MIN_HALF / step)
    levels = (np.arange(first, min(MAX_HALF, float(d.max(initial=0.0))) / step) + 0.5) * step
    widths: list[float] = []
    seeds = np.zeros(d.shape, dtype=np.int32)
    if len(levels) == 0:
        return widths, seeds
    prev, n_prev = nd.label(d > levels[0], structure=_EIGHT)
    if n_prev:
        top = np.flatnonzero(_holds(prev, n_prev, d >= levels[0] + PERSISTENCE))
        lut = np.zeros(n_prev + 1, dtype=np.int32)
        lut[top] = np.arange(1, len(top) + 1)
        seeds = lut[prev]
    n_seeds = int(seeds.max(initial=0))
    for t in levels[1:]:
        cur, n_cur = nd.label(d > t, structure=_EIGHT)
        if n_cur == 0:
            break
        idx = np.arange(1, n_cur + 1)
        inside = cur > 0
        parent = np.zeros(n_cur + 1, dtype=np.int64)
        parent[cur[inside]] = prev[inside]             # the part each lies in (parts nest)
        significant = _holds(cur, n_cur, d >= t + PERSISTENCE)[1:]
        parent = parent[1:]
        counts = np.bincount(parent[significant], minlength=n_prev + 1)
        split = np.flatnonzero(counts >= 2)
        if len(split):
            # t - step < saddle <= t: a passage 2 saddle - cell / 2 wide (within half a cell when it runs
            # along the grid)
            widths.extend(float(2 * t - step - cell / 2) for p in split for _ in range(int(counts[p]) - 1))
            old = np.unique(seeds[np.isin(prev, split)])
            seeds[np.isin(seeds, old[old > 0])] = 0
            children = idx[significant & np.isin(parent, split)]
            lut = np.zeros(n_cur + 1, dtype=np.int32)
            lut[children] = n_seeds + np.arange(1, len(children) + 1)
            n_seeds += len(children)
            new = lut[cur]
            seeds = np.where(new > 0, new, seeds)
        prev, n_prev = cur, n_cur
    return widths, seeds


def _regions(free: npt.NDArray[np.bool_], seeds: npt.NDArray[np.int32]) -> npt.NDArray[np.int32]:
    """Every free cell of a free part holding a seed, labelled with the nearest seed (a seed holds every
    cell of its region farther from the walls than its door's half-width, so the nearest seed is the
    region's own but near the doors); 0 elsewhere."""
    nd = _ndimage()
    if not seeds.any():
        return np.zeros(seeds.shape, dtype=np.int32)
    _, (ri, ci) = nd.distance_transform_edt(seeds == 0, return_indices=True)
    out = seeds[ri, ci]
    parts, _ = nd.label(free, structure=_EIGHT)
    seed_part = np.zeros(int(seeds.max()) + 1, dtype=np.int64)
    seed_part[seeds[seeds > 0]] = parts[seeds > 0]
    ok = free & (parts == seed_part[out])
    return np.where(ok, out, 0).astype(np.int32)


def _rooms(m: BuildingMeasure, d: npt.NDArray[np.float64], regions: npt.NDArray[np.int32], cell: float) -> None:
    """Room areas, corridor widths and areas of the regions."""
    ridge = _ridge(d)
    n = int(regions.max(initial=0))
    if n == 0:
        return
    area = np.bincount(regions.ravel(), minlength=n + 1) * cell * cell
    for k in range(1, n + 1):
        if area[k] < MIN_ROOM:
            continue
        axis = d[(regions == k) & ridge]
        width = 2 * float(np.percentile(axis, 75)) - cell / 2 if len(axis) else 0.0
        if width > 0 and width <= CORRIDOR_MAX and area[k] / width >= CORRIDOR_RATIO * width:
            m.corridor_widths.append(width)
            m.corridor_areas.append(float(area[k]))
        else:
            m.room_areas.append(float(area[k]))


def _clutter(m: BuildingMeasure, occ: npt.NDArray[np.bool_], unknown: npt.NDArray[np.bool_], cell: float) -> None:
    nd = _ndimage()
    parts, n = nd.label(occ, structure=_EIGHT)
    if n == 0:
        return
    sizes = np.bincount(parts.ravel())
    sizes[0] = 0
    bad = np.zeros(n + 1, dtype=bool)
    bad[0] = True
    bad[int(np.argmax(sizes))] = True
    bad[np.unique(parts[nd.binary_dilation(unknown, structure=_EIGHT) & occ])] = True
    edge = np.concatenate([parts[0], parts[-1], parts[:, 0], parts[:, -1]])
    bad[np.unique(edge)] = True
    keep = np.flatnonzero(~bad)
    areas = sizes[keep] * cell * cell
    m.clutter_areas = [float(a) for a in areas]
    m.specks = int(np.count_nonzero(areas <= SPECK + 1e-12))


def _edges(a: npt.NDArray[np.bool_], b: npt.NDArray[np.bool_]) -> int:
    """Number of 4-neighbour cell edges between a cell of `a` and a cell of `b`."""
    return int(np.count_nonzero(a[:, 1:] & b[:, :-1]) + np.count_nonzero(a[:, :-1] & b[:, 1:])
               + np.count_nonzero(a[1:] & b[:-1]) + np.count_nonzero(a[:-1] & b[1:]))


def _walls(m: BuildingMeasure, occ: npt.NDArray[np.bool_], free: npt.NDArray[np.bool_], cell: float) -> None:
    nd = _ndimage()
    inner = np.asarray(nd.distance_transform_edt(np.pad(occ, 1, constant_values=False)))[1:-1, 1:-1] * cell
    axis = inner[_ridge(inner) & (inner <= 0.5)]           # solid blocks wider than 1 m are not walls
    m.wall_thickness = 2 * float(np.median(axis)) - cell / 2 if len(axis) else 0.0
    raw = _edges(free, occ)
    # corners of the wall face: 2 x 2 windows of known cells holding 1 or 3 occupied ones
    known = free | occ
    k = known[:-1, :-1] & known[1:, :-1] & known[:-1, 1:] & known[1:, 1:]
    n_occ = (occ[:-1, :-1].astype(np.int8) + occ[1:, :-1] + occ[:-1, 1:] + occ[1:, 1:])
    corners = int(np.count_nonzero(k & ((n_occ == 1) | (n_occ == 3))))
    m.corners_per_m = corners / (raw * cell) if raw else 0.0
    # one free cell between two occupied ones, across x or y: a gap of one cell in a wall
    p = np.pad(occ, 1, constant_values=False)
    gap = free & ((p[1:-1, :-2] & p[1:-1, 2:]) | (p[:-2, 1:-1] & p[2:, 1:-1]))
    face = raw * cell                                       # [m] of wall face
    m.wall_gaps_per_10m = 10.0 * int(np.count_nonzero(gap)) / face if face else 0.0


def _unknown(m: BuildingMeasure, free: npt.NDArray[np.bool_], occ: npt.NDArray[np.bool_],
             unknown: npt.NDArray[np.bool_], cell: float) -> None:
    nd = _ndimage()
    m.unknown_share = float(np.count_nonzero(unknown)) / unknown.size
    known = free | occ
    rows, cols = np.flatnonzero(known.any(axis=1)), np.flatnonzero(known.any(axis=0))
    if len(rows):
        box = unknown[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
        m.unknown_share_box = float(np.count_nonzero(box)) / box.size
    parts, n = nd.label(unknown)
    outside = np.zeros(n + 1, dtype=bool)
    if n:
        sizes = np.bincount(parts.ravel())
        sizes[0] = 0
        outside[np.unique(np.concatenate([parts[0], parts[-1], parts[:, 0], parts[:, -1]]))] = True
        outside[0] = False
        inner = ~outside
        inner[0] = False
        m.pockets = int(np.count_nonzero(inner & (sizes * cell * cell >= MIN_POCKET)))
        m.pocket_area = float(sizes[inner].sum()) * cell * cell
    edge = int(np.count_nonzero(free[0]) + np.count_nonzero(free[-1]) + np.count_nonzero(free[:, 0])
               + np.count_nonzero(free[:, -1]))
    m.open_length = (_edges(free, outside[parts]) + edge) * cell


def measure_grid(values: npt.NDArray[np.integer], cell: float) -> BuildingMeasure:
    """The measures of the map `values` (rows, cols; 0 free, 100 occupied, -1 unknown) of cells `cell` [m]."""
    values = np.asarray(values)
    unknown = values < 0
    occ = values >= 50
    free = ~unknown & ~occ
    m = BuildingMeasure(cell=cell, free_area=float(np.count_nonzero(free)) * cell * cell)
    d = _clearance(free, cell)
    m.door_widths, seeds = _doors(d, cell)
    _rooms(m, d, _regions(free, seeds), cell)
    _clutter(m, occ, unknown, cell)
    _walls(m, occ, free, cell)
    _unknown(m, free, occ, unknown, cell)
    return m

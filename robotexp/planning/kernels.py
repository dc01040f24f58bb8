"""Numba kernels for grid planning: distance transform, Dijkstra, A*, supercover line of sight.

Grids are C-contiguous arrays indexed [row, col], row 0 at the bottom (see
`robotexp.mapping.geometry`); a cell's flat index is ``row * cols + col``. Costs are float64 per
cell, ``inf`` marks a blocked cell. Moves are 8-connected: a step costs its length (1 or sqrt 2)
times the mean of the two cells' costs, and a diagonal step needs both orthogonal neighbours it
passes between to be passable (no corner cutting).

These kernels trust their inputs (shapes, dtypes, no NaN, no negative cost, cells inside the
grid); `robotexp.planning.grid_planner` checks them and is the documented entry point.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robotexp.mapping.kernels import kernel

__all__ = [
    "SQRT2",
    "box_distance_kernel",
    "box_offsets",
    "box_sq",
    "best_point_kernel",
    "SUB_POINTS",
    "SUB_REACH",
    "astar_kernel",
    "dijkstra_fill",
    "dijkstra_search",
    "nearest_goal_kernel",
    "distance_transform_kernel",
    "edt_1d",
    "line_of_sight_kernel",
    "scan_points_kernel",
    "simplify_kernel",
    "sweep_blocked_kernel",
    "trace_path",
]

SQRT2 = math.sqrt(2.0)

# Cell states in the `pos` array of the indexed heap.
_UNSEEN = -1
_CLOSED = -2


# ---------------------------------------------------------------------------------------------
# Exact Euclidean distance transform (Felzenszwalb & Huttenlocher 2012, "Distance Transforms of
# Sampled Functions", Theory of Computing 8: lower envelope of parabolas, one 1D pass per axis).
# ---------------------------------------------------------------------------------------------

@kernel
def edt_1d(f: npt.NDArray[np.float64], d: npt.NDArray[np.float64], v: npt.NDArray[np.int64],
           z: npt.NDArray[np.float64]) -> None:
    """1D squared distance transform: d[q] = min_p (q - p)^2 + f[p].

    Args:
        f: (n,) float64 sampled function; ``inf`` entries are skipped (no parabola), so the
            result is ``inf`` everywhere when every entry is ``inf``.
        d: (n,) float64 output, must not alias `f`.
        v: (>= n,) int64 scratch (parabola vertices).
        z: (>= n + 1,) float64 scratch (envelope breakpoints).
    """
    n = f.shape[0]
    k = -1
    for q in range(n):
        fq = f[q]
        if math.isinf(fq):
            continue
        if k < 0:
            k = 0
            v[0] = q
            z[0] = -np.inf
            z[1] = np.inf
            continue
        p = v[k]
        s = ((fq + q * q) - (f[p] + p * p)) / (2.0 * (q - p))
        while s <= z[k]:  # z[0] = -inf stops this at k = 0
            k -= 1
            p = v[k]
            s = ((fq + q * q) - (f[p] + p * p)) / (2.0 * (q - p))
        k += 1
        v[k] = q
        z[k] = s
        z[k + 1] = np.inf
    if k < 0:
        for q in range(n):
            d[q] = np.inf
        return
    k = 0
    for q in range(n):
        while z[k + 1] < q:
            k += 1
        p = v[k]
        d[q] = (q - p) * (q - p) + f[p]


@kernel
def distance_transform_kernel(occ: npt.NDArray[np.bool_], out: npt.NDArray[np.float32]) -> None:
    """Euclidean distance [cells] from each cell centre to the nearest occupied cell centre.

    Args:
        occ: (rows, cols) bool, True = occupied.
        out: (rows, cols) float32 output; ``inf`` everywhere when no cell is occupied.
    """
    rows, cols = occ.shape
    n = max(rows, cols)
    f = np.empty(n, dtype=np.float64)
    d = np.empty(n, dtype=np.float64)
    v = np.empty(n, dtype=np.int64)
    z = np.empty(n + 1, dtype=np.float64)
    sq = np.empty((rows, cols), dtype=np.float64)
    for c in range(cols):  # columns: squared distance along the column
        for r in range(rows):
            f[r] = 0.0 if occ[r, c] else np.inf
        edt_1d(f[:rows], d[:rows], v, z)
        for r in range(rows):
            sq[r, c] = d[r]
    for r in range(rows):  # rows: combine the column results
        for c in range(cols):
            f[c] = sq[r, c]
        edt_1d(f[:cols], d[:cols], v, z)
        for c in range(cols):
            out[r, c] = np.float32(math.sqrt(d[c]))


HALF_DIAGONAL = 0.5 * SQRT2 + 1e-6     # [cells] from a cell's centre to its corners, rounded up


def box_offsets(reach: float) -> npt.NDArray[np.float64]:
    """(k, 3) float64 (d_row, d_col, distance) of the cells within `reach` + 2 HALF_DIAGONAL [cells] of a cell,
    nearest first: the order `box_distance_kernel` visits them in."""
    k = int(math.ceil(reach + 2.0 * HALF_DIAGONAL))
    dr, dc = np.mgrid[-k:k + 1, -k:k + 1]
    d = np.hypot(dr, dc).ravel()
    keep = d <= reach + 2.0 * HALF_DIAGONAL
    order = np.argsort(d[keep], kind="stable")
    return np.ascontiguousarray(np.column_stack([dr.ravel()[keep], dc.ravel()[keep], d[keep]])[order])


@kernel
def box_sq(hit_box: npt.NDArray[np.uint8], rr: int, cc: int, qy: float, qx: float) -> float:
    """Squared distance [cells^2] from the point (qy, qx) [cells from the lower-left corner of cell (rr, cc)] to
    that cell's box of laser endpoints (`box_distance_kernel`'s `hit_box`; none: the whole cell)."""
    if hit_box[rr, cc, 0] > hit_box[rr, cc, 1]:
        xl, xh, yl, yh = 0.0, 1.0, 0.0, 1.0
    else:
        xl = hit_box[rr, cc, 0] / 255.0
        xh = hit_box[rr, cc, 1] / 255.0
        yl = hit_box[rr, cc, 2] / 255.0
        yh = hit_box[rr, cc, 3] / 255.0
    dx = max(xl - qx, 0.0, qx - xh)
    dy = max(yl - qy, 0.0, qy - yh)
    return dx * dx + dy * dy


@kernel
def box_distance_kernel(occ: npt.NDArray[np.bool_], hit_box: npt.NDArray[np.uint8], centre: npt.NDArray[np.float32],
                        need: npt.NDArray[np.bool_], offsets: npt.NDArray[np.float64], exact: float, reach: float,
                        r0: int, r1: int, c0: int, c1: int, out: npt.NDArray[np.float32]) -> None:
    """Distance [cells] from the centres of rows r0..r1, columns c0..c1 (half-open) to the nearest box of
    laser endpoints of an occupied cell: exact up to `exact`; from there up to `reach` the distance to the
    nearest occupied cell's centre less half a cell (a wall anywhere in its cell, within a fifth of a cell
    of the exact value: costs beyond the hard limit need no more); beyond `reach` some value larger.

    Args:
        occ: (rows, cols) bool occupied cells.
        hit_box: (rows, cols, 4) uint8 per cell x_lo, x_hi, y_lo, y_hi of its endpoints in 1/255 of a cell
            from its lower-left corner (`OccupancyGrid.hit_box`); x_lo > x_hi: none, the whole cell counts.
        centre: (rows, cols) float32 distance [cells] to the nearest occupied cell's centre
            (`distance_transform(occ)`).
        need: (rows, cols) bool, the cells whose distance is asked (the others get the centre distance less
            HALF_DIAGONAL, a lower bound: e.g. the cells a plan may not enter whatever their distance).
        offsets: `box_offsets(exact)`.
        exact: [cells] how far the result must be exact.
        reach: [cells] how far it must be exact or nearly (>= exact); beyond, a value larger than `reach`.
        r0: first row.
        r1: row past the last.
        c0: first column.
        c1: column past the last.
        out: (r1 - r0, c1 - c0) float32 output.

    A box lies in its cell, within HALF_DIAGONAL of the cell's centre, so a cell whose centre is farther
    than the nearest box found so far plus HALF_DIAGONAL holds no nearer box: the cells are visited
    nearest first and the search stops there.
    """
    rows, cols = occ.shape
    for r in range(r0, r1):
        for c in range(c0, c1):
            d = centre[r, c]
            if d > reach + HALF_DIAGONAL or not need[r, c]:
                out[r - r0, c - c0] = d - HALF_DIAGONAL
                continue
            if d > exact + 2.0 * HALF_DIAGONAL:            # every box farther than `exact`
                out[r - r0, c - c0] = max(d - 0.5, exact + 1e-3)
                continue
            best = np.inf          # squared
            for i in range(offsets.shape[0]):
                od = offsets[i, 2]
                if od > d + 2.0 * HALF_DIAGONAL or (od - HALF_DIAGONAL) * (od - HALF_DIAGONAL) >= best \
                        and od > HALF_DIAGONAL:
                    break
                rr = r + int(offsets[i, 0])
                cc = c + int(offsets[i, 1])
                if rr < 0 or rr >= rows or cc < 0 or cc >= cols or not occ[rr, cc]:
                    continue
                best = min(best, box_sq(hit_box, rr, cc, r - rr + 0.5, c - cc + 0.5))
            out[r - r0, c - c0] = np.float32(math.sqrt(best))


# The points of a cell a plan may pass through (row, col offsets [cells] from its centre): its centre
# first, then the eight others of a 3 x 3 lattice a third of a cell apart (the four beside the centre
# before the four corners), so that a gap whose admissible band for the robot's centre is a third of a
# cell wide holds one, wherever it lies.
SUB_POINTS = np.array([(0.0, 0.0), (-1.0, 0.0), (0.0, -1.0), (0.0, 1.0), (1.0, 0.0),
                       (-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]) / 3.0
SUB_REACH = math.sqrt(2.0) / 3.0 + 1e-6     # [cells] from a cell's centre to its farthest point, rounded up


@kernel
def best_point_kernel(occ: npt.NDArray[np.bool_], hit_box: npt.NDArray[np.uint8], need: npt.NDArray[np.bool_],
                      offsets: npt.NDArray[np.float64], below: float, r0: int, r1: int, c0: int, c1: int,
                      dist: npt.NDArray[np.float32], code: npt.NDArray[np.uint8]) -> None:
    """Cells blocked at their centre but not at another of their `SUB_POINTS`: for each cell of rows
    r0..r1, columns c0..c1 (half-open) asked (`need`) whose centre's distance `dist` to the walls' surface is
    at most `below` [cells] but within `SUB_REACH` of it, the distance from each other point of the cell to
    the nearest box of laser endpoints (as `box_distance_kernel`); when the largest exceeds `below` the cell
    takes that distance and `code` the point's index in `SUB_POINTS` (the first on a tie), else its code
    is 0 (the centre). Every other cell's code is 0.

    Args:
        occ: (rows, cols) bool occupied cells.
        hit_box: (rows, cols, 4) uint8 boxes of laser endpoints (`box_distance_kernel`).
        need: (rows, cols) bool, the cells asked.
        offsets: `box_offsets(below + 1)`: every cell whose box may lie within `below` + `SUB_REACH` of a point.
        below: [cells] the distance a cell's centre must exceed to be passable.
        r0: first row.
        r1: row past the last.
        c0: first column.
        c1: column past the last.
        dist: (r1 - r0, c1 - c0) float32 the centres' distances (`box_distance_kernel`, exact up to
            `below`), updated in place.
        code: (r1 - r0, c1 - c0) uint8 output.
    """
    rows, cols = occ.shape
    n = SUB_POINTS.shape[0]
    best = np.empty(n)          # squared, per point (index 0, the centre, unused)
    for r in range(r0, r1):
        for c in range(c0, c1):
            code[r - r0, c - c0] = 0
            d = dist[r - r0, c - c0]
            if d > below or d <= below - SUB_REACH or not need[r, c]:
                continue
            best[:] = np.inf
            worst = np.inf          # the largest of the points' best so far
            for i in range(offsets.shape[0]):
                lo = offsets[i, 2] - HALF_DIAGONAL - SUB_REACH    # no box in this cell or a later one is nearer
                if lo > 0.0 and lo * lo >= worst:
                    break
                rr = r + int(offsets[i, 0])
                cc = c + int(offsets[i, 1])
                if rr < 0 or rr >= rows or cc < 0 or cc >= cols or not occ[rr, cc]:
                    continue
                worst = 0.0
                for k in range(1, n):
                    best[k] = min(best[k], box_sq(hit_box, rr, cc, r - rr + (0.5 + SUB_POINTS[k, 0]),
                                                  c - cc + (0.5 + SUB_POINTS[k, 1])))
                    worst = max(worst, best[k])
            far = -1.0
            pick = 0
            for k in range(1, n):
                far_k = math.sqrt(best[k]) if best[k] < np.inf else below + 1.0
                if far_k > far:
                    far = far_k
                    pick = k
            if far > below:
                dist[r - r0, c - c0] = np.float32(min(far, below + 1.0))
                code[r - r0, c - c0] = pick


# ---------------------------------------------------------------------------------------------
# Indexed binary min-heap over flat cell indices, ordered by (key, tie); `pos` holds each cell's
# heap slot, _UNSEEN or _CLOSED. Decrease-key keeps the heap at most one entry per cell.
# ---------------------------------------------------------------------------------------------

@kernel
def _less(a: int, b: int, key: npt.NDArray[np.float64], tie: npt.NDArray[np.float64]) -> bool:
    ka = key[a]
    kb = key[b]
    return bool(ka < kb or (ka == kb and tie[a] < tie[b]))


@kernel
def _sift_up(heap: npt.NDArray[np.int64], pos: npt.NDArray[np.int64], i: int,
             key: npt.NDArray[np.float64], tie: npt.NDArray[np.float64]) -> None:
    item = heap[i]
    while i > 0:
        up = (i - 1) >> 1
        other = heap[up]
        if not _less(item, other, key, tie):
            break
        heap[i] = other
        pos[other] = i
        i = up
    heap[i] = item
    pos[item] = i


@kernel
def _pop(heap: npt.NDArray[np.int64], pos: npt.NDArray[np.int64], size: int,
         key: npt.NDArray[np.float64], tie: npt.NDArray[np.float64]) -> int:
    """Remove and return the top cell; the caller decrements its size and sets pos[top]."""
    top = heap[0]
    size -= 1
    if size > 0:
        item = heap[size]
        i = 0
        while True:
            child = 2 * i + 1
            if child >= size:
                break
            if child + 1 < size and _less(heap[child + 1], heap[child], key, tie):
                child += 1
            if not _less(heap[child], item, key, tie):
                break
            heap[i] = heap[child]
            pos[heap[i]] = i
            i = child
        heap[i] = item
        pos[item] = i
    return int(top)


@kernel
def _dijkstra(cost: npt.NDArray[np.float64], start: int, goal: npt.NDArray[np.bool_],
              use_goal: bool, max_dist: float, dist: npt.NDArray[np.float64],
              parent: npt.NDArray[np.int32], lazy: bool) -> int:
    # `seen` marks the cells whose dist, parent and pos hold this search's values; the others are set
    # when the search first reaches them, so a search costs the cells it reaches (and a byte per
    # cell), not the grid. Eager (`lazy` False): every other cell gets inf and -1 at the end.
    rows, cols = cost.shape
    n = rows * cols
    c = cost.ravel()
    g = goal.ravel()
    seen = np.zeros(n, dtype=np.bool_)
    found = -1
    if math.isinf(c[start]):
        _settle_unseen(seen, dist, parent, lazy)
        return found
    pos = np.empty(n, dtype=np.int64)
    heap = np.empty(n, dtype=np.int64)
    seen[start] = True
    parent[start] = -1
    dist[start] = 0.0
    heap[0] = start
    pos[start] = 0
    size = 1
    while size > 0:
        u = _pop(heap, pos, size, dist, dist)
        size -= 1
        pos[u] = _CLOSED
        if use_goal and g[u]:
            found = u
            break
        du = dist[u]
        cu = c[u]
        ur = u // cols
        uc = u - ur * cols
        for dr in range(-1, 2):
            vr = ur + dr
            if vr < 0 or vr >= rows:
                continue
            for dc in range(-1, 2):
                vc = uc + dc
                if (dr == 0 and dc == 0) or vc < 0 or vc >= cols:
                    continue
                w = vr * cols + vc
                if not seen[w]:
                    seen[w] = True
                    dist[w] = np.inf
                    parent[w] = -1
                    pos[w] = _UNSEEN
                if pos[w] == _CLOSED or math.isinf(c[w]):
                    continue
                if dr != 0 and dc != 0:
                    if math.isinf(c[ur * cols + vc]) or math.isinf(c[vr * cols + uc]):
                        continue
                    nd = du + SQRT2 * (0.5 * (cu + c[w]))
                else:
                    nd = du + 0.5 * (cu + c[w])
                if nd > max_dist or nd >= dist[w]:
                    continue
                dist[w] = nd
                parent[w] = u
                if pos[w] == _UNSEEN:
                    heap[size] = w
                    size += 1
                    _sift_up(heap, pos, size - 1, dist, dist)
                else:
                    _sift_up(heap, pos, pos[w], dist, dist)
    # Cells still queued after an early exit hold only upper bounds: forget them.
    for i in range(size):
        w = heap[i]
        dist[w] = np.inf
        parent[w] = -1
    _settle_unseen(seen, dist, parent, lazy)
    return found


@kernel
def _settle_unseen(seen: npt.NDArray[np.bool_], dist: npt.NDArray[np.float64], parent: npt.NDArray[np.int32],
                   lazy: bool) -> None:
    """An eager search's cells it never reached: inf and -1 (a lazy one leaves them undefined)."""
    if lazy:
        return
    for i in range(seen.size):
        if not seen[i]:
            dist[i] = np.inf
            parent[i] = -1


@kernel
def dijkstra_search(cost: npt.NDArray[np.float64], start: int, goal: npt.NDArray[np.bool_],
                    max_dist: float, dist: npt.NDArray[np.float64],
                    parent: npt.NDArray[np.int32]) -> int:
    """Dijkstra from `start` that stops when the first goal cell is settled.

    Args:
        cost: (rows, cols) float64 cell costs, ``inf`` = blocked.
        start: flat index of the start cell.
        goal: (rows, cols) bool goal cells.
        max_dist: [cost units] cells farther than this are not reached.
        dist: (rows * cols,) float64 output: exact distance of every settled cell, ``inf`` for
            the others (so the goal found is the only goal cell with a finite distance).
        parent: (rows * cols,) int32 output: previous cell on a shortest path, -1 for the start
            and for cells not settled.

    Returns:
        Flat index of the goal cell reached, or -1 when none is reachable within `max_dist`.
    """
    return _dijkstra(cost, start, goal, True, max_dist, dist, parent, False)


@kernel
def nearest_goal_kernel(cost: npt.NDArray[np.float64], start: int, goal: npt.NDArray[np.bool_],
                        dist: npt.NDArray[np.float64], parent: npt.NDArray[np.int32]) -> int:
    """`dijkstra_search` without a distance bound that leaves the cells it never reached alone: `dist` and
    `parent` are defined only on the cells it settled (the goal found and the path to it), and a search
    costs the cells it reaches, not the grid (the goal and the path are those of `dijkstra_search`)."""
    return _dijkstra(cost, start, goal, True, np.inf, dist, parent, True)


@kernel
def dijkstra_fill(cost: npt.NDArray[np.float64], start: int, max_dist: float,
                  dist: npt.NDArray[np.float64], parent: npt.NDArray[np.int32]) -> None:
    """Dijkstra from `start` over every cell within `max_dist` (see `dijkstra_search`)."""
    no_goal = np.zeros((1, 1), dtype=np.bool_)
    _dijkstra(cost, start, no_goal, False, max_dist, dist, parent, False)


@kernel
def astar_kernel(cost: npt.NDArray[np.float64], start: int, goal: int, min_cost: float,
                 parent: npt.NDArray[np.int32]) -> float:
    """A* from `start` to `goal` with the octile heuristic times `min_cost`.

    The heuristic is consistent when every step costs at least its length times `min_cost`
    (true when `min_cost` is the smallest finite cell cost), so cells are never reopened and the
    result equals Dijkstra's distance. Ties on f go to the larger g (the deeper cell).

    Args:
        cost: (rows, cols) float64 cell costs, ``inf`` = blocked.
        start: flat index of the start cell.
        goal: flat index of the goal cell.
        min_cost: smallest finite cell cost (>= 0).
        parent: (rows * cols,) int32 output: previous cell on the path (-1 for the start; only the cells
            the search reached are written): follow it back from `goal`.

    Returns:
        Path cost [cost units] from start to goal, ``inf`` when the goal is unreachable.
    """
    rows, cols = cost.shape
    n = rows * cols
    c = cost.ravel()
    if math.isinf(c[start]) or math.isinf(c[goal]):
        return np.inf
    gr = goal // cols
    gc = goal - gr * cols
    # `seen` marks the cells whose g, parent and pos hold this search's values (set when the search
    # first reaches a cell): a search costs the cells it reaches and a byte per cell, not the grid
    seen = np.zeros(n, dtype=np.bool_)
    g = np.empty(n, dtype=np.float64)
    f = np.empty(n, dtype=np.float64)
    h = np.empty(n, dtype=np.float64)
    pos = np.empty(n, dtype=np.int64)
    heap = np.empty(n, dtype=np.int64)
    seen[start] = True
    parent[start] = -1
    sr = start // cols
    ar = abs(sr - gr)
    ac = abs(start - sr * cols - gc)
    h[start] = min_cost * (max(ar, ac) + (SQRT2 - 1.0) * min(ar, ac))
    g[start] = 0.0
    f[start] = h[start]
    heap[0] = start
    pos[start] = 0
    size = 1
    while size > 0:
        u = _pop(heap, pos, size, f, h)
        size -= 1
        pos[u] = _CLOSED
        if u == goal:
            return float(g[u])
        gu = g[u]
        cu = c[u]
        ur = u // cols
        uc = u - ur * cols
        for dr in range(-1, 2):
            vr = ur + dr
            if vr < 0 or vr >= rows:
                continue
            for dc in range(-1, 2):
                vc = uc + dc
                if (dr == 0 and dc == 0) or vc < 0 or vc >= cols:
                    continue
                w = vr * cols + vc
                if not seen[w]:
                    seen[w] = True
                    g[w] = np.inf
                    pos[w] = _UNSEEN
                if pos[w] == _CLOSED or math.isinf(c[w]):
                    continue
                # the same step rule as dijkstra_search, written out: a shared helper measured
                # 20-50 % slower in both searches (numba did not inline it to the same code)
                if dr != 0 and dc != 0:
                    if math.isinf(c[ur * cols + vc]) or math.isinf(c[vr * cols + uc]):
                        continue
                    ng = gu + SQRT2 * (0.5 * (cu + c[w]))
                else:
                    ng = gu + 0.5 * (cu + c[w])
                if ng >= g[w]:
                    continue
                g[w] = ng
                parent[w] = u
                if pos[w] == _UNSEEN:
                    ar = abs(vr - gr)
                    ac = abs(vc - gc)
                    h[w] = min_cost * (max(ar, ac) + (SQRT2 - 1.0) * min(ar, ac))
                    f[w] = ng + h[w]
                    heap[size] = w
                    size += 1
                    _sift_up(heap, pos, size - 1, f, h)
                else:
                    f[w] = ng + h[w]
                    _sift_up(heap, pos, pos[w], f, h)
    return np.inf


@kernel
def trace_path(parent: npt.NDArray[np.int32], cols: int, end: int) -> npt.NDArray[np.int32]:
    """Follow `parent` back from flat cell `end` to a cell whose parent is -1.

    Returns:
        (k, 2) int32 [row, col] cells from that root to `end`, both included.
    """
    k = 1
    i = end
    while parent[i] >= 0:
        i = parent[i]
        k += 1
    out = np.empty((k, 2), dtype=np.int32)
    i = end
    for j in range(k - 1, -1, -1):
        out[j, 0] = i // cols
        out[j, 1] = i % cols
        i = parent[i]
    return out


# ---------------------------------------------------------------------------------------------
# Supercover line of sight: every cell the segment between two cell centres touches, corners
# included (a segment through a grid corner touches all four cells around it).
# ---------------------------------------------------------------------------------------------

@kernel
def line_of_sight_kernel(passable: npt.NDArray[np.bool_], r0: int, c0: int, r1: int,
                         c1: int) -> bool:
    """True when every cell touched by the segment from centre (r0, c0) to (r1, c1) is passable.

    Exact integer walk: with centres at integer coordinates, the segment crosses the i-th
    vertical cell border at t = (i + 1/2)/dc and the j-th horizontal one at t = (j + 1/2)/dr;
    the comparison (2i + 1)*dr vs (2j + 1)*dc tells which comes first, equality is a corner.
    """
    if not passable[r0, c0]:
        return False
    dc = abs(c1 - c0)
    dr = abs(r1 - r0)
    sc = 1 if c1 > c0 else -1
    sr = 1 if r1 > r0 else -1
    r = r0
    c = c0
    i = 0
    j = 0
    while i < dc or j < dr:
        lhs = (2 * i + 1) * dr
        rhs = (2 * j + 1) * dc
        if lhs < rhs:  # vertical border first: step along the columns
            c += sc
            i += 1
        elif lhs > rhs:  # horizontal border first: step along the rows
            r += sr
            j += 1
        else:  # through a corner: the two side cells are touched too
            if not passable[r, c + sc] or not passable[r + sr, c]:
                return False
            c += sc
            r += sr
            i += 1
            j += 1
        if not passable[r, c]:
            return False
    return True


@kernel
def simplify_kernel(path: npt.NDArray[np.int32], passable: npt.NDArray[np.bool_],
                    keep: npt.NDArray[np.bool_]) -> int:
    """Mark in `keep` the cells of `path` needed so that consecutive kept cells see each other.

    Greedy string pulling: from the last kept cell, extend while the next path cell is still in
    line of sight; keep the last visible one. First and last cells are always kept.

    Args:
        path: (k, 2) int32 [row, col], consecutive cells 8-neighbours (as from A*).
        passable: (rows, cols) bool.
        keep: (k,) bool output.

    Returns:
        Number of kept cells.
    """
    k = path.shape[0]
    keep[:] = False
    if k == 0:
        return 0
    keep[0] = True
    keep[k - 1] = True
    anchor = 0
    count = 1 if k == 1 else 2
    for i in range(2, k):
        if not line_of_sight_kernel(passable, path[anchor, 0], path[anchor, 1], path[i, 0],
                                    path[i, 1]):
            anchor = i - 1
            keep[anchor] = True
            count += 1
    return count


@kernel
def sweep_blocked_kernel(pts: npt.NDArray[np.float64], norms: npt.NDArray[np.float64], radius: float,  # noqa: PLR0913
                         clearance: float, length: float, curvature: float, steps: int, graze: float,
                         min_gap: float) -> bool:
    """True when a disc of `radius` [m] swept from the origin along the arc of `curvature` [1/m] leaving
    along +x, at the `steps` positions `length` / `steps` apart up to `length` [m], comes within
    `clearance` of one of the robot-frame points `pts` (k, 2) [m] (at distances `norms` (k,) from the
    origin) and either more than `graze` nearer to it than the disc is now, or within `min_gap` of touching
    it (`robotexp.planning.follower.blocked_ahead`'s rule).
    """
    reach = radius + clearance
    straight = abs(curvature) < 1e-9
    for i in range(pts.shape[0]):
        d0 = norms[i]
        if d0 >= length + reach:        # no position of the arc comes within reach
            continue
        px = pts[i, 0]
        py = pts[i, 1]
        for j in range(1, steps + 1):
            s = length if j == steps else j * (length / steps)
            if straight:
                cx, cy = s, 0.0
            else:
                cx = math.sin(curvature * s) / curvature
                cy = (1.0 - math.cos(curvature * s)) / curvature
            d = math.hypot(px - cx, py - cy)
            if d < reach and (d < d0 - graze or d < radius + min_gap):
                return True
    return False


@kernel
def scan_points_kernel(ranges: npt.NDArray[np.float64], cos: npt.NDArray[np.float64], sin: npt.NDArray[np.float64],
                       offset_x: float, range_max: float) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(k, 2) robot-frame points [m] of a scan's returns (the `ranges` below `range_max`, NaN and inf left
    out), along beams of direction (`cos`, `sin`) from a sensor `offset_x` [m] ahead of the robot's centre,
    and (k,) their distances [m] from the centre."""
    n = 0
    for i in range(ranges.shape[0]):
        if ranges[i] < range_max:
            n += 1
    pts = np.empty((n, 2))
    norms = np.empty(n)
    j = 0
    for i in range(ranges.shape[0]):
        r = ranges[i]
        if r < range_max:
            x = offset_x + r * cos[i]
            y = r * sin[i]
            pts[j, 0] = x
            pts[j, 1] = y
            norms[j] = r if offset_x == 0.0 else math.hypot(x, y)
            j += 1
    return pts, norms

"""What the robots of a team know: the cells each robot's own scans touched (`SeenCells`, for the overlap
of a record), and the scans the robots pass on when they are within communication range of each other
(`ScanExchange`)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robotexp.mapping.grid import OccupancyGrid
from robotexp.mapping.kernels import kernel
from robotexp.robot import LaserScan, Pose

__all__ = ["SeenCells", "ScanExchange", "groups_within", "beams_on_teammates", "beams_on_teammates_reference",
           "teammates_near"]


def beams_on_teammates(sensor: tuple[float, float, float], angles: npt.NDArray[np.float64],  # noqa: PLR0913
                       ranges: npt.NDArray[np.float64], xy: npt.NDArray[np.float64],
                       reach: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    """(beams,) bool: the beams of a scan taken from `sensor` (x, y [m], heading [rad]; beam `angles` relative
    to it) whose end (at `ranges`; a beam with no echo has none) lies within `reach[j]` [m] of teammate j's
    centre `xy[j]` (k, 2): one pass over the beams and teammates (`beams_on_teammates_reference` is the same
    in numpy)."""
    out = np.zeros(len(ranges), np.bool_)
    _beams_on(float(sensor[0]), float(sensor[1]), float(sensor[2]), np.ascontiguousarray(angles, np.float64),
              np.ascontiguousarray(ranges, np.float64), np.ascontiguousarray(xy, np.float64).reshape(-1, 2),
              np.ascontiguousarray(reach, np.float64), out)
    return out


def beams_on_teammates_reference(sensor: tuple[float, float, float], angles: npt.NDArray[np.float64],
                                 ranges: npt.NDArray[np.float64], xy: npt.NDArray[np.float64],
                                 reach: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    """`beams_on_teammates` in numpy (every beam against every teammate at once)."""
    sx, sy, theta = sensor
    hit = np.isfinite(ranges)
    ex = sx + np.where(hit, ranges, 0.0) * np.cos(theta + angles)
    ey = sy + np.where(hit, ranges, 0.0) * np.sin(theta + angles)
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    return hit & (np.hypot(ex[:, None] - xy[:, 0], ey[:, None] - xy[:, 1]) <= reach).any(axis=1)


@kernel
def teammates_near(x: float, y: float, xy: npt.NDArray[np.float64], swing: npt.NDArray[np.float64],  # noqa: PLR0913
                   speed: npt.NDArray[np.float64], brake: npt.NDArray[np.float64], robot: int,
                   reach: float, near: npt.NDArray[np.bool_]) -> tuple[bool, float, float]:
    """Of the teammates (all rows of `xy` (n, 2) [m] but `robot`'s; rows of NaN: none) whose centres lie within
    `reach` [m] plus their `swing` [m] of (x, y), marked True in `near` (n,): whether there is one, the
    farthest one of them may still come before it stops (speed^2 / `brake` + 0.2 s of speed [m], at least
    0), and the least distance from (x, y) to their discs (centre distance less swing) [m] (inf when none)."""
    found = False
    closing = 0.0
    gap = math.inf
    for j in range(xy.shape[0]):
        near[j] = False
        if j == robot:
            continue
        d = math.hypot(xy[j, 0] - x, xy[j, 1] - y)
        if not d <= reach + swing[j]:
            continue
        near[j] = True
        found = True
        v = speed[j]
        closing = max(closing, v * v / brake[j] + v * 0.2)
        gap = min(gap, d - swing[j])
    return found, closing, gap


@kernel
def _beams_on(sx: float, sy: float, theta: float, angles: npt.NDArray[np.float64],  # noqa: PLR0913
              ranges: npt.NDArray[np.float64], xy: npt.NDArray[np.float64], reach: npt.NDArray[np.float64],
              out: npt.NDArray[np.bool_]) -> None:
    for i in range(ranges.shape[0]):
        r = ranges[i]
        if not math.isfinite(r):
            continue
        ex = sx + r * math.cos(theta + angles[i])
        ey = sy + r * math.sin(theta + angles[i])
        for j in range(xy.shape[0]):
            if math.hypot(ex - xy[j, 0], ey - xy[j, 1]) <= reach[j]:
                out[i] = True
                break


class SeenCells:
    """Which robots' scans touched each cell: one bit per robot (at most 64), updated from the box of the
    scan a grid integrated last (its cells carry that scan's stamp), so the cost of a step follows one
    scan's reach, not the map.

    Args:
        shape: (rows, cols) of the team's grids.
        size: robots in the team.
    """

    def __init__(self, shape: tuple[int, int], size: int) -> None:
        dtype = np.uint8 if size <= 8 else np.uint16 if size <= 16 else np.uint32 if size <= 32 else np.uint64
        self.bits = np.zeros(shape, dtype)
        self._one = [dtype(1 << i) for i in range(size)]

    def note(self, robot: int, grid: OccupancyGrid) -> None:
        """Robot `robot`'s scan was the last one `grid` integrated: mark the cells it touched."""
        box = grid.changed_box(grid.scans - 1)
        if box is None:
            return
        r0, r1, c0, c1 = box
        sub = self.bits[r0:r1, c0:c1]
        np.bitwise_or(sub, self._one[robot], out=sub, where=grid.stamp[r0:r1, c0:c1] == grid.scans)

    def seen_by(self, robot: int) -> npt.NDArray[np.bool_]:
        """(rows, cols) bool: the cells robot `robot`'s scans touched."""
        return (self.bits & self._one[robot]) != 0

    def counts(self) -> tuple[int, int]:
        """(cells seen by some robot, cells seen by more than one)."""
        seen = self.bits != 0
        several = (self.bits & (self.bits - 1)) != 0
        return int(np.count_nonzero(seen)), int(np.count_nonzero(several))

    def overlap(self) -> float | None:
        """The share of the cells seen that more than one robot saw (None: no cell seen)."""
        seen, several = self.counts()
        return None if seen == 0 else several / seen


def groups_within(positions: npt.NDArray[np.float64], reach: float | None) -> list[list[int]]:
    """The robots at `positions` (n, 2) [m] that can talk, as groups (each sorted, groups by their first
    robot): two robots within `reach` [m] talk, and a message passes on through any chain of them;
    `reach` None: everyone talks to everyone."""
    n = len(positions)
    if reach is None:
        return [list(range(n))]
    parent = list(range(n))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    d = np.hypot(positions[:, None, 0] - positions[None, :, 0], positions[:, None, 1] - positions[None, :, 1])
    for i, j in zip(*np.nonzero(np.triu(d <= reach, 1)), strict=True):
        a, b = root(int(i)), root(int(j))
        if a != b:
            parent[max(a, b)] = min(a, b)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(i)
    return [groups[k] for k in sorted(groups)]


class ScanExchange:
    """Maps of robots that share what they scanned when they can talk (`robotexp explore --comm-range`).

    Every robot maps its own scans into its own grid and logs them here (`log`), as well as the floor it
    marked free where it stood (`log_stand`, `OccupancyGrid.mark_free_disc`). Robots in one group
    (`groups_within`) bring each other's grids up to the scans any of them knows (`share`): robot i's grid
    gets robot k's logged scans and marks from the first it lacks to the last one someone in the group
    has. The maps of robots that talked are then the maps of the union of their scans, and what robot k
    scanned passes on through the robots that met it. Start poses are known to all (one frame).

    Args:
        grids: each robot's own grid.
    """

    def __init__(self, grids: Sequence[OccupancyGrid]) -> None:
        self.grids = list(grids)
        n = len(grids)
        # each robot's scans (pose, scan) and marks of where it stood (pose, radius [m]), in its grid's order
        self.scans: list[list[tuple[Pose, LaserScan | float]]] = [[] for _ in range(n)]
        self.known = np.zeros((n, n), np.int64)     # known[i, k]: robot k's entries in robot i's grid
        self.received = np.zeros(n, np.int64)       # scans each robot integrated from others

    def log(self, robot: int, pose: Pose, scan: LaserScan) -> None:
        """Robot `robot` mapped `scan`, taken at `pose`, into its own grid."""
        self.scans[robot].append((pose, scan))
        self.known[robot, robot] = len(self.scans[robot])

    def log_stand(self, robot: int, pose: Pose, radius: float) -> None:
        """Robot `robot` marked the floor within `radius` [m] of `pose` free in its own grid (where it stands)."""
        self.scans[robot].append((pose, radius))
        self.known[robot, robot] = len(self.scans[robot])

    def share(self, groups: Sequence[Sequence[int]]) -> int:
        """Bring every robot's grid up to the scans and marks its group knows; gives the scans integrated."""
        total = 0
        for group in groups:
            if len(group) < 2:
                continue
            members = list(group)
            best = self.known[members].max(axis=0)
            for i in members:
                for k in np.flatnonzero(self.known[i] < best):
                    got = 0
                    for pose, entry in self.scans[k][self.known[i, k]:best[k]]:
                        if isinstance(entry, float):
                            self.grids[i].mark_free_disc(pose.x, pose.y, entry)
                        else:
                            self.grids[i].update(pose, entry)
                            got += 1
                    self.received[i] += got
                    total += got
                    self.known[i, k] = best[k]
        return total

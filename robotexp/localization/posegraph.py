"""Loop closure, an optional stage after scan matching: a pose graph over the scan poses with the matched
increments as edges, loop edges found by matching a scan against a submap of an earlier, nearby part
of the path, and Gauss-Newton on the graph (Grisetti et al. 2010, "A tutorial on graph-based SLAM").

Loop edges are only added when the scan fits the submap well and unambiguously (not a corridor), and
the optimisation weighs them with a Cauchy kernel, so that a wrong one pulls little.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.localization.matcher import HitMap, MatcherConfig, ScanMatcher, fill_walls, relative, scan_points
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import LaserScan, Pose

__all__ = ["Edge", "LoopConfig", "optimize", "find_loops", "close_loops"]


@dataclass(frozen=True)
class Edge:
    """A measured pose of node j in the frame of node i, with its information matrix (3x3, inverse
    covariance in x, y [m] and theta [rad]); `loop` edges get the robust kernel."""

    i: int
    j: int
    z: Pose
    info: npt.NDArray[np.float64]
    loop: bool = False


@dataclass(frozen=True)
class LoopConfig:
    """Loop-closure settings.

    Attributes:
        min_gap: a loop edge joins scans at least this many scans apart.
        radius: [m] the earlier scan's estimated position lies within this of the current one.
        every: try a loop closure at every `every`-th scan.
        submap: scans on each side of the earlier scan that make its submap.
        window_xy: [m] half-width of the search window (the drift a loop can correct).
        window_theta: [rad] half-width of the heading window.
        min_score: mean field value a loop match must reach.
        min_conditioning: smallest / largest eigenvalue of the loop match's translation information
            it must reach: along a corridor a loop match can slide by metres and still fit.
        sigma_xy: [m] standard deviation of a matched increment's and a loop edge's position.
        sigma_theta: [rad] the same for heading.
        cauchy: [in standard deviations] scale of the Cauchy kernel on loop edges.
        iterations: Gauss-Newton iterations on the graph.
    """

    min_gap: int = 40
    radius: float = 4.0
    every: int = 2
    submap: int = 6
    window_xy: float = 1.5
    window_theta: float = math.radians(10.0)
    min_score: float = 0.55
    min_conditioning: float = 0.2
    sigma_xy: float = 0.05
    sigma_theta: float = math.radians(0.5)
    cauchy: float = 3.0
    iterations: int = 10

    def __post_init__(self) -> None:
        if self.min_gap < 1 or self.every < 1 or self.submap < 0 or self.iterations < 0:
            raise ConfigError(f"loop closure: min_gap, every >= 1 and submap, iterations >= 0 expected, got {self}")
        if not (self.radius > 0 and self.sigma_xy > 0 and self.sigma_theta > 0 and self.cauchy > 0):
            raise ConfigError(f"loop closure: radius, sigmas and cauchy must be > 0, got {self}")


def _info(cfg: LoopConfig) -> npt.NDArray[np.float64]:
    return np.diag([cfg.sigma_xy ** -2, cfg.sigma_xy ** -2, cfg.sigma_theta ** -2])


def _wrap(a: npt.NDArray[np.float64] | float) -> npt.NDArray[np.float64] | float:
    return (a + np.pi) % (2 * np.pi) - np.pi


def check_edges(edges: Sequence[Edge], n: int) -> None:
    """Raise ConfigError when an edge names a node outside 0..n-1."""
    for e in edges:
        if not (0 <= e.i < n and 0 <= e.j < n):
            raise ConfigError(f"pose graph: edge {e.i} -> {e.j} outside the {n} nodes")


def _edge_arrays(edges: Sequence[Edge]) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp], npt.NDArray[np.float64],
                                                  npt.NDArray[np.float64], npt.NDArray[np.bool_]]:
    i = np.array([e.i for e in edges], np.intp)
    j = np.array([e.j for e in edges], np.intp)
    z = np.array([[e.z.x, e.z.y, e.z.theta] for e in edges], np.float64).reshape(-1, 3)
    info = np.array([e.info for e in edges], np.float64).reshape(-1, 3, 3)
    loop = np.array([e.loop for e in edges], bool)
    return i, j, z, info, loop


def optimize(poses: npt.ArrayLike, edges: Sequence[Edge], *, iterations: int = 10, cauchy: float = 3.0
             ) -> npt.NDArray[np.float64]:
    """Gauss-Newton on the pose graph, node 0 held fixed; loop edges weighted by a Cauchy kernel of
    scale `cauchy` (in units of their standard deviation) by iterative reweighting.

    The normal equations are assembled for all edges at once and solved as a sparse system (scipy), so a
    graph of thousands of poses costs milliseconds and memory in proportion to its edges (a dense
    system of the 4791 scans of Freiburg building 079 took 6 minutes and 3.5 GB);
    `robotexp.localization.reference.optimize_ref` is the edge-by-edge dense reference.

    Args:
        poses: (n, 3) initial [x, y, theta].
        edges: the constraints.
        iterations: at most this many steps (stops when the step is below 1e-6).
        cauchy: the kernel's scale.

    Returns:
        (n, 3) optimised poses.

    Raises:
        ConfigError: an edge names a node outside 0..n-1.
    """
    from scipy.sparse import coo_matrix  # type: ignore[import-untyped]  # scipy: a dependency (statistics)
    from scipy.sparse.linalg import spsolve  # type: ignore[import-untyped]

    x = np.array(poses, np.float64, copy=True).reshape(-1, 3)
    n = len(x)
    check_edges(edges, n)
    if not edges or n == 0:
        return x
    ei, ej, z, info, loop = _edge_arrays(edges)
    m = len(ei)
    k = np.arange(3)
    # the (row, col) of each 3x3 block's entries: blocks (i, i), (i, j), (j, i), (j, j) of every edge
    rows = [np.broadcast_to((3 * a)[:, None, None] + k[None, :, None], (m, 3, 3)) for a in (ei, ei, ej, ej)]
    cols = [np.broadcast_to((3 * a)[:, None, None] + k[None, None, :], (m, 3, 3)) for a in (ei, ej, ei, ej)]
    rr, cc = np.concatenate(rows), np.concatenate(cols)
    diag = np.arange(3 * n)
    for _ in range(iterations):
        xi, xj = x[ei], x[ej]
        ci, si = np.cos(xi[:, 2]), np.sin(xi[:, 2])
        cz, sz = np.cos(z[:, 2]), np.sin(z[:, 2])
        dx, dy = xj[:, 0] - xi[:, 0], xj[:, 1] - xi[:, 1]
        lx, ly = ci * dx + si * dy, -si * dx + ci * dy          # xj's position in xi's frame
        ex, ey = lx - z[:, 0], ly - z[:, 1]
        err = np.column_stack([cz * ex + sz * ey, -sz * ex + cz * ey, _wrap(xj[:, 2] - xi[:, 2] - z[:, 2])])
        c, s = np.cos(xi[:, 2] + z[:, 2]), np.sin(xi[:, 2] + z[:, 2])      # R(-z) R(-theta_i)
        a = np.zeros((m, 3, 3))
        a[:, 0, 0], a[:, 0, 1], a[:, 1, 0], a[:, 1, 1] = -c, -s, s, -c
        a[:, 0, 2] = cz * ly - sz * lx
        a[:, 1, 2] = -sz * ly - cz * lx
        a[:, 2, 2] = -1.0
        b = np.zeros((m, 3, 3))
        b[:, 0, 0], b[:, 0, 1], b[:, 1, 0], b[:, 1, 1] = c, s, -s, c
        b[:, 2, 2] = 1.0
        omega = info
        if loop.any():
            chi2 = np.einsum("mi,mij,mj->m", err, info, err)
            w = np.where(loop, 1.0 / (1.0 + chi2 / (cauchy * cauchy)), 1.0)
            omega = info * w[:, None, None]
        at_o = np.einsum("mki,mkl->mil", a, omega)           # A^T Omega
        bt_o = np.einsum("mki,mkl->mil", b, omega)
        blocks = np.concatenate([np.einsum("mil,mlj->mij", at_o, a), np.einsum("mil,mlj->mij", at_o, b),
                                 np.einsum("mil,mlj->mij", bt_o, a), np.einsum("mil,mlj->mij", bt_o, b)])
        h = coo_matrix((blocks.ravel(), (rr.ravel(), cc.ravel())), shape=(3 * n, 3 * n))
        h = (h + coo_matrix((np.full(3 * n, 1e-9) + np.where(diag < 3, 1e12, 0.0), (diag, diag)),
                            shape=(3 * n, 3 * n))).tocsc()    # hold node 0
        rhs = np.zeros(3 * n)
        np.add.at(rhs, 3 * ei[:, None] + k, np.einsum("mil,ml->mi", at_o, err))
        np.add.at(rhs, 3 * ej[:, None] + k, np.einsum("mil,ml->mi", bt_o, err))
        step = np.asarray(spsolve(h, -rhs))
        x += step.reshape(n, 3)
        x[:, 2] = _wrap(x[:, 2])
        if np.abs(step).max() < 1e-6:
            break
    return x


def _submap(poses: npt.NDArray[np.float64], scans: Sequence[LaserScan], centre: int, k: int, cell: float,
            reach: float, *, fill: bool) -> tuple[OccupancyGrid, HitMap]:
    """The matching map of scans centre-k .. centre+k at their poses (walls filled in with `fill`, as the
    `Localizer` fills its map: `fill_walls`), and where their hits fell."""
    lo, hi = max(centre - k, 0), min(centre + k + 1, len(scans))
    xy = poses[lo:hi, :2]
    # the grid covers what the scans can touch: their own reach when shorter than `reach` (a 3 m laser's
    # submap is 9x smaller than one padded by a 12 m matcher cap, and holds the same cells)
    own = max(s.range_max + abs(s.offset_x) for s in scans[lo:hi]) + cell
    geo = GridGeometry.covering(float(xy[:, 0].min()), float(xy[:, 1].min()), float(xy[:, 0].max()),
                                float(xy[:, 1].max()), cell, margin=min(reach, own))
    grid = OccupancyGrid(geo, p_occ=0.9, p_free=0.4, range_max=reach)
    hits = HitMap(geo)
    for m in range(lo, hi):
        scan = fill_walls(scans[m], cell) if fill else scans[m]
        grid.update(Pose(*poses[m]), scan)
        hits.add(Pose(*poses[m]), scan, reach)
    return grid, hits


def find_loops(poses: npt.NDArray[np.float64], scans: Sequence[LaserScan], cell: float, matcher: MatcherConfig,
               cfg: LoopConfig) -> list[Edge]:
    """Loop edges: for every `cfg.every`-th scan, the nearest earlier scan at least `min_gap` before it
    within `radius`; the scan is matched against that scan's submap and kept when the fit is good."""
    out: list[Edge] = []
    mcfg = replace(matcher, window_xy=cfg.window_xy, window_theta=cfg.window_theta, min_score=cfg.min_score, prior=0.0,
                   motion_sigma_xy=cfg.window_xy, motion_sigma_theta=cfg.window_theta)
    sm = ScanMatcher(mcfg)
    xy = poses[:, :2]
    for i in range(cfg.min_gap, len(poses), cfg.every):
        earlier = xy[: i - cfg.min_gap + 1]
        d = np.hypot(*(earlier - xy[i]).T)
        j = int(np.argmin(d))
        if d[j] > cfg.radius:
            continue
        grid, hits = _submap(poses, scans, j, cfg.submap, cell, matcher.range_max + cfg.window_xy,
                             fill=matcher.exact_field)
        px, py = scan_points(scans[i], matcher.range_max)
        m = sm.match(grid.values, grid.geo, px, py, Pose(*poses[i]), hits)
        if m.status != "matched" or m.conditioning < cfg.min_conditioning:
            continue
        out.append(Edge(j, i, relative(Pose(*poses[j]), m.pose), _info(cfg), loop=True))
    return out


def close_loops(poses: npt.ArrayLike, scans: Sequence[LaserScan], *, cell: float, matcher: MatcherConfig,
                cfg: LoopConfig | None = None, rounds: int = 2) -> tuple[npt.NDArray[np.float64], int]:
    """The scan-matched path (n, 3) corrected by loop closure: sequential edges from the matched
    increments, loop edges from `find_loops`, optimised; repeated `rounds` times (loops found on the
    corrected path). Returns the corrected path and the number of loop edges of the last round."""
    c = cfg or LoopConfig()
    est = np.array(poses, np.float64, copy=True)
    chain = [Edge(k, k + 1, relative(Pose(*est[k]), Pose(*est[k + 1])), _info(c)) for k in range(len(est) - 1)]
    loops: list[Edge] = []
    for _ in range(rounds):
        loops = find_loops(est, scans, cell, matcher, c)
        if not loops:
            break
        est = optimize(est, chain + loops, iterations=c.iterations, cauchy=c.cauchy)
    return est, len(loops)

"""The built-in coordinators of a team: none, greedy, burgard (Burgard et al. 2005) and minpos (Bautin et
al. 2012), as robotexp coordinator plugins (the `robotexp.coordinators` entry-point group)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from robotexp import Candidates, ConfigError, Coordinator

__all__ = ["NoCoordinator", "GreedyCoordinator", "BurgardCoordinator", "MinPosCoordinator"]


class NoCoordinator(Coordinator):
    """No coordination: each robot's explorer decides alone on the team's map (which it shares or, with a
    communication range, merges)."""

    assigns_targets = False

    def assign(self, candidates: Candidates, kept: Sequence[int | None]) -> list[int | None]:
        """Nothing is assigned."""
        return list(kept)


def _free_robots(candidates: Candidates, kept: Sequence[int | None]) -> list[int]:
    """The robots without a target, nearest first to their nearest target (ties: robot order)."""
    free = [i for i, k in enumerate(kept) if k is None]
    nearest = [float(np.min(candidates.cost[i])) if len(candidates) else math.inf for i in free]
    return [i for _, i in sorted(zip(nearest, free, strict=True))]


class GreedyCoordinator(Coordinator):
    """Nearest frontier with reservation: robots without a target, the one nearest to some target first,
    each take the nearest target (by path) that no other robot has taken; when every reachable target is
    taken a robot shares the nearest one."""

    def assign(self, candidates: Candidates, kept: Sequence[int | None]) -> list[int | None]:
        """Each free robot its nearest unreserved target."""
        out = list(kept)
        taken = {k for k in kept if k is not None}
        for i in _free_robots(candidates, kept):
            cost = candidates.cost[i]
            order = [k for k in np.argsort(cost, kind="stable") if math.isfinite(cost[k])]
            choice = next((int(k) for k in order if int(k) not in taken), int(order[0]) if order else None)
            out[i] = choice
            if choice is not None:
                taken.add(choice)
        return out


class BurgardCoordinator(Coordinator):
    """Utility minus cost (Burgard, Moors, Stachniss and Schneider 2005, "Coordinated multi-robot exploration").

    Every target starts with utility 1. Targets already assigned (kept) lower the utility of the targets
    near them: a target at distance d from an assigned one loses 1 - d / range when d < range, the laser
    range (the chance that the assigned robot's sensor covers it, linear in distance). Then, robot by
    robot, the free robot and target with the largest utility minus `beta` times the robot's path cost,
    divided by `cost_scale` (or by the robot's largest finite cost), are paired and the target's
    neighbours are discounted the same way. The paper's assignment gives every robot its target point each
    time it runs; it runs here at every round (`reassigns`), on the frontier the team's scans left, so a
    robot is not held to a target whose neighbourhood a teammate's scans have since taken (the robot told
    its current target again drives on undisturbed).

    Args:
        beta: weight of the cost against the utility (the paper's beta; 1 weighs them equally).
        cost_scale: [m] the path length that costs as much as a whole target's utility (with beta 1); 0:
            each robot's farthest reachable target.
    """

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "beta": (0.0, 100.0), "cost_scale": (0.0, 10000.0)}
    reassigns = True

    def __init__(self, *, beta: float = 1.0, cost_scale: float = 0.0) -> None:
        if not (math.isfinite(beta) and beta >= 0):
            raise ConfigError(f"burgard: beta must be >= 0, got {beta}")
        if not (math.isfinite(cost_scale) and cost_scale >= 0):
            raise ConfigError(f"burgard: cost_scale must be >= 0 m, got {cost_scale}")
        self.beta = beta
        self.cost_scale = cost_scale

    def assign(self, candidates: Candidates, kept: Sequence[int | None]) -> list[int | None]:
        """Pairs of (free robot, target) by the best utility minus cost, one at a time."""
        out = list(kept)
        k = len(candidates)
        if k == 0:
            return out
        pts = candidates.points
        apart = np.hypot(pts[:, None, 0] - pts[None, :, 0], pts[:, None, 1] - pts[None, :, 1])
        rng = max(self.ctx.laser_range, 1e-9)
        utility = np.ones(k)
        for t in kept:
            if t is not None:
                utility -= np.clip(1.0 - apart[t] / rng, 0.0, None)
        cost = candidates.cost
        scaled = np.full_like(cost, -np.inf)
        for i in range(cost.shape[0]):
            finite = np.isfinite(cost[i])
            if finite.any():
                top = self.cost_scale or max(float(cost[i][finite].max()), 1e-9)
                scaled[i, finite] = -self.beta * cost[i, finite] / top
        free = [i for i, t in enumerate(kept) if t is None]
        while free:
            gain = utility[None, :] + scaled[free]
            flat = int(np.argmax(gain))
            r, t = divmod(flat, k)
            if not math.isfinite(gain[r, t]):
                break
            robot = free.pop(r)
            out[robot] = t
            utility -= np.clip(1.0 - apart[t] / rng, 0.0, None)
        return out


class MinPosCoordinator(Coordinator):
    """MinPos (Bautin, Simonin and Charpillet 2012, "MinPos: a novel frontier allocation algorithm for
    multi-robot exploration"): each free robot goes to the target where it ranks best, its rank at a
    target being how many robots are nearer to it by path; ties go to the nearer target. Robots that
    already have a target count in the ranks as well. As in the paper, the allocation is recomputed for
    every robot at every round (`reassigns`): a robot that passes a frontier where it ranks better turns
    to it, and one whose target a teammate now reaches first is sent elsewhere. A robot on its way to a
    target of the best rank keeps it (the nearer target breaks only the other ties): two robots about as
    far from two targets would otherwise swap them back and forth as their paths change by a cell."""

    reassigns = True

    def assign(self, candidates: Candidates, kept: Sequence[int | None]) -> list[int | None]:
        """Each free robot the target of its lowest rank, nearest on a tie."""
        out = list(kept)
        cost = candidates.cost
        for i, t in enumerate(kept):
            if t is not None or len(candidates) == 0:
                continue
            mine = cost[i]
            reachable = np.isfinite(mine)
            if not reachable.any():
                continue
            rank = (cost < mine[None, :]).sum(axis=0).astype(np.float64)
            rank[~reachable] = np.inf
            best = np.flatnonzero(rank == rank.min())
            held = candidates.held[i] if i < len(candidates.held) else None
            out[i] = held if held in best else int(best[np.argmin(mine[best])])
        return out

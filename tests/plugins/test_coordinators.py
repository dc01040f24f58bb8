"""The built-in coordinators on rounds worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp import Candidates, ConfigError, TeamContext
from robotexp_plugins.coordinators import BurgardCoordinator, GreedyCoordinator, MinPosCoordinator, NoCoordinator

INF = math.inf


def round_of(points, cost):
    points = np.asarray(points, np.float64)
    cost = np.asarray(cost, np.float64)
    cells = tuple(np.array([[i, i]], np.int64) for i in range(len(points)))
    return Candidates(points=points, cells=cells, cost=cost, positions=np.zeros((cost.shape[0], 2)))


def ready(c, size=3, laser_range=3.0):
    c.reset(TeamContext(size=size, laser_range=laser_range, radius=(0.25,) * size, rng=np.random.default_rng(0)))
    return c


def test_greedy_reserves_what_the_nearer_robot_took():
    # both robots are nearest to target 0; robot 1 is nearer to it (2 < 3), takes it first; robot 0 gets
    # its next nearest, target 2 (5), not target 1 (6)
    cand = round_of([(0, 0), (10, 0), (0, 10)], [[3.0, 6.0, 5.0], [2.0, 4.0, 9.0]])
    assert ready(GreedyCoordinator()).assign(cand, [None, None]) == [2, 0]
    # a kept target is reserved as well
    assert ready(GreedyCoordinator()).assign(cand, [None, 0]) == [2, 0]
    # more robots than targets: the last one shares its nearest
    cand = round_of([(0, 0)], [[1.0], [2.0]])
    assert ready(GreedyCoordinator()).assign(cand, [None, None]) == [0, 0]


def test_burgard_discounts_targets_within_the_sensor_range_of_an_assigned_one():
    # targets 0 and 1 lie 1 m apart, target 2 far away; laser range 3 m.
    # robot 0: costs 1, 2, 4 (normalised by 4: 0.25, 0.5, 1); robot 1: costs 2, 1, 8 (0.25, 0.125, 1)
    # first pick: utilities 1, 1, 1: best is robot 1 -> target 1 (1 - 0.125 = 0.875 > robot 0's 0.75);
    # then target 0 loses 1 - 1/3 = 2/3 (utility 1/3), target 2 (10 m away) nothing:
    # robot 0: 1/3 - 0.25 = 0.083, 0 - 0.5 (target 1 now 0), 1 - 1 = 0 -> target 0
    cand = round_of([(0, 0), (1, 0), (11, 0)], [[1.0, 2.0, 4.0], [2.0, 1.0, 8.0]])
    assert ready(BurgardCoordinator()).assign(cand, [None, None]) == [0, 1]
    # costs in units of 100 m weigh next to nothing: robot 0 - target 0 first (0.99, tied with robot 1 -
    # target 1, first in order); then robot 1: target 1 at 1/3 - 0.01, target 2 at 1 - 0.08 -> target 2
    assert ready(BurgardCoordinator(cost_scale=100.0)).assign(cand, [None, None]) == [0, 2]
    # beta 0 weighs utility alone: all ties at 1, the first pair (robot 0, target 0) wins; then target 1
    # (1 m away) keeps 1/3 and target 2 (11 m away) 1: robot 1 goes to target 2, not to its nearest
    assert ready(BurgardCoordinator(beta=0.0)).assign(cand, [None, None]) == [0, 2]
    # robot 1 keeps target 1; robot 0's costs 2, 3, 4 normalise to 0.5, 0.75, 1. Laser range 3 m: target 0
    # keeps 1/3, target 2 keeps 1: 1/3 - 0.5 < 1 - 1 -> target 2 (away from robot 1). Range 30 m: target 0
    # keeps 1 - 29/30 = 1/30 and target 2 (10 m) 1/3: 1/30 - 0.5 > 1/3 - 1 -> target 0
    cand = round_of([(0, 0), (1, 0), (11, 0)], [[2.0, 3.0, 4.0], [2.0, 1.0, 8.0]])
    assert ready(BurgardCoordinator()).assign(cand, [None, 1]) == [2, 1]
    assert ready(BurgardCoordinator(), laser_range=30.0).assign(cand, [None, 1]) == [0, 1]


def test_burgard_gives_no_target_a_robot_cannot_reach():
    cand = round_of([(0, 0), (5, 0)], [[INF, INF], [1.0, 2.0]])
    assert ready(BurgardCoordinator()).assign(cand, [None, None]) == [None, 0]
    with pytest.raises(ConfigError, match="beta"):
        BurgardCoordinator(beta=-1.0)


def test_minpos_sends_each_robot_where_fewest_robots_are_nearer():
    # robots 0 and 1 both nearest to target 0; robot 0 is second there (rank 1) but first at target 1
    # (rank 0, robot 1 is farther), so it goes to target 1 although target 0 is nearer to it
    cand = round_of([(0, 0), (5, 0)], [[2.0, 6.0], [1.0, 7.0]])
    assert ready(MinPosCoordinator()).assign(cand, [None, None]) == [1, 0]
    # three robots, two targets: robot 2 ranks 1 at both targets (rank ties: nearer target, 3 < 4)
    cand = round_of([(0, 0), (5, 0)], [[1.0, 9.0], [9.0, 1.0], [3.0, 4.0]])
    assert ready(MinPosCoordinator()).assign(cand, [None, None, None]) == [0, 1, 0]
    # robots that keep a target still count in the ranks
    assert ready(MinPosCoordinator()).assign(cand, [0, 1, None]) == [0, 1, 0]


def test_none_assigns_nothing():
    cand = round_of([(0, 0)], [[1.0]])
    c = ready(NoCoordinator(), size=1)
    assert not c.assigns_targets
    assert c.assign(cand, [None]) == [None]


def test_minpos_and_burgard_choose_every_robots_target_anew_and_minpos_keeps_a_held_one_on_a_tie():
    from dataclasses import replace

    assert MinPosCoordinator.reassigns and BurgardCoordinator.reassigns
    assert not GreedyCoordinator.reassigns
    # robot 0 ranks 0 at both targets (robot 1 is farther from both); the nearer is target 1 (3 < 4), but
    # robot 0 is on its way to target 0, which ranks as well: it keeps it
    cand = round_of([(0, 0), (5, 0)], [[4.0, 3.0], [6.0, 8.0]])
    assert ready(MinPosCoordinator()).assign(cand, [None, None]) == [1, 0]
    assert ready(MinPosCoordinator()).assign(replace(cand, held=(0, None)), [None, None]) == [0, 0]
    # a held target of a worse rank is left: robot 0 ranks 1 at its target 1 (robot 1 is 2 m away, robot 0
    # 3 m) and 0 at target 0; robot 1 ranks 1 at its target 0 and 0 at target 1: they swap
    cand = round_of([(0, 0), (5, 0)], [[4.0, 3.0], [6.0, 2.0]])
    assert ready(MinPosCoordinator()).assign(replace(cand, held=(1, 0)), [None, None]) == [0, 1]

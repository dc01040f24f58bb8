"""Every explorer through the doors real robots pass: five 4 x 4 m rooms in a row joined by off-centre
doors (`rooms_in_a_row`), 0.65 m wide for the P3-DX preset (a 0.5 m disc: 7.5 cm to spare on each side)
and 0.50 m for the Kobuki (0.35 m). Each run goes from the middle of the first room through the
simulator and the run loop, with the ground truth's coverage and the run's honest ending; each takes
1-4 s of wall time (benchmarks/studies/doors.py prints the same matrix with its timings).
"""

from __future__ import annotations

import numpy as np
import pytest

from robotexp.experiment import run_experiment
from robotexp.mapping.geometry import GridGeometry
from robotexp.run.spec import RunSpec
from robotexp.world.builtin import DOOR_CENTRES, rooms_in_a_row
from robotexp.world.groundtruth import ground_truth

DOORS = {"p3dx": (0.65, 0.25), "kobuki": (0.50, 0.175),     # door [m], half the robot's width [m]
         "p3dx-body": (0.65, 0.1905)}                         # the P3-DX's rectangular body: it turns in 0.59 m


@pytest.mark.parametrize("robot", ["p3dx", "kobuki", "p3dx-body"])
@pytest.mark.parametrize("method", ["frontier", "bvp", "srt-laser", "meta-ga", "meta-firefly"])
def test_every_explorer_passes_every_door(method: str, robot: str) -> None:
    door, _ = DOORS[robot]
    out = run_experiment(RunSpec(world=rooms_in_a_row(door), method=method, robot=robot,  # type: ignore[arg-type]
                                 max_time=1800.0), None)
    r = out.record
    assert r["collisions"] == 0
    assert r["completed"], r["reason"]          # ended by the explorer, not by the run's check or a limit
    assert r["coverage"] is not None and r["coverage"] >= 0.95
    # it stood in the last room (x > 16 m): through all four doors
    assert max(x for x, _ in out.run.metrics.path) > 16.3


def test_the_doors_are_open_to_the_robot_and_off_the_middle() -> None:
    for robot, (door, radius) in DOORS.items():
        world = rooms_in_a_row(door)
        geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=0.5)
        truth = ground_truth(world, geo, robot_radius=radius, laser_range=3.0, start=world.poses["first room"])
        # the exact ground truth: every room reachable with this door, none past a door 2 cm narrower than the robot
        for k in range(5):
            assert truth.reachable[geo.cell_of(4 * k + 2.0, 2.0)], (robot, k)
        shut = rooms_in_a_row(2 * radius - 0.02)
        closed = ground_truth(shut, geo, robot_radius=radius, laser_range=3.0, start=shut.poses["first room"])
        assert not closed.reachable[geo.cell_of(6.0, 2.0)]
    # off the middle (2 m), alternating sides
    assert all(abs(y - 2.0) > 0.5 for y in DOOR_CENTRES)
    assert np.all(np.diff(np.sign(np.array(DOOR_CENTRES) - 2.0)) != 0)

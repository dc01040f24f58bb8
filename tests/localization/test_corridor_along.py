"""Scan matching along a corridor keeps odometry's distance: a straight corridor drawn here (walls 0.15 m
thick, shallow recesses in them every few metres: the only features along it), the frontier explorer from
one end to the other with error-free odometry and a 3 m laser. Where a match hardly fixes the position along
the corridor the pose must follow the prediction there; taking each match's correction along it (the fusion's
`fuse_ratio` 0) made the estimate run ahead or behind by decimetres."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from robotexp.experiment import run_experiment
from robotexp.localization.robot import LocalizedRobot
from robotexp.mapping.geometry import GridGeometry
from robotexp.run.spec import RunSpec
from robotexp.world.rosmap import save_ros_map

CELL = 0.05
LENGTH = 30.0


def corridor(folder: Path, width: float, recess_every: float) -> Path:
    """A ROS map: a LENGTH x `width` corridor, closed at both ends, with a 0.3 m long, 0.1 m deep recess in
    alternate walls every `recess_every` metres; unknown outside."""
    geo = GridGeometry(-1.0, -1.0, CELL, int((width + 2) / CELL), int((LENGTH + 2) / CELL))
    x = geo.origin_x + (np.arange(geo.cols) + 0.5) * CELL
    y = geo.origin_y + (np.arange(geo.rows) + 0.5) * CELL
    xx, yy = np.meshgrid(x, y)
    inside = (xx > 0) & (xx < LENGTH) & (yy > 0) & (yy < width)
    wall = (xx > -0.15) & (xx < LENGTH + 0.15) & (yy > -0.15) & (yy < width + 0.15) & ~inside
    values = np.full((geo.rows, geo.cols), -1, np.int8)
    values[wall] = 100
    values[inside] = 0
    for k, x0 in enumerate(np.arange(recess_every, LENGTH, recess_every)):
        side = 0.0 if k % 2 == 0 else width
        values[wall & (xx > x0) & (xx < x0 + 0.3) & (np.abs(yy - side) < 0.1)] = 0
    path = folder / "corridor.yaml"
    save_ros_map(path, values, geo)
    return path


@pytest.mark.parametrize("width, recess_every", [(1.6, 5.0), (2.5, 5.0), (2.0, 8.0)])
def test_the_estimate_keeps_odometrys_distance_along_a_corridor(tmp_path: Path, width: float,
                                                                 recess_every: float) -> None:
    world = corridor(tmp_path, width, recess_every)
    spec = RunSpec(world=str(world), method="frontier", laser_range=3.0, odometry="none", localize="scan-match",
                   pose="1000,1000,0", max_time=600.0)
    out = run_experiment(spec, None)
    robot = out.run.robot
    assert isinstance(robot, LocalizedRobot)
    est = np.array([[p.x, p.y] for p, _ in robot.track])
    true = np.array([[q.x, q.y] for _, q in robot.track])
    assert true[:, 0].max() > LENGTH - 4.0                  # it drove the corridor's length
    along = est[:, 0] - true[:, 0]
    assert np.abs(along).max() < 0.05
    assert out.record["ate_m"] is not None and out.record["ate_m"] < 0.05
    assert math.isfinite(out.record["coverage"]) and out.record["coverage"] > 0.9

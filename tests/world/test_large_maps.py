"""Large and absurd maps: point maps as merged boxes without pybullet bodies, the exact collision
test that replaces them (against pybullet and a numpy reference), sizes refused before allocation."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ConfigError
from robotexp.mapping.geometry import BYTES_PER_CELL, GridGeometry, check_grid_size
from robotexp.sim.engine import Engine
from robotexp.world.raycast import RayIndex
from robotexp.world.mobilesim import load_mobilesim
from robotexp.world.model import World


def random_world(rng: np.random.Generator, collision: str) -> World:
    boxes = np.column_stack([rng.uniform(0, 10, 60), rng.uniform(0, 10, 60), rng.uniform(0.02, 0.6, 60),
                             rng.uniform(0.02, 0.6, 60), rng.uniform(-math.pi, math.pi, 60)])
    discs = np.column_stack([rng.uniform(0, 10, 15), rng.uniform(0, 10, 15), rng.uniform(0.05, 0.4, 15)])
    return World("random", boxes, discs, collision=collision)


def reference_distance(world: World, x: float, y: float) -> float:
    """Distance from (x, y) to the nearest obstacle, in plain numpy (0 inside one)."""
    cx, cy, hx, hy, yaw = world.boxes.T
    px, py = x - cx, y - cy
    lx = np.abs(np.cos(yaw) * px + np.sin(yaw) * py)
    ly = np.abs(-np.sin(yaw) * px + np.cos(yaw) * py)
    d_box = np.hypot(np.maximum(lx - hx, 0.0), np.maximum(ly - hy, 0.0))
    d_disc = np.maximum(np.hypot(x - world.discs[:, 0], y - world.discs[:, 1]) - world.discs[:, 2], 0.0)
    return float(min(d_box.min(), d_disc.min()))


def test_index_collision_agrees_with_the_numpy_reference_and_with_pybullet_bodies():
    rng = np.random.default_rng(5)
    index_world, body_world = random_world(rng, "index"), random_world(np.random.default_rng(5), "bodies")
    radius = 0.25
    index = RayIndex(index_world.boxes, index_world.discs, 1.0)
    with_index = Engine(index_world, radius, 0.5)
    with_bodies = Engine(body_world, radius, 0.5)
    try:
        assert with_index.statics == [] and len(with_bodies.statics) == 75
        checked = 0
        for x, y in rng.uniform(-0.5, 10.5, size=(600, 2)):
            d = reference_distance(index_world, x, y)
            for margin in (0.0, 0.1):
                expected = d <= radius + margin
                assert index.near(x, y, radius + margin) == expected
                if abs(d - radius - margin) < 1e-3:
                    continue                   # pybullet's contact tolerance decides the borderline
                with_index.place_robot(x, y)
                with_bodies.place_robot(x, y)
                assert with_index.robot_near_obstacle(margin) == expected
                assert with_bodies.robot_near_obstacle(margin) == expected
                checked += 1
        assert checked > 1000
    finally:
        with_index.close()
        with_bodies.close()


def test_index_rays_hit_the_same_walls_as_with_bodies():
    world = random_world(np.random.default_rng(8), "index")
    bodies = random_world(np.random.default_rng(8), "bodies")
    a, b = Engine(world, 0.2, 0.5), Engine(bodies, 0.2, 0.5)
    try:
        origins = np.tile([[5.0, 5.0]], (360, 1))
        headings = np.linspace(-math.pi, math.pi, 360, endpoint=False)
        np.testing.assert_array_equal(a.cast_from(origins, headings, 8.0, 0.3),
                                      b.cast_from(origins, headings, 8.0, 0.3))
    finally:
        a.close()
        b.close()


def point_map(tmp_path: Path, n_side: int) -> Path:
    """A square room of 20 mm points, n_side points along each wall, plus a home inside."""
    xs = np.arange(n_side) * 20
    top = xs[-1]
    pts = np.vstack([np.column_stack([xs, np.zeros_like(xs)]), np.column_stack([xs, np.full_like(xs, top)]),
                     np.column_stack([np.zeros_like(xs), xs]), np.column_stack([np.full_like(xs, top), xs])])
    path = tmp_path / "points.map"
    path.write_text(f"2D-Map\nResolution: 20\nCairn: RobotHome {top // 2} {top // 2} 0 \"\" ICON \"\"\nDATA\n"
                    + "\n".join(f"{x} {y}" for x, y in pts) + "\n")
    return path


def test_a_point_map_is_a_few_merged_boxes_and_the_robot_stops_at_its_wall(tmp_path):
    from robotexp.robot import Twist
    from robotexp.sim import SimRobot

    world = load_mobilesim(point_map(tmp_path, 250))        # a 4.98 m room of 4 x 250 points
    assert len(world.boxes) == 4 and world.collision == "index"
    with SimRobot(world, pose=world.home, sonar=False) as robot:
        scan = robot.scan()
        # from the home (2.49, 2.49) the east wall's inner face is at x = 4.98 - 0.01 m (points of 20 mm)
        ahead = int(np.argmin(np.abs(scan.angles)))
        assert scan.angles[ahead] == 0.0
        assert scan.ranges[ahead] == pytest.approx(4.97 - 2.49 - robot.laser_config.offset_x, abs=1e-9)
        robot._command(Twist(0.5, 0.0))
        for _ in range(200):
            robot.advance(0.05)
        assert robot.collisions == 1
        # stopped touching the inner face x = 4.97 m of the east wall
        assert robot.true_pose.x + robot.radius == pytest.approx(4.97, abs=0.01)


def test_check_grid_size_names_the_cell_count_and_the_memory():
    check_grid_size(50.0, 50.0, 0.05)                                      # 1e6 cells: fine
    with pytest.raises(ConfigError) as info:
        check_grid_size(1e6, 1e6, 0.05)
    message = str(info.value)
    assert "4e+14 cells" in message and f"{4e14 * BYTES_PER_CELL / 1e12:.3g} TB" in message
    assert "\n" not in message
    with pytest.raises(ConfigError, match="2.5e\\+07 cells.*limit 2.5e\\+07 cells"):
        check_grid_size(50.0, 50.0, 0.0099999)
    with pytest.raises(ConfigError, match="not finite"):
        GridGeometry.covering(0.0, 0.0, math.inf, 1.0, 0.05)
    with pytest.raises(ConfigError, match="cells"):
        GridGeometry.covering(-1e300, 0.0, 1e300, 1.0, 0.05)


@pytest.mark.parametrize("case", ["yaml-res-1e6", "yaml-res-1e300", "yaml-res-1e-300", "yaml-origin-1e308",
                                  "map-1e9mm", "cell-5mm"])
def test_absurd_sizes_exit_2_with_one_line_before_any_run(tmp_path, case):
    from robotexp.world.rosmap import save_ros_map

    values = np.zeros((20, 20), np.int8)
    values[0, :] = values[-1, :] = values[:, 0] = values[:, -1] = 100
    save_ros_map(tmp_path / "base.yaml", values, GridGeometry(0.0, 0.0, 0.1, 20, 20))
    base = (tmp_path / "base.yaml").read_text()
    args = []
    if case.startswith("yaml"):
        key, value = {"yaml-res-1e6": ("resolution: 0.1", "resolution: 1e6"),
                      "yaml-res-1e300": ("resolution: 0.1", "resolution: 1e300"),
                      "yaml-res-1e-300": ("resolution: 0.1", "resolution: 1e-300"),
                      "yaml-origin-1e308": ("origin: [0.0", "origin: [1e308")}[case]
        world = tmp_path / "bad.yaml"
        world.write_text(base.replace(key, value))
        fragment = "bad.yaml:"
    elif case == "map-1e9mm":
        world = tmp_path / "far.map"
        world.write_text("2D-Map\nLINES\n0 0 999999999 0\n0 0 0 999999999\n")
        fragment = "cells, which would need about"
    else:
        world = tmp_path / "big.map"        # 60 x 60 m: 1.4e8 cells of 5 mm
        world.write_text("2D-Map\nCairn: RobotHome 1000 1000 0 \"\" ICON \"\"\nLINES\n0 0 60000 0\n0 0 0 60000\n"
                         "60000 0 60000 60000\n0 60000 60000 60000\n")
        args = ["--cell", "5"]
        fragment = "cells, which would need about"
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["explore", "-w", str(world), "-o", str(out), "--max-time", "5", *args])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("robotexp: error: ") and fragment in lines[0], result.output
    assert not (out / "results.jsonl").exists()

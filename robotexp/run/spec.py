"""What one run is (`RunSpec`, checked before anything moves) and its plan (world, start, map geometry,
ground truth: `plan_run`), and the embedded simulator's robot for it (`sim_robot`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from robotexp.errors import ConfigError
from robotexp.explorer import Explorer
from robotexp.mapping.geometry import GridGeometry
from robotexp.registry import make_explorer
from robotexp.robot import Pose
from robotexp.world.bounds import exploration_area, with_boundary_walls
from robotexp.world.model import World
from robotexp.world.poses import resolve_pose

if TYPE_CHECKING:
    from robotexp.sim import SimRobot
    from robotexp.world.groundtruth import GroundTruth

__all__ = ["DEFAULT_CELL", "MAP_MARGIN", "MAX_SPEED", "MAX_LASER_RANGE", "MAX_LASER_NOISE", "MAX_SEED",
           "MAX_MAP_CELLS", "RunSpec", "sim_robot", "RunPlan", "plan_run"]

DEFAULT_CELL = 0.1      # [m] map cell unless the method prefers another


MAP_MARGIN = 1.0        # [m] the map reaches this far beyond the world's obstacles


MAX_SPEED = 10.0        # [m/s] a speed limit above this is a typo (robots here do 0.7-1.5 m/s)


MAX_LASER_RANGE = 200.0  # [m] the longest laser range accepted (outdoor scanners reach 80-120 m)


MAX_LASER_NOISE = 1.0   # [m] laser noise (uniform half-width or sigma): real scanners err by 10-30 mm, 1 m


#                         already buries a room's walls; more is a unit mistake (metres given as mm)
MAX_SEED = 2**63 - 1    # seeds are non-negative 64-bit integers (numpy's generators, JSON readers)


MAX_MAP_CELLS = 1e8     # cells of a map given by limits (1e8 cells: 10 km x 10 km at 1 m, 1 km x 1 km at 10 cm)


@dataclass
class RunSpec:
    """Everything that defines one run (SI units)."""

    world: str = "dense"
    method: str = "frontier"
    pose: str | None = None             # a pose name, "x_mm,y_mm,theta_deg", or None for the default
    speed: float = 0.3                  # [m/s] maximum forward speed
    laser_range: float = 3.0            # [m]
    cell: float | None = None           # [m] map cell (None: the method's preferred, else 0.1)
    seed: int = 0
    robot: str = "p3dx"
    params: dict[str, Any] = field(default_factory=dict)   # explorer keyword parameters
    max_time: float = 4 * 3600.0        # [s] robot time
    laser_sigma: float = 0.0            # [m] gaussian laser noise
    laser_uniform: float = 0.0          # [m] uniform laser noise half-width
    map_bounds: tuple[float, float, float, float] | None = None   # [m] xmin, ymin, xmax, ymax of the map
    #                                   (None: the area the map declares, else the world's bounds plus MAP_MARGIN)
    bounds_wall: bool = False           # the simulator gets walls along the exploration area's edge
    odometry: str = "none"              # simulator odometry error (robotexp.sim.odometry_error spec)
    localize: str = "auto"              # "none", "scan-match", "slam", "auto" (robotexp.run.localize: wrap)
    team: tuple[str, ...] = ()          # a team of simulated robots, one preset each (robotexp.run.team); (): one
    coordinator: str = "none"           # the team's coordinator plugin (robotexp.coordinators)
    comm_range: float | None = None     # [m] the team's communication range (None: one shared map)
    coordinator_params: dict[str, Any] = field(default_factory=dict)   # the coordinator's keyword parameters

    def validate(self) -> None:
        """Raise ConfigError on a value out of range."""
        if not (0 < self.speed <= MAX_SPEED):
            raise ConfigError(f"speed must be > 0 and at most {MAX_SPEED * 1000:g} mm/s, got "
                              f"{self.speed * 1000:g} mm/s")
        if not (0 < self.laser_range <= MAX_LASER_RANGE):
            raise ConfigError(f"laser range must be > 0 and at most {MAX_LASER_RANGE * 1000:g} mm, got "
                              f"{self.laser_range * 1000:g} mm")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed <= MAX_SEED:
            raise ConfigError(f"seed must be an integer 0..{MAX_SEED}, got {self.seed!r}")
        if self.cell is not None and not (0.005 <= self.cell <= 2.0):
            raise ConfigError(f"cell size must be within 5..2000 mm, got {self.cell * 1000:g} mm")
        if not self.max_time > 0:
            raise ConfigError(f"max time must be > 0 s, got {self.max_time}")
        for what, noise in (("uniform", self.laser_uniform), ("sigma", self.laser_sigma)):
            if not 0 <= noise <= MAX_LASER_NOISE:       # NaN and inf refused too
                raise ConfigError(f"laser noise {what} must be within 0..{MAX_LASER_NOISE * 1000:g} mm, got "
                                  f"{noise * 1000:g} mm")
        from robotexp.run.localize import check_localize
        from robotexp.sim.presets import odometry_error

        odometry_error(self.odometry)
        check_localize(self.localize)
        if self.team:
            from robotexp.run.team import TeamSpec

            TeamSpec(robots=self.team, coordinator=self.coordinator, comm_range=self.comm_range,
                     coordinator_params=self.coordinator_params).validate()
        if self.map_bounds is not None:
            x0, y0, x1, y1 = self.map_bounds
            if not (all(math.isfinite(v) for v in self.map_bounds) and x0 < x1 and y0 < y1):
                raise ConfigError(f"map limits must be finite with min < max, got x {x0 * 1000:g}..{x1 * 1000:g}, "
                                  f"y {y0 * 1000:g}..{y1 * 1000:g} mm")
            cell = self.cell or DEFAULT_CELL
            cells = ((x1 - x0) / cell) * ((y1 - y0) / cell)
            if cells > MAX_MAP_CELLS:
                raise ConfigError(f"map limits x {x0 * 1000:g}..{x1 * 1000:g}, y {y0 * 1000:g}..{y1 * 1000:g} mm make "
                                  f"{cells:.3g} cells of {cell * 1000:g} mm, more than {MAX_MAP_CELLS:.0e}; give "
                                  "smaller limits or larger cells")


def sim_robot(spec: RunSpec, world: World, start: Pose, *, sonar: bool = True) -> SimRobot:
    """The embedded simulator's robot for `spec`: its preset, seed, laser (range and noise) and speed,
    standing at `start` in `world` (`sonar`: read the sonar ring in every state).

    Raises:
        WorldError: the start pose is outside the world or touches an obstacle.
        ConfigError: an unknown robot preset.
    """
    from robotexp.sim import LaserConfig, SimRobot, odometry_error, preset

    robot_preset = preset(spec.robot)
    laser = LaserConfig(beams=robot_preset.laser.beams, fov=robot_preset.laser.fov, range_max=spec.laser_range,
                        sigma=spec.laser_sigma, uniform=spec.laser_uniform, height=robot_preset.laser.height)
    return SimRobot(world, robot=robot_preset, pose=start, seed=spec.seed, laser=laser, max_speed=spec.speed,
                    sonar=sonar, odometry=odometry_error(spec.odometry))


@dataclass
class RunPlan:
    """A spec resolved against its world before any robot moves: the explorer, the start, the map
    geometry and the ground truth (`plan_run`)."""

    explorer: Explorer
    world: World
    start: Pose
    pose_label: str
    geo: GridGeometry
    truth: GroundTruth
    area: tuple[float, float, float, float] | None = None    # [m] the exploration area (None: the grid)


def plan_run(spec: RunSpec, world: World | str, radius: float, explorer: Explorer | None = None) -> RunPlan:
    """Resolve `spec` in `world` for a robot of `radius` [m]: the explorer (made unless given), the
    start pose, the map and the ground truth. Every check of the input happens here.

    Raises:
        WorldError, PluginError, ConfigError: bad input (unknown world, method or pose, a start in an
            obstacle or outside the map limits).
    """
    from robotexp.world.groundtruth import ground_truth
    from robotexp.world.loader import load_world

    spec.validate()
    w = load_world(world) if isinstance(world, str) else world
    if explorer is None:
        explorer = make_explorer(spec.method, spec.params)
    start, pose_label = resolve_pose(w, spec.pose, radius)
    cell = spec.cell or explorer.preferred_cell or DEFAULT_CELL
    assert w.bounds is not None
    area = exploration_area(w, spec.map_bounds)
    if spec.map_bounds is None and area is not None:
        # the area the map declares, grown to hold the start (a home placed in its margin)
        r = radius + MAP_MARGIN
        area = (min(area[0], start.x - r), min(area[1], start.y - r), max(area[2], start.x + r),
                max(area[3], start.y + r))
        geo = GridGeometry.covering(*area, cell=cell)
    elif spec.map_bounds is None:
        geo = GridGeometry.covering(*w.bounds, cell=cell, margin=MAP_MARGIN)
    else:
        geo = GridGeometry.covering(*spec.map_bounds, cell=cell)
        x0, y0, x1, y1 = spec.map_bounds
        if not (x0 <= start.x <= x1 and y0 <= start.y <= y1):
            raise ConfigError(f"start pose ({start.x * 1000:.0f}, {start.y * 1000:.0f}) mm is outside the map "
                              f"limits x {x0 * 1000:g}..{x1 * 1000:g}, y {y0 * 1000:g}..{y1 * 1000:g} mm")
    if spec.bounds_wall and area is not None:
        w = with_boundary_walls(w, area)
    truth = ground_truth(w, geo, robot_radius=radius, laser_range=spec.laser_range, start=start)
    return RunPlan(explorer, w, start, pose_label, geo, truth, area)

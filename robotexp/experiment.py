"""One exploration run, from a `RunSpec` to written results: the one run path of every robot.

`run_on_robot` runs a spec's explorer on an open robot, any backend; `run_experiment` builds the
embedded simulator's `SimRobot` for the spec and hands it to `run_on_robot`. This is what
`robotexp explore`, the Lua `exploration.start()` and campaigns all call. The parts live in their
own modules: start poses in `robotexp.world.poses`, plugin construction in `robotexp.registry`,
the loop in `robotexp.explorer`, observers in `robotexp.observers`, records in `robotexp.record`
and output files in `robotexp.results`.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robotexp.errors import ConfigError, PluginError
from robotexp.explorer import ExplorationRun, Explorer, RunInfo
from robotexp.mapping.geometry import GridGeometry
from robotexp.observers import RunObserver, SampleCallback
from robotexp.record import EndReason, RunRecord
from robotexp.registry import connect_robot, make_emulator, make_explorer
from robotexp.results import ResultsWriter, map_image, run_id
from robotexp.robot import Capability, Pose, Robot
from robotexp.watch import RunWatch, StallWatch
from robotexp.world.bounds import exploration_area, with_boundary_walls
from robotexp.world.model import World
from robotexp.world.poses import parse_pose, pose_name, resolve_pose

if TYPE_CHECKING:
    from robotexp.mapping.groundtruth import GroundTruth
    from robotexp.sim import SimRobot

__all__ = ["RunSpec", "RunOutput", "RunPlan", "run_experiment", "run_on_robot", "plan_run", "sim_robot",
           "warm_kernels",
           "DEFAULT_CELL", "MAP_MARGIN",
           # where they were before the restructure (they live in world.poses, registry and results now)
           "connect_robot", "make_emulator", "parse_pose", "resolve_pose", "make_explorer", "map_image"]

log = logging.getLogger(__name__)

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
    localize: str = "auto"              # "none", "scan-match", "slam", "auto" (robotexp.localization.run: wrap)

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
        from robotexp.localization.run import check_localize
        from robotexp.sim.presets import odometry_error

        odometry_error(self.odometry)
        check_localize(self.localize)
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


@dataclass
class RunOutput:
    """What a run leaves behind: its record and the files written."""

    record: RunRecord
    run: ExplorationRun
    image: Path | None
    plot: Path | None

    @property
    def end(self) -> EndReason:
        """Why the run ended."""
        return self.record.end

    @property
    def interrupted(self) -> bool:
        """The run was interrupted by Ctrl-C (the caller should exit 130)."""
        return self.record.end is EndReason.INTERRUPTED


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
    from robotexp.mapping.groundtruth import ground_truth
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


def run_experiment(spec: RunSpec, out: Path | None, *, observers: Iterable[RunObserver] = (),
                   on_sample: Callable[[float, float | None], None] | None = None,
                   show: tuple[str, ...] = (), image: bool | tuple[str, ...] = True,
                   record_extra: dict[str, Any] | None = None,
                   on_run: Callable[[ExplorationRun], None] | None = None) -> RunOutput:
    """Run `spec` on the embedded simulator: the spec is planned (`plan_run`), then a `SimRobot`
    (`sim_robot`) at its start is handed to `run_on_robot`, which writes the results under `out`
    (nothing when `out` is None).

    `on_sample(t, coverage)` and `on_run(run)` are called after each coverage sample (an observer's
    `on_sample` does the same; `on_run` may render frames or call `request_stop`). `image`: write the map
    and coverage figures (PNG; a tuple names the formats, e.g. ("png", "svg")) or not.

    Raises:
        WorldError, PluginError, ConfigError: bad input, before the robot moves.
        PluginError: the explorer failed during the run (its record is written first).
        OSError: the results could not be written.
    """
    from robotexp.sim import preset

    spec.validate()
    plan = plan_run(spec, spec.world, preset(spec.robot).radius)
    with sim_robot(spec, plan.world, plan.start, sonar=plan.explorer.uses_sonar) as robot:
        return run_on_robot(spec, robot, out, plan.world, observers=observers, on_sample=on_sample, show=show,
                            image=image, record_extra=record_extra, on_run=on_run, plan=plan)


WARM_TIME = 5.0        # [s] of robot time of the warm-up run (`warm_kernels`)
_WARMED: set[tuple[str, str, bool]] = set()


def warm_kernels(spec: RunSpec, robot: Robot) -> None:
    """Before a robot other than the embedded simulator moves: compile, or load from numba's cache, the
    kernels a run of `spec` calls, on `WARM_TIME` s of the same explorer (its parameters, cell, the
    localizer when the real run has one) on the embedded simulator, once per process and setting.

    numba compiles a kernel at its first call. On a fresh install that takes seconds, and in a real
    robot's run they would pass with the control loop blind: a campaign through the
    Kobuki and RPLidar emulators on a clean clone bumped 10 times in its first 12 s, or never moved.
    The warm-up writes nothing; with the kernels cached it takes a fraction of a second.
    """
    from robotexp.localization.run import wants_localizer
    from robotexp.sim import SimRobot

    if isinstance(robot, SimRobot):
        return
    localize = "scan-match" if wants_localizer(spec, robot) else "none"
    key = (spec.method, json.dumps(spec.params, sort_keys=True, default=str), localize == "scan-match")
    if key in _WARMED:
        return
    warm = RunSpec(world="dense", method=spec.method, speed=min(spec.speed, 0.3), laser_range=spec.laser_range,
                   cell=spec.cell, params=dict(spec.params), max_time=WARM_TIME, localize=localize)
    log.info("warming the kernels of %s (%s) on the embedded simulator before the robot moves", spec.method,
             "with scan matching" if localize == "scan-match" else "no localizer")
    run_experiment(warm, None, image=False)
    from robotexp.planning.grid_planner import warm as warm_planning
    warm_planning()                  # the planners' kernels a 5 s run may not reach (A* once a target is chosen)
    _WARMED.add(key)


def run_on_robot(spec: RunSpec, robot: Robot, out: Path | None, world: World | str | None = None, *,
                 observers: Iterable[RunObserver] = (),
                 on_sample: Callable[[float, float | None], None] | None = None,
                 show: tuple[str, ...] = (), image: bool | tuple[str, ...] = True, map_size: float = 20.0,
                 record_extra: dict[str, Any] | None = None,
                 on_run: Callable[[ExplorationRun], None] | None = None,
                 plan: RunPlan | None = None) -> RunOutput:
    """Run `spec`'s explorer on an open robot (the embedded simulator, MobileSim, an emulator or a
    real one) and write the results under `out` (nothing when `out` is None).

    With a `world` the run starts from `spec.pose` in it (`plan_run`): a robot with
    `Capability.MOVE_TO` is moved there (a simulator teleports; a real robot is told it stands there),
    and the world is ground truth for coverage. Without one the map is a square of `map_size` [m]
    centred on the robot's first pose and coverage is unknown. `spec.world`, `spec.robot` and the
    laser settings of `spec` other than `laser_range` are not used: the robot brings its own
    sensors. The robot is stopped at the end, not closed.

    The loop's observers are, in order: the results writer (with `out`), the `on_sample`/`on_run`
    callbacks, the honest-endings watch (`robotexp.watch.RunWatch`: stall watch, exploration area,
    an explorer's Done checked against the frontier left), then `observers`. The exploration area is
    `spec.map_bounds`, else the map's declared area (`robotexp.world.bounds`). The record names the
    robot by `robot.model` and, when it has one, its `address`; `record_extra` adds keys.

    Args:
        plan: the spec already planned in `world` for this robot (`plan_run`; default: planned here).

    Raises:
        WorldError, PluginError, ConfigError: bad input, before the robot moves.
        RobotError: the robot fails before the run starts (during the run it ends the run).
        PluginError: the explorer failed during the run (its record is written first).
        OSError: the results could not be written (an error of a `critical` observer).
    """
    from robotexp.localization.run import localized, release
    from robotexp.mapping.grid import OccupancyGrid

    spec.validate()
    if not map_size > 0:
        raise ConfigError(f"map size must be > 0, got {map_size * 1000:g} mm")
    truth = None
    goals: dict[str, list[tuple[float, float]]] = {}
    start_name = None
    area = spec.map_bounds
    if world is not None:
        if plan is None:
            plan = plan_run(spec, world, robot.radius)
        explorer, geo, truth, area = plan.explorer, plan.geo, plan.truth, plan.area
        world_name, pose_label = plan.world.name, plan.pose_label
        goals, start_name = plan.world.goals, pose_name(plan.world, spec.pose)
        if Capability.MOVE_TO in robot.capabilities:
            robot.move_to(plan.start)
    else:
        explorer = make_explorer(spec.method, spec.params)
        cell = spec.cell or explorer.preferred_cell or DEFAULT_CELL
        world_name, pose_label = robot.name, "robot"
        p = robot.read().pose
        half = map_size / 2
        geo = GridGeometry.covering(*(spec.map_bounds or (p.x - half, p.y - half, p.x + half, p.y + half)),
                                    cell=cell)
    warm_kernels(spec, robot)
    robot.set_max_speed(spec.speed)
    grid = OccupancyGrid(geo, model=explorer.grid_model, range_max=spec.laser_range)
    robot, tracker = localized(spec, robot, geo)    # robotexp.localization.run: the explorer's pose

    extra: dict[str, Any] = {}
    if robot.address is not None:
        extra["address"] = str(robot.address)
    extra.update(record_extra or {})
    if out is None:
        name = f"{world_name}_{spec.method}_{pose_label}"
    else:
        out.mkdir(parents=True, exist_ok=True)
        name = run_id(world_name, spec.method, pose_label, spec.speed, spec.seed, out)
    info = RunInfo(name=name, method=spec.method, world=world_name, pose=pose_label, robot=robot.model,
                   max_speed=spec.speed, laser_range=spec.laser_range, extra=extra)
    writer = None if out is None else ResultsWriter(out, image=image, show=show)
    chain: list[RunObserver] = [] if writer is None else [writer]
    if on_sample is not None or on_run is not None:
        chain.append(SampleCallback(on_sample, on_run))
    chain.insert(0, tracker)                          # first: ate_m is in the record the writer writes
    chain.append(RunWatch(StallWatch(), area))         # honest endings: stalls, the area, "done" checked
    chain.extend(observers)
    run = ExplorationRun(robot, explorer, grid, truth=truth, max_time=spec.max_time, seed=spec.seed, goals=goals,
                         start_name=start_name, info=info, observers=chain, area=area)
    try:
        run.run()
    finally:
        release(robot)
    for observer, exc in run.observer_errors:
        if observer.critical:
            raise exc
    if run.end is EndReason.PLUGIN_ERROR:
        raise PluginError(run.reason) from run.error
    assert run.record is not None
    return RunOutput(run.record, run, None if writer is None else writer.image_path,
                     None if writer is None else writer.plot_path)

"""One exploration experiment on the embedded simulator, from a `RunSpec` to written results.

This is what `robotexp explore`, the Lua `exploration.start()` and campaigns all call.
"""

from __future__ import annotations

import math
import types
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from robotexp.errors import ConfigError
from robotexp.explorer import ExplorationRun, Explorer
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import Pose, Robot
from robotexp.watch import RunWatch, StallWatch
from robotexp.world.bounds import exploration_area, with_boundary_walls
from robotexp.world.model import World

__all__ = ["RunSpec", "RunOutput", "run_experiment", "run_on_robot", "connect_robot", "make_emulator",
           "parse_pose", "resolve_pose", "make_explorer",
           "DEFAULT_CELL", "MAP_MARGIN"]

DEFAULT_CELL = 0.1      # [m] map cell unless the method prefers another
MAP_MARGIN = 1.0        # [m] the map reaches this far beyond the world's obstacles


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

    def validate(self) -> None:
        """Raise ConfigError on a value out of range."""
        if not (self.speed > 0 and math.isfinite(self.speed)):
            raise ConfigError(f"speed must be > 0, got {self.speed * 1000:g} mm/s")
        if not (self.laser_range > 0 and math.isfinite(self.laser_range)):
            raise ConfigError(f"laser range must be > 0, got {self.laser_range * 1000:g} mm")
        if self.cell is not None and not (0.005 <= self.cell <= 2.0):
            raise ConfigError(f"cell size must be within 5..2000 mm, got {self.cell * 1000:g} mm")
        if not self.max_time > 0:
            raise ConfigError(f"max time must be > 0 s, got {self.max_time}")
        if self.laser_sigma < 0 or self.laser_uniform < 0:
            raise ConfigError(f"laser noise must be >= 0 mm, got uniform {self.laser_uniform * 1000:g}, "
                              f"sigma {self.laser_sigma * 1000:g}")
        if self.map_bounds is not None:
            x0, y0, x1, y1 = self.map_bounds
            if not (all(math.isfinite(v) for v in self.map_bounds) and x0 < x1 and y0 < y1):
                raise ConfigError(f"map limits must be finite with min < max, got x {x0 * 1000:g}..{x1 * 1000:g}, "
                                  f"y {y0 * 1000:g}..{y1 * 1000:g} mm")


@dataclass
class RunOutput:
    """What a run leaves behind: its record and the files written."""

    record: dict[str, Any]
    run: ExplorationRun
    image: Path | None
    plot: Path | None
    interrupted: bool


def parse_pose(text: str) -> Pose:
    """Parse "x,y,theta" (mm, mm, degrees) into a Pose in SI units. Raises ConfigError."""
    parts = text.split(",")
    try:
        if len(parts) not in (2, 3):
            raise ValueError
        x, y = float(parts[0]), float(parts[1])
        th = float(parts[2]) if len(parts) == 3 else 0.0
        if not all(math.isfinite(v) for v in (x, y, th)):
            raise ValueError
    except ValueError:
        raise ConfigError(f"pose {text!r}: expected a pose name or x,y,theta in mm, mm, degrees "
                          "(e.g. -5000,7500,0)") from None
    return Pose(x / 1000, y / 1000, math.radians(th))


def resolve_pose(world: World, pose: str | None, radius: float) -> tuple[Pose, str]:
    """The start pose and its label: a named pose, "x,y,theta", or the default.

    The default is the world's first named pose, a .map file's RobotHome cairn, or else a point
    well inside the largest region where the robot fits (`robotexp.world.start.default_start`).
    """
    if pose is None:
        if world.home is not None:
            return world.home, "home"
        if world.poses:
            name = next(iter(world.poses))
            return world.poses[name], name
        return _central_free_pose(world, radius), "centre"
    if pose in world.poses:
        return world.poses[pose], pose
    if "," not in pose:
        world.pose(pose)                    # raises: lists the names the world has
    p = parse_pose(pose)
    return p, f"{p.x * 1000:.0f},{p.y * 1000:.0f},{math.degrees(p.theta):.0f}"


def _pose_name(world: World, pose: str | None) -> str | None:
    """The world's name for the start pose `pose` (a name, or None for the default), else None."""
    if pose is None:
        return None if world.home is not None or not world.poses else next(iter(world.poses))
    return pose if pose in world.poses else None


def _central_free_pose(world: World, radius: float) -> Pose:
    from robotexp.world.start import default_start

    return default_start(world, radius).pose


def make_explorer(method: str, params: dict[str, Any]) -> Explorer:
    """Instantiate the explorer plugin `method` with keyword `params`.

    Raises:
        PluginError: unknown method.
        ConfigError: an unknown or invalid parameter.
    """
    from robotexp.registry import EXPLORERS, load

    cls = load(EXPLORERS, method, Explorer)
    params = {key: _typed(method, cls, key, value) for key, value in params.items()}
    try:
        return cls(**params)   # type: ignore[no-any-return]
    except TypeError as exc:
        raise ConfigError(f"method {method!r}: {exc} (parameters given: {', '.join(params) or 'none'})") from exc


_KINDS = {bool: "true or false", int: "a whole number", float: "a number", str: "a string"}


def _typed(method: str, cls: type, key: str, value: Any) -> Any:
    """`value` for the keyword `key` of `cls`, checked against its annotation (bool, int, float, str,
    or one of these or None); a whole float for an int and an int for a float are converted.
    Parameters without such an annotation pass unchecked. Raises ConfigError."""
    try:
        hint = typing.get_type_hints(cls.__init__).get(key)   # type: ignore[misc]
    except Exception:       # an annotation that does not resolve: leave the value to the plugin
        return value
    allowed = typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
    if value is None and type(None) in allowed:
        return None
    kinds = [t for t in allowed if t in _KINDS]
    if not kinds or len(kinds) < len([t for t in allowed if t is not type(None)]):
        return value
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    for kind in kinds:
        if kind is bool and isinstance(value, bool) or kind is str and isinstance(value, str):
            return value
        if kind is int and number and float(value).is_integer():
            return int(value)
        if kind is float and number:
            return float(value)
    raise ConfigError(f"method {method!r}: parameter {key!r} must be {' or '.join(_KINDS[k] for k in kinds)}, "
                      f"got {value!r}")


def run_experiment(spec: RunSpec, out: Path | None, *,
                   on_sample: Callable[[float, float | None], None] | None = None,
                   show: tuple[str, ...] = (), image: bool = True,
                   record_extra: dict[str, Any] | None = None,
                   on_run: Callable[[ExplorationRun], None] | None = None) -> RunOutput:
    """Run `spec` on the embedded simulator; append the record to `out/results.jsonl` and save the
    map image, coverage curve and plot there (nothing is written when `out` is None).

    `on_run`, when given, is called with the running `ExplorationRun` after each coverage sample
    (after `on_sample`): it may render frames or call `request_stop`.

    Raises:
        WorldError, PluginError, ConfigError: bad input, before the robot moves.
    """
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.mapping.groundtruth import ground_truth
    from robotexp.sim import LaserConfig, SimRobot, preset
    from robotexp.world.loader import load_world

    spec.validate()
    world = load_world(spec.world)
    explorer = make_explorer(spec.method, spec.params)
    robot_preset = preset(spec.robot)
    start, pose_label = resolve_pose(world, spec.pose, robot_preset.radius)
    cell = spec.cell or explorer.preferred_cell or DEFAULT_CELL
    assert world.bounds is not None
    area = exploration_area(world, spec.map_bounds)
    if spec.map_bounds is None and area is not None:
        # the map's declared area, grown to hold the start (a home placed in its margin)
        r = robot_preset.radius + MAP_MARGIN
        area = (min(area[0], start.x - r), min(area[1], start.y - r), max(area[2], start.x + r),
                max(area[3], start.y + r))
        geo = GridGeometry.covering(*area, cell=cell)
    elif spec.map_bounds is None:
        geo = GridGeometry.covering(*world.bounds, cell=cell, margin=MAP_MARGIN)
    else:
        geo = GridGeometry.covering(*spec.map_bounds, cell=cell)
        x0, y0, x1, y1 = spec.map_bounds
        if not (x0 <= start.x <= x1 and y0 <= start.y <= y1):
            raise ConfigError(f"start pose ({start.x * 1000:.0f}, {start.y * 1000:.0f}) mm is outside the map "
                              f"limits x {x0 * 1000:g}..{x1 * 1000:g}, y {y0 * 1000:g}..{y1 * 1000:g} mm")
    if spec.bounds_wall and area is not None:
        world = with_boundary_walls(world, area)
    truth = ground_truth(world, geo, robot_radius=robot_preset.radius, laser_range=spec.laser_range,
                         start=start)
    laser = LaserConfig(beams=robot_preset.laser.beams, fov=robot_preset.laser.fov, range_max=spec.laser_range,
                        sigma=spec.laser_sigma, uniform=spec.laser_uniform, height=robot_preset.laser.height)
    grid = OccupancyGrid(geo, model=explorer.grid_model, range_max=spec.laser_range)
    with SimRobot(world, robot=robot_preset, pose=start, seed=spec.seed, laser=laser,
                  max_speed=spec.speed, sonar=explorer.uses_sonar) as robot:
        def chained(t: float, cov: float | None) -> None:
            if on_sample is not None:
                on_sample(t, cov)
            if on_run is not None:
                on_run(run)
        sample_cb = on_sample if on_run is None else chained
        run = ExplorationRun(robot, explorer, grid, truth=truth, max_time=spec.max_time, seed=spec.seed,
                             on_sample=sample_cb, goals=world.goals, start_name=_pose_name(world, spec.pose),
                             watch=RunWatch(StallWatch(), area), area=area)
        run.run()
    return write_outputs(run, spec, world.name, pose_label, out, show=show, image=image, record_extra=record_extra)


EMULATORS = "robotexp.emulators"     # entry-point group: robot backend name -> its emulator class


def connect_robot(backend: str, address: str) -> Robot:
    """Connect the robot backend registered as `backend` (`robotexp.robots`) at `address`.

    Raises:
        PluginError: unknown backend.
        RobotError: the robot cannot be reached or the handshake fails.
    """
    from robotexp.registry import ROBOTS, load

    cls = load(ROBOTS, backend, Robot)
    if backend == "sim":
        raise ConfigError("robot 'sim' is the embedded simulator: it has no address; run without --address")
    return cls(address)   # type: ignore[no-any-return]


def make_emulator(backend: str, world: str, *, pose: str | None = None, port: int | None = None,
                  pty: bool = False, speedup: float = 1.0, udp: str | None = None) -> Any:
    """The emulator of robot `backend` (entry-point group `robotexp.emulators`) serving `world`.

    The emulator is not started: call its `start()` (and `close()`); `address` tells where it is.
    `udp` ("HOST:PORT", mavlink only) makes it send to a ground station there instead of listening.

    Raises:
        PluginError: no emulator for `backend`.
        WorldError: unknown world or a start pose in an obstacle.
        ConfigError: a parameter out of range.
    """
    from robotexp.registry import load
    from robotexp.sim import preset
    from robotexp.world.loader import load_world

    if not (speedup > 0 and math.isfinite(speedup)):
        raise ConfigError(f"speedup must be > 0, got {speedup}")
    cls = load(EMULATORS, backend, object)
    w = load_world(world)
    radius = preset(backend).radius if backend in ("p3dx", "kobuki") else preset("p3dx").radius
    start, _ = resolve_pose(w, pose, radius)
    kwargs: dict[str, Any] = {"pose": start, "pty": pty, "speedup": speedup}
    if port is not None:
        kwargs["port"] = port
    if udp is not None:                 # MAVLink: send to a ground station at HOST:PORT
        if backend != "mavlink":
            raise ConfigError(f"--udp is for the mavlink emulator, not {backend!r}")
        kwargs["udp"] = udp
    return cls(w, **kwargs)


def run_on_robot(spec: RunSpec, robot: Robot, out: Path | None, world: World | str | None = None, *,
                 on_sample: Callable[[float, float | None], None] | None = None,
                 show: tuple[str, ...] = (), image: bool = True, map_size: float = 20.0,
                 record_extra: dict[str, Any] | None = None,
                 on_run: Callable[[ExplorationRun], None] | None = None) -> RunOutput:
    """Run `spec`'s explorer on a connected robot (a real one, MobileSim or an emulator).

    With a `world` the run starts from `spec.pose` in it: a robot with the "move_to" capability is
    moved there (MobileSim, emulators; a real robot is told it stands there), and the world is
    ground truth for coverage. Without one the map is a square of `map_size` [m] centred on the
    robot's first pose and coverage is unknown. `spec.world`, `spec.robot` and the laser settings
    of `spec` other than `laser_range` are not used: the robot brings its own sensors. The robot is
    stopped at the end, not closed. Results are written as by `run_experiment`; `record_extra` and
    `on_run` as there.

    Raises:
        WorldError, PluginError, ConfigError: bad input, before the robot moves.
        RobotError: the robot fails before the run starts (during the run it ends the run).
    """
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.mapping.groundtruth import ground_truth
    from robotexp.world.loader import load_world

    spec.validate()
    if not map_size > 0:
        raise ConfigError(f"map size must be > 0, got {map_size * 1000:g} mm")
    explorer = make_explorer(spec.method, spec.params)
    cell = spec.cell or explorer.preferred_cell or DEFAULT_CELL
    truth = None
    goals: dict[str, list[tuple[float, float]]] = {}
    start_name = None
    if world is not None:
        w = load_world(world) if isinstance(world, str) else world
        world_name = w.name
        start, pose_label = resolve_pose(w, spec.pose, robot.radius)
        if "move_to" in robot.capabilities:
            robot.move_to(start)
        assert w.bounds is not None
        geo = GridGeometry.covering(*(spec.map_bounds or w.bounds), cell=cell,
                                    margin=0.0 if spec.map_bounds else MAP_MARGIN)
        truth = ground_truth(w, geo, robot_radius=robot.radius, laser_range=spec.laser_range, start=start)
        goals, start_name = w.goals, _pose_name(w, spec.pose)
        area = spec.map_bounds
    else:
        area = spec.map_bounds
        world_name, pose_label = robot.name, "robot"
        p = robot.read().pose
        half = map_size / 2
        geo = GridGeometry.covering(*(spec.map_bounds or (p.x - half, p.y - half, p.x + half, p.y + half)),
                                    cell=cell)
    robot.set_max_speed(spec.speed)
    grid = OccupancyGrid(geo, model=explorer.grid_model, range_max=spec.laser_range)

    def chained(t: float, cov: float | None) -> None:
        if on_sample is not None:
            on_sample(t, cov)
        if on_run is not None:
            on_run(run)
    run = ExplorationRun(robot, explorer, grid, truth=truth, max_time=spec.max_time, seed=spec.seed,
                         on_sample=on_sample if on_run is None else chained, goals=goals, start_name=start_name,
                         watch=RunWatch(StallWatch(), area), area=area)
    run.run()
    extra: dict[str, Any] = {"robot": robot.name}
    if hasattr(robot, "address"):
        extra["address"] = str(robot.address)
    extra.update(record_extra or {})
    return write_outputs(run, spec, world_name, pose_label, out, show=show, image=image, record_extra=extra)


def write_outputs(run: ExplorationRun, spec: RunSpec, world_name: str, pose_label: str, out: Path | None, *,
                  show: tuple[str, ...] = (), image: bool = True,
                  record_extra: dict[str, Any] | None = None) -> RunOutput:
    """Append the run's record and save its image, curve and plot under `out`."""
    from robotexp.results import append_jsonl, make_record, run_id, write_curve_csv

    interrupted = run.reason.startswith("interrupted")
    if out is None:
        name = f"{world_name}_{spec.method}_{pose_label}"
        return RunOutput(make_record(run, name=name, method=spec.method, world=world_name, seed=spec.seed,
                                     max_speed=spec.speed), run, None, None, interrupted)
    out.mkdir(parents=True, exist_ok=True)
    name = run_id(world_name, spec.method, pose_label, spec.speed, spec.seed, out)
    record = make_record(run, name=name, method=spec.method, world=world_name, seed=spec.seed,
                         max_speed=spec.speed, extra={"pose": pose_label, "laser_range_m": spec.laser_range,
                                                      "robot": spec.robot, **(record_extra or {})})
    append_jsonl(out / "results.jsonl", record)       # first: the record is never lost
    write_curve_csv(out / f"{name}.coverage.csv", run.metrics.curve)
    from robotexp.trajectory import write_path_csv
    write_path_csv(out / f"{name}.path.csv", run.metrics.path)     # overlaid by `campaign plot`
    from robotexp.world.rosmap import save_ros_map
    save_ros_map(out / f"{name}.map.yaml", run.grid.states(), run.grid.geo)   # ROS map_server map
    img_path = plot_path = None
    if image:
        img_path, plot_path = save_run_images(run, out, name, world_name, spec, show)
    return RunOutput(record, run, img_path, plot_path, interrupted)


def save_run_images(run: ExplorationRun, out: Path, name: str, world_name: str, spec: RunSpec,
                    show: tuple[str, ...]) -> tuple[Path, Path]:
    """The map image (grid, walls, path, start, end and the `show` overlays) and the coverage plot."""
    from robotexp.plot import line_plot
    from robotexp.render import save_png

    img_path = out / f"{name}.png"
    save_png(map_image(run, f"{world_name} - {spec.method} - {run.metrics.path_length:.1f} m", show), img_path)
    curve = run.metrics.curve
    plot_path = out / f"{name}.coverage.png"
    if curve and curve[-1][2] >= 0:
        ts = [c[0] / 60 for c in curve]
        plot = line_plot([("coverage", ts, [c[2] for c in curve])], xlabel="robot time [min]",
                         ylabel="coverage", title=f"{name}: coverage of the explorable free space",
                         hlines=(0.9, 0.95, 0.99), ylim=(0.0, 1.0))
        save_png(plot, plot_path)
    return img_path, plot_path


def map_image(run: ExplorationRun, title: str, show: tuple[str, ...] = (), *, scale: int | None = None,
              path: bool = True) -> Any:
    """The PIL image of a run's map with its path and the overlays named in `show`
    (grid, laser, vectors, potential, truth); `scale` in pixels per cell (None: fit), `path` False
    leaves the path out."""
    from robotexp.render import render_map

    m = run.metrics
    overlays = run.explorer.overlays()
    state = run.state
    laser = None
    if "laser" in show and state is not None and state.laser is not None:
        p, sc = state.pose, state.laser
        ok = np.isfinite(sc.ranges)
        a = p.theta + sc.angles[ok]
        laser = np.column_stack([p.x + sc.ranges[ok] * np.cos(a), p.y + sc.ranges[ok] * np.sin(a)])
    end = None if state is None else (state.true_pose or state.pose)
    states = run.grid.states()
    content = states >= 0 if run.truth is None else (states >= 0) | run.truth.explorable
    return render_map(states, run.grid.geo, content=content,
                      truth=run.truth.occupied if run.truth is not None else None,
                      path=np.array(m.path) if m.path and path else None, start=run.start_pose, end=end,
                      scale=scale,
                      show_grid="grid" in show, laser=laser,
                      vectors=overlays.get("vectors") if "vectors" in show else None,
                      potential=overlays.get("potential") if "potential" in show else None,
                      title=title)

"""One exploration run with its outputs, from a `RunSpec` to written results: the one run path of every robot.

`run_on_robot` runs a spec's explorer on an open robot, any backend; `run_experiment` builds the
embedded simulator's `SimRobot` for the spec and hands it to `run_on_robot`. This is what
`robotexp explore`, the Lua `exploration.start()` and campaigns all call. It joins the run
(`robotexp.run`: the spec and plan, the loop, observers, records) and its outputs (`robotexp.output`:
the results writer); start poses are in `robotexp.world.poses`, plugin construction in `robotexp.registry`.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from robotexp.errors import ConfigError, PluginError, WorldError
from robotexp.mapping.geometry import GridGeometry
from robotexp.output.results import ResultsWriter, run_id
from robotexp.registry import make_explorer
from robotexp.robot import Capability, Robot
from robotexp.run.endings import RunWatch, StallWatch
from robotexp.run.loop import ExplorationRun, RunInfo
from robotexp.run.observers import RunObserver, SampleCallback
from robotexp.run.record import EndReason, RunRecord
from robotexp.run.spec import DEFAULT_CELL, RunPlan, RunSpec, plan_run, sim_robot
from robotexp.world.model import World
from robotexp.world.poses import pose_name

if TYPE_CHECKING:
    from robotexp.coordinator import Coordinator
    from robotexp.explorer import Explorer
    from robotexp.run.team import TeamSpec
    from robotexp.sim import SimRobot

__all__ = ["RunOutput", "run_experiment", "run_on_robot", "run_team", "run_team_on_robots", "warm_kernels"]

log = logging.getLogger(__name__)


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
        """The run was interrupted by Ctrl-C or SIGTERM (the caller should exit 130, or 143 for SIGTERM)."""
        return self.record.end is EndReason.INTERRUPTED


def run_experiment(spec: RunSpec, out: Path | None, *, observers: Iterable[RunObserver] = (),
                   on_sample: Callable[[float, float | None], None] | None = None,
                   show: tuple[str, ...] = (), image: bool | tuple[str, ...] = True,
                   record_extra: dict[str, Any] | None = None,
                   on_run: Callable[[ExplorationRun], None] | None = None) -> RunOutput:
    """Run `spec` on the embedded simulator: the spec is planned (`plan_run`), then a `SimRobot`
    (`sim_robot`) at its start is handed to `run_on_robot`, which writes the results under `out`
    (nothing when `out` is None).

    A spec with a `team` runs that team (`run_team`, with the spec's coordinator and communication range).

    `on_sample(t, coverage)` and `on_run(run)` are called after each coverage sample (an observer's
    `on_sample` does the same; `on_run` may render frames or call `request_stop`). `image`: write the map
    and coverage figures (PNG; a tuple names the formats, e.g. ("png", "svg")) or not.

    Raises:
        WorldError, PluginError, ConfigError: bad input, before the robot moves.
        PluginError: the explorer failed during the run (its record is written first).
        OSError: the results could not be written.
    """
    from robotexp.sim import preset

    if spec.team:       # a team (a campaign's `teams`): one record for the team
        from robotexp.run.team import TeamSpec

        team = TeamSpec(robots=spec.team, coordinator=spec.coordinator, comm_range=spec.comm_range,
                        coordinator_params=spec.coordinator_params)
        return run_team(spec, team, out, observers=observers, show=show, image=image, record_extra=record_extra)
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
    from robotexp.run.localize import wants_localizer
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


def run_on_robot(spec: RunSpec, robot: Robot, out: Path | None, world: World | str | None = None, *,  # noqa: PLR0913
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
    callbacks, the honest-endings watch (`robotexp.run.endings.RunWatch`: stall watch, exploration area,
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
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.run.localize import MAP_P_FREE, localized, release

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
    robot, tracker = localized(spec, robot, geo)    # robotexp.run.localize: the explorer's pose
    grid = OccupancyGrid(geo, model=explorer.grid_model, range_max=spec.laser_range,
                         **({"p_free": MAP_P_FREE} if tracker.localize != "none" else {}))

    extra: dict[str, Any] = _settings(spec)
    if robot.address is not None:
        extra["address"] = str(robot.address)
    extra.update(record_extra or {})
    if out is None:
        name = f"{world_name}_{spec.method}_{pose_label}"
    else:
        out.mkdir(parents=True, exist_ok=True)
        # a robot other than the default is in the name: runs of one map with several robots tell apart by file
        label = spec.method if robot.model == RunSpec.robot else f"{spec.method}-{robot.model}"
        name = run_id(world_name, label, pose_label, spec.speed, spec.seed, out)
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
    return _outcome(run, writer)


def _outcome(run: ExplorationRun, writer: ResultsWriter | None) -> RunOutput:
    """A finished run's output (its record and the writer's image and plot), or the error that ended it: a
    critical observer's, or a PluginError for an explorer that failed."""
    for observer, exc in run.observer_errors:
        if observer.critical:
            raise exc
    if run.end is EndReason.PLUGIN_ERROR:
        raise PluginError(run.reason) from run.error
    assert run.record is not None
    return RunOutput(run.record, run, None if writer is None else writer.image_path,
                     None if writer is None else writer.plot_path)


def _check_team(spec: RunSpec, team: TeamSpec, odometry: str) -> None:
    """The run's and the team's settings checked; a team runs with `odometry` and no localizer.

    Raises:
        ConfigError: a bad setting.
    """
    spec.validate()
    team.validate()
    if spec.odometry != "none" or spec.localize not in ("auto", "none"):
        raise ConfigError(f"--team: teams run with {odometry} and no localizer for now; leave out "
                          "--odometry-error and --localize")


def _settings(spec: RunSpec, team: TeamSpec | None = None) -> dict[str, Any]:
    """The record keys that say how a run was set up beyond its name: `params`, the explorer's parameters, and
    for a team `coordinator_params`, its coordinator's, each only when some were given."""
    out: dict[str, Any] = {}
    if spec.params:
        out["params"] = dict(spec.params)
    if team is not None and team.coordinator_params:
        out["coordinator_params"] = dict(team.coordinator_params)
    return out


def _team_coordinator(spec: RunSpec, team: TeamSpec, explorer: Explorer) -> Coordinator:
    """The team's coordinator, made; refused when it assigns frontier targets and `explorer` (the run's
    method) takes none.

    Raises:
        ConfigError: the pair does not fit.
        PluginError: the coordinator cannot be made.
    """
    from robotexp.registry import make_coordinator

    coordinator = make_coordinator(team.coordinator, team.coordinator_params)
    if coordinator.assigns_targets and not explorer.takes_targets:
        raise ConfigError(f"--coordinator {team.coordinator} assigns frontier targets, and method {spec.method!r} "
                          "does not take targets (reactive explorers run with --coordinator none)")
    return coordinator


def run_team(spec: RunSpec, team: TeamSpec, out: Path | None, *, observers: Iterable[RunObserver] = (),
             show: tuple[str, ...] = (), image: bool | tuple[str, ...] = True,
             record_extra: dict[str, Any] | None = None, world: World | None = None) -> RunOutput:
    """Run `spec`'s explorer on a team of simulated robots (`team`) and write one record for the team under
    `out` (nothing when `out` is None): the robots start at `team.poses` or spread from the spec's start
    (`robotexp.sim.team.spread_starts`), share one map (or, with `team.comm_range`, each keep one and pass
    scans on within that range) and take targets from `team.coordinator` (`robotexp.run.team.TeamRun`).
    `world` stands for `spec.world` when given (a world built in code).

    Raises:
        WorldError, PluginError, ConfigError: bad input, before the robots move.
        PluginError: an explorer failed during the run (the record is written first).
        OSError: the results could not be written.
    """
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.run.team import TeamRun
    from robotexp.sim import SimTeam, preset

    _check_team(spec, team, "exact odometry")
    radii = [preset(name).radius for name in team.robots]
    plan = plan_run(spec, spec.world if world is None else world, max(radii))
    coordinator = _team_coordinator(spec, team, plan.explorer)
    explorers = [plan.explorer] + [make_explorer(spec.method, spec.params) for _ in team.robots[1:]]
    robots = _team_robots(spec, team, plan)
    try:
        with SimTeam(robots) as sim:
            geo = plan.geo
            model, rmax = plan.explorer.grid_model, spec.laser_range
            grid = OccupancyGrid(geo, model=model, range_max=rmax)
            grids = [grid] * len(robots) if team.comm_range is None else \
                [OccupancyGrid(geo, model=model, range_max=rmax) for _ in robots]
            n = len(robots)
            label = f"{spec.method}-team{n}-{team.coordinator}"
            if out is None:
                name = f"{plan.world.name}_{label}_{plan.pose_label}"
            else:
                out.mkdir(parents=True, exist_ok=True)
                name = run_id(plan.world.name, label, plan.pose_label, spec.speed, spec.seed, out)
            models = sorted(set(team.robots))
            info = RunInfo(name=name, method=spec.method, world=plan.world.name, pose=plan.pose_label,
                           robot=",".join(team.robots) if len(models) > 1 else models[0], max_speed=spec.speed,
                           laser_range=spec.laser_range, extra={**_settings(spec, team), **(record_extra or {})})
            for robot in robots:
                robot.set_max_speed(spec.speed)
            writer = None if out is None else ResultsWriter(out, image=image, show=show)
            chain: list[RunObserver] = [] if writer is None else [writer]
            chain.extend(observers)
            run = TeamRun(robots, explorers, grids, sim.make_clock(0.1), coordinator=coordinator,
                          comm_range=team.comm_range, grid=grid if team.comm_range is not None else None,
                          truth=plan.truth, max_time=spec.max_time, seed=spec.seed, info=info, observers=chain,
                          area=plan.area)
            run.coordinator_name = team.coordinator
            run.run()
    finally:
        for robot in robots:
            robot.close()
    return _outcome(run, writer)


@contextmanager
def _listed_pose(team: TeamSpec, i: int) -> Iterator[None]:
    """Robot `i` placed at its start: a start of `--team-poses` that is not free names the robot."""
    try:
        yield
    except WorldError as exc:
        if not team.poses:
            raise
        raise WorldError(f"--team-poses: robot {i + 1}: {exc}") from None


def _team_robots(spec: RunSpec, team: TeamSpec, plan: RunPlan) -> list[SimRobot]:
    """The team's simulated robots at their starts: `team.poses`, else spread from the plan's start."""
    from dataclasses import replace

    from robotexp.sim.team import spread_starts

    first = sim_robot(replace(spec, robot=team.robots[0]), plan.world, plan.start, sonar=plan.explorer.uses_sonar)
    robots = [first]
    try:
        from robotexp.sim import preset

        radii = [preset(name).outline.swing for name in team.robots]     # each must have room to turn
        if team.poses:
            from robotexp.run.teamrobots import listed_starts

            starts = listed_starts(plan.world, team.poses, radii)
            with _listed_pose(team, 0):
                first.move_to(starts[0])
        else:
            starts = spread_starts(plan.truth, plan.start, radii, free=first)
        for i, (name, start) in enumerate(zip(team.robots[1:], starts[1:], strict=True), start=1):
            seed = int(np.random.SeedSequence([spec.seed, i]).generate_state(1)[0])
            with _listed_pose(team, i):
                robots.append(sim_robot(replace(spec, robot=name, seed=seed), plan.world, start,
                                        sonar=plan.explorer.uses_sonar))
    except BaseException:
        for robot in robots:
            robot.close()
        raise
    return robots


def run_team_on_robots(spec: RunSpec, team: TeamSpec, robots: list[Robot], out: Path | None,  # noqa: PLR0913
                       world: World | str | None = None, *, observers: Iterable[RunObserver] = (),
                       show: tuple[str, ...] = (), image: bool | tuple[str, ...] = True,
                       record_extra: dict[str, Any] | None = None, map_size: float = 20.0) -> RunOutput:
    """Run `spec`'s explorer on a team of open robots (over their drivers: `robotexp.run.teamrobots`) and write
    one record for the team under `out` (nothing when `out` is None), as `run_team` does for simulated ones.

    Each robot is told where it starts (`Robot.move_to`): in `world` at `robotexp.run.teamrobots.team_starts`
    (`team.poses`, else spread from `spec.pose`, as `robotexp emulate p3dx,p3dx,kobuki` places them), and the
    world is ground truth for coverage; without one at `team.poses` (needed then), on a map covering
    `spec.map_bounds`, else a square of `map_size` [m] around them, and coverage is unknown. The team's clock
    is the robots' own (`robotexp.clock.TeamClock`). The robots are stopped at the end, not closed.

    Raises:
        WorldError, PluginError, ConfigError: bad input, before the robots move.
        RobotError: a robot fails before the run starts (during the run it ends the run).
        PluginError: an explorer failed during the run (the record is written first).
        OSError: the results could not be written.
    """
    from robotexp.clock import TeamClock
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.run.team import TeamRun
    from robotexp.run.teamrobots import team_starts
    from robotexp.world.poses import parse_pose

    _check_team(spec, team, "the robots' odometry")
    if len(robots) != len(team.robots):
        raise ConfigError(f"team: {len(robots)} robots for {len(team.robots)} names")
    radii = [r.radius for r in robots]
    truth = area = None
    if world is not None:
        plan = plan_run(spec, world, max(radii))
        explorer0, geo, truth, area = plan.explorer, plan.geo, plan.truth, plan.area
        world_name, pose_label = plan.world.name, plan.pose_label
        starts = team_starts(plan.world, spec.pose, radii, team.poses)
    else:
        if not team.poses:
            raise ConfigError("--team: robots without --world need --team-poses (where each one stands, in one frame)")
        explorer0 = make_explorer(spec.method, spec.params)
        starts = [parse_pose(p) for p in team.poses]
        cell = spec.cell or explorer0.preferred_cell or DEFAULT_CELL
        half = map_size / 2
        xs, ys = [p.x for p in starts], [p.y for p in starts]
        geo = GridGeometry.covering(*(spec.map_bounds or (min(xs) - half, min(ys) - half, max(xs) + half,
                                                          max(ys) + half)), cell=cell)
        world_name, pose_label = "robots", "robots"
    coordinator = _team_coordinator(spec, team, explorer0)
    explorers = [explorer0] + [make_explorer(spec.method, spec.params) for _ in robots[1:]]
    warm_kernels(spec, robots[0])
    for robot, start in zip(robots, starts, strict=True):
        robot.move_to(start)
        robot.set_max_speed(spec.speed)
    model, rmax = explorer0.grid_model, spec.laser_range
    grid = OccupancyGrid(geo, model=model, range_max=rmax)
    grids = [grid] * len(robots) if team.comm_range is None else \
        [OccupancyGrid(geo, model=model, range_max=rmax) for _ in robots]
    label = f"{spec.method}-team{len(robots)}-{team.coordinator}"
    if out is None:
        name = f"{world_name}_{label}_{pose_label}"
    else:
        out.mkdir(parents=True, exist_ok=True)
        name = run_id(world_name, label, pose_label, spec.speed, spec.seed, out)
    models = [r.model for r in robots]
    info = RunInfo(name=name, method=spec.method, world=world_name, pose=pose_label,
                   robot=",".join(models) if len(set(models)) > 1 else models[0], max_speed=spec.speed,
                   laser_range=spec.laser_range, extra={**_settings(spec, team), **(record_extra or {})})
    writer = None if out is None else ResultsWriter(out, image=image, show=show)
    chain: list[RunObserver] = [] if writer is None else [writer]
    chain.extend(observers)
    run = TeamRun(robots, explorers, grids, TeamClock([r.make_clock(0.1) for r in robots]),
                  coordinator=coordinator, comm_range=team.comm_range,
                  grid=grid if team.comm_range is not None else None, truth=truth, max_time=spec.max_time,
                  seed=spec.seed, info=info, observers=chain, area=area)
    run.coordinator_name = team.coordinator
    run.run()
    return _outcome(run, writer)

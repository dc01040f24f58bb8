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
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robotexp.errors import ConfigError, PluginError
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

__all__ = ["RunOutput", "run_experiment", "run_on_robot", "warm_kernels"]

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
        """The run was interrupted by Ctrl-C (the caller should exit 130)."""
        return self.record.end is EndReason.INTERRUPTED


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
    from robotexp.run.localize import localized, release

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
    robot, tracker = localized(spec, robot, geo)    # robotexp.run.localize: the explorer's pose

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

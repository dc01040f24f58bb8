"""Campaigns: sets of runs defined in a TOML file, run in parallel processes, and their report tables.

A campaign file (see `campaigns/thesis.toml`):

    [campaign]                      # defaults for every set
    name = "thesis"
    laser_range_mm = 3000
    seeds = [0]

    [[set]]
    world = "dense"
    poses = "all"                   # or a list of the world's pose names
    methods = ["bvp", "srt-laser"]
    speeds_mm_s = [100, 40]

    [set.params.bvp]                # keyword parameters of one method in this set
    iterations = 30

    [set.sweep.frontier]            # a sweep: one run per combination of these values
    clearance = [0.2, 0.3]                               # a list of values
    replan_period = {start = 1.0, stop = 3.0, step = 1.0}  # a range, stop included

Everything is checked before the first run starts, so a bad file leaves no results behind.
Each finished run is appended to `OUT/results.jsonl` at once; `resume` skips the runs recorded there.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import math
import os
import re
import signal
import statistics
import time
import tomllib
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from robotexp.campaign_robot import DEVICE_KEYS, Place, RobotDevices, check_starts, robot_devices, run_on_robots
from robotexp.errors import ConfigError, PluginError, WorldError
from robotexp.experiment import RunSpec
from robotexp.record import EndReason, RunRecord
from robotexp.registry import make_explorer
from robotexp.world.bounds import parse_bounds

__all__ = ["Campaign", "RunKey", "RunTiming", "expected_robot_time", "load_campaign", "method_label", "run_campaign",
           "run_key", "run_order", "record_key", "report_tables", "Table"]

_CAMPAIGN_KEYS = {"name", "description", "laser_range_mm", "seeds", "max_time_s", "robot", "cell_mm",
                  "laser_sigma_mm", "laser_uniform_mm", "bounds_mm", "bounds_wall", "record"} | DEVICE_KEYS
MAX_RUNS = 100_000      # runs of one campaign (checked before any list of them is made)
_SET_KEYS = ({"world", "worlds", "poses", "methods", "speeds_mm_s", "params", "sweep"}
             | _CAMPAIGN_KEYS - {"name", "description", "record"})


RunKey = tuple[str, str, str, int, int, str]


@dataclass
class Campaign:
    """A parsed campaign: its name, source file and the expanded list of runs (with, for the runs of a
    sweep, the swept explorer parameters of each: `sweep_of`)."""

    name: str
    source: Path
    runs: list[RunSpec]
    record: bool = False        # each run also written as a ROS 2 bag, <out>/bags/<run>.mcap (key `record`)
    sweeps: dict[int, dict[str, Any]] | None = None    # id(spec) -> swept parameter values
    devices: dict[int, RobotDevices] | None = None     # id(spec) -> the robot it runs on (robotexp.campaign_robot)
    areas: dict[str, float] | None = None     # world spec -> [m^2] area of its bounds (for `run_order`)

    def sweep_of(self, spec: RunSpec) -> dict[str, Any]:
        """The swept parameter values of a run of this campaign ({} outside a sweep)."""
        return (self.sweeps or {}).get(id(spec), {})

    def devices_of(self, spec: RunSpec) -> RobotDevices | None:
        """The robot (and laser) a run of this campaign is made on (None: the embedded simulator)."""
        return (self.devices or {}).get(id(spec))

    def key(self, spec: RunSpec) -> RunKey:
        """`run_key` of a run of this campaign."""
        return run_key(spec, _pose_label(spec), self.sweep_of(spec))


def sweep_label(sweep: Mapping[str, Any] | None) -> str:
    """The swept values as text, names sorted: "clearance=0.2,replan_period=1.0" ("" for none)."""
    return ",".join(f"{k}={json.dumps(v)}" for k, v in sorted((sweep or {}).items()))


def run_key(spec: RunSpec, pose_label: str, sweep: Mapping[str, Any] | None = None) -> RunKey:
    """The identity of a run within a campaign: (world, method, pose, speed [mm/s], seed, swept values)."""
    return (spec.world, spec.method, pose_label, round(spec.speed * 1000), spec.seed, sweep_label(sweep))


def record_key(record: RunRecord | Mapping[str, Any]) -> RunKey:
    """`run_key` of a results.jsonl record."""
    r = RunRecord.from_dict(record)
    # through the mapping (not `extra` alone): a hand-made line without pose/robot keys keeps them elsewhere
    sweep = r.get("sweep")
    return (str(r.get("world_spec", r.world)), r.method, str(r.get("pose_spec", r.pose)),
            round(float(r.max_speed_m_s or 0) * 1000), int(r.seed or 0),
            sweep_label(sweep if isinstance(sweep, dict) else None))


def method_label(record: RunRecord | Mapping[str, Any]) -> str:
    """The method of a record as the report names it: with its swept values, "frontier [clearance=0.2]"."""
    r = RunRecord.from_dict(record)
    sweep = r.get("sweep")
    label = sweep_label(sweep if isinstance(sweep, dict) else None)
    return f"{r.method} [{label}]" if label else r.method


def _fail(path: Path, where: str, message: str, kind: type[Exception] = ConfigError) -> Exception:
    return kind(f"{path}: {where}: {message}")


def _get(table: dict[str, Any], key: str, default: Any, kind: type | tuple[type, ...], path: Path, where: str) -> Any:
    value = table.get(key, default)
    if value is not default and not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
        raise _fail(path, f"{where}.{key}", f"expected {getattr(kind, '__name__', kind)}, got {value!r}")
    return value


def load_campaign(path: str | Path) -> Campaign:
    """Parse and check a campaign file; expand it into runs.

    Raises:
        ConfigError: unreadable or malformed file, unknown key, a value out of range.
        PluginError: a method that is not installed.
        WorldError: an unknown world or a pose name the world lacks.
    """
    from robotexp.registry import EXPLORERS, available
    from robotexp.world.loader import load_world

    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read the campaign file ({exc.strerror or exc})") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from exc
    except RecursionError:
        raise ConfigError(f"{p}: not valid TOML: nested too deeply (arrays or tables within each other); a "
                          "campaign file needs two levels") from None
    unknown = set(data) - {"campaign", "set"}
    if unknown:
        raise _fail(p, "top level", f"unknown key(s) {', '.join(sorted(unknown))} (use [campaign] and [[set]])")
    head = data.get("campaign", {})
    if not isinstance(head, dict):
        raise _fail(p, "campaign", "must be a table [campaign]")
    _check_keys(head, _CAMPAIGN_KEYS, p, "[campaign]")
    sets = data.get("set", [])
    if not isinstance(sets, list) or not sets:
        raise _fail(p, "set", "no [[set]] of runs")
    methods_installed = available(EXPLORERS)
    runs: list[RunSpec] = []
    sweeps: dict[int, dict[str, Any]] = {}
    devices: dict[int, RobotDevices] = {}
    areas: dict[str, float] = {}

    def world_of(spec: str) -> Any:
        world = load_world(spec)
        if world.bounds is not None:
            x0, y0, x1, y1 = world.bounds
            areas[spec] = max(x1 - x0, 0.0) * max(y1 - y0, 0.0)
        return world

    for i, raw in enumerate(sets, start=1):
        where = f"[[set]] #{i}"
        if not isinstance(raw, dict):
            raise _fail(p, where, "must be a table")
        _check_keys(raw, _SET_KEYS, p, where)
        merged = {**{k: v for k, v in head.items() if k in _SET_KEYS}, **raw}
        robot = robot_devices(merged, lambda key, msg, kind=ConfigError, w=where: _fail(p, f"{w}.{key}", msg, kind))
        for world in _worlds(merged, p, where):
            expanded = _expand({**merged, "world": world}, p, where, methods_installed, world_of)
            if len(runs) + len(expanded) > MAX_RUNS:
                raise _fail(p, where, f"the campaign reaches {len(runs) + len(expanded)} runs here; a campaign "
                            f"has at most {MAX_RUNS} runs")
            for spec, sweep in expanded:
                runs.append(spec)
                if sweep:
                    sweeps[id(spec)] = sweep
                if robot is not None:
                    devices[id(spec)] = robot
    name = head.get("name", p.stem)
    if not (isinstance(name, str) and re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}", name)):
        raise _fail(p, "campaign.name", f"{str(name)[:60]!r} is not a folder name (letters, digits, '_', '.', "
                    "'-'; not starting with '.'): it names the output folder out/<name>")
    keys: dict[RunKey, RunSpec] = {}
    for spec in runs:      # --resume and the report tell runs apart by this key: two runs must not share one
        key = run_key(spec, _pose_label(spec), sweeps.get(id(spec)))
        if key in keys:
            raise _fail(p, "set", f"two runs share the key world {key[0]!r}, method {key[1]!r}, pose {key[2]!r}, "
                        f"speed {key[3]} mm/s, seed {key[4]}{f', sweep {key[5]}' if key[5] else ''} (speeds "
                        f"{keys[key].speed * 1000:g} and {spec.speed * 1000:g} mm/s; a seed, speed or swept value "
                        "given twice?); give each run once")
        keys[key] = spec
    campaign = Campaign(name, p, runs, _get(head, "record", False, bool, p, "[campaign]"), sweeps, devices, areas)
    check_starts(campaign)      # runs on a robot: every start pose planned before anything connects
    return campaign


def _worlds(merged: dict[str, Any], p: Path, where: str) -> list[str | None]:
    """The worlds of a set: `world` (one) or `worlds` (one or a list), each `generated:KIND:A-B` range
    expanded to its seeds (`robotexp.world.generate.expand_generated`)."""
    from robotexp.world.generate import expand_generated

    if "worlds" in merged and "world" in merged:
        raise _fail(p, where, "give either world or worlds, not both")
    given = merged.pop("worlds", merged.get("world"))
    items = given if isinstance(given, list) else [given]
    if not items or not all(isinstance(w, str) or w is None for w in items):
        raise _fail(p, f"{where}.worlds", f"expected a world name or a list of them, got {given!r}")
    out: list[str | None] = []
    for w in items:
        try:
            out += expand_generated(w) if isinstance(w, str) else [w]
        except WorldError as exc:
            raise _fail(p, f"{where}.worlds", str(exc), WorldError) from None
    return out


def _check_keys(table: dict[str, Any], allowed: set[str], path: Path, where: str) -> None:
    bad = sorted(set(table) - allowed)
    if bad:
        raise _fail(path, where, f"unknown key {bad[0]!r} (allowed: {', '.join(sorted(allowed))})")


def _sweep_values(value: Any, p: Path, where: str) -> list[Any]:
    """The values of one swept parameter: a non-empty list, or {start, stop, step} (stop included)."""
    if isinstance(value, list) and value:
        return value
    if isinstance(value, dict) and set(value) == {"start", "stop", "step"} and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value.values()):
        start, stop, step = value["start"], value["stop"], value["step"]
        if not step > 0 or stop < start:
            raise _fail(p, where, f"a range needs step > 0 and stop >= start, got {value!r}")
        count = int(math.floor((stop - start) / step + 1e-9)) + 1
        if count > 10_000:
            raise _fail(p, where, f"the range {value!r} gives {count} values; at most 10000")
        as_int = all(isinstance(v, int) for v in value.values())
        return [start + k * step if as_int else round(start + k * step, 12) for k in range(count)]
    raise _fail(p, where, f"expected a non-empty list of values or {{start, stop, step}}, got {value!r}")


def _sweeps(s: dict[str, Any], methods: list[str], params: dict[str, Any], p: Path,
            where: str) -> dict[str, list[dict[str, Any]]]:
    """Per method, the combinations of its swept values ([{}] for a method without a sweep)."""
    sweep = s.get("sweep", {})
    if not isinstance(sweep, dict) or not all(isinstance(v, dict) and v for v in sweep.values()):
        raise _fail(p, f"{where}.sweep", "expected tables [set.sweep.<method>] of parameter = values")
    out: dict[str, list[dict[str, Any]]] = {m: [{}] for m in methods}
    for m, table in sweep.items():
        if m not in methods:
            raise _fail(p, f"{where}.sweep.{m}", f"a sweep for a method this set does not run ({methods})")
        both = sorted(set(table) & set(params.get(m, {})))
        if both:
            raise _fail(p, f"{where}.sweep.{m}.{both[0]}", "set in both params and sweep; give it once")
        names = sorted(table)
        values = [_sweep_values(table[n], p, f"{where}.sweep.{m}.{n}") for n in names]
        count = math.prod(len(v) for v in values)
        if count > MAX_RUNS:
            raise _fail(p, f"{where}.sweep.{m}", f"{' x '.join(str(len(v)) for v in values)} values give {count:.3g} "
                        f"combinations; a campaign has at most {MAX_RUNS} runs: sweep fewer values")
        out[m] = [dict(zip(names, combo, strict=True)) for combo in itertools.product(*values)]
        for combo in out[m]:
            try:
                make_explorer(m, {**params.get(m, {}), **combo})      # names, types and ranges, before any run
            except ConfigError as exc:
                raise _fail(p, f"{where}.sweep.{m}", f"{sweep_label(combo)}: {exc}") from None
    return out


def _expand(s: dict[str, Any], p: Path, where: str, installed: dict[str, Any],
            load_world: Callable[[str], Any]) -> list[tuple[RunSpec, dict[str, Any]]]:
    world_name = _get(s, "world", None, str, p, where)
    if world_name is None:
        raise _fail(p, f"{where}.world", "missing")
    world_spec = world_name
    if world_name.endswith((".map", ".yaml", ".yml")) and not Path(world_name).is_absolute():
        world_spec = str((p.parent / world_name).resolve())
    try:
        world = load_world(world_spec)
    except WorldError as exc:
        raise _fail(p, f"{where}.world", str(exc), WorldError) from None
    poses = s.get("poses", "all")
    if poses == "all":
        pose_names: list[str] = list(world.poses) or ["default"]
    elif isinstance(poses, list) and poses and all(isinstance(x, str) for x in poses):
        pose_names = poses
        for name in pose_names:
            if name not in world.poses:
                raise _fail(p, f"{where}.poses", f"world {world_name!r} has no pose {name!r} "
                            f"(it has: {', '.join(world.poses) or 'none'})", WorldError)
    else:
        raise _fail(p, f"{where}.poses", f"expected \"all\" or a list of pose names, got {poses!r}")
    methods = s.get("methods")
    if not (isinstance(methods, list) and methods and all(isinstance(m, str) for m in methods)):
        raise _fail(p, f"{where}.methods", f"expected a list of method names, got {methods!r}")
    for m in methods:
        if m not in installed:
            raise _fail(p, f"{where}.methods", f"unknown method {m!r}; available: {', '.join(installed)}",
                        PluginError)
    speeds = s.get("speeds_mm_s", [300])
    seeds = s.get("seeds", [0])
    for key, values, kind in (("speeds_mm_s", speeds, (int, float)), ("seeds", seeds, int)):
        if not (isinstance(values, list) and values and all(isinstance(v, kind) and not isinstance(v, bool)
                                                            for v in values)):
            raise _fail(p, f"{where}.{key}", f"expected a non-empty list of numbers, got {values!r}")
    if any(not (v > 0 and math.isfinite(v)) for v in speeds):
        raise _fail(p, f"{where}.speeds_mm_s", f"speeds must be > 0, got {speeds!r}")
    params = s.get("params", {})
    if not isinstance(params, dict) or not all(isinstance(v, dict) for v in params.values()):
        raise _fail(p, f"{where}.params", "expected tables [set.params.<method>]")
    for m, values in params.items():
        if m not in methods:
            raise _fail(p, f"{where}.params.{m}", f"parameters for a method this set does not run ({methods})")
        try:
            make_explorer(m, dict(values))       # names, types and ranges, before any run starts
        except ConfigError as exc:
            raise _fail(p, f"{where}.params.{m}", str(exc)) from None
    laser = float(_get(s, "laser_range_mm", 3000, (int, float), p, where)) / 1000
    cell_mm = _get(s, "cell_mm", None, (int, float), p, where)
    max_time = float(_get(s, "max_time_s", 4 * 3600, (int, float), p, where))
    robot = _get(s, "robot", "p3dx", str, p, where)
    sigma = float(_get(s, "laser_sigma_mm", 0, (int, float), p, where)) / 1000
    uniform = float(_get(s, "laser_uniform_mm", 0, (int, float), p, where)) / 1000
    bounds = s.get("bounds_mm")
    if bounds is not None:
        if not (isinstance(bounds, list) and len(bounds) == 4 and all(isinstance(v, (int, float))
                                                                     and not isinstance(v, bool) for v in bounds)):
            raise _fail(p, f"{where}.bounds_mm", f"expected [xmin, ymin, xmax, ymax] in mm, got {bounds!r}")
        bounds = parse_bounds(",".join(str(v) for v in bounds), f"{where}.bounds_mm")
    bounds_wall = _get(s, "bounds_wall", False, bool, p, where)
    swept = _sweeps(s, methods, params, p, where)
    count = sum(len(swept[m]) for m in methods) * len(pose_names) * len(speeds) * len(seeds)
    if count > MAX_RUNS:
        raise _fail(p, where, f"{count:.3g} runs (methods and swept values x {len(pose_names)} poses x "
                    f"{len(speeds)} speeds x {len(seeds)} seeds); a campaign has at most {MAX_RUNS} runs")
    runs = []
    for method in methods:
        for sweep, pose, speed, seed in itertools.product(swept[method], pose_names, speeds, seeds):
            spec = RunSpec(world=world_spec, method=method, pose=None if pose == "default" else pose,
                           speed=speed / 1000, laser_range=laser,
                           cell=None if cell_mm is None else cell_mm / 1000, seed=seed, robot=robot,
                           params={**params.get(method, {}), **sweep}, max_time=max_time,
                           laser_sigma=sigma, laser_uniform=uniform, map_bounds=bounds,
                           bounds_wall=bounds_wall)
            try:
                spec.validate()
            except ConfigError as exc:
                raise _fail(p, where, str(exc)) from None
            runs.append((spec, sweep))
    return runs


def _pose_label(spec: RunSpec) -> str:
    return spec.pose or "default"


def expected_robot_time(spec: RunSpec, area: float | None) -> float:
    """A guess of a run's robot time [s] before it runs, for ordering runs: the world's area [m^2]
    over the run's speed [m/s] (about a metre of path per square metre: the thesis's runs took
    0.5-1.1 m/m^2 in `dense` and `sparse`), at most the run's time limit; the time limit without an area."""
    if area is None or not area > 0:
        return spec.max_time
    return min(spec.max_time, area / spec.speed)


def run_order(campaign: Campaign, runs: Iterable[RunSpec]) -> list[RunSpec]:
    """`runs` longest expected first (`expected_robot_time`), ties in the campaign's own order.

    Longest first (LPT scheduling): the workers take the next run as they come free, so the short runs
    fill the gaps at the end instead of one long run keeping a core busy while the others idle."""
    index = {id(spec): i for i, spec in enumerate(campaign.runs)}
    areas = campaign.areas or {}
    listed = list(runs)
    order = sorted(range(len(listed)), key=lambda i: (-expected_robot_time(listed[i], areas.get(listed[i].world)),
                                                       index.get(id(listed[i]), len(index) + i)))
    return [listed[i] for i in order]


@dataclass(frozen=True)
class RunTiming:
    """Where one run of a campaign spent its time, measured in the process that made it.

    Attributes:
        run: the run's name.
        worker: the process that made it ("pid N" in the pool; the Dask worker's address on a cluster).
        start: [s] time.time() when the worker began the run (before its imports, world and set-up).
        end: [s] time.time() when the run's record and files were done.
        cpu_s: [s] CPU time of the worker process over the run (all its threads).
        loop_s: [s] wall time of the run loop (the record's wall_time_s).
        first_in_worker: the first run this worker made (its imports and numba cache loads are in it).
    """

    run: str
    worker: str
    start: float
    end: float
    cpu_s: float
    loop_s: float
    first_in_worker: bool

    @property
    def wall_s(self) -> float:
        """[s] the run's wall time in its worker, set-up and writing included."""
        return self.end - self.start

    @property
    def setup_s(self) -> float:
        """[s] the wall time outside the run loop: imports (first run), world, ground truth, robot, files."""
        return self.wall_s - self.loop_s


_runs_made = 0                  # in a worker: runs begun so far


_worker_interrupted = False     # in a worker: Ctrl-C came; queued runs are skipped at once
_worker_running = False         # in a worker: a run is being made (Ctrl-C interrupts it)


def _worker_init() -> None:
    """Worker start: die with the campaign process (kill -9 included), and remember a Ctrl-C so that
    the runs already queued to this worker are skipped instead of run in full."""
    from robotexp.lifeline import die_with_parent, exit_without_teardown

    die_with_parent()
    exit_without_teardown()     # the pool's shutdown at the end of a campaign waits for its workers to exit

    def interrupted(signum: int, frame: Any) -> None:
        global _worker_interrupted
        first = not _worker_interrupted
        _worker_interrupted = True
        if first and _worker_running:    # idle (waiting for work): only remember it
            raise KeyboardInterrupt

    signal.signal(signal.SIGINT, interrupted)


def _record_extra(spec: RunSpec, sweep: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The keys a campaign adds to a run's record: the world and pose as the campaign file gave them,
    and the swept parameter values of a run of a sweep."""
    extra: dict[str, Any] = {"world_spec": spec.world, "pose_spec": _pose_label(spec)}
    if sweep:
        extra["sweep"] = dict(sweep)
    return extra


def timed_run(worker: str) -> Callable[[RunRecord], RunTiming]:
    """In a worker: start timing a run; call the result with the run's record when the run is done."""
    global _runs_made
    start, cpu0, first = time.time(), time.process_time(), _runs_made == 0
    _runs_made += 1

    def done(record: RunRecord) -> RunTiming:
        return RunTiming(record.run, worker, start, time.time(), time.process_time() - cpu0,
                         float(record.wall_time_s), first)
    return done


def _run_one(spec: RunSpec, out: str, record: bool = False,
             extra: dict[str, Any] | None = None) -> tuple[RunRecord, RunTiming] | None:
    """Worker: one run, written to `out` (record first, then images; with `record` its bag in
    `out/bags`). Returns the record and its timing (None: a run queued after Ctrl-C, not made)."""
    global _worker_running
    if _worker_interrupted:
        return None
    timing = timed_run(f"pid {os.getpid()}")
    from robotexp.experiment import run_experiment

    _worker_running = True
    try:
        observers = []
        if record:
            from robotexp.bag.recorder import BagRecorder

            (Path(out) / "bags").mkdir(exist_ok=True)
            observers.append(BagRecorder(folder=Path(out) / "bags", world=spec.world))
        result = run_experiment(spec, Path(out), observers=observers, record_extra=extra or _record_extra(spec))
    finally:
        _worker_running = False
    return result.record, timing(result.record)


def run_campaign(campaign: Campaign, out: Path, *, jobs: int, resume: bool = False,
                 progress: Callable[[int, int, RunRecord | None], None] | None = None,
                 cluster: str | None = None, place: Place | None = None,
                 timings: list[RunTiming] | None = None) -> list[RunRecord]:
    """Run every run of `campaign` not yet recorded (with `resume`) in `jobs` processes, or on the
    Dask cluster at `cluster` (`robotexp.cluster`: tcp://HOST:PORT or local:N; `jobs` is then unused).
    The runs start longest expected first (`run_order`); with `timings`, each finished run's
    `RunTiming` is appended to it (benchmarks/speed/bench_thesis_campaign.py reads them).

    Returns the records of the runs made now. Ctrl-C stops the workers (each stops its robot and
    writes its partial run), cancels the queued runs at once and re-raises KeyboardInterrupt. The
    output folder is locked for the campaign (`robotexp.safefile.folder_lock`) and the workers die
    with this process.

    A campaign with runs on a robot (`campaign.devices`) makes its runs one after another here, in the
    file's order, whatever `jobs` (`robotexp.campaign_robot.run_on_robots`; `place` is its operator hook).

    Raises:
        ConfigError: --jobs < 1, a bad cluster address or no scheduler there, another campaign is
            writing into `out`, or a cluster for a campaign with runs on a robot.
    """
    if jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, got {jobs}")
    if cluster is not None and campaign.devices:
        raise ConfigError(f"{campaign.source}: runs on a robot (address in a [[set]]) are made here, one after "
                          "another; run without --cluster")
    from robotexp.safefile import folder_lock

    if cluster is not None:
        from robotexp.cluster import check_cluster_address
        check_cluster_address(cluster)
    with folder_lock(out, f"campaign {campaign.name}"):
        return _run_locked(campaign, out, jobs=jobs, resume=resume, progress=progress, cluster=cluster, place=place,
                           timings=timings)


def _run_locked(campaign: Campaign, out: Path, *, jobs: int, resume: bool,
                progress: Callable[[int, int, RunRecord | None], None] | None,
                cluster: str | None = None, place: Place | None = None,
                timings: list[RunTiming] | None = None) -> list[RunRecord]:
    from robotexp.results import read_records

    results = out / "results.jsonl"
    done: set[RunKey] = set()
    if resume and results.exists():
        done = {record_key(r) for r in read_records(results) if r.end is not EndReason.INTERRUPTED}
    todo = [s for s in campaign.runs if campaign.key(s) not in done]
    if not campaign.devices:        # on a robot: the file's order; else likely-longest first (`run_order`)
        todo = run_order(campaign, todo)
    total = len(todo)
    if progress:
        progress(0, total, None)
    if not todo:
        return []
    out.mkdir(parents=True, exist_ok=True)
    if campaign.devices:
        return run_on_robots(campaign, todo, out, progress=progress, place=place,
                             extra=lambda spec: _record_extra(spec, campaign.sweep_of(spec)))
    records: list[RunRecord] = []
    if cluster is not None:
        from robotexp.cluster import run_on_cluster

        def written(record: RunRecord) -> None:
            records.append(record)
            if progress:
                progress(len(records), total, record)

        run_on_cluster(todo, out, cluster, lambda spec: _record_extra(spec, campaign.sweep_of(spec)), written,
                       record=campaign.record, timings=timings)
        return records
    pool = ProcessPoolExecutor(max_workers=min(jobs, total), mp_context=get_context("spawn"),
                               initializer=_worker_init)
    try:
        # submitted in order; the pool hands each worker the next one as it comes free
        pending: set[Future[tuple[RunRecord, RunTiming] | None]] = {
            pool.submit(_run_one, spec, str(out), campaign.record, _record_extra(spec, campaign.sweep_of(spec)))
            for spec in todo}
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                made = fut.result()
                if made is None:
                    continue
                record, timing = made
                if timings is not None:
                    timings.append(timing)
                records.append(record)
                if progress:
                    progress(len(records), total, record)
    except KeyboardInterrupt:
        # queued runs are dropped now; the running ones write their partial run and end (the SIGINT is
        # passed on for a Ctrl-C sent to this process alone; a worker ignores a second one)
        for proc in list(getattr(pool, "_processes", {}).values()):
            with contextlib.suppress(OSError):
                os.kill(proc.pid, signal.SIGINT)
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return records


# -- report -------------------------------------------------------------------------------------

@dataclass
class Table:
    """One of the thesis's tables: a world at a speed, per start pose and method."""

    title: str
    methods: list[str]
    header: list[str]
    rows: list[list[str]]


def _mmss(seconds: float) -> str:
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m:02d}:{sec:02d}"


def report_tables(records: Iterable[RunRecord | Mapping[str, Any]]) -> list[Table]:
    """Tables in the layout of the thesis's Tables 4.1-4.4: per start pose (and seed, when there are
    several) the path [m] and duration (mm:ss) of each method and the SRT nodes; then mean, standard
    deviation, range and mean speed of the runs that completed (a run cut short is marked * and left
    out of the statistics), and, when the runs measured it, their mean map IoU, strict and with one
    cell of tolerance."""
    groups: dict[tuple[str, int], dict[str, dict[tuple[str, int], RunRecord]]] = {}
    for r in map(RunRecord.from_dict, records):
        if r.end is EndReason.INTERRUPTED:
            continue
        key = (r.world, round(float(r.max_speed_m_s or 0) * 1000))
        row_key = (str(r.pose), int(r.seed or 0))
        groups.setdefault(key, {}).setdefault(method_label(r), {})[row_key] = r
    tables = []
    for (world, speed), by_method in sorted(groups.items(), key=lambda kv: (kv[0][0], -kv[0][1])):
        methods = sorted(by_method)
        poses = sorted({k for m in by_method.values() for k in m}, key=lambda k: (_natural(k[0]), k[1]))
        # one row per start pose, or per (pose, seed) when the campaign has several seeds
        seeded = len({seed for _, seed in poses}) > 1
        labels = {k: f"{k[0]} seed {k[1]}" if seeded else k[0] for k in poses}
        # a method whose runs count tree nodes (the SRT explorers) gets a nodes column
        has_nodes = {m: any(r.nodes is not None for r in by_method[m].values()) for m in methods}
        header = ["pose"]
        for m in methods:
            header += [f"{m} path (m)", f"{m} time (mm:ss)"] + ([f"{m} nodes"] if has_nodes[m] else [])
        rows = []
        for pose in poses:
            row = [labels[pose]]
            for m in methods:
                rec = by_method[m].get(pose)
                if rec is None:
                    row += ["-", "-"] + (["-"] if has_nodes[m] else [])
                    continue
                flag = "" if rec.completed else "*"
                row += [f"{rec.path_length_m:.1f}{flag}", _mmss(rec.robot_time_s)]
                if has_nodes[m]:
                    row.append("-" if rec.nodes is None else str(rec.nodes))
            rows.append(row)
        for label, fn in (("mean", statistics.fmean), ("std dev", _stdev), ("range", _range)):
            row = [label]
            for m in methods:
                recs = _completed(by_method[m].values())
                if not recs:
                    row += ["-", "-"] + (["-"] if has_nodes[m] else [])
                    continue
                paths = [r.path_length_m for r in recs]
                times = [r.robot_time_s for r in recs]
                row += [f"{fn(paths):.1f}", _mmss(fn(times))]
                if has_nodes[m]:
                    nodes = [float(r.nodes) for r in recs if r.nodes is not None]
                    row.append(f"{fn(nodes):.0f}" if nodes else "-")
            rows.append(row)
        row = ["mean speed"]
        for m in methods:
            recs = _completed(by_method[m].values()) or list(by_method[m].values())
            v = sum(r.path_length_m for r in recs) / max(sum(r.robot_time_s for r in recs), 1e-9)
            row += [f"{v * 1000:.0f} mm/s", ""] + ([""] if has_nodes[m] else [])
        rows.append(row)
        if any(r.map_iou is not None for recs in by_method.values() for r in recs.values()):
            # map quality of the runs that completed: strict, and with one cell of tolerance
            for label, field in (("mean map IoU", "map_iou"), ("mean map IoU (1 cell)", "map_iou_tolerant")):
                row = [label]
                for m in methods:
                    known = [float(getattr(r, field)) for r in _completed(by_method[m].values())
                             if getattr(r, field) is not None]
                    row += [f"{statistics.fmean(known):.3f}" if known else "-", ""] + ([""] if has_nodes[m] else [])
                rows.append(row)
        tables.append(Table(f"{world}, max speed {speed} mm/s", methods, header, rows))
    return tables


def _completed(records: Iterable[RunRecord]) -> list[RunRecord]:
    """The runs that completed: the statistics leave out runs cut short (marked * in the rows)."""
    return [r for r in records if r.completed]


def _stdev(values: list[float]) -> float:
    return statistics.stdev(values) if len(values) > 1 else 0.0


def _range(values: list[float]) -> float:
    return max(values) - min(values)


def _natural(s: str) -> tuple[int, str]:
    return (int(s), "") if s.isdigit() else (1 << 30, s)


def table_markdown(table: Table) -> str:
    """The table as GitHub Markdown."""
    lines = [f"### {table.title}", "", "| " + " | ".join(table.header) + " |",
             "|" + "---|" * len(table.header)]
    lines += ["| " + " | ".join(r) + " |" for r in table.rows]
    return "\n".join(lines) + "\n"


def table_text(table: Table) -> str:
    """The table as aligned plain text for a terminal."""
    widths = [max(len(table.header[i]), *(len(r[i]) for r in table.rows)) for i in range(len(table.header))]
    fmt = "  ".join(f"{{:>{w}}}" for w in widths)
    out = [table.title, fmt.format(*table.header)]
    out += [fmt.format(*r) for r in table.rows]
    return "\n".join(out) + "\n"

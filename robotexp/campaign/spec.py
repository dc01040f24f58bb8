"""Campaign files: a TOML file of run sets, checked and expanded into `RunSpec`s before the first run.

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

    [[set]]                         # teams: 1 robot alone, then teams of 4 with each coordinator
    world = "dense"
    methods = ["frontier"]
    teams = [1, 4]
    coordinators = ["none", "burgard"]

    [set.coordinator_params.burgard]    # keyword parameters of one coordinator in this set
    beta = 4

Everything is checked before the first run starts, so a bad file leaves no results behind."""

from __future__ import annotations

import itertools
import json
import math
import re
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

from robotexp.campaign.robots import DEVICE_KEYS, RobotDevices, check_starts, robot_devices
from robotexp.errors import ConfigError, PluginError, WorldError
from robotexp.registry import EXPLORERS, available, make_explorer
from robotexp.run.record import RunRecord
from robotexp.run.spec import RunSpec
from robotexp.world.bounds import parse_bounds

__all__ = ["MAX_RUNS", "RunKey", "Campaign", "run_key", "record_key", "method_label", "load_campaign"]

_CAMPAIGN_KEYS = {"name", "description", "laser_range_mm", "seeds", "max_time_s", "robot", "cell_mm",
                  "laser_sigma_mm", "laser_uniform_mm", "bounds_mm", "bounds_wall", "record"} | DEVICE_KEYS


MAX_RUNS = 100_000      # runs of one campaign (checked before any list of them is made)


_SET_KEYS = ({"world", "worlds", "poses", "methods", "speeds_mm_s", "params", "sweep", "teams", "coordinators",
              "coordinator_params", "comm_range_mm"}
             | _CAMPAIGN_KEYS - {"name", "description", "record"})


RunKey = tuple[str, str, str, int, int, str, str]


@dataclass
class Campaign:
    """A parsed campaign: its name, source file and the expanded list of runs (with, for the runs of a
    sweep, the swept explorer parameters of each: `sweep_of`)."""

    name: str
    source: Path
    runs: list[RunSpec]
    record: bool = False        # each run also written as a ROS 2 bag, <out>/bags/<run>.mcap (key `record`)
    sweeps: dict[int, dict[str, Any]] | None = None    # id(spec) -> swept parameter values
    devices: dict[int, RobotDevices] | None = None     # id(spec) -> the robot it runs on (robotexp.campaign.robots)
    areas: dict[str, float] | None = None     # world spec -> [m^2] area of its bounds (for `run_order`)

    def sweep_of(self, spec: RunSpec) -> dict[str, Any]:
        """The swept parameter values of a run of this campaign ({} outside a sweep)."""
        return (self.sweeps or {}).get(id(spec), {})

    def devices_of(self, spec: RunSpec) -> RobotDevices | None:
        """The robot (and laser) a run of this campaign is made on (None: the embedded simulator)."""
        return (self.devices or {}).get(id(spec))

    def key(self, spec: RunSpec) -> RunKey:
        """`run_key` of a run of this campaign."""
        return run_key(spec, pose_label(spec), self.sweep_of(spec))


def _sweep_label(sweep: Mapping[str, Any] | None) -> str:
    """The swept values as text, names sorted: "clearance=0.2,replan_period=1.0" ("" for none)."""
    return ",".join(f"{k}={json.dumps(v)}" for k, v in sorted((sweep or {}).items()))


def _team_label(size: int | None, coordinator: str | None, comm_range: float | None,
                coordinator_params: Mapping[str, Any] | None = None) -> str:
    """A team as keys and reports name it: "team=4,coordinator=burgard[,comm_range_m=3.0]", the coordinator's
    parameters after colons, names sorted ("coordinator=burgard:beta=4"); "" for one robot."""
    if not size:
        return ""
    given = "".join(f":{k}={json.dumps(v)}" for k, v in sorted((coordinator_params or {}).items()))
    return (f"team={size},coordinator={coordinator}{given}"
            + ("" if comm_range is None else f",comm_range_m={comm_range:g}"))


def _table(record: RunRecord, key: str) -> Mapping[str, Any] | None:
    """A record's table under `key` (`sweep`, `coordinator_params`): None when it has none, or something else
    under that key."""
    value = record.get(key)
    return value if isinstance(value, dict) else None


def _label(sweep: str, team: str) -> str:
    return ",".join(x for x in (sweep, team) if x)


def run_key(spec: RunSpec, pose_label: str, sweep: Mapping[str, Any] | None = None) -> RunKey:
    """The identity of a run within a campaign: (world, method, pose, speed [mm/s], seed, swept values and team,
    robot)."""
    team = _team_label(len(spec.team), spec.coordinator, spec.comm_range, spec.coordinator_params)
    return (spec.world, spec.method, pose_label, round(spec.speed * 1000), spec.seed, _label(_sweep_label(sweep), team),
            spec.robot)


def record_key(record: RunRecord | Mapping[str, Any]) -> RunKey:
    """`run_key` of a results.jsonl record."""
    r = RunRecord.from_dict(record)
    # through the mapping (not `extra` alone): a hand-made line without pose/robot keys keeps them elsewhere
    team = _team_label(r.team_size, r.coordinator, r.comm_range_m, _table(r, "coordinator_params"))
    return (str(r.get("world_spec", r.world)), r.method, str(r.get("pose_spec", r.pose)),
            round(float(r.max_speed_m_s or 0) * 1000), int(r.seed or 0),
            _label(_sweep_label(_table(r, "sweep")), team), str(r.robot or "p3dx"))


def method_label(record: RunRecord | Mapping[str, Any]) -> str:
    """The method of a record as the report names it: with its swept values and team, "frontier [clearance=0.2]",
    "frontier [team=4,coordinator=burgard]"."""
    r = RunRecord.from_dict(record)
    label = _label(_sweep_label(_table(r, "sweep")),
                   _team_label(r.team_size, r.coordinator, r.comm_range_m, _table(r, "coordinator_params")))
    return f"{r.method} [{label}]" if label else r.method


def _fail(path: Path, where: str, message: str, kind: type[Exception] = ConfigError) -> Exception:
    return kind(f"{path}: {where}: {message}")


def _get(table: dict[str, Any], key: str, default: Any, kind: type | tuple[type, ...], path: Path, where: str) -> Any:
    value = table.get(key, default)
    if value is not default and not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
        raise _fail(path, f"{where}.{key}", f"expected {getattr(kind, '__name__', kind)}, got {value!r}")
    return value


def load_campaign(path: str | Path) -> Campaign:  # noqa: C901
    """Parse and check a campaign file; expand it into runs.

    Raises:
        ConfigError: unreadable or malformed file, unknown key, a value out of range.
        PluginError: a method that is not installed.
        WorldError: an unknown world or a pose name the world lacks.
    """
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
        worlds = _worlds(merged, p, where)
        least = len(worlds) * _least_runs_per_world(merged)
        if len(runs) + least > MAX_RUNS:      # before any world is loaded (100000 generated ones take minutes)
            raise _fail(p, where, f"{len(worlds)} worlds x at least {_least_runs_per_world(merged)} runs each: the "
                        f"campaign reaches {len(runs) + least:.3g} runs or more here; a campaign has at most "
                        f"{MAX_RUNS} runs")
        for world in worlds:
            expanded = _expand({**merged, "world": world}, p, where, methods_installed, world_of)
            if len(runs) + len(expanded) > MAX_RUNS:
                raise _fail(p, where, f"the campaign reaches {len(runs) + len(expanded)} runs here; a campaign "
                            f"has at most {MAX_RUNS} runs")
            for spec, sweep in expanded:
                runs.append(spec)
                if sweep:
                    sweeps[id(spec)] = sweep
                if robot is not None:
                    if spec.team:
                        raise _fail(p, where, "teams run on the embedded simulator: leave `teams` out of a set "
                                    "on a robot")
                    devices[id(spec)] = robot
    name = head.get("name", p.stem)
    if not (isinstance(name, str) and re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}", name)):
        raise _fail(p, "campaign.name", f"{str(name)[:60]!r} is not a folder name (letters, digits, '_', '.', "
                    "'-'; not starting with '.'): it names the output folder out/<name>")
    keys: dict[RunKey, RunSpec] = {}
    for spec in runs:      # --resume and the report tell runs apart by this key: two runs must not share one
        key = run_key(spec, pose_label(spec), sweeps.get(id(spec)))
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


def _least_runs_per_world(merged: dict[str, Any]) -> int:
    """The fewest runs a set makes in each of its worlds, from its axes as given (before they are checked: an
    axis that is not a list counts once)."""
    count = 1
    for key in ("methods", "poses", "speeds_mm_s", "seeds", "teams"):
        values = merged.get(key)
        if isinstance(values, list) and values:
            count *= len(values)
    return count


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
            raise _fail(p, where, f"the range {value!r} gives {count:.3g} values; at most 10000")
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
                raise _fail(p, f"{where}.sweep.{m}", f"{_sweep_label(combo)}: {exc}") from None
    return out


def _expand(s: dict[str, Any], p: Path, where: str, installed: dict[str, Any],  # noqa: C901
            load_world: Callable[[str], Any]) -> list[tuple[RunSpec, dict[str, Any]]]:
    world_name = _get(s, "world", None, str, p, where)
    if world_name is None:
        raise _fail(p, f"{where}.world", "missing")
    world_spec = world_name
    if world_name.endswith((".map", ".yaml", ".yml")) and not Path(world_name).is_absolute():
        world_spec = str((p.parent / world_name).resolve())
    try:
        world = load_world(world_spec)
    except (WorldError, ConfigError) as exc:
        raise _fail(p, f"{where}.world", str(exc), type(exc)) from None
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
    teams = _teams(s, robot, p, where)
    coordinator_params = _coordinator_params(s, teams, p, where)
    _check_targets(methods, teams, p, where)
    count = sum(len(swept[m]) for m in methods) * len(pose_names) * len(speeds) * len(seeds) * len(teams)
    if count > MAX_RUNS:
        raise _fail(p, where, f"{count:.3g} runs (methods and swept values x {len(pose_names)} poses x "
                    f"{len(speeds)} speeds x {len(seeds)} seeds); a campaign has at most {MAX_RUNS} runs")
    runs = []
    for method in methods:
        for sweep, pose, speed, seed, (team, coordinator, comm) in itertools.product(
                swept[method], pose_names, speeds, seeds, teams):
            spec = RunSpec(world=world_spec, method=method, pose=None if pose == "default" else pose,
                           speed=speed / 1000, laser_range=laser,
                           cell=None if cell_mm is None else cell_mm / 1000, seed=seed, robot=robot,
                           params={**params.get(method, {}), **sweep}, max_time=max_time,
                           laser_sigma=sigma, laser_uniform=uniform, map_bounds=bounds,
                           bounds_wall=bounds_wall, team=team, coordinator=coordinator, comm_range=comm,
                           coordinator_params=dict(coordinator_params.get(coordinator, {})) if team else {})
            try:
                spec.validate()
            except ConfigError as exc:
                raise _fail(p, where, str(exc)) from None
            runs.append((spec, sweep))
    return runs


def _teams(s: dict[str, Any], robot: str, p: Path, where: str) -> list[tuple[tuple[str, ...], str, float | None]]:
    """A set's team axes: `teams` (robots per team, 1 = one robot alone; default [1]) times `coordinators`
    (default ["none"]; a team of one has none), with `comm_range_mm` (default: one shared map), as
    (presets, coordinator, communication range [m])."""
    from robotexp.registry import COORDINATORS
    from robotexp.sim.team import MAX_TEAM

    sizes = s.get("teams", [1])
    if not (isinstance(sizes, list) and sizes and all(isinstance(n, int) and not isinstance(n, bool)
                                                      and 1 <= n <= MAX_TEAM for n in sizes)):
        raise _fail(p, f"{where}.teams", f"expected a list of robots per team, 1..{MAX_TEAM}, got {sizes!r}")
    names = s.get("coordinators", ["none"])
    known = available(COORDINATORS)
    if not (isinstance(names, list) and names and all(isinstance(c, str) for c in names)):
        raise _fail(p, f"{where}.coordinators", f"expected a list of coordinator names, got {names!r}")
    for c in names:
        if c not in known:
            raise _fail(p, f"{where}.coordinators", f"unknown coordinator {c!r}; available: {', '.join(known)}",
                        PluginError)
    for key, values in (("teams", sizes), ("coordinators", names)):
        twice = [v for i, v in enumerate(values) if v in values[:i]]
        if twice:
            raise _fail(p, f"{where}.{key}", f"{twice[0]!r} is given twice; give each once")
    comm = _get(s, "comm_range_mm", None, (int, float), p, where)
    if comm is not None and not (comm > 0 and math.isfinite(comm)):
        raise _fail(p, f"{where}.comm_range_mm", f"must be > 0 mm, got {comm!r}")
    out: list[tuple[tuple[str, ...], str, float | None]] = []
    for n in sizes:
        if n == 1:
            out.append(((), "none", None))
        else:
            out.extend(((robot,) * n, c, None if comm is None else comm / 1000) for c in names)
    return out


def _coordinator_params(s: dict[str, Any], teams: list[tuple[tuple[str, ...], str, float | None]], p: Path,
                        where: str) -> dict[str, dict[str, Any]]:
    """A set's `[set.coordinator_params.<name>]` tables: each names a coordinator of the set's teams, and its
    parameters are checked (names, types, ranges) by making the coordinator."""
    from robotexp.registry import make_coordinator

    given = s.get("coordinator_params", {})
    if not isinstance(given, dict) or not all(isinstance(v, dict) for v in given.values()):
        raise _fail(p, f"{where}.coordinator_params", "expected tables [set.coordinator_params.<coordinator>]")
    used = sorted({c for team, c, _ in teams if team})
    for name, values in given.items():
        if name not in used:
            raise _fail(p, f"{where}.coordinator_params.{name}",
                        f"parameters for a coordinator this set's teams do not have ({used or 'no team'})")
        try:
            make_coordinator(name, dict(values))
        except ConfigError as exc:
            raise _fail(p, f"{where}.coordinator_params.{name}", str(exc)) from None
    return given


def _check_targets(methods: list[str], teams: list[tuple[tuple[str, ...], str, float | None]], p: Path,
                   where: str) -> None:
    """Refuse, before any run, a set whose teams have a coordinator that assigns frontier targets beside a
    method whose explorer takes none (a reactive one: bvp, SRT)."""
    from robotexp.coordinator import Coordinator
    from robotexp.explorer import Explorer
    from robotexp.registry import COORDINATORS, load

    for team, coordinator, _ in teams:
        if not team or not cast("type[Coordinator]", load(COORDINATORS, coordinator, Coordinator)).assigns_targets:
            continue
        for m in methods:
            if not cast("type[Explorer]", load(EXPLORERS, m, Explorer)).takes_targets:
                raise _fail(p, f"{where}.coordinators", f"coordinator {coordinator!r} assigns frontier targets and "
                            f"method {m!r} takes none; run the reactive explorers in a set of their own with "
                            "coordinators = [\"none\"]")


def pose_label(spec: RunSpec) -> str:
    return spec.pose or "default"

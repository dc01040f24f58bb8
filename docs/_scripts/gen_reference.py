"""Generated reference pages (mkdocs-gen-files), read from the code so they cannot drift from it.

- reference/explorers.md (at its marker): every installed explorer plugin (entry point group `robotexp.explorers`)
  with the parameters of its `__init__`, as `robotexp explore -m METHOD -p help` prints them;
- reference/lua.md (at its marker): every function of the Lua tables (`robot`, `exploration`, `mapView`,
  `robotView`, `team`), its arguments and its docstring, from the Lua API's `Session.lua_<table>__<name>` methods
  (and `TeamCalls`');
- reference/results.md (at its marker): the keys of a results.jsonl record, from `robotexp.RunRecord`'s fields, with
  the meaning given below (a field without one fails the strict build, naming it).

The internal modules these read (the parameter reader, the Lua API) are found by name under the `robotexp`
package, wherever they live, so moving them to another subpackage does not break the build.
"""

from __future__ import annotations

import importlib
import inspect
import logging
import pkgutil
import re
from dataclasses import fields
from importlib.metadata import entry_points
from types import ModuleType
from typing import Any

import mkdocs_gen_files

import robotexp

log = logging.getLogger("mkdocs.plugins.robotexp_reference")

EXPLORER_GROUP = "robotexp.explorers"

# results.jsonl keys -> meaning (SI units); every RunRecord field must be here
RESULT_KEYS = {
    "run": "the run's name: its image, curve and path files are `<run>.png`, `<run>.coverage.csv`, ...",
    "method": "the explorer plugin's registered name",
    "world": "the world: a built-in name, a map file, `generated:KIND:SEED`, or the robot's name",
    "start_pose": "[x_m, y_m, theta_rad] where the run started",
    "max_speed_m_s": "the robot's maximum forward speed [m/s]",
    "path_length_m": "length of the true path [m]",
    "robot_time_s": "robot time the run took [s] (simulated time on the simulator)",
    "wall_time_s": "wall-clock time the run took [s]",
    "coverage": "0..1: share of the explorable free space the map marks free (null without ground truth)",
    "coverage_inside": "0..1: coverage of the floor more than a cell from every obstacle (absent without ground truth)",
    "collisions": "contacts with obstacles (each bumper press on a real robot)",
    "nodes": "tree size of a tree-building explorer (SRT); null for the others",
    "visited_cells": "map cells the robot's centre passed",
    "seed": "seed of every random choice of the run",
    "completed": "true when the explorer itself said it was done",
    "reason": "why the run ended; starts with the end reason (`explored`, `time limit`, `stalled`, ...)",
    "map_iou": "mean of the IoU of mapped vs true occupied cells and of mapped vs explorable free cells",
    "map_iou_tolerant": "map_iou with one cell of tolerance: a mark counts as right, a cell as found, within one cell",
    "cell_m": "the map's cell size [m]",
    "time_to_coverage_90_s": "robot time when coverage first reached 0.90 [s] (null if never)",
    "path_to_coverage_90_m": "path length when coverage first reached 0.90 [m] (null if never)",
    "time_to_coverage_95_s": "the same at 0.95 [s]",
    "path_to_coverage_95_m": "the same at 0.95 [m]",
    "time_to_coverage_99_s": "the same at 0.99 [s]",
    "path_to_coverage_99_m": "the same at 0.99 [m]",
    "pose": "the start pose as given (a pose name, or x,y,theta)",
    "laser_range_m": "the laser's range [m]",
    "robot": "the robot: a simulated preset (`p3dx`, `kobuki`) or a backend",
    "method_fields": "not a key itself: the explorer's own keys (`result_fields()`, e.g. `targets`, `detours`), "
                     "written after the milestones",
    "extra": "not a key itself: what the caller adds after `robot` (`script`, `address`, `laser`, `sweep`, "
             "`ate_m`, `localize`, `odometry_error`, `matches`, ...)",
    "end": "why the run ended, an `EndReason` value: `explored`, `time limit`, `interrupted`, `robot error`, "
           "`stalled`, `stopped`, `plugin error`",
    "schema_version": "the version of the record's schema",
    "team_size": "team runs only (`--team`): the robots of the team; the record is the team's: `path_length_m` and "
                 "`collisions` are the sums over the robots, coverage and its milestones the team map's",
    "coordinator": "team runs only: the coordinator plugin (`none`, `greedy`, `burgard`, `minpos`, ...)",
    "comm_range_m": "team runs only: the communication range [m]; null: one map shared by all",
    "total_path_m": "team runs only: the robots' paths summed [m]",
    "max_path_m": "team runs only: the longest path of one robot [m]",
    "overlap_ratio": "team runs only: the share of the cells seen (touched by a scan) that more than one robot's "
                     "scans touched",
    "idle_time_s": "team runs only: robot time the robots stood idle, summed [s]: after their explorer was done, or "
                   "commanded to stand still",
    "robot_collisions": "team runs only: the collisions with another robot, counted per robot as `collisions` are "
                        "(a contact both drove into counts twice; counted in `collisions` too)",
    "coordinator_rounds": "team runs only: the coordinator's rounds that assigned targets (null: coordinator `none`)",
    "robots": "team runs only: one object per robot: `robot`, `start_pose`, `end_pose`, `path_length_m`, "
              "`collisions`, `robot_collisions`, `idle_time_s`, `give_way_s`, `planned_around` (times it planned "
              "around teammates held beside it), `end`, `reason`, `cells_seen`, "
              "`scans_received` (with a communication range), `address` (a robot over its driver) and the "
              "explorer's own keys",
}


def find_module(leaf: str, inside: str | None = None) -> ModuleType:
    """The module of `robotexp` whose last name is `leaf` (and whose parent's last name is `inside`)."""
    for info in pkgutil.walk_packages(robotexp.__path__, "robotexp."):
        parts = info.name.split(".")
        if parts[-1] == leaf and (inside is None or (len(parts) > 1 and parts[-2] == inside)):
            return importlib.import_module(info.name)
    raise ModuleNotFoundError(f"no module robotexp...{inside + '.' if inside else ''}{leaf}")


def cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ").strip()


def explorers_page() -> str:
    explorer_parameters = find_module("paramhelp").explorer_parameters
    eps = sorted(entry_points(group=EXPLORER_GROUP), key=lambda ep: ep.name)
    out: list[str] = []
    for ep in eps:
        cls: Any = ep.load()
        summary = (inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " ")
        out += [f"## `{ep.name}`", "", f"`{ep.value}`. {summary}", ""]
        params = explorer_parameters(ep.name)
        if not params:
            out += ["No parameters.", ""]
            continue
        out += ["| parameter | type | default | meaning |", "| --- | --- | --- | --- |"]
        for p in params:
            # type and default outside code spans, where an escaped `|` would show its backslash
            out.append(f"| `{p.name}` | {cell(p.kind)} | {cell(p.default)} | {cell(p.doc)} |")
        out.append("")
    return "\n".join(out)


_USAGE = re.compile(r"""_args\(\s*"[^"]+",\s*(?:"([^"]*)"|usage)""")


def lua_page() -> str:
    api = find_module("api", inside="lua")
    session = api.Session
    tables: dict[str, list[tuple[str, str, str]]] = {}
    team = find_module("team", inside="lua").TeamCalls          # the `team` table's
    methods = {attr: f for klass in (session, team) for attr, f in vars(klass).items()}
    for attr in sorted(methods):
        if not attr.startswith("lua_"):
            continue
        table, _, name = attr[4:].partition("__")
        func = methods[attr]
        source = inspect.getsource(func)
        m = _USAGE.search(source)
        if m and m.group(1) is not None:
            usage = m.group(1)
        else:               # `usage = "..."` in the function (the team table's, which check their own arguments)
            u = re.search(r'usage\s*=\s*"([^"]*)"', source)
            usage = u.group(1) if u else ""
        doc = inspect.getdoc(func) or ""
        tables.setdefault(table, []).append((name, usage, doc))
    out = []
    for table in ("robot", "exploration", "mapView", "robotView", *sorted(set(tables) - {"robot", "exploration",
                                                                                            "mapView", "robotView"})):
        if table not in tables:
            continue
        out += [f"### `{table}`", "", "| function | what it does |", "| --- | --- |"]
        for name, usage, doc in tables[table]:
            out.append(f"| `{table}.{name}({cell(usage)})` | {cell(doc)} |")
        out.append("")
    return "\n".join(out)


def results_page() -> str:
    out = ["| key | meaning |", "| --- | --- |"]
    for f in fields(robotexp.RunRecord):
        meaning = RESULT_KEYS.get(f.name)
        if meaning is None:
            log.warning("docs: RunRecord field %r has no meaning in docs/_scripts/gen_reference.py RESULT_KEYS",
                        f.name)
            meaning = ""
        out.append(f"| `{f.name}` | {cell(meaning)} |")
    return "\n".join(out) + "\n"


# the hand-written pages carry a marker where the generated table goes
for path, marker, make in (("reference/explorers.md", "<!-- generated: explorer parameters -->", explorers_page),
                           ("reference/lua.md", "<!-- generated: lua functions -->", lua_page),
                           ("reference/results.md", "<!-- generated: record keys -->", results_page)):
    with mkdocs_gen_files.open(path, "r") as fh:
        text = fh.read()
    if marker not in text:
        raise RuntimeError(f"docs/{path} lacks the marker {marker}")
    with mkdocs_gen_files.open(path, "w") as fh:
        fh.write(text.replace(marker, make()))

"""`robotexp bench`: explorers over many maps (files, folders, generated worlds), one table.

Every map is run from its default start pose with every method and every robot preset (through the
campaign runner: parallel processes, `--resume`), then a row per run (coverage, path, robot time, end
reason, success) and a success rate per method and robot are printed and written as `bench.csv` /
`bench.txt` / `bench.md` (a Markdown table for documentation).
A run succeeds when it reached `SUCCESS_COVERAGE` of the space the robot can physically reach, with no
collision, and ended with an honest "explored": the explorer said it was done and the run's own check
found nothing reachable left unexplored (a run stopped by the time limit, the stall watch, Ctrl-C, a
robot or plugin error, leaving the exploration area, or an explorer that gave up with frontier left is
no success) - and when no point of its path (`RUN.path.csv` in the output folder) lies outside the
map's exploration area. The table shows every end reason.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from robotexp.errors import ConfigError, WorldError
from robotexp.run.spec import RunSpec
from robotexp.world.loader import MAP_SUFFIXES, is_map_file

__all__ = ["DONE_WHEN_METHODS", "DONE_WHEN_ROBOTS", "OUTSIDE", "SUCCESS_COVERAGE", "bench_markdown", "bench_table",
           "done_when_maps",           "expand_maps", "failure_causes", "success"]

SUCCESS_COVERAGE = 0.95
DONE_WHEN_METHODS = ("frontier", "bvp", "srt-laser", "meta-ga", "meta-firefly")    # the Done-when benchmark
DONE_WHEN_ROBOTS = ("p3dx", "kobuki")
OUTSIDE = "path_points_outside"     # added to a record by `run_bench` from its path file (None: not checked)
COLUMNS = ("map", "method", "robot", "coverage", "path_m", "robot_time_s", "collisions", "completed", "reason",
           "success")


def expand_maps(items: Iterable[str]) -> list[str]:
    """World specs of `items`: a folder gives its `.map` / `.yaml` files (sorted), `generated:KIND:A-B`
    one spec per seed, anything else itself (a file or a built-in name, checked when loaded).

    Raises:
        WorldError: a folder without maps, a missing path, a malformed generated spec.
    """
    from robotexp.world.generate import expand_generated

    out: list[str] = []
    for item in items:
        path = Path(item)
        if item.startswith("generated:"):
            out += expand_generated(item)
        elif path.is_dir():
            found = sorted(str(p) for p in path.iterdir() if p.suffix.lower() in MAP_SUFFIXES and p.is_file())
            if not found:
                raise WorldError(f"{item}: no .map or .yaml map in this folder, expected map files")
            out += found
        elif path.suffix.lower() in MAP_SUFFIXES and not path.is_file():
            raise WorldError(f"{item}: no such map file")
        else:
            out.append(str(path.resolve()) if path.suffix.lower() in MAP_SUFFIXES else item)
    return out


def done_when_maps(maps: Iterable[str], seeds: str = "0-49") -> list[str]:
    """The Done-when benchmark's set: `maps` (the real maps: files or folders) then `generated:KIND:seeds`
    for every generated kind (office, warehouse, cave)."""
    from robotexp.world.generate import KINDS

    return [*maps, *(f"generated:{kind}:{seeds}" for kind in KINDS if kind != "building")]


def _bench_specs(maps: list[str], methods: list[str], robots: Iterable[str] = ("p3dx",), *, speed: float = 0.3,
                 laser_range: float = 3.0, max_time: float = 4 * 3600.0, seed: int = 0,
                 load: Callable[[str], Any] | None = None) -> list[RunSpec]:
    """One `RunSpec` per map, method and robot preset (default start pose), every map loaded once first
    so that a bad one is reported before any run starts.

    Raises:
        WorldError, PluginError, ConfigError: a map that does not load, an unknown method or robot preset.
    """
    from robotexp.registry import make_explorer
    from robotexp.sim.presets import preset
    from robotexp.world.loader import load_world

    robots = list(robots)
    if not maps or not methods or not robots:
        raise ConfigError("bench: give at least one map, one method and one robot")
    for method in methods:
        make_explorer(method, {})
    for robot in robots:
        preset(robot)
    for spec in maps:
        (load or load_world)(spec)
    specs = [RunSpec(world=m, method=method, pose=None, speed=speed, laser_range=laser_range, seed=seed,
                     max_time=max_time, robot=robot) for m in maps for method in methods for robot in robots]
    for s in specs:
        s.validate()
    return specs


def success(record: dict[str, Any]) -> bool:
    """True when the run covered SUCCESS_COVERAGE, never collided and ended explored (see the module)."""
    from robotexp.run.record import EndReason

    cov = record.get("coverage")
    end = EndReason.classify(bool(record.get("completed")), str(record.get("reason", "")))
    return (end is EndReason.EXPLORED and cov is not None and cov >= SUCCESS_COVERAGE
            and record.get("collisions", 1) == 0 and not record.get(OUTSIDE))


def failure_causes(record: dict[str, Any]) -> list[str]:
    """Why a run is no success, each rule it broke in words (empty for a success)."""
    from robotexp.run.record import EndReason

    if success(record):
        return []
    out = []
    cov = record.get("coverage")
    if cov is None or cov < SUCCESS_COVERAGE:
        out.append("no coverage" if cov is None else f"coverage {cov:.3f} < {SUCCESS_COVERAGE}")
    if record.get("collisions", 1) != 0:
        out.append(f"{record.get('collisions')} collisions")
    if record.get(OUTSIDE):
        out.append(f"{record[OUTSIDE]} path points outside the exploration area")
    reason = str(record.get("reason", ""))
    end = EndReason.classify(bool(record.get("completed")), reason)
    if end is not EndReason.EXPLORED:
        out.append(f"did not end explored ({end.value})")
    return out


def _map_name(record: dict[str, Any]) -> str:
    spec = str(record.get("world_spec") or record.get("world"))
    return spec if spec.startswith("generated:") else Path(spec).name


def _map_group(record: dict[str, Any]) -> str:
    """The map's group in the summary: `generated:KIND` (plus its options but the seed) for a generated
    world, `map files` for a file, else the built-in world's name."""
    spec = str(record.get("world_spec") or record.get("world"))
    if spec.startswith("generated:"):
        parts = spec.split(":")
        return ":".join(parts[:2] + parts[3:])
    return "map files" if is_map_file(spec) else spec


def _robot(record: Mapping[str, Any]) -> str:
    """The record's robot (the default preset for records that name none)."""
    return str(record.get("robot") or "p3dx")


def _key(record: Mapping[str, Any]) -> tuple[Any, Any, str]:
    """The record's map, method and robot: the run of the bench it is a record of."""
    return record.get("world_spec"), record.get("method"), _robot(record)


def _interrupted(record: Mapping[str, Any]) -> bool:
    """True for the record of a run that a Ctrl-C or SIGTERM cut off (`--resume` makes it again)."""
    from robotexp.run.record import EndReason

    return EndReason.classify(bool(record.get("completed")), str(record.get("reason", ""))) is EndReason.INTERRUPTED


def _label(record: Mapping[str, Any]) -> str:
    """The record's method and robot, as the summaries group runs: `frontier p3dx`."""
    return f"{record.get('method')} {_robot(record)}"


def _rows(records: Iterable[dict[str, Any]]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The records sorted by map, method and robot, and their table rows (`COLUMNS`, as text)."""
    rows = sorted(records, key=lambda r: (_map_name(r), str(r.get("method")), _robot(r)))
    table = []
    for r in rows:
        cov = r.get("coverage")
        table.append({"map": _map_name(r), "method": str(r.get("method")), "robot": _robot(r),
                      "coverage": "" if cov is None else f"{cov:.4f}",
                      "path_m": f"{r.get('path_length_m', 0.0):.1f}",
                      "robot_time_s": f"{r.get('robot_time_s', 0.0):.0f}",
                      "collisions": str(r.get("collisions")), "completed": str(bool(r.get("completed"))).lower(),
                      "reason": str(r.get("reason", "")), "success": "yes" if success(r) else "no"})
    return rows, table


def bench_table(records: Iterable[dict[str, Any]]) -> tuple[str, str]:
    """(text, csv) of the runs (sorted by map, method and robot) and the success rate per method and robot."""
    rows, table = _rows(records)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(table)
    width = max([len(str(t["map"])) for t in table] + [3])
    lines = [f"{'map':<{width}}  {'method':<12} {'robot':<7} {'coverage':>8} {'path m':>8} {'time s':>7} "
             f"{'coll':>4} {'ok':>3}  end reason"]
    for t in table:
        lines.append(f"{t['map']:<{width}}  {t['method']:<12} {t['robot']:<7} {t['coverage']:>8} {t['path_m']:>8} "
                     f"{t['robot_time_s']:>7} {t['collisions']:>4} {t['success']:>3}  {t['reason']}")
    lines.append("")
    lines.append(f"per method and robot: success (coverage >= {SUCCESS_COVERAGE} of the reachable space, no "
                 "collision, ended explored), and runs the explorer itself completed")
    by_label: dict[str, list[tuple[bool, bool]]] = {}
    for r in rows:
        by_label.setdefault(_label(r), []).append((success(r), bool(r.get("completed"))))
    for label, res in sorted(by_label.items()):
        ok, done = sum(a for a, _ in res), sum(b for _, b in res)
        lines.append(f"  {label:<20} success {ok}/{len(res)} = {ok / len(res):.0%}   completed {done}/{len(res)}")
    groups = sorted({_map_group(r) for r in rows})
    if len(groups) > 1:
        lines.append("")
        lines.append("success per method, robot and group of maps (ok/runs)")
        gw = max(len(g) for g in groups)
        lines.append(f"  {'method robot':<20} " + " ".join(f"{g:>{gw}}" for g in groups))
        for label in sorted(by_label):
            cells = []
            for g in groups:
                runs = [r for r in rows if _label(r) == label and _map_group(r) == g]
                cells.append(f"{sum(success(r) for r in runs)}/{len(runs)}" if runs else "-")
            lines.append(f"  {label:<20} " + " ".join(f"{c:>{gw}}" for c in cells))
    checked = [r for r in rows if r.get(OUTSIDE) is not None]
    if checked:
        lines.append("")
        lines.append(f"path points outside the exploration area: {sum(int(r[OUTSIDE]) for r in checked)} "
                     f"(paths of {len(checked)} of {len(rows)} runs checked: the others have no path file "
                     "or their map declares no area)")
    failed = [r for r in rows if not success(r)]
    lines.append("")
    lines.append(f"failures: {len(failed)} of {len(rows)} runs" + (":" if failed else ""))
    for r in failed:
        lines.append(f"  {_map_name(r)} {_label(r)}: {'; '.join(failure_causes(r))} - "
                     f"end reason: {r.get('reason', '')}")
    return "\n".join(lines) + "\n", buf.getvalue()


def _md(text: str) -> str:
    """`text` as a Markdown table cell (pipes escaped, one line)."""
    return text.replace("|", "\\|").replace("\n", " ")


def bench_markdown(records: Iterable[dict[str, Any]]) -> str:
    """The runs as Markdown for documentation: success per method and robot, then every run (map,
    method, robot, coverage, path, robot time, collisions, success and end reason), then every failure
    with the rules it broke."""
    rows, table = _rows(records)
    by_label: dict[str, list[bool]] = {}
    for r in rows:
        by_label.setdefault(_label(r), []).append(success(r))
    out = ["| method | robot | success | rate |", "|---|---|---:|---:|"]
    for label, res in sorted(by_label.items()):
        method, robot = label.rsplit(" ", 1)
        out.append(f"| {method} | {robot} | {sum(res)}/{len(res)} | {sum(res) / len(res):.0%} |")
    out += ["", "| map | method | robot | coverage | path m | time s | collisions | ok | end reason |",
            "|---|---|---|---:|---:|---:|---:|---|---|"]
    for t in table:
        out.append(f"| {_md(t['map'])} | {t['method']} | {t['robot']} | {t['coverage']} | {t['path_m']} | "
                   f"{t['robot_time_s']} | {t['collisions']} | {t['success']} | {_md(t['reason'])} |")
    failed = [r for r in rows if not success(r)]
    out += ["", f"Failures: {len(failed)} of {len(rows)} runs."]
    if failed:
        out.append("")
        out += [f"- {_md(_map_name(r))}, {_label(r)}: {_md('; '.join(failure_causes(r)))}" for r in failed]
    return "\n".join(out) + "\n"


def _mark_outside(records: list[dict[str, Any]], out: Path) -> None:
    """Set each record's `OUTSIDE`: how many points of its path (`out/RUN.path.csv`) lie outside the
    exploration area its map declares (None: no path file, or no area)."""
    import numpy as np

    from robotexp.world.bounds import exploration_area
    from robotexp.world.loader import load_world

    areas: dict[str, tuple[float, float, float, float] | None] = {}
    for r in records:
        path = out / f"{r.get('run')}.path.csv"
        spec = str(r.get("world_spec") or r.get("world"))
        r[OUTSIDE] = None
        if not path.is_file():
            continue
        if spec not in areas:
            try:
                areas[spec] = exploration_area(load_world(spec), None)
            except (ConfigError, WorldError):
                areas[spec] = None
        area = areas[spec]
        if area is None:
            continue
        xy = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        if xy.size == 0:
            r[OUTSIDE] = 0
            continue
        x0, y0, x1, y1 = area
        r[OUTSIDE] = int(np.count_nonzero((xy[:, 0] < x0) | (xy[:, 0] > x1) | (xy[:, 1] < y0) | (xy[:, 1] > y1)))


def _no_load(spec: str) -> None:
    """`_bench_specs` without loading the maps (a report of runs already made)."""


def run_bench(maps: list[str], methods: list[str], out: Path, *, jobs: int, resume: bool = False,
              max_time: float = 4 * 3600.0, run: bool = True, robots: Iterable[str] = ("p3dx",),
              progress: Callable[[int, int, Mapping[str, Any] | None], None] | None = None) -> tuple[str, str]:
    """Run every map x method x robot (see `_bench_specs`) through the campaign runner into `out` (`run`
    False: none, only the table), write `bench.txt`, `bench.csv` and `bench.md` there from the records of
    these runs in `out/results.jsonl` (the text says how many have none), return (text, csv)."""
    from robotexp.campaign.spec import Campaign
    from robotexp.campaign.runner import run_campaign
    from robotexp.output.results import read_jsonl

    specs = _bench_specs(expand_maps(maps), methods, robots, max_time=max_time, load=None if run else _no_load)
    if run:
        run_campaign(Campaign("bench", out, specs), out, jobs=jobs, resume=resume, progress=progress)
    wanted = {(s.world, s.method, s.robot) for s in specs}
    path = out / "results.jsonl"
    records = [r for r in read_jsonl(path) if _key(r) in wanted] if path.is_file() else []
    # a run interrupted and made again by --resume: its interrupted record is left out
    made = {_key(r) for r in records if not _interrupted(r)}
    records = [r for r in records if not (_interrupted(r) and _key(r) in made)]
    _mark_outside(records, out)
    text, table = bench_table(records)
    missing = len(wanted) - len({_key(r) for r in records})
    if missing:
        text += f"not run: {missing} of {len(wanted)} map x method x robot runs (no record in {path})\n"
    (out / "bench.txt").write_text(text, encoding="utf-8")
    (out / "bench.csv").write_text(table, encoding="utf-8")
    (out / "bench.md").write_text(bench_markdown(records), encoding="utf-8")
    return text, table

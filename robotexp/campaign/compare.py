"""Method comparisons of a campaign's results: visited-cells tables with Welch's t-test, box plots
and overlaid trajectories.

`comparison_tables` gives, for each world (and maximum speed) run with two or more methods, the
layout of Santos 2016's Table 8: one row per method with the number of runs, visited cells
mean +- standard deviation, mean coverage and mean path length, then one row per pair of methods
with the two-sided p-value of Welch's two-sample t-test on visited cells. `campaign_plots` draws
(on matplotlib, `robotexp.output.figures`) `visited_cells.png` (a box per world and method, every run a point),
`coverage_<world>.png` (every run's coverage curve, one colour per method, from its `NAME.coverage.csv`)
and `paths_<world>_<method>.png` (every run's trajectory, read from its `NAME.path.csv`, on the world's
map).

As in the thesis tables, runs cut short (not completed) are left out of the statistics unless
`include_incomplete` is set; interrupted runs are always left out.
"""

from __future__ import annotations

import itertools
import json
import logging
import re
import statistics
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from robotexp.campaign.report import Table
from robotexp.campaign.spec import method_label, record_key
from robotexp.output.safefile import record_skipped, warn
from robotexp.errors import ConfigError, WorldError
from robotexp.run.record import EndReason, RunRecord, record_problem
from robotexp.campaign.statistics import NoVariance, bootstrap_mean_difference, mann_whitney_u, welch_t_test

__all__ = ["REQUIRED_KEYS", "campaign_plots", "comparison_tables", "excluded_table", "load_results", "path_file"]

log = logging.getLogger(__name__)

REQUIRED_KEYS = ("run", "world", "method", "visited_cells")


def load_results(path: Path, *, duplicates: list[RunRecord] | None = None) -> list[RunRecord]:
    """The records of a results.jsonl, checked to be robotexp run records (any robotexp wrote).

    A line that is not whole JSON (torn by a run killed while writing or a full disk) is skipped
    and reported, as by `results.read_jsonl`; runs recorded twice are reported and counted once
    (the records left out are appended to `duplicates` when given).

    Raises:
        ConfigError: no such file, not UTF-8 text, a line that is not a JSON object, a record
            without the keys `REQUIRED_KEYS`, or no record at all (a record with a field of the wrong
            type, `record_problem`, is reported and skipped).
    """
    if not path.is_file():
        raise ConfigError(f"{path}: no such results file (give the results.jsonl a run or campaign wrote)")
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not a results file (not UTF-8 text); give a results.jsonl") from None
    numbered = [(i, line.strip()) for i, line in enumerate(lines, start=1) if line.strip()]
    records: list[RunRecord] = []
    torn: list[str] = []
    mistyped: list[int] = []
    for i, line in numbered:
        try:
            rec = json.loads(line)
        except json.JSONDecodeError as exc:
            # a torn line (a run cut off while it was written, a full disk) is skipped and said, not fatal
            torn.append(f"{i} ({exc.msg})")
            continue
        if not isinstance(rec, dict):
            raise ConfigError(f"{path}:{i}: expected a JSON object per line, got {type(rec).__name__}")
        missing = [key for key in REQUIRED_KEYS if key not in rec]
        if missing:
            raise ConfigError(f"{path}:{i}: record lacks {', '.join(missing)}; is this a robotexp results.jsonl?")
        problem = record_problem(rec)
        if problem is not None:     # as `results.read_jsonl` does: said and skipped
            warn(record_skipped(path, i, problem))
            mistyped.append(i)
            continue
        records.append(RunRecord.from_dict(rec))
    if not records:
        if mistyped:
            raise ConfigError(f"{path}: no usable record ({len(mistyped)} with a field of the wrong type, said "
                              f"above{f', {len(torn)} torn' if torn else ''}); give a results.jsonl a run or "
                              "campaign wrote")
        if torn:
            raise ConfigError(f"{path}:{torn[0].split()[0]}: not a JSON record; give a results.jsonl "
                              "(one JSON object per line)")
        raise ConfigError(f"{path}: no runs recorded (the file is empty)")
    if torn:
        warn(f"{path}: skipped {len(torn)} line(s) that are not whole JSON records (torn by a fault): line "
             + ", ".join(torn[:5]) + (" ..." if len(torn) > 5 else ""))
    return _unique(path, records, duplicates)


def _unique(path: Path, records: list[RunRecord], dropped: list[RunRecord] | None = None) -> list[RunRecord]:
    """`records` with one record per run key (world, method, pose, speed, seed): the first of each,
    the others reported (a campaign run twice into one folder, a --resume over a killed campaign)."""

    seen: dict[tuple[Any, ...], int] = {}
    kept: list[RunRecord] = []
    dups: list[str] = []
    for rec in records:
        if "pose_spec" not in rec or str(rec.get("reason", "")).startswith("interrupted"):
            kept.append(rec)        # a single run (no campaign key), or an interrupted one --resume redoes
            continue
        try:
            key = record_key(rec)
        except (KeyError, TypeError, ValueError):
            kept.append(rec)
            continue
        if key in seen:
            dups.append(str(rec.get("run", key)))
            if dropped is not None:
                dropped.append(rec)
            continue
        seen[key] = len(kept)
        kept.append(rec)
    if dups:
        warn(f"{path}: {len(dups)} run(s) recorded more than once (same world, method, pose, speed and seed); "
             f"only the first record of each is counted: {', '.join(dups[:5])}{' ...' if len(dups) > 5 else ''}")
    return kept


def _finished(records: Iterable[RunRecord | Mapping[str, Any]]) -> list[RunRecord]:
    """The records (as `RunRecord`s) of the runs that were not interrupted."""
    return [r for r in map(RunRecord.from_dict, records) if r.end is not EndReason.INTERRUPTED]


def _selected(records: Iterable[RunRecord], include_incomplete: bool) -> list[RunRecord]:
    return [r for r in _finished(records) if include_incomplete or r.completed]


def _speed(record: RunRecord) -> int:
    return round(float(record.max_speed_m_s or 0) * 1000)


def _mean_sd(values: list[float], decimals: int) -> str:
    if not values:
        return "-"
    mean = statistics.fmean(values)
    if len(values) < 2:
        return f"{mean:.{decimals}f}"
    return f"{mean:.{decimals}f} ± {statistics.stdev(values):.{decimals}f}"


def _mean(values: list[float | None], decimals: int) -> str:
    known = [float(v) for v in values if v is not None]
    return f"{statistics.fmean(known):.{decimals}f}" if known else "-"


def _cell_label(cell: float | None) -> str:
    return "cell size unknown" if cell is None else f"cells of {cell:g} m"


def _cell(record: RunRecord) -> float | None:
    return None if record.cell_m is None else round(float(record.cell_m), 6)


def _pair_rows(a: str, b: str, xa: list[float], xb: list[float]) -> list[list[str]]:
    """Welch's t-test, Mann-Whitney U and the bootstrap 95 % interval of mean(a) - mean(b)."""
    if len(xa) < 2 or len(xb) < 2:
        few = "- (fewer than 2 runs)"
        return [[f"Welch p, {a} vs {b}", "", few, "", ""], [f"Mann-Whitney p, {a} vs {b}", "", few, "", ""],
                [f"95% CI of mean {a} - {b}", "", few, "", ""]]
    try:
        w = welch_t_test(xa, xb)
        welch = f"{w.p:.3g} (t = {w.t:.2f}, df = {w.df:.1f})"
    except NoVariance:
        welch = "no variance (every run of both gave the same count)"
    try:
        u = mann_whitney_u(xa, xb)
        mwu = f"{u.p:.3g} (U = {u.u:g})"
    except NoVariance:
        mwu = "no variance (every run gave the same count)"
    try:
        ci = bootstrap_mean_difference(xa, xb)
        boot = f"{ci.difference:.1f} [{ci.low:.1f}, {ci.high:.1f}] (bootstrap)"
    except NoVariance:
        boot = f"{statistics.fmean(xa) - statistics.fmean(xb):.1f} (no variance: no interval)"
    return [[f"Welch p, {a} vs {b}", "", welch, "", ""], [f"Mann-Whitney p, {a} vs {b}", "", mwu, "", ""],
            [f"95% CI of mean {a} - {b}", "", boot, "", ""]]


def comparison_tables(records: Iterable[RunRecord | Mapping[str, Any]], *,
                      include_incomplete: bool = False) -> list[Table]:
    """Santos 2016 Table 8 per world, maximum speed and map cell size that has runs of two or more
    methods.

    Rows: per method (sorted) the runs used (n; "+k*" counts the runs cut short and left out),
    visited cells mean ± sample standard deviation, mean coverage (0..1) and mean path [m] (and, when
    the runs measured it, the mean `map_iou` and `map_iou_tolerant`); then
    per pair of methods: "Welch p, A vs B" with the two-sided p-value of Welch's t-test on the
    visited cells, its t (A minus B) and df; "Mann-Whitney p, A vs B"; "95% CI of mean A - B" (a
    percentile bootstrap). "no variance" where a test needs variance the runs lack; "-" when a method
    has fewer than 2 runs.

    Visited cells count cells of the run's map: methods mapping at different cell sizes are never
    compared. A world and speed run at several cell sizes gives one table per size, each saying which
    methods were left out of it for their cell size.

    Args:
        records: results.jsonl records (`RunRecord`s, or their JSON objects).
        include_incomplete: also use the runs cut short (time limit, stuck); interrupted runs are
            always left out.

    Returns:
        The tables, sorted by world, decreasing speed, then cell size.
    """
    all_runs = _finished(records)
    used = {id(r) for r in _selected(all_runs, include_incomplete)}
    groups: dict[tuple[str, int], dict[float | None, dict[str, list[RunRecord]]]] = {}
    for r in all_runs:
        groups.setdefault((r.world, _speed(r)), {}).setdefault(_cell(r), {}).setdefault(method_label(r), []).append(r)
    tables = []
    for (world, speed), by_cell in sorted(groups.items(), key=lambda kv: (kv[0][0], -kv[0][1])):
        if len({m for by_method in by_cell.values() for m in by_method}) < 2 and len(by_cell) == 1:
            continue
        mixed = len(by_cell) > 1
        for cell, by_method in sorted(by_cell.items(), key=lambda kv: (kv[0] is None, kv[0] or 0.0)):
            methods = sorted(by_method)
            header = ["method", "n", "visited cells", "coverage", "path (m)"]
            # map quality where the runs measured it: strict, and with one cell of tolerance
            quality = any(r.map_iou is not None for recs in by_method.values() for r in recs)
            if quality:
                header += ["map IoU", "map IoU (1 cell)"]
            rows = []
            cells: dict[str, list[float]] = {}
            for m in methods:
                recs = [r for r in by_method[m] if id(r) in used]
                left_out = len(by_method[m]) - len(recs)
                cells[m] = [float(r.visited_cells) for r in recs]
                n = f"{len(recs)}" + (f" +{left_out}*" if left_out else "")
                rows.append([m, n, _mean_sd(cells[m], 1), _mean([r.coverage for r in recs], 3),
                             _mean([r.path_length_m for r in recs], 1)])
                if quality:
                    rows[-1] += [_mean([r.map_iou for r in recs], 3), _mean([r.map_iou_tolerant for r in recs], 3)]
            for a, b in itertools.combinations(methods, 2):
                rows += _pair_rows(a, b, cells[a], cells[b])
            title = f"{world}, max speed {speed} mm/s: visited cells per run"
            if mixed:
                title += f", {_cell_label(cell)}"
                others = [f"{', '.join(sorted(bm))} ({_cell_label(c)})" for c, bm in by_cell.items() if c != cell]
                rows.append(["not compared", "", "different cell size: " + "; ".join(others)
                             + " (visited cells of different sizes are not comparable)", "", ""])
            rows = [row + [""] * (len(header) - len(row)) for row in rows]
            tables.append(Table(title, methods, header, rows))
    return tables


def excluded_table(records: Iterable[RunRecord | Mapping[str, Any]], *, duplicates: Iterable[RunRecord] = (),
                   include_incomplete: bool = False) -> Table | None:
    """The runs the statistics leave out and why: interrupted, cut short (time limit, stalled,
    robot or plugin error; unless `include_incomplete`), recorded twice. None when there are none."""
    rows = []
    for r in map(RunRecord.from_dict, records):
        if r.end is EndReason.INTERRUPTED:
            why = "interrupted (--resume makes it again)"
        elif not r.completed and not include_incomplete:
            why = f"not completed ({r.end.value}): {r.reason}"
        else:
            continue
        rows.append([str(r.run), r.world, r.method, why])
    for r in duplicates:
        rows.append([str(r.run), r.world, r.method, "recorded more than once: only the first record counts"])
    if not rows:
        return None
    return Table(f"runs left out of the statistics: {len(rows)}", [], ["run", "world", "method", "why"], rows)


def path_file(results_dir: Path, record: RunRecord | Mapping[str, Any]) -> Path:
    """The path file `NAME.path.csv` of a run record, in the folder of its results.jsonl."""
    return results_dir / f"{record['run']}.path.csv"


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-") or "x"


def _run_label(record: RunRecord, with_speed: bool) -> str:
    label = f"pose {record.pose if record.pose is not None else record.start_pose}, seed {record.seed}"
    if with_speed:
        label += f", {_speed(record)} mm/s"
    label += f": {record.visited_cells} cells"
    return label + ("" if record.completed else " *")


def campaign_plots(records: Iterable[RunRecord | Mapping[str, Any]], results_dir: Path, out: Path, *,  # noqa: C901
                   include_incomplete: bool = False,
                   note: Callable[[str], None] | None = None) -> list[Path]:
    """Write `visited_cells.png`, one `coverage_<world>.png` per world and one `paths_<world>_<method>.png`
    per world and method into `out`.

    The box figure has one box per (world, method) over the runs `comparison_tables` uses, every run a
    point, the cell size in the axis label (or under each box when a world has runs at several sizes).
    The coverage and path figures show every run that was not interrupted (a run cut short is marked * in
    the legend), the paths on the static obstacles of the record's `world_spec` (else `world`); a run
    whose path or coverage file is missing, or a world that cannot be loaded, is reported through `note`
    and skipped / drawn without its map.

    Args:
        records: results.jsonl records.
        results_dir: the folder holding the runs' path and coverage files (that of results.jsonl).
        out: output folder (created when missing).
        include_incomplete: also count the runs cut short in the box plot.
        note: called with a one-line message for each skipped run or world.

    Returns:
        The images written.

    Raises:
        ConfigError: no run left to plot.
    """
    from robotexp.output.figures import PAGE_WIDTH, box_figure, curve_figure, figure_title, paths_figure, save_figure
    from robotexp.output.results import read_curve_csv
    from robotexp.output.trajectory import read_path_csv
    from robotexp.world.loader import load_world

    say = note or (lambda text: log.info("%s", text))
    runs = _finished(records)
    if not runs:
        raise ConfigError("no finished runs to plot (every run was interrupted)")
    out.mkdir(parents=True, exist_ok=True)
    by_group: dict[tuple[str, str], list[RunRecord]] = {}
    for r in runs:
        by_group.setdefault((r.world, method_label(r)), []).append(r)
    keys = sorted(by_group)
    used = {id(r) for r in _selected(runs, include_incomplete)}
    # visited cells are counted in cells of each run's map: where a world has runs at several cell
    # sizes, each box says its size (boxes of different sizes are not comparable)
    sizes: dict[str, set[float | None]] = {}
    for r in runs:
        sizes.setdefault(r.world, set()).add(_cell(r))
    groups = []
    for w, m in keys:
        by_cell: dict[float | None, list[float]] = {}
        for r in by_group[(w, m)]:
            if id(r) in used:
                by_cell.setdefault(_cell(r), []).append(float(r.visited_cells))
        if len(sizes[w]) > 1:
            groups += [(f"{w} {m} ({_cell_label(c)})", v) for c, v in sorted(
                by_cell.items(), key=lambda kv: (kv[0] is None, kv[0] or 0.0))]
        else:
            groups.append((f"{w} {m}", next(iter(by_cell.values()), [])))
    what = "all finished runs" if include_incomplete else "completed runs"
    every = set().union(*sizes.values())
    only = next(iter(every)) if len(every) == 1 else None
    unit = f"[cells of {only * 1000:g} mm]" if only is not None else "[cells of each run's map]"
    box = box_figure(groups, ylabel=f"visited cells {unit}",
                     title=f"Visited cells per run, by world and method ({what})",
                     width=max(PAGE_WIDTH, 1.1 * len(groups)))
    written = save_figure(box, out / "visited_cells", ("png",))
    for world in sorted(sizes):
        curves = []
        for (w, method) in keys:
            for r in by_group[(w, method)] if w == world else ():
                f = results_dir / f"{r.run}.coverage.csv"
                if not f.is_file():
                    say(f"{r.run}: no coverage file {f.name}; curve skipped")
                    continue
                curve = read_curve_csv(f)
                if len(curve) and curve[-1, 2] >= 0:
                    curves.append((method, curve[:, 0] / 60, curve[:, 2] * 100))
        if curves:
            methods = {c[0] for c in curves}
            cells = " / ".join(f"{c * 1000:g}" for c in sorted(c for c in sizes[world] if c is not None))
            fig = curve_figure(curves, xlabel="robot time [min]",
                               ylabel="coverage [%]" + (f" ({cells} mm cells)" if cells else ""),
                               title=f"{figure_title(world, methods.pop()) if len(methods) == 1 else world}: "
                                     f"coverage of the explorable free space, {len(curves)} run(s)",
                               hlines=(90, 95, 99), ylim=(0, 100))
            written += save_figure(fig, out / f"coverage_{_safe(world)}", ("png",))
    worlds: dict[str, Any] = {}
    for world, method in keys:
        recs = sorted(by_group[(world, method)], key=lambda r: (str(r.pose), _speed(r), r.seed))
        spec = str(recs[0].extra.get("world_spec") or world)
        if spec not in worlds:
            try:
                worlds[spec] = load_world(spec)
            except WorldError as exc:
                say(f"world {spec!r}: {exc}; paths drawn without the map")
                worlds[spec] = None
        with_speed = len({_speed(r) for r in recs}) > 1
        lines = []
        for r in recs:
            f = path_file(results_dir, r)
            if not f.is_file():
                say(f"{r.run}: no path file {f.name}; run skipped")
                continue
            lines.append((_run_label(r, with_speed), read_path_csv(f)))
        if not lines:
            continue
        title = f"{world} - {method}: {len(lines)} run(s)"
        notes = ["dot: start of a path"] + (["*: run cut short"] if any(not r.completed for r in recs) else [])
        fig = paths_figure(worlds[spec], lines, title=title, notes=notes)
        written += save_figure(fig, out / f"paths_{_safe(world)}_{_safe(method)}", ("png",))
    return written

"""Campaign report tables: time to explore and visited cells per world, pose and method (Markdown, text)."""

from __future__ import annotations

import statistics
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from robotexp.campaign.spec import method_label
from robotexp.run.record import EndReason, RunRecord

__all__ = ["Table", "report_tables", "table_markdown", "table_text"]

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


def report_tables(records: Iterable[RunRecord | Mapping[str, Any]]) -> list[Table]:  # noqa: C901
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

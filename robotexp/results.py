"""Run results: the record of one run, the JSONL file runs are appended to, and the curve files.

Each finished (or interrupted) run is appended to `OUT/results.jsonl` as one JSON object and
flushed to disk at once, so an interrupted campaign keeps every run already written.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robotexp.explorer import COVERAGE_MILESTONES

if TYPE_CHECKING:
    from robotexp.explorer import ExplorationRun

__all__ = ["make_record", "append_jsonl", "read_jsonl", "run_id", "write_curve_csv", "RESULT_KEYS"]

RESULT_KEYS = ("run", "method", "world", "start_pose", "max_speed_m_s", "path_length_m", "robot_time_s",
               "wall_time_s", "coverage", "collisions", "nodes", "visited_cells", "seed", "completed",
               "reason", "map_iou")


def run_id(world: str, method: str, pose: str, speed: float, seed: int, out: Path) -> str:
    """A file-name-safe run name, unique in `out` (a numeric suffix is added when taken)."""
    base = re.sub(r"[^A-Za-z0-9_.-]+", "-", f"{world}_{method}_{pose}_{speed * 1000:.0f}mms_s{seed}").strip("-")
    name, k = base, 1
    while (out / f"{name}.png").exists() or (out / f"{name}.coverage.csv").exists():
        k += 1
        name = f"{base}_{k}"
    return name


def make_record(run: ExplorationRun, *, name: str, method: str, world: str, seed: int,
                max_speed: float, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """The JSON record of a run (SI units; see README "Results" for every key)."""
    from robotexp.mapping.groundtruth import map_iou

    m = run.metrics
    cov = run.coverage()
    record: dict[str, Any] = {
        "run": name,
        "method": method,
        "world": world,
        "start_pose": run.start_pose.as_list() if run.start_pose else None,
        "max_speed_m_s": max_speed,
        "path_length_m": round(m.path_length, 4),
        "robot_time_s": round(run.robot_time, 3),
        "wall_time_s": round(run.wall_time, 3),
        "coverage": None if cov is None else round(cov, 5),
        "collisions": m.collisions,
        "nodes": None,
        "visited_cells": len(m.visited),
        "seed": seed,
        "completed": run.completed,
        "reason": run.reason,
        "map_iou": None if run.truth is None else round(map_iou(run.grid.states(), run.truth), 5),
        "cell_m": run.grid.geo.cell,
    }
    for level in COVERAGE_MILESTONES:
        hit = m.milestones.get(level)
        key = f"{round(level * 100)}"
        record[f"time_to_coverage_{key}_s"] = None if hit is None else round(hit[0], 3)
        record[f"path_to_coverage_{key}_m"] = None if hit is None else round(hit[1], 4)
    record.update(run.explorer.result_fields())
    if extra:
        record.update(extra)
    return record


def append_jsonl(path: Path, record: dict[str, Any]) -> None:
    """Append `record` as one line to `path` and force it to disk; a torn last line left by an
    earlier fault is repaired first (and reported), and a failed write leaves no half line
    (`robotexp.safefile.append_line`)."""
    from robotexp.safefile import append_line
    append_line(path, record)


def read_jsonl(path: Path) -> list[dict[str, Any]]:
    """Every record of a results file; a torn or damaged line is reported and skipped."""
    from robotexp.safefile import read_records
    return read_records(path)


def write_curve_csv(path: Path, curve: list[tuple[float, float, float]]) -> None:
    """The coverage curve: robot time [s], path length [m], coverage (0..1, -1 when unknown)."""
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["robot_time_s", "path_length_m", "coverage"])
        for t, s, c in curve:
            w.writerow([f"{t:.3f}", f"{s:.4f}", f"{c:.5f}"])

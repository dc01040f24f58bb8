"""Records regression: two built-in explorers give, through the public entry point, the records they
gave before the core restructure, to the last digit; wall times aside.

The expected figures were recorded with the code before the restructure (commit 064b793), by
`benchmarks/regression/records_regression.py` (the full list of explorers and worlds is run there; this is the
fast part); coverage, map IoU and the coverage curves since follow the ground truth's reachable set
computed from the exact geometry (`robotexp.world.clearance`). A change of the run loop, the mapping, the
planners or these explorers that alters a
run shows here.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.run.record import EndReason, RunRecord
from robotexp.output.results import read_records

EXPECTED = {
    # dense, frontier, cut at 60 s of robot time; frontier as it was (before it skipped grazed wall
    # faces, `face_reach`, which changes its runs on purpose): the run loop, the mapping and the planners
    # still give the same records to the last digit
    ("dense", "frontier", 60.0): {
        "params": {"face_reach": 0.0},
        "record": {"run": "dense_frontier_1_300mms_s0", "path_length_m": 15.0526, "robot_time_s": 60.0,
                   "coverage": 0.1705, "map_iou": 0.15269, "visited_cells": 156, "collisions": 0,
                   "reason": "time limit of 60 s reached", "completed": False, "nodes": None,
                   "start_pose": [-5.0, 7.5, 0.0], "time_to_coverage_90_s": None, "pose": "1",
                   "robot": "p3dx", "laser_range_m": 3.0, "cell_m": 0.1, "max_speed_m_s": 0.3, "seed": 0},
        "end": EndReason.TIME_LIMIT,
        "curve_sha256": "9e2a221bc78a5f466966583c9942f018605dbfa899759915c4fea33835999ff9",
        "path_sha256": "a35f4d19504488090d9b564549775ff5a70068666929953db657c1614396de1e",
    },
    # dense, srt-laser, to its end: the thesis's srt-laser (without the frontier rescue, an extension)
    ("dense", "srt-laser", 4 * 3600.0): {
        "params": {"frontier": False},
        "record": {"run": "dense_srt-laser_1_300mms_s0", "path_length_m": 235.1939, "robot_time_s": 1261.2,
                   "coverage": 0.98683, "map_iou": 0.89186, "visited_cells": 1683, "collisions": 0, "nodes": 52,
                   "reason": "explored; back at the start", "completed": True,
                   "time_to_coverage_90_s": 983.0, "path_to_coverage_90_m": 182.9542,
                   "time_to_coverage_95_s": 1147.0, "path_to_coverage_95_m": 212.7656,
                   "time_to_coverage_99_s": None, "path_to_coverage_99_m": None,
                   "backtracks": 51, "detours": 0, "abandoned": 0},
        "end": EndReason.EXPLORED,
        "curve_sha256": "1e4e15f43e5c11ce7d20d97fa89d64ba7ed0e840cafceca8e4d08ddadc338011",
        "path_sha256": "61222bf8d2ee3bc7bb30fedb18eaa672a1a926cc69a1447f18d324a5fc385358",
    },
}




@pytest.mark.parametrize("case", list(EXPECTED), ids=lambda c: f"{c[0]}-{c[1]}")
def test_builtin_explorer_records_are_unchanged(case: tuple[str, str, float], tmp_path: Path) -> None:
    world, method, max_time = case
    want = EXPECTED[case]
    params = dict(want.get("params", {}))        # type: ignore[call-overload]
    out = run_experiment(RunSpec(world=world, method=method, max_time=max_time, params=params), tmp_path, image=False)
    got = out.record
    for key, value in want["record"].items():      # type: ignore[union-attr]
        assert got[key] == value, key
    assert got.end is want["end"]
    name = got.run
    assert hashlib.sha256((tmp_path / f"{name}.coverage.csv").read_bytes()).hexdigest() == want["curve_sha256"]
    assert hashlib.sha256((tmp_path / f"{name}.path.csv").read_bytes()).hexdigest() == want["path_sha256"]
    # what was written is what was returned, and reads back as the same typed record
    (written,) = read_records(tmp_path / "results.jsonl")
    assert isinstance(written, RunRecord) and written.as_dict() == got.as_dict() and written.end is got.end

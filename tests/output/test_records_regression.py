"""Records regression: two built-in explorers give, through the public entry point, the records they
gave before the core restructure, to the last digit; wall times aside.

The expected figures were recorded with the code before the restructure (commit 064b793), by
`benchmarks/regression/records_regression.py` (the full list of explorers and worlds is run there; this is the
fast part); coverage, map IoU and the coverage curves since follow the ground truth's reachable set
computed from the exact geometry (`robotexp.world.clearance`), and both runs follow the planners' passability
measured to the walls' surface and the path follower that drives it (recorded again then). A change of
the run loop, the mapping, the planners or these explorers that alters a run shows here.
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
    # dense, frontier, cut at 60 s of robot time; frontier without skipping grazed wall faces
    # (`face_reach`); recorded again when the planners came to measure to the walls' surface with a 2 cm
    # margin and the follower to steer at a carrot with the swept-disc guard (runs changed on purpose)
    ("dense", "frontier", 60.0): {
        "params": {"face_reach": 0.0},
        "record": {"run": "dense_frontier_1_300mms_s0", "path_length_m": 15.004, "robot_time_s": 60.0,
                   "coverage": 0.1713, "map_iou": 0.15217, "visited_cells": 171, "collisions": 0,
                   "reason": "time limit of 60 s reached", "completed": False, "nodes": None,
                   "start_pose": [-5.0, 7.5, 0.0], "time_to_coverage_90_s": None, "pose": "1",
                   "robot": "p3dx", "laser_range_m": 3.0, "cell_m": 0.1, "max_speed_m_s": 0.3, "seed": 0},
        "end": EndReason.TIME_LIMIT,
        "curve_sha256": "5c7642eda5d35e4bf487fe657149adb195e22cb71003cba33f048097278251d2",
        "path_sha256": "6d873b59c66444015ebbf28e7123ae00351405210d6e56b1691c885922069819",
    },
    # dense, srt-laser, to its end: the thesis's srt-laser (without the frontier rescue, an extension);
    # recorded again with the 2 cm margin and the new follower, as frontier above, and again (the map, not the
    # path) when the sweeps' obstacle points stopped going into the map as walls; the thesis's way back too,
    # node by node (`skip_back`, an extension)
    ("dense", "srt-laser", 4 * 3600.0): {
        "params": {"frontier": False, "skip_back": False},
        "record": {"run": "dense_srt-laser_1_300mms_s0", "path_length_m": 256.6843, "robot_time_s": 1377.0,
                   "coverage": 0.995, "map_iou": 0.90309, "visited_cells": 1628, "collisions": 0, "nodes": 52,
                   "reason": "explored; back at the start", "completed": True,
                   "time_to_coverage_90_s": 1084.0, "path_to_coverage_90_m": 203.4544,
                   "time_to_coverage_95_s": 1229.0, "path_to_coverage_95_m": 230.0725,
                   "time_to_coverage_99_s": 1248.0, "path_to_coverage_99_m": 233.2081,
                   "backtracks": 51, "detours": 0, "abandoned": 1},
        "end": EndReason.EXPLORED,
        "curve_sha256": "24fb040526da4e96c3a842dc37caa952ad9718c3b526a8e4eb3a6b6437d77d4d",
        "path_sha256": "16d6a7b62dbdb8ff91c0f857df1410fb648a3b4721fd50485f3ed47e266426e3",
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

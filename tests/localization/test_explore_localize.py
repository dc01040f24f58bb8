"""`robotexp explore --odometry-error --localize`: the record carries ate_m, and scan matching lowers it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.run.record import RunRecord


def test_explore_records_ate_with_and_without_scan_matching(tmp_path: Path) -> None:
    runner = CliRunner()
    base = ["explore", "-w", "dense", "-m", "srt-laser", "--max-time", "60", "--odometry-error", "p3dx",
            "--out", str(tmp_path)]
    summaries = []
    for extra in (["--localize", "none"], [], ["--odometry-error", "none"]):
        res = runner.invoke(main, base + extra)
        assert res.exit_code == 0, res.output
        summaries.append(res.output.splitlines()[-2])
    raw, fixed, exact = (json.loads(line) for line in (tmp_path / "results.jsonl").read_text().splitlines())
    # the summary line says what the record says: map IoU always, ATE where the odometry erred
    for line, rec in zip(summaries, (raw, fixed, exact), strict=True):
        assert f"map IoU {rec['map_iou']:.3f}" in line, line
    assert f"ATE {raw['ate_m']:.3f} m" in summaries[0] and f"ATE {fixed['ate_m']:.3f} m" in summaries[1]
    assert "ATE" not in summaries[2]
    assert raw["localize"] == "none" and raw["odometry_error"] == "p3dx"
    assert fixed["localize"] == "scan-match" and fixed["matches"]["matched"] > 0     # auto: on with the error
    assert exact["localize"] == "none" and exact["ate_m"] == 0.0                     # auto: off without it
    assert fixed["ate_m"] < 0.1 < raw["ate_m"]
    # both paths are written: the true one, and the one the explorer got where it differs
    runs = [r["run"] for r in (raw, fixed, exact)]
    for name in runs[:2]:
        true_path = np.loadtxt(tmp_path / f"{name}.path.csv", delimiter=",", skiprows=1)
        est = np.loadtxt(tmp_path / f"{name}.estimated_path.csv", delimiter=",", skiprows=1)
        assert len(true_path) > 10 and len(est) > 10
    assert not (tmp_path / f"{runs[2]}.estimated_path.csv").exists()          # exact odometry: one path
    # the typed record keeps the new keys
    assert RunRecord.from_dict(fixed).as_dict() == fixed


def test_explore_rejects_a_bad_odometry_error_before_the_run(tmp_path: Path) -> None:
    res = CliRunner().invoke(main, ["explore", "--odometry-error", "pioneer", "--out", str(tmp_path)])
    assert res.exit_code == 2 and "unknown preset 'pioneer'" in res.output
    assert not (tmp_path / "results.jsonl").exists()


def test_a_map_built_at_an_estimated_pose_weighs_a_miss_less_than_a_hit() -> None:
    """Runs that localize build their map with `MAP_P_FREE` (a beam that crossed a cell: logit(0.3), 0.39 of a
    hit's logit(0.9)); at the exact pose a miss weighs as much as a hit (logit(0.1))."""
    import math

    from robotexp.experiment import run_experiment
    from robotexp.run.localize import MAP_P_FREE
    from robotexp.run.spec import RunSpec

    def logit(p: float) -> float:
        return math.log(p / (1 - p))

    assert MAP_P_FREE == 0.3
    for localize, odometry, p_free in (("scan-match", "p3dx", 0.3), ("slam", "p3dx", 0.3), ("none", "p3dx", 0.1),
                                       ("none", "none", 0.1)):
        spec = RunSpec(world="dense", method="frontier", max_time=3.0, odometry=odometry, localize=localize)
        grid = run_experiment(spec, None, image=False).run.grid
        assert grid.p_free == p_free and math.isclose(grid.l_free, logit(p_free), rel_tol=1e-6), localize
        assert math.isclose(grid.l_occ, logit(0.9), rel_tol=1e-6)

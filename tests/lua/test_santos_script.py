"""scripts_lua/santos.lua (Santos's Table 8 as a Lua script), cut to one seed and 10 s runs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robotexp.campaign.report import report_tables
from robotexp.campaign.compare import comparison_tables
from robotexp.lua import run_script

SCRIPT = Path(__file__).parents[2] / "scripts_lua" / "santos.lua"


def test_santos_script_runs_every_method_in_both_worlds_from_pose_1(tmp_path: Path) -> None:
    code = SCRIPT.read_text()
    assert "local SEEDS = 5" in code
    code = code.replace("local SEEDS = 5", "local SEEDS = 1").replace(
        'exploration.setParameter("objective", "proportional")',
        'exploration.setParameter("objective", "proportional")\nexploration.setMaxTime(10000)')
    run_script(SCRIPT, code=code, out=tmp_path)
    records = [json.loads(x) for x in (tmp_path / "results.jsonl").read_text().splitlines()]
    assert [(r["world"], r["method"]) for r in records] == [
        (w, m) for w in ("dense", "sparse") for m in ("meta-firefly", "meta-ga", "meta-exhaustive")]
    starts = {"dense": [-5.0, 7.5, 0.0], "sparse": [-12.0, -4.0, 0.0]}
    for r in records:
        assert r["start_pose"] == pytest.approx(starts[r["world"]])      # every run from pose 1
        assert r["cell_m"] == pytest.approx(0.05) and r["visited_cells"] > 0
    for w in ("dense", "sparse"):
        for label in ("FA", "GA", "optimum"):
            assert (tmp_path / f"santos_{w}_{label}_s0.png").is_file()
    # the records make the report's tables (Table 8 needs 2+ runs per method for its p-values)
    assert len(report_tables(records)) == 2 and len(comparison_tables(records, include_incomplete=True)) == 2

"""The map benchmark: which maps it runs, the success rule, the table, and one real run end to end."""

from __future__ import annotations

import csv
import json
import io

import pytest
from click.testing import CliRunner

from robotexp.campaign.bench import (SUCCESS_COVERAGE, bench_markdown, bench_table, done_when_maps, expand_maps,
                                     failure_causes, success)
from robotexp.cli import main
from robotexp.errors import WorldError
from robotexp.world.generate import write_generated


def test_folders_generated_ranges_and_names_expand(tmp_path):
    write_generated(tmp_path / "b.yaml", "cave", 0, (10.0, 10.0))
    write_generated(tmp_path / "a.map", "cave", 1, (10.0, 10.0))
    (tmp_path / "notes.txt").write_text("not a map")
    assert expand_maps([str(tmp_path), "generated:office:3-4", "dense"]) == [
        str(tmp_path / "a.map"), str(tmp_path / "b.yaml"), "generated:office:3", "generated:office:4", "dense"]
    (tmp_path / "empty").mkdir()
    with pytest.raises(WorldError, match="no .map or .yaml map"):
        expand_maps([str(tmp_path / "empty")])
    with pytest.raises(WorldError, match="no such map file"):
        expand_maps([str(tmp_path / "nope.yaml")])


def record(method: str, cov: float | None, completed: bool, collisions: int = 0, reason: str = "x") -> dict:
    return {"world_spec": "generated:office:1", "method": method, "coverage": cov, "completed": completed,
            "collisions": collisions, "reason": reason, "path_length_m": 12.34, "robot_time_s": 56.7}


def test_success_needs_an_explored_ending_the_coverage_and_no_collision():
    assert success(record("a", SUCCESS_COVERAGE, True))
    assert not success(record("a", SUCCESS_COVERAGE - 1e-9, True))
    assert not success(record("a", 1.0, True, collisions=1))
    assert not success(record("a", None, True))
    # only an honest "explored" counts: a stall, a time limit, an error, leaving the area, or an explorer that
    # said it was done with reachable frontier left (the run's check turns that into "stopped") do not
    assert not success(record("a", 1.0, False, reason="stalled: no newly known space for 3 x 120 s"))
    assert not success(record("a", 1.0, False, reason="time limit of 3600 s reached"))
    assert not success(record("a", 1.0, False, reason="robot error: link lost"))
    assert not success(record("a", 1.0, False, reason="stopped: the robot left the exploration area at (1, 2) m"))
    assert not success(record("a", 0.99, False, reason="stopped: the explorer ended (x) with 5 frontier cells left"))
    assert failure_causes(record("a", 0.99, False, reason="stalled: x")) == ["did not end explored (stalled)"]


def test_the_table_has_a_row_per_run_and_a_rate_per_method():
    text, table = bench_table([record("frontier", 0.99, True, reason="done"),
                               record("bvp", 0.99, False, reason="time limit of 9 s reached"),
                               record("frontier", 0.5, True, reason="early")])
    rows = list(csv.DictReader(io.StringIO(table)))
    assert [(r["method"], r["coverage"], r["success"]) for r in rows] == [
        ("bvp", "0.9900", "no"), ("frontier", "0.9900", "yes"), ("frontier", "0.5000", "no")]
    assert rows[0]["path_m"] == "12.3" and rows[0]["reason"] == "time limit of 9 s reached"
    assert rows[0]["map"] == "generated:office:1" and rows[0]["robot"] == "p3dx"
    assert "  bvp p3dx             success 0/1 = 0%   completed 0/1" in text
    assert "  frontier p3dx        success 1/2 = 50%   completed 2/2" in text


def test_runs_are_told_apart_and_summed_per_robot():
    runs = [{**record("frontier", 0.99, True, reason="done"), "robot": "kobuki"},
            {**record("frontier", 0.5, True, reason="early"), "robot": "p3dx"},
            {**record("frontier", 0.97, True, reason="done"), "robot": "p3dx", "world_spec": "/m/b.yaml"}]
    text, table = bench_table(runs)
    assert [(r["map"], r["robot"], r["success"]) for r in csv.DictReader(io.StringIO(table))] == [
        ("b.yaml", "p3dx", "yes"), ("generated:office:1", "kobuki", "yes"), ("generated:office:1", "p3dx", "no")]
    assert "  frontier kobuki      success 1/1 = 100%" in text
    assert "  frontier p3dx        success 1/2 = 50%" in text
    md = bench_markdown(runs)
    assert "| frontier | kobuki | 1/1 | 100% |" in md and "| frontier | p3dx | 1/2 | 50% |" in md
    assert "| generated:office:1 | frontier | p3dx | 0.5000 | 12.3 | 57 | 0 | no | early |" in md
    assert "- generated:office:1, frontier p3dx: coverage 0.500 < 0.95" in md
    assert bench_markdown([{**runs[0], "reason": "a | b"}]).count("a \\| b") == 1


def test_bench_runs_a_generated_world_end_to_end_and_writes_its_table(tmp_path):
    out = tmp_path / "bench"
    result = CliRunner().invoke(main, ["bench", "generated:office:0:10x8", "-m", "frontier", "-j", "1",
                                       "-o", str(out), "--max-time", "900"])
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(io.StringIO((out / "bench.csv").read_text())))
    assert len(rows) == 1 and rows[0]["method"] == "frontier" and rows[0]["map"] == "generated:office:0:10x8"
    assert float(rows[0]["coverage"]) > 0.5 and rows[0]["collisions"] == "0"
    assert (out / "bench.txt").read_text() in result.output
    assert "path points outside the exploration area: 0 (paths of 1 of 1 runs checked" in result.output
    bad = CliRunner().invoke(main, ["bench", "generated:castle:0", "-o", str(out)])
    assert bad.exit_code == 2 and "unknown kind 'castle'" in bad.output
    bad = CliRunner().invoke(main, ["bench", "dense", "-m", "nosuch", "-o", str(out)])
    assert bad.exit_code == 2 and "nosuch" in bad.output


def test_failures_are_listed_with_the_rules_they_broke_and_groups_are_tallied():
    runs = [record("frontier", 0.99, True, reason="done"),
            {**record("frontier", 0.97, False, reason="time limit of 9 s reached"), "world_spec": "/m/a.yaml"},
            {**record("bvp", 0.5, True, collisions=2, reason="explored"), "world_spec": "generated:cave:3"}]
    text, _ = bench_table(runs)
    assert "failures: 2 of 3 runs:" in text
    assert ("  a.yaml frontier p3dx: did not end explored (time limit) - end reason: time limit of 9 s reached"
            in text)
    assert "  generated:cave:3 bvp p3dx: coverage 0.500 < 0.95; 2 collisions - end reason: explored" in text
    header = next(line for line in text.splitlines() if line.startswith("  method robot "))
    assert header.split() == ["method", "robot", "generated:cave", "generated:office", "map", "files"]
    assert next(line for line in text.splitlines() if line.startswith("  frontier ") and "/" in line
                and "success" not in line).split() == ["frontier", "p3dx", "-", "1/1", "0/1"]
    assert failure_causes(runs[0]) == []


def test_done_when_names_the_real_maps_and_three_generated_kinds():
    assert done_when_maps(["/maps"], "0-1") == ["/maps", "generated:office:0-1", "generated:warehouse:0-1",
                                                "generated:cave:0-1"]
    assert len(expand_maps(done_when_maps([], "0-49"))) == 150
    result = CliRunner().invoke(main, ["bench"])
    assert result.exit_code == 2 and "--done-when" in result.output


def test_report_tables_the_recorded_runs_and_counts_the_missing(tmp_path):
    out = tmp_path / "bench"
    out.mkdir()
    rec = {**record("frontier", 0.99, True, reason="done"), "world_spec": "generated:cave:0"}
    (out / "results.jsonl").write_text(json.dumps(rec) + "\n")
    result = CliRunner().invoke(main, ["bench", "generated:cave:0-1", "-m", "frontier", "-o", str(out), "--report"])
    assert result.exit_code == 0, result.output
    assert "frontier p3dx        success 1/1 = 100%" in result.output
    assert "not run: 1 of 2 map x method x robot runs" in result.output
    assert (out / "bench.csv").read_text().count("\n") == 2
    # each robot preset is a run of its own: the kobuki's is missing, and --resume would make just that one
    result = CliRunner().invoke(main, ["bench", "generated:cave:0", "-m", "frontier", "-r", "p3dx,kobuki",
                                       "-o", str(out), "--report"])
    assert result.exit_code == 0, result.output
    assert "not run: 1 of 2 map x method x robot runs" in result.output
    assert "| frontier | p3dx | 1/1 | 100% |" in (out / "bench.md").read_text()
    bad = CliRunner().invoke(main, ["bench", "generated:cave:0", "-r", "roomba", "-o", str(out)])
    assert bad.exit_code == 2 and "roomba" in bad.output


def test_a_runs_robot_is_part_of_its_key_for_resume():
    from robotexp.campaign.spec import record_key, run_key
    from robotexp.run.spec import RunSpec

    p3dx, kobuki = (RunSpec(world="dense", method="frontier", robot=r) for r in ("p3dx", "kobuki"))
    assert run_key(p3dx, "default") != run_key(kobuki, "default")
    rec = {"run": "x", "method": "frontier", "world": "dense", "world_spec": "dense", "pose_spec": "default",
           "max_speed_m_s": 0.3, "seed": 0, "robot": "kobuki"}
    assert record_key(rec) == run_key(kobuki, "default")
    assert record_key({**rec, "robot": None}) == run_key(p3dx, "default")     # records that name no robot


def test_report_counts_the_path_points_outside_the_exploration_area(tmp_path):
    # generated worlds declare their area (the map with its 0.5 m band); a run's path file is checked
    # against it: a point outside makes the run a failure, and the summary counts the points
    out = tmp_path / "bench"
    out.mkdir()
    recs = [{**record("frontier", 0.99, True, reason="done"), "world_spec": "generated:cave:0", "run": "in"},
            {**record("bvp", 0.99, True, reason="done"), "world_spec": "generated:cave:0", "run": "out"}]
    (out / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    (out / "in.path.csv").write_text("x_m,y_m\n1.0,1.0\n2.5,3.0\n")
    (out / "out.path.csv").write_text("x_m,y_m\n1.0,1.0\n-0.6,3.0\n1.0,-2.0\n")     # area x, y from -0.5
    result = CliRunner().invoke(main, ["bench", "generated:cave:0", "-m", "frontier,bvp", "-o", str(out), "--report"])
    assert result.exit_code == 0, result.output
    assert "path points outside the exploration area: 2 (paths of 2 of 2 runs checked" in result.output
    assert "frontier p3dx        success 1/1 = 100%" in result.output
    assert "bvp p3dx             success 0/1 = 0%" in result.output
    assert "generated:cave:0 bvp p3dx: 2 path points outside the exploration area" in result.output


def test_a_run_interrupted_and_made_again_by_resume_counts_once(tmp_path):
    # a bench stopped mid-run and resumed: the interrupted record stays in results.jsonl beside the run made again;
    # the table counts the run once, as made; a run still only interrupted stays (--resume has not made it yet)
    out = tmp_path / "bench"
    out.mkdir()
    base = {**record("frontier", 0.99, True, reason="done"), "world_spec": "generated:cave:0", "end": "explored"}
    cut = {**base, "coverage": 0.4, "completed": False, "reason": "interrupted (SIGTERM)", "end": "interrupted"}
    other = {**cut, "world_spec": "generated:cave:1"}
    (out / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in (cut, base, other)))
    result = CliRunner().invoke(main, ["bench", "generated:cave:0-1", "-m", "frontier", "-o", str(out), "--report"])
    assert result.exit_code == 0, result.output
    assert "frontier p3dx        success 1/2 = 50%" in result.output
    rows = list(csv.DictReader(io.StringIO((out / "bench.csv").read_text())))
    assert len(rows) == 2
    assert "not run" not in result.output

"""Records with a schema: every record says its format (`schema_version`), why the run ended (`end`) and
its map quality with one cell of tolerance (`map_iou_tolerant`); the published JSON Schema accepts what
runs write (tests/conftest.py checks every record the suite writes under a tmp_path) and refuses what
breaks it; a record is immutable; records of the earlier format still load and write back as they were."""

from __future__ import annotations

import dataclasses
import json
import pickle
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from robotexp.campaign.report import report_tables
from robotexp.campaign.compare import comparison_tables
from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.run.record import SCHEMA_VERSION, EndReason, RunRecord, results_schema

# a line as records were written before they had a schema version (no end, no map_iou_tolerant)
OLD_LINE = ('{"run": "dense_frontier_1_300mms_s0", "method": "frontier", "world": "dense", "start_pose": [-5.0, 7.5, '
            '0.0], "max_speed_m_s": 0.3, "path_length_m": 172.0196, "robot_time_s": 640.1, "wall_time_s": 22.4, '
            '"coverage": 0.9982, "collisions": 0, "nodes": null, "visited_cells": 2600, "seed": 0, "completed": '
            'false, "reason": "stalled: no coverage gain for 180 s", "map_iou": 0.91, "cell_m": 0.05, '
            '"time_to_coverage_90_s": 300.0, "path_to_coverage_90_m": 80.0, "time_to_coverage_95_s": null, '
            '"path_to_coverage_95_m": null, "time_to_coverage_99_s": null, "path_to_coverage_99_m": null, '
            '"targets": 12, "pose": "1", "laser_range_m": 3.0, "robot": "p3dx", "ate_m": 0.0}')


@pytest.fixture(scope="module")
def validator() -> Any:
    schema = results_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def test_a_run_writes_a_versioned_record_the_schema_accepts(tmp_path: Path, validator: Any) -> None:
    out = run_experiment(RunSpec(world="dense", method="frontier", max_time=20.0), tmp_path, image=False)
    (line,) = (tmp_path / "results.jsonl").read_text().splitlines()
    data = json.loads(line)
    assert list(data)[0] == "schema_version" and data["schema_version"] == SCHEMA_VERSION == 1
    assert data["end"] == "time limit" and out.record.end is EndReason.TIME_LIMIT
    # one cell of tolerance forgives what the strict IoU counts twice: never below it
    assert data["map_iou_tolerant"] >= data["map_iou"] > 0
    assert list(data).index("map_iou_tolerant") == list(data).index("map_iou") + 1
    assert not list(validator.iter_errors(data))
    assert RunRecord.from_dict(data).as_dict() == data and list(RunRecord.from_dict(data).as_dict()) == list(data)


@pytest.mark.parametrize("change", [{"end": "finished"}, {"schema_version": 2}, {"map_iou_tolerant": 1.5},
                                    {"collisions": -1}, {"start_pose": [1.0, 2.0]}, {"end": None}])
def test_the_schema_refuses_a_broken_record(change: dict[str, Any], validator: Any) -> None:
    data = {"schema_version": 1, **json.loads(OLD_LINE), "end": "stalled", "map_iou_tolerant": 0.95}
    assert not list(validator.iter_errors(data))
    data.update(change)
    assert list(validator.iter_errors(data))
    missing = {k: v for k, v in data.items() if k != "end"} | {"end": "stalled"}
    del missing["map_iou_tolerant"]
    assert list(validator.iter_errors(missing))


def test_the_suite_hook_finds_a_broken_record(tmp_path: Path) -> None:
    import importlib.util      # the suite's own conftest (a folder's conftest may be the one named `conftest`)

    top = next(d / "conftest.py" for d in Path(__file__).resolve().parents if d.name == "tests")
    spec = importlib.util.spec_from_file_location("_suite_conftest", top)
    assert spec is not None and spec.loader is not None
    suite = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(suite)
    check_results_files = suite.check_results_files

    folder = tmp_path / "elsewhere"
    (folder / "deep").mkdir(parents=True)
    good = {"schema_version": 1, **json.loads(OLD_LINE), "end": "stalled", "map_iou_tolerant": 0.95}
    bad = dict(good, end="finished")
    (folder / "deep" / "results.jsonl").write_text("\n".join([json.dumps(good), OLD_LINE, "{torn", json.dumps(bad)]))
    (errors,) = check_results_files(folder)
    assert errors.endswith("results.jsonl:4: end: 'finished' is not one of ['explored', 'time limit', 'interrupted', "
                           "'robot error', 'stalled', 'stopped', 'plugin error', 'unknown']")
    (folder / "deep" / "results.jsonl").unlink()         # this test's own tmp_path must pass the hook


def test_an_old_line_loads_and_writes_back_as_it_was() -> None:
    data = json.loads(OLD_LINE)
    record = RunRecord.from_dict(data)
    assert record.schema_version is None and record.map_iou_tolerant is None
    assert record.end is EndReason.STALLED                  # from the reason text
    assert record.method_fields == {"targets": 12} and record.extra == {"ate_m": 0.0}
    assert record.as_dict() == data and list(record.as_dict()) == list(data)


def test_a_versioned_line_reads_its_end_from_the_key() -> None:
    data = {"schema_version": 1, **json.loads(OLD_LINE), "end": "stopped", "map_iou_tolerant": 0.95}
    record = RunRecord.from_dict(data)
    assert record.end is EndReason.STOPPED and record.map_iou_tolerant == 0.95 and record.schema_version == 1
    assert record.as_dict() == data


def test_a_record_is_immutable() -> None:
    record = RunRecord.from_dict(json.loads(OLD_LINE))
    with pytest.raises(dataclasses.FrozenInstanceError):
        record.coverage = 1.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        record.extra["ate_m"] = 1.0  # type: ignore[index]
    with pytest.raises(TypeError):
        record.method_fields["targets"] = 0  # type: ignore[index]
    again = pickle.loads(pickle.dumps(record))              # campaign workers send records back
    assert again == record and again.as_dict() == record.as_dict()


def _rec(method: str, seed: int, iou: float, tolerant: float | None) -> dict[str, Any]:
    return {"run": f"w_{method}_s{seed}", "world": "w", "method": method, "pose": "1", "seed": seed,
            "visited_cells": 100 + seed, "coverage": 0.9, "path_length_m": 40.0, "robot_time_s": 600.0,
            "max_speed_m_s": 0.3, "completed": True, "reason": "explored", "nodes": None, "map_iou": iou,
            **({} if tolerant is None else {"map_iou_tolerant": tolerant, "schema_version": 1, "end": "explored"})}


def test_report_and_compare_show_both_map_scores() -> None:
    recs = [_rec("a", 0, 0.60, 0.90), _rec("a", 1, 0.70, 0.94), _rec("b", 0, 0.50, 0.80), _rec("b", 1, 0.40, None)]
    (t,) = comparison_tables(recs)
    assert t.header == ["method", "n", "visited cells", "coverage", "path (m)", "map IoU", "map IoU (1 cell)"]
    rows = {r[0]: r for r in t.rows}
    assert rows["a"][5:] == ["0.650", "0.920"] and rows["b"][5:] == ["0.450", "0.800"]   # b's old record: no tolerant
    assert all(len(r) == len(t.header) for r in t.rows)
    (report,) = report_tables(recs)
    rows = {r[0]: r for r in report.rows}
    assert rows["mean map IoU"][1::2] == ["0.650", "0.450"]
    assert rows["mean map IoU (1 cell)"][1::2] == ["0.920", "0.800"]


def test_a_noisy_laser_leaves_a_fringe_along_the_walls_that_coverage_inside_leaves_out(tmp_path: Path) -> None:
    # gaussian noise of 1 cm: about half the hits on a wall land in the free cell in front of it, and that
    # cell's log-odds keeps climbing however long the robot looks; the floor away from the walls is covered
    from robotexp.world.groundtruth import coverage_inside

    out = run_experiment(RunSpec(world="ufmg-static", method="frontier", laser_sigma=0.01), tmp_path, image=False)
    r = out.record
    assert r.end is EndReason.EXPLORED and r.coverage is not None and r.coverage_inside is not None
    assert r.coverage < 0.99 <= r.coverage_inside
    data = json.loads((tmp_path / "results.jsonl").read_text())
    assert list(data).index("coverage_inside") == list(data).index("coverage") + 1
    assert data["coverage_inside"] == r.coverage_inside
    # the key is the ground truth's `coverage_inside` of the run's map
    assert out.run.truth is not None
    assert r.coverage_inside == round(coverage_inside(out.run.grid.free(), out.run.truth), 5)


def test_the_run_line_gives_the_floor_away_from_the_walls_only_when_a_fringe_hides_it(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from robotexp.cli import main

    noisy = CliRunner().invoke(main, ["explore", "-w", "ufmg-static", "--noise-sigma", "10", "-o", str(tmp_path / "a")])
    assert noisy.exit_code == 0, noisy.output
    r = RunRecord.from_dict(json.loads((tmp_path / "a" / "results.jsonl").read_text()))
    assert r.coverage is not None and r.coverage_inside is not None
    line = f"coverage {r.coverage * 100:.1f}% (floor away from the walls {r.coverage_inside * 100:.1f}%)"
    assert r.completed and line in noisy.output
    # cut short, the floor away from the walls may be the more explored (the walls' cells are seen last), but
    # a run that did not end explored has no fringe to explain: the line says nothing more
    short = CliRunner().invoke(main, ["explore", "-w", "dense", "--max-time", "30", "-o", str(tmp_path / "b")])
    assert short.exit_code == 0, short.output
    r = RunRecord.from_dict(json.loads((tmp_path / "b" / "results.jsonl").read_text()))
    assert r.coverage is not None and r.coverage_inside is not None and not r.completed
    assert f"coverage {r.coverage * 100:.1f}%," in short.output and "floor away" not in short.output


def test_a_record_says_the_parameters_its_run_was_given(tmp_path: Path, validator: Any) -> None:
    from robotexp.experiment import run_team
    from robotexp.run.team import TeamSpec

    given = run_experiment(RunSpec(world="ufmg-static", method="frontier", max_time=2.0,
                                   params={"replan_period": 3.0, "return_home": True}), tmp_path / "a", image=False)
    plain = run_experiment(RunSpec(world="ufmg-static", method="frontier", max_time=2.0), tmp_path / "b", image=False)
    team = run_team(RunSpec(world="ufmg-static", method="frontier", max_time=2.0, params={"replan_period": 3.0}),
                    TeamSpec(robots=("p3dx", "p3dx"), coordinator="burgard", coordinator_params={"beta": 4.0}),
                    tmp_path / "c", image=False)
    lines = {k: json.loads((tmp_path / k / "results.jsonl").read_text()) for k in "abc"}
    assert lines["a"]["params"] == {"replan_period": 3.0, "return_home": True} and given.record["params"]["return_home"]
    assert "params" not in lines["b"] and "coordinator_params" not in lines["b"] and "params" not in plain.record
    assert lines["c"]["params"] == {"replan_period": 3.0} and lines["c"]["coordinator_params"] == {"beta": 4.0}
    assert team.record["coordinator"] == "burgard"
    keys = list(lines["a"])
    assert keys.index("params") > keys.index("robot")       # the caller's keys, after robot
    for line in lines.values():
        validator.validate(line)
        assert RunRecord.from_dict(line).as_dict() == line  # read back and written as it was
    bad = dict(lines["c"], coordinator_params=[4.0])
    with pytest.raises(jsonschema.ValidationError):
        validator.validate(bad)

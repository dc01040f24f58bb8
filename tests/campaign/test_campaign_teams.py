"""Campaigns with team size and coordinator as axes: expansion, keys that tell team runs apart, a run, the report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robotexp.campaign.jobs import record_extra, run_one
from robotexp.campaign.report import report_tables
from robotexp.campaign.runner import run_campaign
from robotexp.campaign.spec import load_campaign, method_label, record_key, run_key
from robotexp.errors import ConfigError, PluginError

TEAMS = """
[campaign]
name = "teams"
max_time_s = 10
[[set]]
world = "ufmg-static"
poses = ["path1"]
methods = ["frontier"]
seeds = [0]
teams = [1, 2]
coordinators = ["none", "greedy"]
"""


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "c.toml"
    p.write_text(text, encoding="utf-8")
    return p


def test_teams_and_coordinators_expand_and_key_apart(tmp_path: Path) -> None:
    camp = load_campaign(_write(tmp_path, TEAMS))
    # one robot alone (no coordinator), then a team of two with each coordinator
    assert [(s.team, s.coordinator) for s in camp.runs] == [((), "none"), (("p3dx", "p3dx"), "none"),
                                                              (("p3dx", "p3dx"), "greedy")]
    keys = [run_key(s, s.pose or "default") for s in camp.runs]
    assert [k[5] for k in keys] == ["", "team=2,coordinator=none", "team=2,coordinator=greedy"]
    ranged = load_campaign(_write(tmp_path, TEAMS.replace("teams = [1, 2]", "teams = [3]\ncomm_range_mm = 2500")))
    assert [(len(s.team), s.comm_range) for s in ranged.runs] == [(3, 2.5), (3, 2.5)]


@pytest.mark.parametrize(("change", "error", "words"), [
    (("teams = [1, 2]", "teams = [0]"), ConfigError, ["teams", "1..64"]),
    (("teams = [1, 2]", "teams = 2"), ConfigError, ["teams", "expected a list"]),
    (('coordinators = ["none", "greedy"]', 'coordinators = ["boss"]'), PluginError, ["unknown coordinator 'boss'"]),
    (("teams = [1, 2]", "teams = [2]\ncomm_range_mm = -1"), ConfigError, ["comm_range_mm", "> 0 mm"]),
    # a reactive explorer beside a coordinator that assigns targets: refused at loading, not at its first run
    (('methods = ["frontier"]', 'methods = ["frontier", "bvp"]'), ConfigError,
     ["[[set]] #1.coordinators", "coordinator 'greedy'", "method 'bvp'"]),
])
def test_bad_team_axes_name_the_file_and_key(tmp_path: Path, change, error, words) -> None:
    with pytest.raises(error) as info:
        load_campaign(_write(tmp_path, TEAMS.replace(*change)))
    for w in words:
        assert w in str(info.value)


def test_a_team_campaign_runs_resumes_and_reports_each_setting(tmp_path: Path) -> None:
    camp = load_campaign(_write(tmp_path, TEAMS.replace('["none", "greedy"]', '["greedy"]').replace(
        "max_time_s = 10", "max_time_s = 4")))
    out = tmp_path / "out"
    out.mkdir()
    # each run as a campaign worker makes it (in this process: a pool's start-up is not what is tested)
    records = [run_one(spec, str(out), extra=record_extra(spec))[0] for spec in camp.runs]
    assert sorted(r.team_size or 1 for r in records) == [1, 2]
    stored = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert {record_key(r) for r in stored} == {run_key(s, s.pose or "default") for s in camp.runs}
    assert run_campaign(camp, out, jobs=1, resume=True) == []
    assert sorted(method_label(r) for r in stored) == ["frontier", "frontier [team=2,coordinator=greedy]"]
    (table,) = report_tables(stored)
    assert "frontier [team=2,coordinator=greedy] path (m)" in table.header


PARAMS = TEAMS.replace('coordinators = ["none", "greedy"]', 'coordinators = ["none", "burgard"]') + """
[set.coordinator_params.burgard]
beta = 4
"""


def test_coordinator_parameters_reach_the_team_its_key_its_record_and_the_report(tmp_path: Path) -> None:
    camp = load_campaign(_write(tmp_path, PARAMS.replace("max_time_s = 10", "max_time_s = 3")))
    assert [(len(s.team), s.coordinator, s.coordinator_params) for s in camp.runs] == [
        (0, "none", {}), (2, "none", {}), (2, "burgard", {"beta": 4})]
    assert [run_key(s, s.pose or "default")[5] for s in camp.runs] == [
        "", "team=2,coordinator=none", "team=2,coordinator=burgard:beta=4"]
    out = tmp_path / "out"
    out.mkdir()
    spec = camp.runs[2]
    run_one(spec, str(out), extra=record_extra(spec))
    (line,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert line["coordinator"] == "burgard" and line["coordinator_params"] == {"beta": 4}
    assert record_key(line) == run_key(spec, spec.pose or "default")      # --resume finds it
    assert method_label(line) == "frontier [team=2,coordinator=burgard:beta=4]"
    # two sets that differ only in a coordinator parameter are two settings, not one run twice
    one = 'world = "ufmg-static"\nposes = ["path1"]\nmethods = ["frontier"]\nteams = [2]\ncoordinators = ["burgard"]\n'
    both = load_campaign(_write(tmp_path, f"[[set]]\n{one}[set.coordinator_params.burgard]\nbeta = 4\n"
                                          f"[[set]]\n{one}[set.coordinator_params.burgard]\nbeta = 0.5\n"))
    assert [run_key(s, s.pose or "default")[5] for s in both.runs] == [
        "team=2,coordinator=burgard:beta=4", "team=2,coordinator=burgard:beta=0.5"]


@pytest.mark.parametrize(("params", "words"), [
    ("[set.coordinator_params.burgard]\nbeta = -1\n", ["[[set]] #1.coordinator_params.burgard", "beta", ">= 0"]),
    ("[set.coordinator_params.burgard]\ngamma = 1\n", ["coordinator_params.burgard", "unknown parameter(s) gamma"]),
    ("[set.coordinator_params.minpos]\nbeta = 1\n", ["coordinator_params.minpos", "do not have"]),
    ("coordinator_params = 3\n", ["coordinator_params", "expected tables"]),
])
def test_bad_coordinator_parameters_name_the_file_and_key(tmp_path: Path, params: str, words: list[str]) -> None:
    text = TEAMS.replace('coordinators = ["none", "greedy"]', 'coordinators = ["none", "burgard"]\n' + (
        params if not params.startswith("[") else "")) + (params if params.startswith("[") else "")
    with pytest.raises(ConfigError) as info:
        load_campaign(_write(tmp_path, text))
    for w in words:
        assert w in str(info.value), str(info.value)

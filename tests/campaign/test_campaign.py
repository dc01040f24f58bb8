"""Campaign files, the parallel runner with resume, and the thesis-style report tables."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path

import pytest

from robotexp.campaign.jobs import RunTiming
from robotexp.campaign.runner import expected_robot_time, run_campaign, run_order
from robotexp.campaign.spec import load_campaign, record_key, run_key
from robotexp.campaign.report import report_tables
from robotexp.errors import ConfigError, PluginError, WorldError

MINI = """
[campaign]
name = "mini"
max_time_s = 20
[[set]]
world = "ufmg-static"
poses = ["path1", "path2"]
methods = ["frontier"]
speeds_mm_s = [300, 200]
seeds = [0, 1]
"""


def _write(tmp_path: Path, text: str, name: str = "c.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_expansion_counts_every_combination(tmp_path: Path) -> None:
    camp = load_campaign(_write(tmp_path, MINI))
    assert camp.name == "mini"
    assert len(camp.runs) == 2 * 2 * 2          # poses x speeds x seeds
    keys = {run_key(s, s.pose or "default") for s in camp.runs}
    assert ("ufmg-static", "frontier", "path2", 200, 1, "", "p3dx") in keys
    assert all(s.max_time == 20 for s in camp.runs)


def test_thesis_campaign_has_66_runs_when_its_methods_are_installed() -> None:
    from robotexp.registry import EXPLORERS, available
    missing = {"bvp", "srt-laser", "srt-ball"} - set(available(EXPLORERS))
    if missing:
        with pytest.raises(PluginError, match="unknown method"):
            load_campaign(Path(__file__).parents[2] / "campaigns" / "thesis.toml")
        pytest.skip(f"methods not installed yet: {sorted(missing)}")
    camp = load_campaign(Path(__file__).parents[2] / "campaigns" / "thesis.toml")
    assert len(camp.runs) == 9 * 2 * 2 + 5 * 3 * 2 == 66
    assert {round(s.speed * 1000) for s in camp.runs} == {100, 40}
    assert all(s.laser_range == 3.0 for s in camp.runs)


def test_runs_start_longest_expected_first_each_once_in_a_fixed_order() -> None:
    from robotexp.registry import EXPLORERS, available
    if {"bvp", "srt-laser", "srt-ball"} - set(available(EXPLORERS)):
        pytest.skip("the thesis's methods are not installed")
    camp = load_campaign(Path(__file__).parents[2] / "campaigns" / "thesis.toml")
    # the bounds of the worlds: dense 20.1 x 15.1 m, sparse 30.1 x 20.1 m
    assert camp.areas == {"dense": pytest.approx(20.1 * 15.1), "sparse": pytest.approx(30.1 * 20.1)}
    order = run_order(camp, camp.runs)
    assert sorted(map(id, order)) == sorted(map(id, camp.runs))          # each run exactly once
    shuffled = list(camp.runs)
    random.Random(3).shuffle(shuffled)
    assert run_order(camp, shuffled) == order                            # whatever order they come in
    guess = [expected_robot_time(s, camp.areas[s.world]) for s in order]
    assert guess == sorted(guess, reverse=True)
    # sparse at 40 mm/s: 605 m^2 / 0.04 m/s = 15,125 s, under SRT-Ball's 6 h limit, the others cut at 4 h;
    # then dense at 40 mm/s (7,588 s), sparse at 100 mm/s (6,050 s), dense at 100 mm/s (3,035 s) last
    assert guess[0] == pytest.approx(605.01 / 0.04) and guess[5] == 4 * 3600
    assert [(s.world, s.method, round(s.speed * 1000)) for s in order[:6]] == \
        [("sparse", "srt-ball", 40)] * 5 + [("sparse", "bvp", 40)]
    assert {(s.world, round(s.speed * 1000)) for s in order[-18:]} == {("dense", 100)}
    # ties keep the campaign's order (poses 1..9 of the same world, method and speed)
    assert [s.pose for s in order if (s.world, s.method, s.speed) == ("dense", "bvp", 0.1)] == \
        [str(i) for i in range(1, 10)]
    # no area known (a world without bounds): the time limit decides
    assert expected_robot_time(order[0], None) == order[0].max_time


@pytest.mark.parametrize("text, error, words", [
    (MINI.replace("methods", "methds"), ConfigError, ["[[set]] #1", "methds"]),
    (MINI.replace('name = "mini"', 'name = "mini"\nspeed = 3'), ConfigError, ["[campaign]", "speed"]),
    (MINI.replace('"frontier"', '"frontierr"'), PluginError, ["methods", "frontierr", "frontier"]),
    (MINI.replace('"path2"', '"nowhere"'), WorldError, ["poses", "nowhere", "path1"]),
    (MINI.replace('"ufmg-static"', '"atlantis"'), WorldError, ["world", "atlantis"]),
    (MINI.replace("[300, 200]", "[300, -5]"), ConfigError, ["speeds_mm_s"]),
    (MINI + "\n[[set]]\nworld = 3\n", ConfigError, ["[[set]] #2", "world"]),
    ("[campaign\nname=1", ConfigError, ["not valid TOML"]),
    # explorer parameters are checked (name, type, range) before any run starts
    (MINI + "[set.params.frontier]\nreturn_home = \"maybe\"\n", ConfigError,
     ["[[set]] #1.params.frontier", "return_home", "true or false"]),
    (MINI + "[set.params.frontier]\nclearance = -1\n", ConfigError, ["params.frontier", "clearance"]),
    (MINI + "[set.params.frontier]\nspeed = 3\n", ConfigError, ["params.frontier", "speed"]),
])
def test_bad_files_name_the_file_and_key(tmp_path: Path, text: str, error: type, words: list[str]) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(error) as info:
        load_campaign(path)
    message = str(info.value)
    assert str(path) in message
    for word in words:
        assert word in message


def test_cli_bad_campaign_exits_2_with_one_line_and_writes_nothing(tmp_path: Path) -> None:
    path = _write(tmp_path, MINI.replace("methods", "methds"))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "robotexp.cli", "campaign", str(path), "--out", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("robotexp: error:") and "methds" in lines[0]
    assert not out.exists()


def test_run_resume_and_report(tmp_path: Path) -> None:
    camp = load_campaign(_write(tmp_path, MINI.replace("seeds = [0, 1]", "seeds = [0]")))
    out = tmp_path / "out"
    seen: list[int] = []
    timings: list[RunTiming] = []
    records = run_campaign(camp, out, jobs=2, progress=lambda done, total, rec: seen.append(done), timings=timings)
    assert len(records) == 4 and seen[-1] == 4
    # every run timed once, in the process that made it: two workers, each with one first run
    assert sorted(t.run for t in timings) == sorted(r.run for r in records)
    assert sum(t.first_in_worker for t in timings) == len({t.worker for t in timings}) <= 2
    by_run = {r.run: r for r in records}
    for t in timings:
        assert t.loop_s == by_run[t.run].wall_time_s and 0 < t.loop_s < t.wall_s and t.setup_s > 0
        assert t.cpu_s > 0 and t.worker.startswith("pid ") and t.worker != f"pid {os.getpid()}"
    lines = (out / "results.jsonl").read_text().splitlines()
    assert len(lines) == 4
    stored = [json.loads(x) for x in lines]
    assert {record_key(r) for r in stored} == {run_key(s, s.pose or "default") for s in camp.runs}
    assert all((out / f"{r['run']}.png").exists() for r in stored)
    # a resumed campaign runs only what is missing: drop one record, resume, get exactly that one back
    (out / "results.jsonl").write_text("\n".join(lines[1:]) + "\n")
    again = run_campaign(camp, out, jobs=1, resume=True)
    assert [record_key(r) for r in again] == [record_key(stored[0])]
    assert run_campaign(camp, out, jobs=1, resume=True) == []
    tables = report_tables(json.loads(x) for x in (out / "results.jsonl").read_text().splitlines())
    assert [t.title for t in tables] == ["ufmg-static, max speed 300 mm/s", "ufmg-static, max speed 200 mm/s"]
    t = tables[0]
    assert t.header == ["pose", "frontier path (m)", "frontier time (mm:ss)"]
    assert [r[0] for r in t.rows] == ["path1", "path2", "mean", "std dev", "range", "mean speed", "mean map IoU",
                                      "mean map IoU (1 cell)"]


def test_report_statistics_by_hand() -> None:
    recs = [{"world": "w", "max_speed_m_s": 0.1, "method": "srt-laser", "pose": str(i), "path_length_m": p,
             "robot_time_s": t, "nodes": n, "completed": True, "reason": "explored"}
            for i, (p, t, n) in enumerate([(70.0, 1000.0, 17), (74.0, 1060.0, 19), (72.0, 1000.0, 18)], start=1)]
    (t,) = report_tables(recs)
    assert t.header == ["pose", "srt-laser path (m)", "srt-laser time (mm:ss)", "srt-laser nodes"]
    assert t.rows[0] == ["1", "70.0", "16:40", "17"]
    rows = {r[0]: r for r in t.rows}
    assert rows["mean"][1:] == ["72.0", "17:00", "18"]          # 1020 s
    assert rows["std dev"][1:] == ["2.0", "00:35", "1"]         # stdev(1000, 1060, 1000) = 34.6 s
    assert rows["range"][1:] == ["4.0", "01:00", "2"]
    assert rows["mean speed"][1] == "71 mm/s"                    # 216 m / 3060 s


def test_report_leaves_incomplete_runs_out_of_the_statistics() -> None:
    base = {"world": "w", "max_speed_m_s": 0.1, "method": "bvp", "nodes": None, "reason": "explored"}
    recs = [{**base, "pose": "1", "path_length_m": 10.0, "robot_time_s": 100.0, "completed": True},
            {**base, "pose": "2", "path_length_m": 20.0, "robot_time_s": 300.0, "completed": True},
            {**base, "pose": "3", "path_length_m": 0.0, "robot_time_s": 14400.0, "completed": False,
             "reason": "time limit of 14400 s reached"}]
    (t,) = report_tables(recs)
    rows = {r[0]: r for r in t.rows}
    assert rows["3"][1] == "0.0*"
    assert rows["mean"][1:] == ["15.0", "03:20"]
    assert rows["range"][1:] == ["10.0", "03:20"]
    assert rows["mean speed"][1] == "75 mm/s"        # 30 m / 400 s


def test_report_has_a_row_per_seed_when_a_campaign_repeats_poses() -> None:
    # Santos's layout: one pose, several seeds; every run is a row and counts in the statistics.
    recs = [{"world": "w", "max_speed_m_s": 0.3, "method": "meta-ga", "pose": "1", "seed": s, "path_length_m": p,
             "robot_time_s": 100.0 * (s + 1), "nodes": None, "completed": True, "reason": "done"}
            for s, p in enumerate([10.0, 30.0, 20.0])]
    (t,) = report_tables(recs)
    assert [r[0] for r in t.rows][:3] == ["1 seed 0", "1 seed 1", "1 seed 2"]
    assert [r[1] for r in t.rows][:3] == ["10.0", "30.0", "20.0"]
    assert {r[0]: r for r in t.rows}["mean"][1:] == ["20.0", "03:20"]


SWEEP = """
[campaign]
name = "sweep"
max_time_s = 8
[[set]]
world = "ufmg-static"
poses = ["path1"]
methods = ["frontier"]
speeds_mm_s = [300]
[set.sweep.frontier]
clearance = [0.2, 0.35]
replan_period = {start = 1.0, stop = 2.0, step = 0.5}
"""


def test_sweep_over_two_parameters_runs_and_reports_by_them(tmp_path: Path) -> None:
    camp = load_campaign(_write(tmp_path, SWEEP))
    # 2 clearances x 3 replan periods (1.0, 1.5, 2.0: the stop is included)
    assert len(camp.runs) == 6
    combos = {(s.params["clearance"], s.params["replan_period"]) for s in camp.runs}
    assert combos == {(c, r) for c in (0.2, 0.35) for r in (1.0, 1.5, 2.0)}
    keys = {camp.key(s) for s in camp.runs}
    assert len(keys) == 6 and ("ufmg-static", "frontier", "path1", 300, 0,
                               "clearance=0.35,replan_period=1.5", "p3dx") in keys
    out = tmp_path / "out"
    records = run_campaign(camp, out, jobs=2)
    stored = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert len(records) == len(stored) == 6
    assert {record_key(r) for r in stored} == keys                # every swept value is in the run key
    assert all(set(r["sweep"]) == {"clearance", "replan_period"} for r in stored)
    assert run_campaign(camp, out, jobs=1, resume=True) == []     # --resume tells the swept runs apart
    (table,) = report_tables(stored)
    methods = [f"frontier [clearance={c},replan_period={r}]" for c in (0.2, 0.35) for r in (1.0, 1.5, 2.0)]
    assert table.methods == methods                                # one column group per swept combination
    assert f"{methods[4]} path (m)" in table.header


@pytest.mark.parametrize("sweep, words", [
    ("clearance = []", "non-empty list"),
    ("clearance = {start = 1.0, stop = 0.5, step = 0.1}", "stop >= start"),
    ("clearance = {start = 0.1, stop = 0.5}", "{start, stop, step}"),
    ("clearance = [-1.0]", "parameter 'clearance' must be >= 0"),
    ("speed = [1, 2]", "speed"),
])
def test_bad_sweeps_name_the_key(tmp_path: Path, sweep: str, words: str) -> None:
    text = SWEEP.split("[set.sweep.frontier]")[0] + "[set.sweep.frontier]\n" + sweep + "\n"
    with pytest.raises(ConfigError, match="sweep") as err:
        load_campaign(_write(tmp_path, text))
    assert words in str(err.value)

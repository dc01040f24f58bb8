"""The Lua `team` table on the real lupa runtime: a script drives a team and reads its record and each
robot's path; wrong calls are one line naming the function; the sandbox's rules hold for a team."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from robotexp.bag.replay import read_bag
from robotexp.errors import ScriptError
from robotexp.output.results import read_jsonl


SCRIPT = """
exploration.setWorld("room.map")
exploration.setMethod(ExplorationMethod.FRONTIER)
exploration.setMaxTime(8000)
team.setRobots("p3dx,kobuki")
team.setCoordinator("greedy")
team.setCommRange(2500)
exploration.setRecordFolder("bags")
local r = team.explore()
local out = {size = r.team_size, coverage = r.coverage, coordinator = r.coordinator, comm = r.comm_range_m,
             robots = {}, results_size = exploration.results().team_size, path_mm = robot.pathLength()}
for i = 1, r.team_size do
  local p = team.getPath(i)
  local length = 0
  for k = 2, #p do length = length + math.sqrt((p[k][1] - p[k-1][1])^2 + (p[k][2] - p[k-1][2])^2) end
  local x, y, th = team.getPose(i)
  out.robots[i] = {model = r.robots[i].robot, record_m = r.robots[i].path_length_m, points = #p,
                   length_mm = length, first = p[1], last = p[#p], pose = {x, y, th}}
end
local parts = {}
print(string.format('{"size": %d, "coverage": %.6f, "coordinator": "%s", "comm": %.3f, "results_size": %d, '
                    .. '"path_mm": %.1f, "robots": [', out.size, out.coverage, out.coordinator, out.comm,
                    out.results_size, out.path_mm))
for i, q in ipairs(out.robots) do
  parts[i] = string.format('{"model": "%s", "record_m": %.4f, "points": %d, "length_mm": %.3f, '
                           .. '"first": [%.1f, %.1f], "last": [%.1f, %.1f], "pose": [%.3f, %.3f, %.3f]}',
                           q.model, q.record_m, q.points, q.length_mm, q.first[1], q.first[2],
                           q.last[1], q.last[2], q.pose[1], q.pose[2], q.pose[3])
end
print(table.concat(parts, ", ") .. "]}")
"""


@pytest.fixture
def room(lua, team_room) -> Path:
    lua.out.mkdir(parents=True, exist_ok=True)
    (lua.out / "room.map").write_text(team_room)
    return lua.out / "room.map"


def test_a_script_drives_a_team_and_reads_its_record_and_paths(lua, room):
    result = lua(SCRIPT, name="team.lua", sandbox=True)
    assert result.exit_code == 0
    got = json.loads("".join(lua.lines))
    (record,) = read_jsonl(lua.out / "results.jsonl")
    assert record["team_size"] == got["size"] == got["results_size"] == 2
    assert record["script"] == "team.lua" and record["coordinator"] == got["coordinator"] == "greedy"
    assert record["comm_range_m"] == pytest.approx(got["comm"]) == 2.5
    assert record["robot_time_s"] == pytest.approx(8.0)
    assert got["coverage"] == pytest.approx(record["coverage"], abs=1e-6) and record["coverage"] > 0.3
    assert got["path_mm"] == pytest.approx(record["path_length_m"] * 1000, abs=0.1)
    assert [r["model"] for r in got["robots"]] == ["p3dx", "kobuki"]
    for mine, theirs in zip(got["robots"], record["robots"], strict=True):
        # one point a control tick of 0.1 s; the path summed in Lua is the record's (points rounded to 0.1 mm)
        assert 79 <= mine["points"] <= 81
        assert mine["record_m"] == theirs["path_length_m"] > 0.2
        assert mine["length_mm"] == pytest.approx(theirs["path_length_m"] * 1000, abs=0.05 * mine["points"])
        assert mine["first"] == pytest.approx([v * 1000 for v in theirs["start_pose"][:2]], abs=0.1)
        assert mine["last"] == pytest.approx(mine["pose"][:2], abs=0.1)
        end = theirs["end_pose"]
        assert mine["pose"] == pytest.approx([end[0] * 1000, end[1] * 1000, math.degrees(end[2])], abs=1e-3)
    a, b = got["robots"]
    assert math.dist(a["first"], b["first"]) >= 600        # spread apart at the start (footprints + 0.3 m)
    # the script's record folder holds the team's recording: each robot under its namespace
    bag = read_bag(lua.out / "bags" / f"{record['run']}.mcap")
    assert [len(ticks) for ticks in bag.team] == [m["points"] for m in got["robots"]]
    assert {"/robot_1/odom", "/robot_2/odom", "/robot_1/robotexp/scan", "/robot_2/robotexp/scan"} <= set(bag.topics)


@pytest.mark.parametrize(("code", "message"), [
    ("team.setRobots(0)", r"^s.lua:1: team.setRobots\(0\): a team has 1..64 robots$"),
    ("team.setRobots(65)", r"team.setRobots\(65\): a team has 1..64 robots"),
    ("team.setRobots(2.5)", r"team.setRobots\(count_or_presets\): expected an integer 1..64 or a string of presets"),
    ('team.setRobots("p3dx,roomba")', r"unknown robot preset 'roomba'; available: p3dx, p3dx-body, kobuki"),
    ('team.setRobots(string.rep("p3dx,", 64) .. "p3dx")', r"a team has 1..64 robots, got 65"),
    ('team.setRobots("p3dx,,kobuki")', r"team.setRobots\('p3dx,,kobuki'\): robot 2 is empty: give one preset"),
    ('team.setRobots("p3dx,")', r"team.setRobots\('p3dx,'\): robot 2 is empty"),
    ('team.setCoordinator("nobody")', r"team.setCoordinator\('nobody'\): unknown coordinator; available: .*burgard"),
    ('team.setCoordinatorParameter("beta")', r"team.setCoordinatorParameter\(name, value\): expected a parameter "),
    ('team.setCoordinatorParameter("beta", 0/0)', r"expected a parameter name \(string\) and a number, boolean or"),
    ('team.setCoordinatorParameter("be ta", 1)', r"team.setCoordinatorParameter\('be ta', ...\): expected a param"),
    ('team.setCoordinator("burgard")\nteam.setCoordinatorParameter("gamma", 1)\nteam.explore()',
     r"^s.lua:3: team.explore: coordinator 'burgard': unknown parameter\(s\) gamma; its parameters: beta, "
     r"cost_scale \(team.setCoordinatorParameter\)$"),
    ('team.setCoordinator("burgard")\nteam.setCoordinatorParameter("beta", -1)\nteam.explore()',
     r"team.explore: coordinator 'burgard': parameter 'beta' must be >= 0, got -1"),
    ("team.setCommRange(-1)", r"team.setCommRange\(range_mm\): expected a range > 0 mm or nil, got -1"),
    ("team.setCommRange(0/0)", r"expected a range > 0 mm or nil"),
    ("team.getPath(1)", r"^s.lua:1: team.getPath: no team exploration has run yet; call team.explore\(\) first$"),
    ('team.getPose("one")', r"team.getPose\(robot\): expected a robot number \(an integer from 1\), got a string"),
    ("team.explore(3)", r"team.explore\(\): expected 0 arguments, got 1"),
    ('robot.setAddress("localhost:9")\nteam.explore()',
     r"^s.lua:2: team.explore: a team runs on the embedded simulator, and robot.setAddress named 'localhost:9'"),
    ('exploration.setMethod(ExplorationMethod.BVP)\nteam.setCoordinator("minpos")\nteam.explore()',
     r"^s.lua:3: team.explore: .*does not take targets"),
])
def test_wrong_team_calls_are_one_line_naming_the_function(lua, code, message):
    with pytest.raises(ScriptError, match=message) as info:
        lua(code, name="s.lua")
    assert "\n" not in str(info.value)
    assert not (lua.out / "results.jsonl").exists()


def test_a_team_obeys_the_sandbox_and_the_robot_number_is_checked(lua, room, tmp_path, team_room):
    outside = tmp_path / "elsewhere.map"
    outside.write_text(team_room)
    with pytest.raises(ScriptError, match=r"exploration.setWorld\(.*\): refused by --sandbox"):
        lua(f'exploration.setWorld("{outside}")\nteam.explore()', name="s.lua", sandbox=True)
    code = ('exploration.setWorld("room.map")\nexploration.setMaxTime(1000)\nteam.setRobots(3)\nteam.explore()\n'
            "team.getPath(4)")
    with pytest.raises(ScriptError, match=r"^s.lua:5: team.getPath\(4\): the last team had robots 1..3$"):
        lua(code, name="s.lua", sandbox=True)
    (record,) = read_jsonl(lua.out / "results.jsonl")       # the team's run before the error is kept
    assert record["team_size"] == 3 and len(record["robots"]) == 3


def test_a_script_gives_the_coordinator_its_parameters(lua, room):
    code = ('exploration.setWorld("room.map")\nexploration.setMaxTime(2000)\nteam.setCoordinator("burgard")\n'
            'team.setCoordinatorParameter("beta", 4)\nteam.setCoordinatorParameter("cost_scale", 10)\n'
            'print(team.explore().coordinator_params.beta)\nteam.clearCoordinatorParameters()\n'
            'print(team.explore().coordinator_params)')
    assert lua(code, name="s.lua").exit_code == 0
    assert lua.lines == ["4", "nil"]
    first, second = read_jsonl(lua.out / "results.jsonl")
    assert first["coordinator_params"] == {"beta": 4, "cost_scale": 10} and "coordinator_params" not in second


def test_the_example_team_script_runs(lua):
    """scripts_lua/team.lua, its runs cut to 1 s of robot time: one robot, then teams of 2 and 4."""
    script = Path(__file__).parents[2] / "scripts_lua" / "team.lua"
    code = script.read_text().replace("exploration.setMaxTime(600000)", "exploration.setMaxTime(1000)")
    assert code != script.read_text()
    result = lua(code, name="team.lua", sandbox=True)
    assert result.exit_code == 0
    records = read_jsonl(lua.out / "results.jsonl")
    assert [r.get("team_size") for r in records] == [None, 2, 4]
    assert [r["coordinator"] for r in records[1:]] == ["burgard", "burgard"]
    assert all(r["robot_time_s"] == pytest.approx(1.0) for r in records)
    starts = [r["start_pose"][:2] for r in records]        # every run from the same start
    assert starts == [pytest.approx([-5.0, 7.5])] * 3
    assert sum(line.startswith("  robot ") for line in lua.lines) == 6
    assert (lua.out / "team.png").stat().st_size > 10_000

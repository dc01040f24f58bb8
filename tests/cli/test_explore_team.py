"""`robotexp explore --team`: one record for the team; bad team input is one line and exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.cli import main


def test_a_team_explores_from_the_command_line(tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["explore", "--team", "2", "--coordinator", "greedy", "--max-time", "20",
                                       "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "team of 2 (greedy): total path" in result.output
    (record,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert record["team_size"] == 2 and record["coordinator"] == "greedy" and len(record["robots"]) == 2
    assert record["robot_time_s"] == pytest.approx(20.0)
    assert record["run"].startswith("dense_frontier-team2-greedy_")
    assert (out / f"{record['run']}.robot_2.path.csv").is_file()


@pytest.mark.parametrize(("args", "words"), [
    (["--comm-range", "3000"], ["--comm-range needs --team"]),
    (["--coordinator", "burgard"], ["--coordinator needs --team"]),
    (["--team", "2", "--coordinator", "nobody"], ["unknown coordinator 'nobody'", "burgard"]),
    (["--team", "2", "--method", "bvp", "--coordinator", "minpos"], ["does not take targets"]),
    (["--team", "p3dx,roomba"], ["unknown robot preset 'roomba'"]),
    (["--team", "0"], ["1..64 robots, got 0"]),
    (["--team", "99999999999999999999999"], ["1..64 robots, got 23 digits"]),
    (["--team", "1000000000"], ["1..64 robots, got 1000000000"]),
    (["--team", "2", "--team-poses", ";"], ["--team-poses: no pose in ';'"]),
    (["--team", "2", "--comm-range", "-5"], ["--comm-range must be a positive number of mm"]),
    (["--team", "2", "--team-poses", "1"], ["1 poses for 2 robots"]),
    (["--team", "2", "--address", "socket://localhost:1"], ["leave out --address"]),
    (["--team", "2", "--odometry-error", "p3dx"], ["exact odometry"]),
    (["--team", "200"], ["1..64 robots"]),
    (["--team", "2", "--team-poses", "1;1"], ["overlap"]),
    (["--team", "3", "--team-poses", "1000,1000,0;0,0,0;2000,2000,0"],
     ["--team-poses: robot 2: start pose (0.000, 0.000) m", "touches an obstacle"]),
    (["--team", "2", "--team-poses", "1000,1000,0;50000,1000,0"], ["--team-poses: robot 2: start pose (50.000, 1.000) m"
                                                                   " is outside world 'dense'"]),
    (["--team", "2", "--coordinator", "burgard", "--coordinator-param", "beta=-1"],
     ["coordinator 'burgard': parameter 'beta' must be >= 0, got -1"]),
    (["--team", "2", "--coordinator", "burgard", "--coordinator-param", "gamma=1"],
     ["coordinator 'burgard': unknown parameter(s) gamma", "beta, cost_scale"]),
    (["--team", "2", "--coordinator", "burgard", "--coordinator-param", "beta"],
     ["--coordinator-param 'beta': expected key=value"]),
])
def test_bad_team_input_is_one_line_and_exit_2(tmp_path: Path, args: list[str], words: list[str],
                                               one_line_error) -> None:
    result = CliRunner().invoke(main, ["explore", "--out", str(tmp_path / "out"), "--max-time", "5", *args])
    one_line_error(result, words, tmp_path / "out")

"""What a newcomer trips on: `explore -p help` lists an explorer's parameters with types,
defaults and units (from its signature and docstring, nothing run), `--coordinator-param help` a
coordinator's; a --pose in x,y without heading or
with metre-sized numbers is said how it is read; pose names match whatever their case."""

from __future__ import annotations

import os

from click.testing import CliRunner

from robotexp.cli import main
from robotexp.cli.paramhelp import explorer_parameters


def test_frontier_parameters_listed_with_type_default_and_unit() -> None:
    result = CliRunner().invoke(main, ["explore", "-m", "frontier", "-p", "help"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].startswith("parameters of 'frontier'")
    goal = next(line for line in lines if line.split()[0] == "goal_timeout")
    assert goal.split()[1:4] == ["float", "default", "20.0"] and "[s]" in goal
    assert any(line.split()[:2] == ["min_group_cells", "int"] for line in lines)


def test_parameters_passed_on_through_kwargs_are_listed() -> None:
    names = [p.name for p in explorer_parameters("meta-ga")]
    assert names[:2] == ["population", "generations"]
    assert {"objective", "goal_timeout", "clearance"} <= set(names)     # MetaheuristicExplorer's, via **kwargs
    assert "kwargs" not in names


def test_unknown_method_is_one_line_exit_2() -> None:
    result = CliRunner().invoke(main, ["explore", "-m", "nope", "-p", "help"])
    assert result.exit_code == 2 and "unknown method 'nope'" in result.output


def test_coordinator_parameters_listed_and_nothing_run(tmp_path: object) -> None:
    out = f"{tmp_path}/out"
    result = CliRunner().invoke(main, ["explore", "--coordinator", "burgard", "--coordinator-param", "help",
                                       "--out", out])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].startswith("parameters of 'burgard' (set with --coordinator-param NAME=VALUE")
    beta = next(line for line in lines if line.split()[0] == "beta")
    assert beta.split()[1:6] == ["float", "default", "1.0", "range", "0..100"]
    scale = next(line for line in lines if line.split()[0] == "cost_scale")
    assert scale.split()[1:6] == ["float", "default", "0.0", "range", "0..10000"] and "[m]" in scale
    assert not os.path.exists(out)          # nothing ran
    none = CliRunner().invoke(main, ["explore", "--coordinator", "minpos", "--coordinator-param", "help"])
    assert none.exit_code == 0 and none.output.strip() == "coordinator 'minpos' takes no parameters"
    unknown = CliRunner().invoke(main, ["explore", "--coordinator", "nope", "--coordinator-param", "help"])
    assert unknown.exit_code == 2 and "unknown coordinator 'nope'" in unknown.output


def test_pose_notice_for_metre_sized_or_headless_poses(tmp_path: object) -> None:
    runner = CliRunner()
    out = str(tmp_path)
    # refused (in a wall): one line, the error and how the pose was read
    result = runner.invoke(main, ["explore", "--pose", "3,0", "--max-time", "1", "--out", out])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("robotexp: error: ")
    assert lines[0].endswith("(--pose 3,0 is read as x 3 mm, y 0 mm, heading 0 deg (none given); in metres "
                             "write 3000,0)")
    # accepted: said once as the run starts
    result = runner.invoke(main, ["explore", "-w", "ufmg-static", "--pose", "-4200,-4200", "--max-time", "1",
                                  "--out", out])
    assert result.exit_code == 0, result.output
    assert "robotexp: --pose -4200,-4200 is read as x -4200 mm, y -4200 mm, heading 0 deg (none given)\n" in \
        result.output
    result = runner.invoke(main, ["explore", "-w", "ufmg-static", "--pose", "-4200,-4200,45", "--max-time", "1",
                                  "--out", out])
    assert result.exit_code == 0 and "is read as" not in result.output    # a full pose in mm: nothing to say


def test_pose_names_match_whatever_their_case() -> None:
    from robotexp.world.builtin import builtin_world
    from robotexp.world.poses import pose_name, resolve_pose

    world = builtin_world("ufmg-static")
    assert resolve_pose(world, "PATH1", 0.25) == resolve_pose(world, "path1", 0.25)
    assert resolve_pose(world, "Path2", 0.25)[1] == "path2" and pose_name(world, "Path2") == "path2"


def test_progress_without_terminal_a_line_a_minute_with_estimate_and_stall(capsys: object) -> None:
    from robotexp.cli.progress import Progress

    now = [1000.0]
    prog = Progress("dense frontier", enabled=False, every=60.0, clock=lambda: now[0])

    class Run:
        max_time = 1000.0

    prog.on_start(Run())
    for k in range(1, 200):           # 1 s of wall per sample, 5 s of robot time: 5x real time
        now[0] += 1.0
        cov = min(0.5, 0.01 * k)      # gains until t = 250 s, then nothing
        prog(5.0 * k, cov)
    err = capsys.readouterr().err.splitlines()  # type: ignore[attr-defined]
    assert len(err) == 3                          # at 60, 120 and 180 s of wall time
    assert err[0] == ("dense frontier  [###############---------------]  50.0%  robot time     300 s, "
                      "wall    60 s  <= 140 s left (time limit)")
    assert "no gain" not in err[0]                # gained up to t = 250 s
    assert "no gain for 350 s" in err[1]          # t = 600 s, last gain at 250 s

"""`robotexp explore -m METHOD -p help` (issue 16, item 5): an explorer's parameters with types, defaults and
units, from its signature and docstring, without running anything."""

from __future__ import annotations

from click.testing import CliRunner

from robotexp.cli import main
from robotexp.paramhelp import explorer_parameters


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

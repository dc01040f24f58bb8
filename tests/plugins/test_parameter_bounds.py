"""Every numeric parameter of the built-in explorers has a declared range, shown by `-p help` and
checked before anything runs (a population of 1e8 is one line and exit 2, not a memory blow-up)."""

from __future__ import annotations

import resource
import subprocess
import sys

import pytest
from robotexp.errors import ConfigError, PluginError, ScriptError
from robotexp.cli.paramhelp import explorer_parameters, parameters_text
from robotexp.registry import make_explorer

BUILT_IN = ["frontier", "waypoints", "bvp", "meta-ga", "meta-firefly", "meta-exhaustive", "srt-ball", "srt-laser",
            "srt-star"]
NUMERIC = {"int", "float", "int | None", "float | None"}


@pytest.mark.parametrize("method", BUILT_IN)
def test_every_numeric_parameter_has_an_upper_bound(method):
    params = [p for p in explorer_parameters(method) if p.kind in NUMERIC]
    assert params
    unbounded = [p.name for p in params if not p.range or p.range.startswith(">=")]
    assert unbounded == []
    text = parameters_text(method)
    assert all(f"range {p.range}" in text for p in params)


def _address_space_limit() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30))   # what an unchecked value would ask fails


@pytest.mark.parametrize("method, param, value, limit", [
    ("meta-ga", "population", 1e8, "<= 100000"),
    ("meta-firefly", "population", 1e6, "<= 200"),
    ("srt-laser", "bins", 1e9, "<= 36000"),
    ("srt-laser", "step", 1e-9, ">= 0.001"),
])
def test_out_of_range_is_refused(method, param, value, limit):
    shown = repr(value) if value < 1 else str(int(value))
    with pytest.raises(ConfigError) as err:
        make_explorer(method, {param: value})
    assert str(err.value) == f"method {method!r}: parameter {param!r} must be {limit}, got {shown}"


def test_out_of_range_is_one_line_before_the_run(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "robotexp.cli", "explore", "-m", "meta-firefly", "-p",
                           "population=1e6", "--out", str(tmp_path), "--max-time", "20"], capture_output=True,
                          text=True, timeout=60, preexec_fn=_address_space_limit)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr == "robotexp: error: method 'meta-firefly': parameter 'population' must be <= 200, got 1000000\n"
    assert not (tmp_path / "results.jsonl").exists()


def test_bounds_are_inclusive_and_nan_is_refused():
    make_explorer("meta-firefly", {"population": 200, "iterations": 500})
    with pytest.raises(ConfigError, match=r"parameter 'population' must be <= 200, got 201"):
        make_explorer("meta-firefly", {"population": 201})
    with pytest.raises(ConfigError, match=r"parameter 'clearance' must be a number in 0..10, got nan"):
        make_explorer("frontier", {"clearance": float("nan")})


def test_lua_scripts_get_the_same_check(tmp_path):
    from robotexp.lua import run_script

    script = tmp_path / "s.lua"
    script.write_text('exploration.setMethod(ExplorationMethod.META_GA); exploration.setParameter("population", 1e8)\n'
                      'exploration.setWorld("dense"); exploration.start(); error("not refused")')
    with pytest.raises(ScriptError, match=r"s.lua:2: .*parameter 'population' must be <= 100000, got 100000000"):
        run_script(script, out=tmp_path / "out", emit=lambda line: None)


def test_conformance_checks_the_declared_bounds():
    from robotexp.testing.explorer_contract import _check_parameters
    from robotexp.explorer import Explorer
    from robotexp.registry import EXPLORERS, load

    base = load(EXPLORERS, "frontier", Explorer)
    wrong_name = type("WrongName", (base,), {"parameter_bounds": {"nonsense": (0, 1)}})
    with pytest.raises(PluginError, match="parameter_bounds names 'nonsense'"):
        _check_parameters(wrong_name, "wrong")
    default_out = type("DefaultOut", (base,), {"parameter_bounds": {"clearance": (0.5, 1.0)}})
    with pytest.raises(PluginError, match="parameter 'clearance' defaults to 0.3, outside"):
        _check_parameters(default_out, "out")

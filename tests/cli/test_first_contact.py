"""What a first-time user meets on the command line: an explorer that cannot start is one line and exit 2,
plugin errors name the plugin without a traceback (the traceback only with --debug), a closed stdout ends
quietly, output folders are created, the progress line never counts below zero."""

from __future__ import annotations

import functools
import logging
import re
import subprocess
import sys
from pathlib import Path

from click.testing import CliRunner

from robotexp.cli.progress import Progress
from robotexp.cli import main
from robotexp.errors import ConfigError, PluginError


def test_waypoints_without_goals_is_one_line_exit_2_saying_what_to_pass(tmp_path: Path) -> None:
    result = CliRunner().invoke(main, ["explore", "--world", "dense", "--method", "waypoints", "--out",
                                       str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert "Traceback" not in result.output and "AttributeError" not in result.output
    line = lines[0]
    assert line.startswith("robotexp: error: plugin error: explorer 'waypoints'")
    assert "reset raised ConfigError" in line and "-p 'goals=[[" in line and "-p path=NAME" in line


def test_plugin_error_traceback_only_with_debug(tmp_path: Path) -> None:
    result = CliRunner().invoke(main, ["--debug", "explore", "--world", "dense", "--method", "waypoints",
                                       "--out", str(tmp_path / "out")])
    assert isinstance(result.exception, PluginError)         # raised on to Python: the traceback shows
    assert isinstance(result.exception.__cause__, ConfigError)


def test_the_run_loop_logs_a_plugin_error_without_traceback_unless_debugging(caplog, tmp_path: Path) -> None:
    from robotexp.run.spec import RunSpec
    from robotexp.experiment import run_experiment

    spec = RunSpec(world="dense", method="waypoints", max_time=5.0)
    with caplog.at_level(logging.INFO, logger="robotexp"):
        try:
            run_experiment(spec, None, image=False)
        except PluginError:
            pass
    mine = [r for r in caplog.records if "plugin error" in r.getMessage()]
    assert mine and all(r.exc_info is None for r in mine)
    assert all(r.levelno < logging.WARNING for r in mine)     # the caller reports it, once
    caplog.clear()
    with caplog.at_level(logging.DEBUG, logger="robotexp"):
        try:
            run_experiment(spec, None, image=False)
        except PluginError:
            pass
    mine = [r for r in caplog.records if "plugin error" in r.getMessage()]
    assert mine and mine[0].exc_info is not None


def test_progress_never_says_negative_time_left() -> None:
    now = [0.0]
    p = Progress("x", enabled=False, clock=lambda: now[0])

    class Run:
        max_time = 100.0
    p.on_start(Run())
    now[0] = 10.0
    for t in (99.9, 100.0, 100.04):
        text = p.line(t, 0.5)
        assert "-0 s" not in text and "<= -" not in text, text
    assert "<= 0 s left" in p.line(100.04, 0.5)


def test_a_closed_stdout_ends_quietly() -> None:
    robotexp = Path(sys.executable).with_name("robotexp")
    done = subprocess.run(f"'{robotexp}' plugins | head -1", shell=True, capture_output=True, text=True,
                          timeout=60)
    assert done.stdout.strip(), done.stderr
    assert "Broken pipe" not in done.stderr and "Traceback" not in done.stderr, done.stderr


def test_worlds_generate_makes_the_folders_it_names(tmp_path: Path) -> None:
    out = tmp_path / "new" / "dir" / "x.yaml"
    result = CliRunner().invoke(main, ["worlds", "generate", "--kind", "cave", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert out.is_file() and out.with_suffix(".pgm").is_file()
    (tmp_path / "afile").write_text("")
    result = CliRunner().invoke(main, ["worlds", "generate", "--kind", "cave", "--out",
                                       str(tmp_path / "afile" / "x.map")])
    assert result.exit_code == 2 and len(result.output.strip().splitlines()) == 1, result.output


def test_run_shows_the_progress_of_each_run_of_the_script(tmp_path: Path) -> None:
    script = tmp_path / "two.lua"
    script.write_text('exploration.setWorld("dense")\nexploration.setMaxTime(3000)\n'
                      'exploration.setMethod(ExplorationMethod.FRONTIER)\nexploration.start()\nexploration.wait()\n'
                      'exploration.setMethod(ExplorationMethod.BVP)\nexploration.start()\nexploration.wait()\n')
    result = CliRunner().invoke(main, ["run", "--child", "--tty-progress", str(script), "--out", str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    lines = [line.split("\r")[-1] for line in result.stderr.split("\n") if "\r" in line]   # each run's last redraw
    assert [line.split("[")[0].split() for line in lines] == [["dense", "frontier"], ["dense", "bvp"]], result.stderr
    assert all("robot time       3 s" in line for line in lines), lines


def _box_runs(monkeypatch, draw) -> dict[str, list[float]]:
    """The values of each box the figure code draws (the original figures are still made)."""
    import matplotlib.pyplot as plt

    import robotexp.output.figures as figures

    boxes: dict[str, list[float]] = {}
    original = figures.box_figure

    def spy(groups, **kwargs):
        if "visited" in kwargs.get("ylabel", ""):
            boxes.update({label.split()[-1]: sorted(values) for label, values in groups})
        return original(groups, **kwargs)
    monkeypatch.setattr(figures, "box_figure", spy)
    monkeypatch.setattr(figures, "save_figure", lambda fig, *args, **kwargs: plt.close(fig) or [])   # no files
    draw()
    return boxes


def test_figure_and_campaign_plot_count_the_same_runs(tmp_path: Path, monkeypatch) -> None:
    from robotexp.campaign.compare import campaign_plots
    from robotexp.output.figures import campaign_figures

    def rec(seed: int, cells: int, reason: str) -> dict[str, object]:
        return {"run": f"w_a_s{seed}", "world": "nowhere", "method": "a", "pose": "1", "seed": seed,
                "visited_cells": cells, "coverage": 0.9, "path_length_m": 10.0, "robot_time_s": 60.0,
                "max_speed_m_s": 0.3, "completed": reason == "explored", "reason": reason, "cell_m": 0.1}
    recs = [rec(0, 100, "explored"), rec(1, 120, "explored"), rec(2, 900, "time limit of 60 s reached"),
            rec(3, 5, "interrupted (Ctrl-C)")]
    for include, expected in ((False, [100.0, 120.0]), (True, [100.0, 120.0, 900.0])):
        fig = _box_runs(monkeypatch, functools.partial(campaign_figures, recs, tmp_path / "f", ("png",),
                                                       include_incomplete=include))
        plot = _box_runs(monkeypatch, functools.partial(campaign_plots, recs, tmp_path, tmp_path / "p",
                                                        include_incomplete=include, note=lambda _: None))
        assert fig == {"a": expected} and plot == {"a": expected}


def test_parameter_help_of_every_explorer_is_clean() -> None:
    from robotexp.cli.paramhelp import WIDTH, explorer_parameters, parameters_text
    from robotexp.registry import EXPLORERS, available

    methods = sorted(available(EXPLORERS))
    assert {"frontier", "bvp", "srt-ball", "srt-star", "srt-laser", "meta-ga", "meta-firefly", "meta-exhaustive",
            "waypoints"} <= set(methods)
    for method in methods:
        for p in explorer_parameters(method):
            assert p.doc, f"{method}: {p.name} has no description"
            for debris in ("`", "see above", "see ", "session", "**kwargs"):
                assert debris not in p.doc, f"{method}: {p.name}: {p.doc!r}"
        text = parameters_text(method)
        assert all(len(line) <= WIDTH for line in text.splitlines()), method
    from robotexp.cli.paramhelp import coordinator_parameters
    from robotexp.registry import COORDINATORS

    for name in sorted(available(COORDINATORS)):
        for p in coordinator_parameters(name):
            assert p.doc and p.range, f"{name}: {p.name} has no description or range"
        assert all(len(line) <= WIDTH for line in parameters_text(name, coordinator=True).splitlines()), name
    star = {p.name: p for p in explorer_parameters("srt-star")}
    assert star["cone"].default == "0.261799" and star["alpha"].doc.startswith("fraction of RADIUS")
    assert star["margin"].doc == "[m] each cone's radius is its reading less this."
    laser = {p.name: p for p in explorer_parameters("srt-laser")}
    assert laser["step"].doc == "[m] sampling step of the shrunk region along each direction."
    assert laser["sweep_rate"].doc == "[rad/s] turn rate while perceiving."


def _kernel_of(module: str):
    """A fresh numba kernel that says it belongs to `module` (compiled at its first call: never cached)."""
    import numba

    def scale(x: float) -> float:
        return x * 2.0
    scale.__module__ = module
    return numba.njit(scale)


def test_compilation_is_said_at_once_per_group_with_progress() -> None:
    from robotexp.compilewatch import CompileWatch

    lines: list[str] = []
    now = [0.0]
    with CompileWatch(lines.append, clock=lambda: now[0]) as watch:
        kernel = _kernel_of("robotexp.localization.kernels")
        now[0] = 1.0
        assert kernel(1.5) == 3.0
        now[0] = 4.0
        _kernel_of("robotexp.mapping.kernels")(1.0)
        _kernel_of("numpy_user_code")(1.0)                   # not robotexp's: not said
    assert lines == [
        "compiling the localization kernels (first run after an install, ~45 s; cached for the next runs)...",
        "  localization kernels: 1 compiled (scale), 0 s",
        "  localization kernels ready (1 compiled in 3 s)",
        "compiling the map kernels (first run after an install, ~20 s; cached for the next runs)...",
        "  map kernels: 1 compiled (scale), 0 s",
        "  map kernels ready (1 compiled in 0 s)"]
    assert watch.compiled == {"localization": 1, "map": 1}
    _kernel_of("robotexp.localization.kernels")(1.0)         # closed: silent
    assert len(lines) == 6


def test_compilation_tells_busy_when_it_starts_and_when_it_ends() -> None:
    # the supervisor of `robotexp run` holds its kill at --timeout while numba compiles (robotexp.lua.supervise)
    from robotexp.compilewatch import CompileWatch

    told: list[object] = []
    with CompileWatch(lambda text: told.append(text.split(" (")[0]), busy=told.append):
        _kernel_of("robotexp.mapping.kernels")(1.0)
        _kernel_of("numpy_user_code")(1.0)                   # not robotexp's: not told
    assert told == [True, "compiling the map kernels", False, "  map kernels: 1 compiled", "  map kernels ready"]


def test_explore_says_the_compilation_before_the_run_goes_on(tmp_path: Path, monkeypatch) -> None:
    import robotexp.experiment as experiment

    def compiles_then_stops(*args, **kwargs):
        _kernel_of("robotexp.localization.kernels")(1.0)
        raise ConfigError("stopped after compiling")
    monkeypatch.setattr(experiment, "run_experiment", compiles_then_stops)
    result = CliRunner().invoke(main, ["explore", "--out", str(tmp_path / "o")])
    assert result.exit_code == 2
    lines = result.stderr.splitlines()
    assert lines[0].startswith("robotexp: compiling the localization kernels (first run after an install, ~")
    assert re.fullmatch(r"  localization kernels: 1 compiled \(scale\), \d+ s", lines[1]), lines
    assert re.fullmatch(r"  localization kernels ready \(1 compiled in \d+ s\)", lines[2]), lines
    assert lines[-1] == "robotexp: error: stopped after compiling"


def test_every_lua_function_documents_itself_laser_noise_included() -> None:
    import inspect

    from robotexp.lua.api import Session

    functions = {name: inspect.getdoc(f) for name, f in vars(Session).items() if name.startswith("lua_")}
    assert "lua_robot__setLaserNoise" in functions
    assert all(functions.values()), [name for name, doc in functions.items() if not doc]
    doc = functions["lua_robot__setLaserNoise"]
    assert doc.splitlines()[0].startswith("robot.setLaserNoise(uniform_mm[, sigma_mm]):")
    for words in ("+-`uniform_mm` [mm]", "`sigma_mm` [mm]", "robot.setLaserNoise(0)", "--noise-uniform",
                  "laser_uniform_mm", "ScriptError"):
        assert words in doc, words

"""Script errors name the script, line and function; stops (timeout, Ctrl-C) keep the results."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ConfigError, ScriptError
from robotexp.run.loop import TERMINATED_REASON
from procs import children, importing


@pytest.mark.parametrize(("code", "message"), [
    ("\n\nlocal x = nil + 1", r"^s.lua:3: attempt to perform arithmetic on a nil value$"),
    ('error("boom")', r"^s.lua:1: boom$"),
    ("\nrobot.moveMobileSim(1, 2)",
     r"^s.lua:2: robot.moveMobileSim\(x_mm, y_mm, theta_deg\): expected 3 argument\(s\), got 2$"),
    ("function f() exploration.setSeed(1.5) end\nf()",
     r"^s.lua:1: exploration.setSeed\(seed\): argument 1 must be an integer, got 1.5$"),
    ('robot.setMaxSpeed("fast")', r"robot.setMaxSpeed\(speed_mm_s\): argument 1 must be a number"),
    ("robot.setMaxSpeed(-5)", r"robot.setMaxSpeed\(speed_mm_s\): expected a value > 0 mm/s, got -5"),
    ("robot.setMaxSpeed(0/0)", r"argument 1 must be a number \(finite\), got nan$"),
    ("robot.setMaxSpeed(-1/0)", r"argument 1 must be a number \(finite\), got -inf$"),
    ("mapView.setShowGrid(1)", r"mapView.setShowGrid\(on\): argument 1 must be a boolean, got 1"),
    ("print(exploration.elapsedTime())", r"^s.lua:1: exploration.elapsedTime: no exploration has run yet"),
    ("exploration.setMethod(ExplorationMethod.NO_SUCH)",
     r"exploration.setMethod\(method\): expected an installed method, got nil .*available: .*"
     r"ExplorationMethod.FRONTIER"),
    ('exploration.setMethod("nope")', r"unknown method; available: .*ExplorationMethod.FRONTIER"),
    ('exploration.setWorld("atlantis")', r"^s.lua:1: exploration.setWorld: .*atlantis"),
    ('robot.setModel("r2d2")', r"unknown robot; available: p3dx, p3dx-body, kobuki"),
    ("exploration.setMapLimits(0, 0, -1, 5)", r"expected xmin < xmax and ymin < ymax"),
    ("exploration.setCellSize(1)", r"expected 5..2000 mm"),
])
@pytest.mark.untimed
def test_errors_name_script_line_and_function(lua, code, message):
    with pytest.raises(ScriptError, match=message):
        lua(code, name="s.lua")


@pytest.mark.untimed
def test_syntax_error_is_bad_input_and_nothing_runs(lua):
    with pytest.raises(ConfigError, match=r"^s.lua:2: unexpected symbol near '=' \(the script does not compile"):
        lua('print("ran")\nlocal y = = 2', name="s.lua")
    assert lua.lines == []


@pytest.mark.untimed
def test_error_in_pcall_is_a_plain_string(lua):
    lua('local ok, e = pcall(robot.setMaxSpeed, "x"); print(ok, type(e))')
    assert lua.lines == ["false\tstring"]


@pytest.mark.untimed
def test_cli_prints_one_line_and_exits_1(tmp_path):
    script = tmp_path / "bad.lua"
    script.write_text("print('before')\nlocal x = {} .. 1\n")
    result = CliRunner().invoke(main, ["run", str(script), "--out", str(tmp_path / "out")])
    assert result.exit_code == 1
    assert "robotexp: error: bad.lua:2: attempt to concatenate a table value" in result.output
    assert "before" in result.output and "Traceback" not in result.output


@pytest.mark.untimed
def test_cli_os_exit_status(tmp_path):
    script = tmp_path / "exit.lua"
    script.write_text("os.exit(4)")
    assert CliRunner().invoke(main, ["run", str(script), "--out", str(tmp_path)]).exit_code == 4


@pytest.mark.parametrize("loop", [
    "while true do end",
    "while true do pcall(function() while true do end end) end",          # cannot swallow the stop
    "local co = coroutine.wrap(function() while true do end end); co()",
    "while true do coroutine.resume(coroutine.create(function() while true do end end)) end",
])
def test_timeout_stops_a_stuck_script(lua, loop):
    t0 = time.monotonic()
    with pytest.raises(ScriptError, match=r"^s.lua: stopped by --timeout after 0.3 s; the 0 run\(s\)"):
        lua(loop, name="s.lua", timeout=0.3)
    assert time.monotonic() - t0 < 5.0


def test_timeout_during_a_run_keeps_its_record(lua):
    with pytest.raises(ScriptError, match="stopped by --timeout after 2 s; the 1 run"):
        # at 40 mm/s the exploration takes about a minute of wall time: the timeout always falls inside it
        lua('exploration.setWorld("dense"); robot.setMaxSpeed(40); exploration.start(); exploration.wait(); '
            'print("not reached")', name="s.lua", timeout=2.0)
    (rec,) = [json.loads(x) for x in (lua.out / "results.jsonl").read_text().splitlines()]
    assert rec["completed"] is False and "--timeout of 2 s" in rec["reason"]
    assert lua.lines == []


def _sigint_after_ready(tmp_path: Path, code: str, wait_for: str, sig: int = signal.SIGINT,
                       ignored: bool = False) -> tuple[subprocess.CompletedProcess, Path]:
    """Run `code`, wait for its "ready" line and then for the file `wait_for` in the output folder; Ctrl-C (or
    `sig` sent to the command's process). `ignored`: the command starts with SIGINT ignored, as a shell starts
    a command in the background."""
    script = tmp_path / "s.lua"
    script.write_text(code)
    out = tmp_path / "out"
    # a terminal's Ctrl-C: SIGINT back to its default in the child even when the tests run in the background
    start = signal.SIG_IGN if ignored else signal.SIG_DFL
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, start))
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "ready"
        deadline = time.monotonic() + 60
        while not (out / wait_for).exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr), out


def test_ctrl_c_stops_a_pure_lua_loop(tmp_path):
    done, _ = _sigint_after_ready(tmp_path, 'print("ready"); io.stdout:flush(); io.open("go", "w"):close()\n'
                                            'while true do pcall(function() end) end', "go")
    assert done.returncode == 130, done.stderr
    assert "interrupted" in done.stderr and "Traceback" not in done.stderr


def test_sigterm_stops_a_pure_lua_loop_and_says_so(tmp_path):
    done, _ = _sigint_after_ready(tmp_path, 'print("ready"); io.stdout:flush(); io.open("go", "w"):close()\n'
                                            'while true do pcall(function() end) end', "go", signal.SIGTERM)
    assert done.returncode == 143, done.stderr
    assert done.stderr.strip().splitlines() == ["robotexp: terminated (SIGTERM)"], done.stderr


def test_ctrl_c_during_a_run_writes_it_and_exits_130(tmp_path):
    done, out = _sigint_after_ready(tmp_path, 'print("ready"); io.stdout:flush(); mapView.setFrameFolder("f")\n'
                                              'exploration.setWorld("dense"); robot.setMaxSpeed(40)\n'
                                              'exploration.start(); exploration.wait(); print("not reached")',
                                    "f/frame_000003.png")
    assert done.returncode == 130, done.stderr
    assert "not reached" not in done.stdout and "Traceback" not in done.stderr
    assert (out / "results.jsonl").is_file(), done.stderr      # the command's account of what it did
    (rec,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert rec["completed"] is False and "interrupted" in rec["reason"]


def test_sigterm_during_a_run_writes_it_and_exits_143(tmp_path):
    """`kill` of `robotexp run`: as Ctrl-C, the script's run written as interrupted, exit status 143."""
    done, out = _sigint_after_ready(tmp_path, 'print("ready"); io.stdout:flush(); mapView.setFrameFolder("f")\n'
                                              'exploration.setWorld("dense"); robot.setMaxSpeed(40)\n'
                                              'exploration.start(); exploration.wait(); print("not reached")',
                                    "f/frame_000003.png", signal.SIGTERM)
    assert done.returncode == 143, done.stderr
    assert "not reached" not in done.stdout and "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines()[-1] == "robotexp: terminated (SIGTERM)", done.stderr
    assert (out / "results.jsonl").is_file(), done.stderr      # the command's account of what it did
    (rec,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert rec["completed"] is False and rec["end"] == "interrupted" and rec["reason"] == TERMINATED_REASON


def test_sigterm_to_the_scripts_own_process_ends_the_script_not_only_its_run(tmp_path):
    """A process manager that stops a whole group (systemd's control group, `kill 0`) sends SIGTERM to the script's
    process too: its run is written as terminated and the script ends there, it does not go on to the next line."""
    script = tmp_path / "s.lua"
    script.write_text('mapView.setFrameFolder("f"); exploration.setWorld("dense"); robot.setMaxSpeed(40)\n'
                      'exploration.start(); exploration.wait(); print("not reached")')
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not (out / "f/frame_000003.png").exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        (child,) = children(proc.pid)
        os.kill(child, signal.SIGTERM)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 143, stderr
    assert "not reached" not in stdout and stderr.strip().splitlines()[-1] == "robotexp: terminated (SIGTERM)", stderr
    (rec,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert rec["completed"] is False and rec["reason"] == TERMINATED_REASON


def test_sigterm_stops_a_run_of_a_command_started_in_the_background(tmp_path):
    """A shell starts a background command with Ctrl-C ignored, and its children inherit that: the script's
    process still obeys the SIGTERM its supervisor passes on, and the run is written as terminated."""
    done, out = _sigint_after_ready(tmp_path, 'print("ready"); io.stdout:flush(); mapView.setFrameFolder("f")\n'
                                              'exploration.setWorld("dense"); robot.setMaxSpeed(40)\n'
                                              'exploration.start(); exploration.wait(); print("not reached")',
                                    "f/frame_000003.png", signal.SIGTERM, ignored=True)
    assert done.returncode == 143, done.stderr
    assert "not reached" not in done.stdout and "killed" not in done.stderr, done.stderr
    (rec,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert rec["completed"] is False and rec["reason"] == TERMINATED_REASON


def test_sigterm_ends_the_view_kept_after_the_script_of_a_command_started_in_the_background(tmp_path):
    """`robotexp run --view` keeps its page up after the script until Ctrl-C; started in the background (Ctrl-C
    ignored, and inherited by the script's process), a `kill` still ends it at once, not after the grace (then
    the script's process is killed)."""
    script = tmp_path / "s.lua"
    script.write_text('print("ready"); io.stdout:flush()')
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(tmp_path / "out"),
                             "--view"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline().strip() for _ in range(2)]     # the page's address, then the script's line
        assert lines[0].startswith("view: http://") and lines[1] == "ready", lines
        time.sleep(1.0)                 # the script is over; the page stays up
        sent = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err         # the script was over: the page's end is its normal end
    assert "killed" not in err and took < 2.5, (took, err)


if os.name != "posix":   # pragma: no cover
    pytestmark = pytest.mark.skip("SIGINT tests need POSIX")


@pytest.mark.untimed
def test_an_interrupt_python_cannot_pass_on_is_not_printed_once_the_script_is_interrupted(monkeypatch):
    """Ctrl-C raised inside a callback Python cannot raise from (llvmlite's object cache while numba
    compiles: met in CI on a fresh install) goes to sys.unraisablehook, which prints "Exception ignored
    in" and a traceback; once the script is marked interrupted it is dropped, anything else still
    reaches the hook that was there before."""
    import gc

    from robotexp.lua.runtime import Control, _stops_set

    reached: list[type] = []
    monkeypatch.setattr(sys, "unraisablehook", lambda info: reached.append(type(info.exc_value)))

    class RaisesOnDel:
        def __init__(self, exc: BaseException) -> None:
            self.exc = exc

        def __del__(self) -> None:
            raise self.exc

    control = Control(None, time.monotonic)
    with _stops_set(control):
        RaisesOnDel(KeyboardInterrupt())          # not interrupted yet: passed on
        control.reason = "interrupted"
        RaisesOnDel(KeyboardInterrupt())          # dropped
        RaisesOnDel(ValueError("other"))          # passed on
        gc.collect()
    RaisesOnDel(KeyboardInterrupt())              # outside: the hook from before again
    gc.collect()
    assert reached == [KeyboardInterrupt, ValueError, KeyboardInterrupt]



@pytest.mark.parametrize(("sig", "status", "line"), [(signal.SIGINT, 130, "robotexp: interrupted"),
                                                     (signal.SIGTERM, 143, "robotexp: terminated (SIGTERM)")])
@pytest.mark.parametrize("when", ["importing", "running"])
def test_a_signal_to_the_whole_group_is_taken_once(tmp_path, sig, status, line, when):
    """A terminal's Ctrl-C (or a process manager's SIGTERM to the group) reaches the script's process as well as
    `robotexp run`, which passes it on again: the script's process, started with both signals blocked, hears
    them once its script starts, and takes the first one only. While it still imports: no traceback out of
    its imports; during a run: the run written, one line (a second copy raised as the first was said ended in
    click's "Aborted!", exit 1)."""
    script = tmp_path / "s.lua"
    script.write_text('mapView.setFrameFolder("f"); exploration.setWorld("dense"); robot.setMaxSpeed(40)\n'
                      'exploration.start(); exploration.wait(); print("not reached")')
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            kids = children(proc.pid)
            if when == "importing" and kids and importing(kids[0]):
                break
            if when == "running" and (out / "f/frame_000003.png").exists():
                break
            time.sleep(0.002 if when == "importing" else 0.05)
        assert kids and not (out / "results.jsonl").exists(), "the script's process was not caught"
        if when == "importing":     # the signal reaches the script's process first: blocked, it waits for its
            os.kill(kids[0], sig)   # script's start (or the kill that follows the same signal to its parent)
            time.sleep(0.2)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, sig)
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == status, stderr
    assert "Traceback" not in stderr and "Aborted" not in stderr and stderr.strip().splitlines() == [line], stderr
    if when == "running":
        (rec,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
        assert rec["completed"] is False and rec["end"] == "interrupted"

"""Every script stops (timed: these run alone): constructs the interrupt hook cannot see, Ctrl-C; the memory
limit and exit codes (untimed)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ScriptError

def _cli(*args: str) -> tuple[int, str, float]:
    t0 = time.monotonic()
    result = CliRunner().invoke(main, list(args))
    return result.exit_code, result.output, time.monotonic() - t0


def _cli_since(mark: str, *args: str) -> tuple[int, str, float]:
    """`robotexp ARGS` in a process of its own: its exit status, its output (stdout and stderr) and the
    seconds from the first line holding `mark` (which the script prints and flushes when it starts: the
    timeout counts from the script's start, not from the process's, slow to import on a loaded machine)
    to its end."""
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    lines, since = [], None
    try:
        for line in proc.stdout:
            lines.append(line)
            if since is None and mark in line:
                since = time.monotonic()
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.stdout.close()
        proc.wait()
    assert since is not None, "".join(lines)
    return proc.returncode, "".join(lines), time.monotonic() - since


UNSTOPPABLE = {
    "finalizer": "local t = setmetatable({}, {__gc = function() while true do end end}); t = nil; collectgarbage()",
    "pattern": 'string.find(("a"):rep(40), ("a*"):rep(40) .. "b")',
    "handler": "xpcall(error, function() while true do end end)",
}


@pytest.mark.parametrize("name", sorted(UNSTOPPABLE))
def test_constructs_the_hook_cannot_see_are_stopped_at_the_timeout(tmp_path, name):
    script, out = tmp_path / "s.lua", tmp_path / "out"
    script.write_text(f'print("start"); io.stdout:flush()\n{UNSTOPPABLE[name]}\nprint("not reached")')
    code, output, took = _cli_since("start", "run", str(script), "--out", str(out), "--timeout", "1.5", "--sandbox")
    assert code == 1, output
    assert took < 1.5 + 2.0, took
    assert "start" in output and "not reached" not in output and "Traceback" not in output
    assert "stopped by --timeout after 1.5 s" in output and "the 0 run(s) finished so far" in output


def test_runs_written_before_a_stuck_construct_are_kept(tmp_path):
    script, out = tmp_path / "s.lua", tmp_path / "out"
    script.write_text('print("start"); io.stdout:flush()\n'
                      'exploration.setWorld("dense"); exploration.setMaxTime(2000); exploration.start(); '
                      f'exploration.wait(); print("run done")\n{UNSTOPPABLE["finalizer"]}\nprint("not reached")')
    code, output, took = _cli_since("start", "run", str(script), "--out", str(out), "--timeout", "6", "--sandbox")
    assert code == 1 and took < 6 + 2.0, (took, output)
    assert "run done" in output and "not reached" not in output and "Traceback" not in output
    assert "stopped by --timeout after 6 s" in output and "the 1 run(s) finished so far" in output
    (rec,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert rec["robot_time_s"] >= 1.9


def test_a_looping_finalizer_pending_at_exit_does_not_hang(tmp_path):
    script = tmp_path / "s.lua"
    script.write_text('X = setmetatable({}, {__gc = function() while true do end end}); print("end")')
    code, output, took = _cli("run", str(script), "--out", str(tmp_path / "out"))
    assert code == 0 and "end" in output and took < 10


def test_ctrl_c_kills_a_script_stuck_in_a_pattern(tmp_path):
    script, out = tmp_path / "s.lua", tmp_path / "out"
    script.write_text('print("ready"); io.stdout:flush()\n' + UNSTOPPABLE["pattern"])
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        time.sleep(0.3)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=30)
        took = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130 and "interrupted" in stderr and "Traceback" not in stderr
    assert took < 3.0 + 1.5


@pytest.mark.untimed
def test_memory_limit(lua, tmp_path):
    grow = 'local t = {} for i = 1, 1e9 do t[i] = ("x"):rep(64) .. i end'
    with pytest.raises(ScriptError, match=r"^s.lua: out of memory: the script's Lua data reached its memory limit "
                                          r"of 20 MB; raise it with --max-memory"):
        lua(grow, name="s.lua", max_memory=20 * 2**20)
    script = tmp_path / "g.lua"
    script.write_text('local s = ("x"):rep(600 * 2^20)')      # one allocation over the sandbox's default
    code, output, _ = _cli("run", str(script), "--out", str(tmp_path / "o"), "--sandbox")
    assert code == 1 and "memory limit of 512 MB" in output
    script.write_text(grow)
    code, output, _ = _cli("run", str(script), "--out", str(tmp_path / "o"), "--max-memory", "30")
    assert code == 1 and "memory limit of 30 MB" in output and output.count("\n") == 1
    assert _cli("run", str(script), "--out", str(tmp_path / "o"), "--max-memory", "0.5")[0] == 2


@pytest.mark.untimed
def test_exit_status_is_one_byte(tmp_path):
    script = tmp_path / "s.lua"
    script.write_text("os.exit(256)")
    code, output, _ = _cli("run", str(script), "--out", str(tmp_path / "o"))
    assert code == 1 and "expected an integer 0..255" in output
    script.write_text("os.exit(255)")
    assert _cli("run", str(script), "--out", str(tmp_path / "o"))[0] == 255

"""What a script cannot break: the stop hook (through closures made while it runs), the metatables
Python objects and files share, robotexp's records, and the disk (the write limit)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ScriptError

WRAP_ATTACK = """
local w = coroutine.wrap(function() end)
local i = 1
while true do
  local ok, n = pcall(debug.getupvalue, w, i)
  if not ok then print("refused: " .. n) break end
  if n == nil then break end
  if n == "error" then debug.setupvalue(w, i, function() end) end
  if n == "aborting" then debug.setupvalue(w, i, function() return false end) end
  i = i + 1
end
"""


def _cli(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(main, list(args))
    return result.exit_code, result.output


@pytest.mark.untimed
def test_coroutine_wrap_closure_is_closed_to_debug(lua):
    lua(WRAP_ATTACK + 'print(pcall(debug.setupvalue, coroutine.wrap(print), 6, print))')
    assert lua.lines[0].startswith("refused: ") and "robotexp's own functions are closed" in lua.lines[0]
    assert lua.lines[1].startswith("false\t") and "debug.setupvalue" in lua.lines[1]


def test_the_stop_hook_survives_the_wrap_attack(tmp_path):
    # the script stops itself at --timeout (writing the run in progress, if any); it is not killed
    script, out = tmp_path / "s.lua", tmp_path / "out"
    script.write_text(WRAP_ATTACK + "while true do end")
    t0 = time.monotonic()
    code, output = _cli("run", str(script), "--out", str(out), "--timeout", "2")
    assert code == 1 and time.monotonic() - t0 < 2 + 1.5, output
    assert "stopped by --timeout after 2 s; the 0 run(s) finished so far" in output
    assert "killed" not in output


@pytest.mark.untimed       # but the timed command (alone)
def test_a_run_in_progress_at_the_timeout_is_written_before_the_kill(tmp_path, alone):
    # every Python process of the command starts 1.5 s late (more than the 1 s grace): the supervisor's
    # kill still counts from the script's start, so the child stops its run at --timeout and writes it.
    # The run is meta-firefly's on dense (about 6 s of CPU, where frontier's takes 1.3 s and ended within the 2 s).
    # Its kernels are compiled first, so that a run, not a compilation, is in progress at the timeout (the kill
    # waiting for a compilation is tested below)
    warm = subprocess.run([sys.executable, "-m", "robotexp.cli", "explore", "--world", "dense", "-m", "meta-firefly",
                           "--max-time", "5", "-o", str(tmp_path / "warm")],
                          capture_output=True, text=True, timeout=300)
    assert warm.returncode == 0, warm.stderr
    slow = tmp_path / "slow"
    slow.mkdir()
    (slow / "sitecustomize.py").write_text("import time\ntime.sleep(1.5)\n")
    script, out = tmp_path / "s.lua", tmp_path / "out"
    script.write_text('exploration.setWorld("dense"); exploration.setMethod("meta-firefly")\n'
                      'exploration.setMaxTime(3600000); exploration.start(); exploration.wait(); print("not reached")')
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(slow), os.environ.get("PYTHONPATH", "")])}
    with alone():
        proc = subprocess.run([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(out),
                               "--timeout", "2"], capture_output=True, text=True, env=env, timeout=60)
    assert proc.returncode == 1 and "not reached" not in proc.stdout and "killed" not in proc.stderr, proc.stderr
    assert "stopped by --timeout after 2 s; the 1 run(s) finished so far" in proc.stderr
    (record,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert record["completed"] is False and "--timeout of 2 s" in record["reason"]


def test_a_run_slow_to_write_at_the_timeout_is_waited_for(tmp_path):
    # the child's results writer takes 2.5 s for each run (a loaded machine, a large map), more than the 1 s grace
    # after --timeout: the child says a run is in progress, and the kill waits for it to be written
    slow = tmp_path / "slow"
    slow.mkdir()
    (slow / "sitecustomize.py").write_text(
        "import time\nfrom robotexp.output.results import ResultsWriter\n_end = ResultsWriter.on_end\n"
        "def on_end(self, run, record):\n    time.sleep(2.5)\n    _end(self, run, record)\n"
        "ResultsWriter.on_end = on_end\n")
    script, out = tmp_path / "s.lua", tmp_path / "out"
    script.write_text('exploration.setWorld("dense"); exploration.setMaxTime(3600000); exploration.start(); '
                      'exploration.wait(); print("not reached")')
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(slow), os.environ.get("PYTHONPATH", "")])}
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(out),
                           "--timeout", "2"], capture_output=True, text=True, env=env, timeout=120)
    took = time.monotonic() - t0
    assert proc.returncode == 1 and "not reached" not in proc.stdout and "killed" not in proc.stderr, proc.stderr
    assert "stopped by --timeout after 2 s; the 1 run(s) finished so far" in proc.stderr
    (record,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert record["completed"] is False and "--timeout of 2 s" in record["reason"]
    assert (out / f"{record['run']}.map.yaml").is_file()
    assert took >= 2 + 2.5


@pytest.mark.untimed
def test_print_of_bytes_that_are_not_utf8(lua):
    lua('print(pcall(print, "a\\255b\\237\\160\\128c\\226\\130", 1))')
    assert lua.lines == ["a\ufffdb\ufffd\ufffd\ufffdc\ufffd\ufffd\t1", "true"]


@pytest.mark.untimed
def test_shared_metatables_are_locked(lua):
    code = ('print(getmetatable(io.stdout), debug.getmetatable(io.stdout))\n'
            'print(pcall(debug.setmetatable, io.stdout, {}))\n'
            'print(pcall(setmetatable, io.stdout, {}))')
    lua(code)
    assert lua.lines[0] == "robotexp: locked\trobotexp: locked"
    assert lua.lines[1].startswith("false\t") and "debug.setmetatable" in lua.lines[1]
    assert lua.lines[2].startswith("false\t")


RECORD_WRITES = [
    'io.open("results.jsonl", "w")', 'io.open("results.jsonl", "a")', 'io.open("results.jsonl", "r+")',
    'io.open("RESULTS.JSONL", "w")', 'io.open("Results.Jsonl.torn", "a")', 'io.open("sub/../results.jsonl", "w")',
    'io.open("./results.jsonl.torn", "w")', 'io.open(".robotexp.lock", "w")', 'io.open("results.jsonl/x", "w")',
    'io.open("link", "w")', 'io.open("shared/results.jsonl", "w")', 'io.output("results.jsonl")',
    'os.remove("results.jsonl")', 'os.rename("results.jsonl", "x")', 'os.rename("mine.txt", "results.jsonl")',
    'os.rename("shared", "elsewhere")', 'mapView.setFrameFolder("results.jsonl")',
    'exploration.setRecordFolder("shared/results.jsonl.torn")', 'mapView.saveMapImage("results.jsonl")',
]


@pytest.mark.parametrize("sandbox", [True, False])
@pytest.mark.untimed
def test_scripts_cannot_touch_the_records(lua, sandbox):
    out = lua.out
    (out / "shared").mkdir(parents=True)
    for f in (out / "results.jsonl", out / "shared" / "results.jsonl"):
        f.write_text('{"run": "earlier", "coverage": 0.25}\n')
    (out / "mine.txt").write_text("x")
    os.symlink("results.jsonl", out / "link")
    code = "local refused = 0\n"
    for w in RECORD_WRITES:
        code += (f"local ok, e = pcall(function() return {w} end)\n"
                 "if not ok and e:find(\"refused\", 1, true) then refused = refused + 1 else print(e) end\n")
    lua(code + "print(refused)", sandbox=sandbox)
    assert lua.lines == [str(len(RECORD_WRITES))]
    for f in (out / "results.jsonl", out / "shared" / "results.jsonl"):
        assert f.read_text() == '{"run": "earlier", "coverage": 0.25}\n'
    assert sorted(p.name for p in out.iterdir()) == ["link", "mine.txt", "results.jsonl", "shared"]


@pytest.mark.untimed
def test_a_results_file_that_is_a_folder_is_refused_before_the_run(tmp_path):
    script, out = tmp_path / "s.lua", tmp_path / "out"
    script.write_text('print("ran")')
    (out / "results.jsonl").mkdir(parents=True)
    code, output = _cli("run", str(script), "--out", str(out))
    assert code == 2 and "ran" not in output and "Traceback" not in output
    assert output == f"robotexp: error: {out / 'results.jsonl'}: is a folder, not a results file; move it away " \
                     "or give another --out (the runs' records go there)\n"


@pytest.mark.untimed
def test_the_write_limit_stops_a_write_loop(lua):
    code = """
    local f = io.open("big.bin", "wb")
    local chunk, n = ("x"):rep(65536), 0
    local ok, e = pcall(function() while true do f:write(chunk); n = n + 1 end end)
    print(n, e)
    print(pcall(f.write, f, "y"))
    io.output(f)
    print(pcall(io.write, "y"))
    io.output(io.stdout)
    print(pcall(io.write, "to the terminal: not counted "))
    f:close()
    print(pcall(io.open, "other.txt", "w"))
    """
    lua(code, sandbox=True, max_write=2**20)
    n, error = lua.lines[0].split("\t")
    assert int(n) == 15          # 16 x 64 KiB fill 1 MB; the file costs 4 KiB
    assert "file:write: refused: the script's files reached its --max-write limit of 1 MB" in error
    assert (lua.out / "big.bin").stat().st_size == 15 * 65536
    assert [line.split("\t")[0] for line in lua.lines[1:]] == ["false", "false", "true", "false"]
    assert all("--max-write" in line for line in lua.lines[1:] if line.startswith("false"))
    assert not (lua.out / "other.txt").exists()


@pytest.mark.untimed
def test_the_write_limit_counts_files_created(lua):
    code = ('local n = 0\nlocal ok, e = pcall(function() while true do io.open("f" .. n, "w"):close(); '
            'n = n + 1 end end)\nprint(n, e)')
    lua(code, sandbox=True, max_write=2**20)
    n, error = lua.lines[0].split("\t")
    assert int(n) == 256 and "io.open: refused" in error and "--max-write" in error     # 1 MB / 4 KiB


@pytest.mark.untimed
def test_max_write_on_the_command_line(tmp_path):
    script, out = tmp_path / "s.lua", tmp_path / "out"
    script.write_text('local f = io.open("a.bin", "wb"); f:write(("x"):rep(3 * 2^20)); print("not reached")')
    code, output = _cli("run", str(script), "--out", str(out), "--sandbox", "--max-write", "2")
    assert code == 1 and "not reached" not in output and "Traceback" not in output
    assert "s.lua:1: file:write: refused: the script's files reached its --max-write limit of 2 MB" in output
    code, output = _cli("run", str(script), "--out", str(out), "--sandbox")       # the default: 512 MB
    assert code == 0 and "not reached" in output
    code, output = _cli("run", str(script), "--out", str(out), "--max-write", "-1")
    assert code == 2 and output == "robotexp: error: --max-write must be 0..1073741824 MB, got -1\n"


@pytest.mark.untimed
def test_a_results_file_made_a_folder_during_the_run_keeps_the_record(lua):
    # without --sandbox a script can still start programs: the record goes beside the folder
    code = ('os.execute("mkdir -p \'" .. exploration.outputFolder() .. "/results.jsonl\'")\n'
            'exploration.setWorld("dense"); exploration.setMaxTime(2000); exploration.start(); exploration.wait()')
    with pytest.raises(ScriptError, match=r"results.jsonl is a folder, not a results file: this run's record was "
                                          r"written to .*\.record\.json instead"):
        lua(code)
    (rescued,) = lua.out.glob("*.record.json")
    (record,) = [json.loads(x) for x in rescued.read_text().splitlines()]
    assert record["run"] == rescued.name.removesuffix(".record.json") and record["robot_time_s"] > 0


# A stand-in for the script's process: it says on the supervisor's pipe that its script starts and that a
# step starts (a compilation, "c" ... "d", or a run, "s" ... "e"), stays in it for HOLD s (a step it cannot stop
# in, or a slow one), says it ended (unless told not to), then stops as a timed-out child does: it writes its run
# and exits 1.
STAND_IN = """
import os, signal, sys, time
signal.signal(signal.SIGINT, signal.SIG_IGN)
fd = int([a for a in sys.argv if a.startswith("--ready-fd=")][0].split("=")[1])
out, hold, ends, step = sys.argv[1], float(sys.argv[2]), sys.argv[3] == "ends", sys.argv[4]
begin, end = {"compile": (b"c", b"d"), "run": (b"s", b"e")}[step]
os.write(fd, b"r")
os.write(fd, begin)
time.sleep(hold)
if ends:
    with open(os.path.join(out, "results.jsonl"), "a") as f:
        f.write('{"run": "stopped at the timeout"}\\n')
    os.write(fd, end)
    sys.exit(1)
time.sleep(60)
"""


def _supervising(tmp_path, hold: float, ends: bool, step: str, **options: object) -> str:
    """Python code that supervises the stand-in (`supervise` with `options`) and exits with its status."""
    script = tmp_path / "stand_in.py"
    script.write_text(STAND_IN)
    given = "".join(f", {k}={v!r}" for k, v in options.items())
    return ("import sys; from pathlib import Path; from robotexp.lua.supervise import supervise; "
            f"sys.exit(supervise([{str(tmp_path)!r}, {str(hold)!r}, {'ends' if ends else 'hangs'!r}, {step!r}], "
            f"script='s.lua', out=Path({str(tmp_path)!r}){given}, child=[sys.executable, {str(script)!r}]))")


def _stand_in(tmp_path, hold: float, ends: bool, compile_hold: float = 300.0, step: str = "compile",
              write_hold: float = 60.0) -> tuple[int, float, str]:
    """Supervise the stand-in with a 0.5 s timeout (1 s grace): its exit status, the seconds it took, stderr."""
    code = _supervising(tmp_path, hold, ends, step, timeout=0.5, compile_hold=compile_hold, write_hold=write_hold)
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    return proc.returncode, time.monotonic() - t0, proc.stderr


def test_the_kill_at_the_timeout_waits_for_a_run_to_be_written(tmp_path):
    # in a run at the timeout for 2.2 s (a long step, a slow write), more than the 0.5 s + 1 s grace: not killed,
    # the run is written
    code, took, err = _stand_in(tmp_path, hold=2.2, ends=True, step="run", write_hold=30.0)
    assert code == 1 and took >= 2.2, err
    assert "killed" not in err, err
    assert (tmp_path / "results.jsonl").read_text() == '{"run": "stopped at the timeout"}\n'


def test_a_second_ctrl_c_ends_the_wait_for_a_run(tmp_path):
    code = _supervising(tmp_path, 60.0, False, "run", timeout=None, interrupt_grace=1.0, write_hold=30.0)
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-c", code], stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)     # the kill 1 s later falls in the run: it waits 30 s more
        time.sleep(2.5)
        assert proc.poll() is None
        proc.send_signal(signal.SIGINT)     # ... until a second Ctrl-C: 1 s more
        _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    took = time.monotonic() - t0
    assert proc.returncode == 130 and 3.5 + 1.0 <= took < 3.5 + 1.0 + 3.0, (took, err)
    assert "did not stop within 1 s of Ctrl-C: killed" in err


def test_a_run_that_never_ends_is_killed_after_the_hold(tmp_path):
    # the kill falls in the run at 0.5 + 1 s and waits 1 s more, once
    code, took, err = _stand_in(tmp_path, hold=60.0, ends=False, step="run", write_hold=1.0)
    assert code == 1 and 0.5 + 1.0 + 1.0 <= took < 0.5 + 1.0 + 1.0 + 3.0, (took, err)
    assert "stopped by --timeout after 0.5 s (it did not stop by itself within 1 s: killed)" in err
    assert not (tmp_path / "results.jsonl").exists()


def test_the_kill_at_the_timeout_waits_for_a_compilation_to_end(tmp_path):
    # in the compilation at the timeout for 2.5 s, more than the 1 s grace: not killed, the run it stops is written
    code, took, err = _stand_in(tmp_path, hold=2.5, ends=True, compile_hold=30.0)
    assert code == 1 and took >= 2.5, err
    assert "numba is compiling kernels" in err and "killed" not in err, err
    assert (tmp_path / "results.jsonl").read_text() == '{"run": "stopped at the timeout"}\n'


def test_a_compilation_that_never_ends_is_killed_after_the_hold(tmp_path):
    code, took, err = _stand_in(tmp_path, hold=60.0, ends=False, compile_hold=2.0)
    assert code == 1 and 2.0 <= took < 2.0 + 0.5 + 1.0 + 3.0, (took, err)
    assert "stopped by --timeout after 0.5 s (it did not stop by itself within 1 s: killed)" in err
    assert not (tmp_path / "results.jsonl").exists()


# A stand-in that writes one run, says its script runs, and dies of SIGSEGV at Ctrl-C (a crash while it stops).
CRASHES_AT_CTRL_C = """
import os, signal, sys, time
fd = int([a for a in sys.argv if a.startswith("--ready-fd=")][0].split("=")[1])
with open(os.path.join(sys.argv[1], "results.jsonl"), "a") as f:
    f.write('{"run": "finished before Ctrl-C"}\\n')
signal.signal(signal.SIGINT, lambda *_: os.kill(os.getpid(), signal.SIGSEGV))
os.write(fd, b"r")
signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})   # started with them blocked
time.sleep(60)
"""


def test_a_script_process_that_dies_of_a_signal_after_ctrl_c_is_named(tmp_path):
    """Ctrl-C, and the script's process dies of a signal instead of stopping by itself: one line says so and
    how many runs are in results.jsonl (not a silent exit 130)."""
    script = tmp_path / "crashes.py"
    script.write_text(CRASHES_AT_CTRL_C)
    code = ("import sys; from pathlib import Path; from robotexp.lua.supervise import supervise; "
            f"sys.exit(supervise([{str(tmp_path)!r}], script='s.lua', out=Path({str(tmp_path)!r}), timeout=None, "
            f"child=[sys.executable, {str(script)!r}]))")
    proc = subprocess.Popen([sys.executable, "-c", code], stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30
        while not (tmp_path / "results.jsonl").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, err
    assert (f"robotexp: error: s.lua: the script's process was killed by SIGSEGV after Ctrl-C, before it stopped "
            f"by itself; the 1 run(s) finished so far are in {tmp_path / 'results.jsonl'}") in err, err


# A stand-in that takes seconds to start its script (Python's imports) and never says it started.
SLOW_TO_START = """
import time
time.sleep(60)
"""


@pytest.mark.parametrize(("sig", "code", "line"), [(signal.SIGINT, 130, "robotexp: interrupted"),
                                                   (signal.SIGTERM, 143, "robotexp: terminated (SIGTERM)")])
def test_a_signal_before_the_script_started_stops_its_process_at_once(tmp_path, sig, code, line):
    """Ctrl-C (or SIGTERM) before the script's process said its script started: nothing of the script can be
    lost, so the process is stopped at once, not sent a Ctrl-C that lands in its start-up (a traceback from
    Python's imports) and waited for; one line, exit 130 (143)."""
    script = tmp_path / "slow.py"
    script.write_text(SLOW_TO_START)
    prog = ("import sys; from pathlib import Path; from robotexp.cli.common import watch_signals; "
            "from robotexp.lua.supervise import supervise; watch_signals(); "
            f"sys.exit(supervise([{str(tmp_path)!r}], script='s.lua', out=Path({str(tmp_path)!r}), timeout=None, "
            f"child=[sys.executable, {str(script)!r}]))")
    proc = subprocess.Popen([sys.executable, "-c", prog], stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        time.sleep(1.5)
        sent = time.monotonic()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == code and err.strip().splitlines() == [line], err
    assert took < 2.0, took         # not the 3 s grace after Ctrl-C


def test_a_crash_of_the_script_process_shows_its_python_stack_and_is_named(tmp_path):
    """The script's process dies of a fault (SIGSEGV, as a fault in a compiled library would raise): the Python
    stack it happened in is on stderr (faulthandler), then one line names the signal; exit 1."""
    script = tmp_path / "s.lua"
    script.write_text('print("ready"); io.stdout:flush()\nwhile true do pcall(function() end) end')
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "ready"
        with open(f"/proc/{proc.pid}/task/{proc.pid}/children") as f:
            (child,) = [int(p) for p in f.read().split()]
        os.kill(child, signal.SIGSEGV)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 1, err
    assert "Fatal Python error: Segmentation fault" in err and "lua_child.py" in err, err
    assert err.strip().splitlines()[-1] == (
        f"robotexp: error: s.lua: the script's process was killed by SIGSEGV (a crash: the lines above give the "
        f"Python stack it happened in); the 0 run(s) finished so far are in {out / 'results.jsonl'}"), err

"""Run a Lua script in a child process that the parent stops from outside.

The interrupt hook of the prelude stops a script only where Lua calls hooks: not inside a __gc
finalizer, a long pattern match (`string.find(("a"):rep(40), ("a*"):rep(40) .. "b")`), a
message handler that loops, or the finalizers Lua runs when its state is closed. `robotexp run`
therefore runs the script in a child process (`python -m robotexp.cli.lua_child`, the same command
in-process) and watches it:

- the child stops itself first (the hook: --timeout, Ctrl-C), writing the run in progress; the
  parent's clock for the kill starts when the child says its script started (a byte on the pipe
  `--ready-fd`), so a child slow to start (imports on a loaded machine) is not killed before its
  own deadline; a child that never says so is killed `STARTUP_GRACE` s later than the timeout;
- at --timeout + `TIMEOUT_GRACE` s, or `INTERRUPT_GRACE` s after Ctrl-C, the parent kills it
  (SIGKILL): every run already in results.jsonl stays there, and the parent says how many there
  are; a timeout exits 1, Ctrl-C 130, SIGTERM 143; a child that dies of a signal (a crash, the out-of-memory
  killer), after Ctrl-C or not, is named on stderr with the runs already written;
- a numba compilation (the first run of a method after an install) is one step the child cannot
  stop in; the child says when one starts and ends (COMPILING, COMPILED on the same pipe), and the
  kill at --timeout waits for it to end (`COMPILE_HOLD` s at most) and `TIMEOUT_GRACE` s more, so the
  child stops at its next step and writes the run in progress;
- no Lua code runs during a run of the script (the explorer, the robot, the record), so a child in a run
  is never stuck where the hook cannot stop it, only slow: the run sees the deadline or Ctrl-C at its
  next step and is written (its record, its map), which on a loaded machine can take longer than the
  grace. The child says when each run starts and ends (RUN_STARTS, RUN_ENDS); a kill that falls in a run
  waits `WRITE_HOLD` s more once (a second Ctrl-C ends the wait), and the grace again from its end;
- Ctrl-C or SIGTERM is passed on to the child as it came: the child ends its script the same way for both,
  and a SIGTERM's run record, line and exit status say SIGTERM;
- the child starts with Ctrl-C and SIGTERM blocked, and unblocks them once its script starts and its
  handlers are in place: a terminal's Ctrl-C (or a SIGTERM to the whole group) reaches it too, and waits until
  then; it takes its first Ctrl-C or SIGTERM only (`robotexp.signals.first_stop_only`: the one passed on by
  the parent is the same signal again);
- Ctrl-C or SIGTERM before the child said its script started kills it at once (nothing of the script ran);
  the child obeys the Ctrl-C passed on to it even when it started with Ctrl-C ignored (a background job);
- the child dies with the parent (kill -9 of `robotexp run` included: `robotexp.lifeline`);
- the child's output is relayed to the parent's stdout and stderr as it comes, not by lines (a
  redrawn progress line too), in chunks of at most `CHUNK` bytes (a script writing gigabytes without a
  newline costs the parent no memory); when the parent cannot write it (a full disk, a closed pipe) the
  rest is drained and dropped, and the exit status is 1 with one line on stderr, never 0.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO, BinaryIO

import click

from robotexp.errors import Terminated, stop_line
from robotexp.lifeline import die_with_parent
from robotexp.signals import children_start_deaf

__all__ = ["supervise", "TIMEOUT_GRACE", "INTERRUPT_GRACE", "COMPILE_HOLD", "WRITE_HOLD", "READY", "COMPILING",
           "COMPILED", "RUN_STARTS", "RUN_ENDS"]

TIMEOUT_GRACE = 1.0     # [s] after --timeout before the child is killed (it writes the run it stopped)
INTERRUPT_GRACE = 3.0   # [s] after Ctrl-C before the child is killed (robot stopped, run written)
_POLL = 0.05            # [s]
CHUNK = 65536           # [bytes] the most of the child's output the parent holds at once
STARTUP_GRACE = 60.0    # [s] for the child to start its script, on top of the timeout (it normally says so)
# [s] the longest numba compilation the kill at --timeout waits for: every kernel group of a real robot
# with scan matching compiles in about 120 s on a loaded 2-core machine (robotexp.compilewatch.GROUPS)
COMPILE_HOLD = 300.0
# [s] how much longer a kill that falls in a run waits for the run to stop and be written (a step of an explorer,
# the record and the map of a large floor take seconds on a loaded 2-core machine)
WRITE_HOLD = 60.0
# what the child says on its pipe, a byte each
READY, COMPILING, COMPILED, RUN_STARTS, RUN_ENDS = b"r", b"c", b"d", b"s", b"e"


def _records(path: Path) -> int:
    """Complete lines in a results file (0 when there is none)."""
    try:
        with open(path, "rb") as f:
            return f.read().count(b"\n")
    except OSError:
        return 0


def _relay(stream: IO[bytes], target: BinaryIO, failures: list[OSError | ValueError]) -> None:
    """Copy `stream` to `target` in chunks of at most CHUNK bytes until its end; after a failed write
    (kept in `failures`) drain the rest so the child never blocks on a full pipe."""
    fd = stream.fileno()
    try:
        while True:
            data = os.read(fd, CHUNK)
            if not data:
                break
            if failures:
                continue
            try:
                target.write(data)
                target.flush()
            except (OSError, ValueError) as exc:       # ValueError: the target was closed
                failures.append(exc)
    finally:
        stream.close()


def _heard(fd: int) -> bytes:
    """What the child wrote to the (non-blocking) pipe `fd` since the last call."""
    try:
        return os.read(fd, 4096)
    except BlockingIOError:
        return b""


def _signal_name(number: int) -> str:
    """SIGKILL for 9; the number for a signal Python does not name."""
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def _tell(text: str) -> None:
    """One line on stderr, whatever state stdout is in."""
    try:
        click.echo(text, err=True)
    except (OSError, ValueError):
        pass


def supervise(args: list[str], *, script: str, out: Path, timeout: float | None,  # noqa: C901, PLR0912, PLR0915
              timeout_grace: float = TIMEOUT_GRACE, interrupt_grace: float = INTERRUPT_GRACE,
              compile_hold: float = COMPILE_HOLD, write_hold: float = WRITE_HOLD,
              child: list[str] | None = None) -> int:
    """Run `robotexp run ARGS` in a child process; return its exit status (see the module docstring).

    Args:
        args: the `robotexp run` arguments (the script and its options; the child adds --child).
        script: the script's name, for messages.
        out: the output folder (results.jsonl).
        timeout: [s] the script's --timeout, or None.
        timeout_grace: [s] after `timeout` before the child is killed.
        interrupt_grace: [s] after Ctrl-C before the child is killed.
        compile_hold: [s] the longest compilation the kill at the timeout waits for.
        write_hold: [s] how much longer a kill that falls in a run waits for the run to be written.
        child: the child's command before its arguments (default: this Python, `-m robotexp.cli.lua_child`).

    Returns:
        The exit status: the child's, 1 after a kill at the timeout, 130 after Ctrl-C, 143 after SIGTERM.
    """
    results = out / "results.jsonl"
    before = _records(results)
    start = time.monotonic()
    ready, ready_w = os.pipe()          # the child says there when its script starts and when it compiles
    os.set_blocking(ready, False)
    cmd = [*(child or [sys.executable, "-m", "robotexp.cli.lua_child"]), *args, f"--ready-fd={ready_w}"]
    proc = None
    try:
        # the child starts with Ctrl-C and SIGTERM blocked and hears them once its script starts (a terminal's
        # Ctrl-C reaches it too: before, in its imports, it printed a traceback); one that came here meanwhile
        # is raised at the block's end, and the child goes with it
        with children_start_deaf():
            proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                    preexec_fn=die_with_parent, pass_fds=(ready_w,))
    except KeyboardInterrupt:
        if proc is not None:
            proc.kill()
            proc.wait()
        raise
    finally:
        os.close(ready_w)
    failures: list[OSError | ValueError] = []
    assert proc.stdout is not None and proc.stderr is not None
    pairs: list[tuple[IO[bytes], BinaryIO]] = [(proc.stdout, sys.stdout.buffer), (proc.stderr, sys.stderr.buffer)]
    relays = [threading.Thread(target=_relay, args=(s, t, failures), daemon=True) for s, t in pairs]
    for t in relays:
        t.start()
    kill_at = None if timeout is None else start + timeout + timeout_grace + STARTUP_GRACE
    started = False                 # the child said its script started: its timeout runs from then
    compiling: float | None = None  # since when the child compiles (it said COMPILING, not yet COMPILED)
    held = False                    # the kill at the timeout waited for a compilation (said once)
    in_run = False                  # the child said a run of its script is in progress
    waited = False                  # the kill fell in a run and waits for it (once)
    why: str | None = None          # "timeout" or "interrupted": the parent killed the child
    interrupted = terminated = False
    interrupts = 0
    early = False                   # stopped by a signal before its script started: killed at once
    unread = b""                    # what the child said, read when a signal came
    try:
        while True:
            try:
                while proc.poll() is None:
                    now = time.monotonic()
                    heard, unread = unread + _heard(ready), b""
                    for said in heard:
                        if said == READY[0] and not started:
                            started = True
                            if timeout is not None:
                                at = now + timeout + timeout_grace
                                kill_at = at if kill_at is None else min(kill_at, at)
                        elif said == COMPILING[0]:
                            compiling = now
                        elif said == COMPILED[0]:
                            compiling = None
                            if held and kill_at is not None and not interrupted:
                                kill_at = max(kill_at, now + timeout_grace)   # the child's next step stops it
                        elif said == RUN_STARTS[0]:
                            in_run = True
                        elif said == RUN_ENDS[0]:
                            in_run = False
                            if waited and kill_at is not None:      # the run is written: it stops by itself
                                kill_at = min(kill_at, now + (interrupt_grace if interrupted else timeout_grace))
                    if kill_at is not None and now >= kill_at and not interrupted and compiling is not None \
                            and started and now - compiling < compile_hold:
                        if not held:
                            _tell(f"robotexp: {script}: --timeout: numba is compiling kernels (a step that cannot "
                                  f"be interrupted); the run stops when it ends (at most {compile_hold:g} s)")
                        held = True
                    elif kill_at is not None and now >= kill_at and in_run and not waited and interrupts < 2:
                        waited = True               # a run is in progress: it stops at its next step, is written
                        kill_at = now + write_hold
                    elif kill_at is not None and now >= kill_at:
                        why = "interrupted" if interrupted else "timeout"
                        proc.kill()
                        proc.wait()
                        break
                    time.sleep(_POLL)
                break
            except KeyboardInterrupt as stop:
                interrupted = True
                interrupts += 1             # a second Ctrl-C cuts the wait for a run being written
                terminated = terminated or isinstance(stop, Terminated)
                unread += _heard(ready)
                if not started and READY[0] not in unread and proc.poll() is None:
                    # its script has not started, so nothing of it can be lost; a signal would land in the
                    # child's own start-up (Python's imports: a traceback)
                    early = True
                    proc.kill()
                    proc.wait()
                    break
                if proc.poll() is None:     # passed on as it came (the child ignores a second one)
                    proc.send_signal(signal.SIGTERM if terminated else signal.SIGINT)
                limit = time.monotonic() + interrupt_grace
                if not waited or interrupts >= 2:
                    kill_at = limit if kill_at is None else min(kill_at, limit)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(ready)
        for t in relays:
            t.join(timeout=2.0)
    made = max(_records(results) - before, 0)
    if failures:
        exc = failures[0]
        why_not = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        _tell(f"robotexp: error: {script}: the script's output could not be written ({why_not}); the rest of it "
              f"was dropped; the {made} run(s) finished are in {results}")
    if early:
        line, status = stop_line(terminated)
        click.echo(line, err=True)
        return status
    if why == "timeout":
        click.echo(f"robotexp: error: {script}: stopped by --timeout after {timeout:g} s (it did not stop by "
                   f"itself within {timeout_grace:g} s: killed); the {made} run(s) finished so far are in "
                   f"{results}", err=True)
        return 1
    if interrupted:
        if why == "interrupted":
            click.echo(f"robotexp: {script}: did not stop within {interrupt_grace:g} s of "
                       f"{'SIGTERM' if terminated else 'Ctrl-C'}: killed; the {made} run(s) finished so far are in "
                       f"{results}", err=True)
            click.echo(stop_line(terminated)[0], err=True)
        elif proc.returncode < 0:       # it died of a signal before it stopped by itself (not the parent's kill)
            click.echo(f"robotexp: error: {script}: the script's process was killed by "
                       f"{_signal_name(-proc.returncode)} after {'SIGTERM' if terminated else 'Ctrl-C'}, before it "
                       f"stopped by itself; the {made} run(s) finished so far are in {results}", err=True)
        # a child that ended by itself tells: 130 when Ctrl-C stopped its script, 0 when the script was
        # over (`run --view` keeps its page up until Ctrl-C)
        code = proc.returncode if why is None and proc.returncode >= 0 else 130
        return 143 if terminated and code == 130 else code        # SIGTERM: as the other commands
    code = proc.returncode
    if failures and code == 0:
        return 1
    if code < 0:
        crash = (signal.SIGSEGV, signal.SIGBUS, signal.SIGFPE, signal.SIGILL, signal.SIGABRT)
        why_dead = (" (out of memory? see --max-memory)" if -code == signal.SIGKILL
                    else " (a crash: the lines above give the Python stack it happened in)" if -code in crash else "")
        click.echo(f"robotexp: error: {script}: the script's process was killed by {_signal_name(-code)}{why_dead}; "
                   f"the {made} run(s) finished so far are in {results}", err=True)
        return 1
    return code

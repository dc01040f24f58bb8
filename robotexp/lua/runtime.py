"""Run an IfTEA-style Lua experiment script on lupa (`robotexp run SCRIPT.lua`).

The runtime is locked down whatever the options: no `python` table, no eval or builtins, an
attribute filter that refuses every Python attribute, and only plain Lua functions and tables in
the script's globals. Errors come back as `ScriptError` with the script name, line and message.
"""

from __future__ import annotations

import logging
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any

from robotexp.errors import ConfigError, PluginError, RobotError, ScriptError, Terminated, WorldError
from robotexp.lua.api import Control, Session
from robotexp.lua.sandbox import ABORT, HOOK_EVERY, PRELUDE, AddressPolicy, PathPolicy, lua_kind
from robotexp.run.observers import RunObserver
from robotexp.run.record import RunRecord
from robotexp.signals import safe_handler

__all__ = ["ScriptResult", "run_script", "read_script", "MAX_SCRIPT_BYTES", "substitute_method",
           "SANDBOX_MAX_MEMORY_MB", "SANDBOX_MAX_WRITE_MB"]

log = logging.getLogger(__name__)

SANDBOX_MAX_MEMORY_MB = 512     # [MB] the Lua memory limit under --sandbox when --max-memory is not given
SANDBOX_MAX_WRITE_MB = 512      # [MB] what a script may write to files under --sandbox when --max-write is not given
_RETIRED: list[Any] = []        # Lua states never closed (retire=True): closing runs __gc finalizers


@dataclass
class ScriptResult:
    """What a script left: its exit status (0, or the code given to os.exit) and the records of
    its runs (also in OUT/results.jsonl)."""

    exit_code: int = 0
    records: list[RunRecord] = field(default_factory=list)


def substitute_method(code: str, old: str, new: str) -> str:
    """`code` with every `ExplorationMethod.<old>` replaced by `ExplorationMethod.<new>`.

    Used to run a script written for a plugin that is not installed (e.g. the thesis script's BVP)
    with another one; nothing else in the script changes.
    """
    import re
    return re.sub(rf"\bExplorationMethod\.{re.escape(old)}\b", f"ExplorationMethod.{new}", code)


def _refuse_attribute(obj: object, name: object, is_setting: bool) -> object:
    raise AttributeError("scripts cannot reach Python attributes")


def _plain(lua: Any, value: Any) -> Any:
    """A Python result as a Lua value: numbers, strings, booleans, nil, tuples (several results)
    and tables; never a Python object."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, tuple):
        return tuple(_plain(lua, v) for v in value)
    if isinstance(value, (dict, list)):
        return lua.table_from(value, recursive=True)
    raise ScriptError(f"internal: a {type(value).__name__} cannot be given to a script")


def _message(exc: BaseException, name: str, max_memory: int | None) -> str:
    """The one-line message of a Lua error (never empty)."""
    from lupa import LuaMemoryError  # type: ignore[import-untyped]

    if isinstance(exc, LuaMemoryError):
        limit = f"its memory limit of {max_memory / 2**20:g} MB" if max_memory else "the memory available"
        return (f"{name}: out of memory: the script's Lua data reached {limit}; raise it with --max-memory MB "
                "if the script needs more")
    text = str(exc)
    for prefix in ("error loading code: ",):
        if text.startswith(prefix):
            text = text[len(prefix):]
    text = text.split("stack traceback:", 1)[0].strip()
    if not text:
        return (f"{name}: the script raised an error without a message (error(nil), error({{}}) or another "
                "value that is not a string)")
    return text


@contextmanager
def _stops_set(control: Control) -> Iterator[None]:
    """Ctrl-C (SIGINT) or SIGTERM marks the script as interrupted (`control.terminated` for a SIGTERM), then
    raises KeyboardInterrupt, or `Terminated`, as usual; a second one is ignored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        if control.reason == "interrupted":
            return          # a second signal (or the supervisor's copy of the first) must not cut the cleanup
        if control.reason is None:
            control.reason, control.terminated = "interrupted", signum == signal.SIGTERM
        raise Terminated if control.terminated else KeyboardInterrupt

    def unraisable(info: Any) -> None:
        # the KeyboardInterrupt raised in a callback that cannot pass it on (llvmlite's object cache, called
        # from C while numba compiles a kernel): Python would print it as "Exception ignored in"; the
        # script is marked interrupted already and stops at its next check
        if isinstance(info.exc_value, KeyboardInterrupt) and control.reason == "interrupted":
            return
        previous_hook(info)

    previous = {sig: signal.signal(sig, safe_handler(handler))       # held back while numba's code runs
                for sig in (signal.SIGINT, signal.SIGTERM)}
    previous_hook, sys.unraisablehook = sys.unraisablehook, unraisable
    try:
        yield
    finally:
        for sig, before in previous.items():
            signal.signal(sig, before)
        sys.unraisablehook = previous_hook


MAX_SCRIPT_BYTES = 16 * 2**20   # the largest script file read (a script is text written by hand or a program)


def read_script(path: Path) -> str:
    """The text of the script at `path`, as Lua's own loader takes a file: a UTF-8 byte order mark and a first
    line starting with "#" (`#!/usr/bin/env lua`) are left out (the line's end is kept: line numbers stay).
    A file that is not UTF-8 (a script saved as Latin-1, as editors of Portuguese text often do) is read as
    Latin-1: it runs, and its text prints as the characters it meant (in Lua's strings each non-ASCII
    character is then two bytes, its UTF-8).

    Raises:
        ConfigError: the file cannot be read, or is larger than MAX_SCRIPT_BYTES (checked before reading it
            whole: /dev/zero, a 3 GB file).
    """
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_SCRIPT_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the script ({exc.strerror or exc})") from None
    if len(data) > MAX_SCRIPT_BYTES:
        raise ConfigError(f"{path}: the script is larger than {MAX_SCRIPT_BYTES // 2**20} MB; is it the right "
                          "file? (a Lua script is text)")
    data = data.removeprefix(b"\xef\xbb\xbf")
    if data.startswith(b"#"):
        end = data.find(b"\n")
        data = b"" if end < 0 else data[end:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def run_script(path: Path, *, out: Path, world: str | None = None, robot: str = "p3dx", sandbox: bool = False,  # noqa: C901, PLR0913
               timeout: float | None = None, code: str | None = None,
               emit: Callable[[str], None] = log.info, notice: Callable[[str], None] = log.warning,
               max_memory: int | None = None, allow_addresses: tuple[str, ...] = (),
               retire: bool = False, observers: Sequence[RunObserver] = (),
               record: Path | None = None, max_write: int | None = None,
               on_start: Callable[[], None] | None = None,
               on_run: Callable[[bool], None] | None = None) -> ScriptResult:
    """Run the Lua script at `path` (or the text `code`, named after `path`).

    Relative paths in the script are relative to `out`. An exploration still armed when the script
    ends is run to its end. A robot the script connected to (robot.setAddress) is stopped and
    disconnected at the end, on an error and on Ctrl-C.

    Args:
        path: the script file.
        out: output folder: results.jsonl, images, the script's relative files.
        world: run on the embedded simulator of this world whatever robot.setAddress says.
        robot: simulated robot preset (p3dx, kobuki).
        sandbox: refuse programs, C modules and files outside `out`.
        timeout: [s] wall-time limit of the whole script.
        code: the script text (default: read from `path`).
        emit: receives each line the script prints.
        notice: receives notices for the user (e.g. the simulator replaces the address).
        max_memory: [bytes] limit of the script's Lua memory (None: no limit; --sandbox gives
            `SANDBOX_MAX_MEMORY_MB` by default at the command line).
        allow_addresses: with `sandbox`, the robot addresses the script may open besides the simulator.
        retire: never close the Lua state (closing runs the script's __gc finalizers, which could
            loop); for a process that exits right after.
        observers: told about each of the script's runs (a live view).
        record: a folder where each run is also written as a ROS 2 bag, <run>.mcap (as the script's
            `exploration.setRecordFolder` does; the script may change it).
        max_write: [bytes] what the script may write to files in all (`robotexp.lua.sandbox.WriteQuota`;
            None: no limit; --sandbox gives `SANDBOX_MAX_WRITE_MB` by default at the command line).
        on_start: called as the script starts, its handlers of Ctrl-C and SIGTERM in place (the supervisor's
            kill counts from then).
        on_run: called with True when a run of the script starts, with False when it is over (written or
            failed): the supervisor's kill waits for a run in progress to be written.

    Returns:
        The exit status and the records of the script's runs.

    Raises:
        ScriptError: runtime error (script:line: message), a bad API call, --timeout, the memory limit.
        ConfigError: a syntax error (the script is not run); an allowed address that is not a
            host[:port] or a device path; max_memory < 1 MB.
        KeyboardInterrupt: Ctrl-C, after the robot is stopped and the runs so far are written.
    """
    from lupa import LuaError, LuaRuntime, LuaSyntaxError

    if timeout is not None and not timeout > 0:
        raise ScriptError(f"--timeout must be > 0 s, got {timeout:g}")
    name = path.name
    if code is None:
        code = read_script(path)
    if max_memory is not None and max_memory < 2**20:
        raise ConfigError(f"--max-memory must be at least 1 MB, got {max_memory / 2**20:g} MB")
    addresses = AddressPolicy(sandbox, allow_addresses)
    control = Control(timeout, time.monotonic, on_run)
    if max_write is not None and max_write < 0:
        raise ConfigError(f"--max-write must be >= 0 MB, got {max_write / 2**20:g} MB")
    paths = PathPolicy(out, sandbox, max_write)
    session = Session(out=out, paths=paths, control=control, world=world, robot=robot, notice=notice,
                      script=name, addresses=addresses, observers=observers)
    session.record_folder = record
    lua = LuaRuntime(register_eval=False, register_builtins=False, unpack_returned_tuples=True,
                     attribute_filter=_refuse_attribute, max_memory=max_memory)
    if retire:
        _RETIRED.append(lua)
    g = lua.globals()
    g.python = None
    lua.execute("package.loaded.python = nil")

    def exit_request(code_value: object = None) -> None:
        if code_value is None or code_value is True:
            control.exit_code = 0
        elif code_value is False:
            control.exit_code = 1
        elif isinstance(code_value, int) and 0 <= code_value <= 255:
            control.exit_code = code_value
        else:
            raise ScriptError(f"os.exit([code]): expected an integer 0..255 or a boolean, got {lua_kind(code_value)} "
                              "(an exit status is one byte: 256 would read as 0, success)")
        control.reason = control.reason or "exit"

    def lua_function(f: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            return _plain(lua, f(*args))
        return call

    api = lua.table_from({t: lua.table_from({n: lua_function(f) for n, f in funcs.items()})
                          for t, funcs in session.functions().items()})
    script_dir = str(path.resolve().parent) if path.parent != Path("") else ""
    prelude = lua.compile(PRELUDE, name="=robotexp prelude", mode="t")
    try:        # a short --timeout may pass already here
        prelude(control.check, paths.resolve, paths.refuse, emit, exit_request, api,
                lua.table_from(session.methods()), sandbox, HOOK_EVERY, ABORT, script_dir, str(out),
                paths.quota.grant, max_write is not None)
    except LuaError as exc:
        session.close()
        if _stopped(control, name, session):
            return ScriptResult(control.exit_code, session.records)
        raise ScriptError(_message(exc, name, max_memory)) from None

    try:
        chunk = lua.compile(code, name=f"={name}", mode="t")
    except LuaSyntaxError as exc:   # bad input, found before anything runs: exit 2 like the CLI's
        session.close()
        raise ConfigError(f"{_message(exc, name, max_memory)} (the script does not compile; nothing was run)") from None
    with _stops_set(control):
        try:
            if on_start is not None:
                on_start()
            chunk()
            try:
                session.finish()
            except (WorldError, ConfigError, PluginError, RobotError) as exc:
                raise ScriptError(f"{name}: the exploration still armed at the end of the script: {exc}") from exc
        except LuaError as exc:
            if _stopped(control, name, session):
                return ScriptResult(control.exit_code, session.records)
            raise ScriptError(_message(exc, name, max_memory)) from None
        except KeyboardInterrupt as stop:
            if control.reason is None:
                control.reason, control.terminated = "interrupted", isinstance(stop, Terminated)
            _stopped(control, name, session)
            raise
        except ScriptError:
            if _stopped(control, name, session):
                return ScriptResult(control.exit_code, session.records)
            raise
        except Exception as exc:     # a raw Python function reached through debug.getupvalue, say
            if _stopped(control, name, session):
                return ScriptResult(control.exit_code, session.records)
            raise ScriptError(f"{name}: {type(exc).__name__}: {exc}") from None
        finally:
            session.close()         # stop the connected robot and release its link (Ctrl-C too)
            _flush_stdout(lua)
    return ScriptResult(control.exit_code, session.records)


def _stopped(control: Control, name: str, session: Session) -> bool:
    """Turn a stop into its outcome: raise KeyboardInterrupt (Ctrl-C), `Terminated` (SIGTERM) or ScriptError
    (--timeout); True for os.exit, False for an ordinary error."""
    if control.reason == "interrupted":
        raise Terminated if control.terminated else KeyboardInterrupt
    if control.reason == "timeout":
        raise ScriptError(f"{name}: stopped by --timeout after {control.timeout:g} s; the "
                          f"{len(session.records)} run(s) finished so far are in {session.out / 'results.jsonl'}")
    return control.reason == "exit"


def _flush_stdout(lua: Any) -> None:
    try:
        lua.execute("io.stdout:flush()")
    except Exception:   # the script closed stdout: nothing to flush
        log.debug("io.stdout:flush() failed", exc_info=True)

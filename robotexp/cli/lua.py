"""`robotexp run SCRIPT`: a Lua experiment script (the IfTEA API), optionally sandboxed."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import click

from robotexp.cli.common import compile_watch, handle_errors
from robotexp.cli.progress import Progress
from robotexp.errors import ConfigError, WorldError
from robotexp.output.safefile import writable_folder
from robotexp.view.live import end_view, parse_speed, start_view, view_options

__all__ = ["run_lua"]

def _tell_supervisor(fd: int | None, what: bytes) -> None:
    """One byte to the supervisor (`robotexp.lua.supervise`): READY once the script starts (its --timeout
    runs from then), COMPILING / COMPILED around a numba compilation and RUN_STARTS / RUN_ENDS around each
    run of the script (steps its kill waits for)."""
    if fd is None:
        return
    import os

    try:
        os.write(fd, what)
    except OSError:
        pass


def _started(fd: int | None, ready: bytes) -> None:
    """The script starts (its handlers of Ctrl-C and SIGTERM in place): tell the supervisor, then hear the signals
    it started this process with blocked (one that came meanwhile acts now)."""
    _tell_supervisor(fd, ready)
    from robotexp.signals import hear_signals

    hear_signals()


def _check_robot_and_world(robot: str, world: str | None) -> None:
    """--robot and --world name things the script cannot change: checked before it starts (it may write files
    before its first run)."""
    from robotexp.sim.presets import preset
    from robotexp.world.loader import load_world

    try:
        preset(robot)
    except ConfigError as exc:
        raise ConfigError(f"--robot: {exc}") from None
    if world is not None:
        try:
            load_world(world)
        except (WorldError, ConfigError) as exc:
            raise type(exc)(f"--world: {exc}") from None


@click.command("run")
@click.argument("script", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--world", "-w", default=None,
              help="Run on the embedded simulator of this world whatever robot.setAddress says.")
@click.option("--robot", default="p3dx", show_default=True, help="Simulated robot preset (p3dx, kobuki).")
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=Path("out"),
              show_default=True, help="Output folder; the script's relative paths are relative to it.")
@click.option("--sandbox", is_flag=True,
              help="Refuse os.execute, io.popen, C modules, files outside the output folder and robot addresses "
                   "not given with --allow-address; limit the script's memory (--max-memory, default 512 MB) "
                   "and what it writes to files (--max-write, default 512 MB).")
@click.option("--allow-address", multiple=True,
              help="With --sandbox: a robot or laser address (host[:port] or device path) the script may open "
                   "(repeatable).")
@click.option("--max-memory", type=float, default=None,
              help="Limit of the script's Lua memory [MB] (default: none; 512 with --sandbox).")
@click.option("--timeout", type=float, default=None, help="Stop the script after this many seconds (exit 1).")
@click.option("--child", is_flag=True, hidden=True, help="Run in this process (robotexp.lua.supervise's child).")
@click.option("--tty-progress", is_flag=True, hidden=True,
              help="Redraw the progress line (the child's stderr is a pipe to a terminal).")
@click.option("--ready-fd", type=int, default=None, hidden=True,
              help="A pipe to tell the supervisor when the script starts and when numba compiles "
                   "(robotexp.lua.supervise's child).")
@click.option("--max-write", type=float, default=None,
              help="Limit of what the script writes to files [MB] (default: none; 512 with --sandbox).")
@click.option("--record", type=click.Path(file_okay=False, path_type=Path), default=None, metavar="DIR",
              help="Record each run of the script as a ROS 2 bag, DIR/<run>.mcap.")
@view_options
@handle_errors
def run_lua(script: Path, world: str | None, robot: str, out: Path, sandbox: bool, allow_address: tuple[str, ...],
            max_memory: float | None, timeout: float | None, child: bool, tty_progress: bool, record: Path | None,
            view: bool, view_port: int, view_host: str, view_speed: str | None, ready_fd: int | None = None,
            max_write: float | None = None) -> None:
    """Run a Lua experiment script (IfTEA's API: robot, exploration, mapView, robotView).

    The script runs in a child process that is killed at --timeout (+1 s) or 3 s after Ctrl-C
    if it does not stop by itself; runs already written stay in results.jsonl."""
    from robotexp.lua.runtime import SANDBOX_MAX_MEMORY_MB, SANDBOX_MAX_WRITE_MB
    from robotexp.lua.sandbox import AddressPolicy

    if timeout is not None and not (timeout > 0 and math.isfinite(timeout)):
        raise ConfigError(f"--timeout must be a number of seconds > 0, got {timeout:g}")
    if max_memory is not None and not (1 <= max_memory <= 2**20):
        raise ConfigError(f"--max-memory must be 1..1048576 MB, got {max_memory:g}")
    if allow_address and not sandbox:
        raise ConfigError("--allow-address only means something with --sandbox (without it a script may open "
                          "any address)")
    AddressPolicy(sandbox, allow_address)       # a malformed --allow-address: one line, before anything runs
    memory = max_memory if max_memory is not None else (SANDBOX_MAX_MEMORY_MB if sandbox else None)
    if max_write is not None and not (0 <= max_write <= 2**30):
        raise ConfigError(f"--max-write must be 0..1073741824 MB, got {max_write:g}")
    written = max_write if max_write is not None else (SANDBOX_MAX_WRITE_MB if sandbox else None)
    writable_folder(out)
    parse_speed(view_speed)                     # a bad --view-speed: one line, before anything runs
    if record is not None:
        writable_folder(record, "--record")
        record = record.resolve()
    if not child:
        from robotexp.lua.supervise import supervise

        _check_robot_and_world(robot, world)

        args = [str(script), "--robot", robot, "--out", str(out)] + (["--world", world] if world else [])
        args += (["--sandbox"] if sandbox else []) + [f"--allow-address={a}" for a in allow_address]
        args += [f"--max-memory={max_memory!r}"] if max_memory is not None else []
        args += [f"--max-write={max_write!r}"] if max_write is not None else []
        args += [f"--timeout={timeout!r}"] if timeout is not None else []
        args += [f"--record={record}"] if record is not None else []
        if view:            # the child runs the script, so it serves the view
            args += ["--view", f"--view-port={view_port}", f"--view-host={view_host}"]
            args += [f"--view-speed={view_speed}"] if view_speed is not None else []
        if click.get_current_context().find_root().params.get("debug", False):
            args.append("--debug")
        if sys.stderr.isatty():         # the child writes to a pipe, relayed here: it redraws for a terminal
            args.append("--tty-progress")
        sys.exit(supervise(args, script=script.name, out=out, timeout=timeout))

    from robotexp.lua import run_script

    live = start_view(view, view_host, view_port, view_speed)
    progress = Progress(None, enabled=True if tty_progress else None)      # each run of the script
    try:
        from robotexp.lua.supervise import COMPILED, COMPILING, READY, RUN_ENDS, RUN_STARTS

        with compile_watch(True if tty_progress else None,
                           busy=lambda on: _tell_supervisor(ready_fd, COMPILING if on else COMPILED)):
            result = run_script(script, out=out, world=world, robot=robot, sandbox=sandbox, timeout=timeout,
                                emit=click.echo, notice=lambda text: click.echo(f"robotexp: {text}", err=True),
                                max_memory=None if memory is None else int(memory * 2**20),
                                allow_addresses=allow_address, retire=True,
                                observers=(progress,) if live is None else (progress, live.observer),
                                record=record, max_write=None if written is None else int(written * 2**20),
                                on_start=lambda: _started(ready_fd, READY),
                                on_run=lambda on: _tell_supervisor(ready_fd, RUN_STARTS if on else RUN_ENDS))
    except BaseException:
        end_view(live, interrupted=True)
        raise
    finally:
        progress.close()
    if result.records:
        click.echo(f"{script.name}: {len(result.records)} exploration(s); results: {out / 'results.jsonl'}", err=True)
    else:
        click.echo(f"{script.name}: no exploration ran", err=True)
    end_view(live, interrupted=False)
    if result.exit_code:
        sys.exit(result.exit_code)

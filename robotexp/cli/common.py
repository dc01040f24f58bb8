"""What every command shares: error handling (one line and an exit code), folders, option parsing."""

from __future__ import annotations

import functools
import math
import sys
from collections.abc import Callable
from typing import Any, NoReturn, TypeVar

import click

from robotexp.errors import (ConfigError, PluginError, RobotError, RobotexpError, ScriptError, Terminated, WorldError,
                             interrupt_in, stop_line)

__all__ = ["fail", "one_line", "handle_errors", "interrupted", "mm", "params", "image_formats", "compile_watch",
           "watch_signals"]

F = TypeVar("F", bound=Callable[..., Any])


MAX_ERROR_CHARS = 2000      # the longest error line said; its middle is left out beyond


def one_line(message: str, limit: int = MAX_ERROR_CHARS) -> str:
    """`message` as one line of about `limit` characters at most: line breaks and other control characters
    written as escapes (\\n, \\x1b), the middle of a longer one left out (its start says what and where, its
    end what to do), saying how much was."""
    if len(message) <= limit:
        return _escaped(message)
    head, tail = limit * 2 // 3, limit // 3
    return (f"{_escaped(message[:head])} [... {len(message) - head - tail} characters left out ...] "
            f"{_escaped(message[-tail:])}")


_ESCAPES = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def _escaped(text: str) -> str:
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else _ESCAPES.get(c) or (f"\\x{ord(c):02x}" if ord(c) < 256 else
                                                                 f"\\u{ord(c):04x}") for c in text)


def fail(message: str, code: int) -> None:
    click.echo(f"robotexp: error: {one_line(message)}", err=True)
    sys.exit(code)


def interrupted(exc: KeyboardInterrupt) -> NoReturn:
    """End the command after a Ctrl-C (exit status 130) or a SIGTERM (`Terminated`, 143), saying which."""
    end_interrupted(isinstance(exc, Terminated))


def end_interrupted(terminated: bool) -> NoReturn:
    """End a command that a SIGTERM (`terminated`: exit status 143) or a Ctrl-C (130) interrupted, saying which."""
    line, status = stop_line(terminated)
    click.echo(line, err=True)
    sys.exit(status)


def watch_signals() -> None:
    """Take SIGTERM as a Ctrl-C (raise `Terminated` in the main thread): a run then stops its robot and
    writes what it has, as it does on Ctrl-C. Without it Python ends at once: no `finally`, a robot over
    a driver left with its last command, the run in progress lost. Both handlers are held back while
    numba's code runs (`robotexp.signals`: an exception raised there crashes the process)."""
    import signal

    from robotexp.signals import install_safe

    def terminate(signum: int, frame: Any) -> None:
        raise Terminated

    install_safe(signal.SIGINT)
    install_safe(signal.SIGTERM, terminate)


def _quiet_stdout() -> None:
    """The reader of stdout went away (`robotexp plugins | head -1`): point stdout at the null device,
    so that nothing more (not even the flush at exit) fails on the closed pipe."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def handle_errors(func: F) -> F:
    """Turn our errors into one line and an exit code (a traceback only with --debug)."""
    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        debug = click.get_current_context().find_root().params.get("debug", False)
        try:
            return func(*args, **kwargs)
        except (ConfigError, WorldError, PluginError) as exc:
            if debug:
                raise
            fail(str(exc), 2)
        except (RobotError, ScriptError, RobotexpError) as exc:
            if debug:
                raise
            fail(str(exc), 1)
        except (KeyboardInterrupt, SystemError) as exc:
            # a SystemError: a Ctrl-C that landed in a numba kernel outside a run's loop (loading a compiled
            # kernel), the KeyboardInterrupt behind it
            interrupt = interrupt_in(exc)
            if interrupt is None:
                raise
            interrupted(interrupt)
        except BrokenPipeError:
            _quiet_stdout()
            sys.exit(0)
        except OSError as exc:
            if debug:
                raise
            where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
            fail(f"{exc.strerror or exc}{where}", 1)
    return wrapper  # type: ignore[return-value]


def mm(value: float | None, what: str) -> float | None:
    if value is None:
        return None
    if not (value > 0 and math.isfinite(value)):
        raise ConfigError(f"{what} must be a positive number of mm, got {value:g}")
    return value / 1000.0


def params(items: tuple[str, ...], option: str = "--param") -> dict[str, Any]:
    """Parse repeated `--param key=value` (values as JSON numbers/booleans, else strings); errors name
    `option`."""
    import json
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key.isidentifier():
            raise ConfigError(f"{option} {item!r}: expected key=value with key a parameter name")
        try:
            out[key] = json.loads(raw)
        except json.JSONDecodeError:
            out[key] = raw
    return out


def image_formats(text: str) -> tuple[str, ...]:
    """--image-format: "png,svg" -> ("png", "svg"); ConfigError for anything else."""
    from robotexp.output.figures import FORMATS

    fmts = tuple(dict.fromkeys(f.strip().lower() for f in text.split(",") if f.strip()))
    if not fmts or set(fmts) - set(FORMATS):
        raise ConfigError(f"--image-format {text!r}: use png, svg, pdf (comma-separated)")
    return fmts


def compile_watch(tty: bool | None = None, busy: Callable[[bool], None] | None = None) -> Any:
    """A `robotexp.compilewatch.CompileWatch` that tells stderr, as it happens, that numba compiles the
    kernels of a group (the first run after an install) and how far it got: on a terminal (`tty`,
    default: whether stderr is one) one line redrawn per group, else a line per kernel; `busy` is told
    when a compilation starts and ends."""
    from robotexp.compilewatch import CompileWatch

    redraw = sys.stderr.isatty() if tty is None else tty
    drawn = [False]

    def say(text: str) -> None:
        step = text.startswith("  ")
        if step and redraw:
            click.echo(f"\r{text.strip()}\033[K", nl=False, err=True)
            drawn[0] = True
            return
        if drawn[0]:
            click.echo("", err=True)
            drawn[0] = False
        click.echo(text if step else f"robotexp: {text}", err=True)
    return CompileWatch(say, busy=busy)

"""The one exception tree of robotexp.

Every error robotexp raises on purpose is a `RobotexpError`; messages say what failed, where,
and what to do. Only `robotexp.cli` maps these to exit codes (2 for bad input, 1 for run failures).
"""

from __future__ import annotations

__all__ = [
    "RobotexpError", "RobotError", "ConnectionLost", "ProtocolError",
    "WorldError", "ScriptError", "PluginError", "ConfigError", "Terminated", "stop_line",
]


class RobotexpError(Exception):
    """Root of every error robotexp raises on purpose."""


class RobotError(RobotexpError):
    """Talking to or driving a robot failed."""


class ConnectionLost(RobotError, ConnectionError):
    """The link to the robot closed or went silent."""


class ProtocolError(RobotError):
    """Bad checksum, impossible length or a failed handshake."""


class WorldError(RobotexpError):
    """A malformed map file, an unknown world, or a start pose inside an obstacle."""


class ScriptError(RobotexpError):
    """A Lua syntax or runtime error (script, line, message)."""


class PluginError(RobotexpError):
    """An unknown plugin name, a failed plugin import or a contract violation."""


class ConfigError(RobotexpError, ValueError):
    """A parameter out of range."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (a `kill`, a process manager, `timeout`) taken as a Ctrl-C: the run in progress ends with its
    robot stopped and its partial result written (`robotexp.cli` installs the handler that raises it)."""


def stop_line(terminated: bool) -> tuple[str, int]:
    """What a command that a SIGTERM (`terminated`) or a Ctrl-C ended says last, and its exit status."""
    return ("robotexp: terminated (SIGTERM)", 143) if terminated else ("robotexp: interrupted", 130)


def interrupt_in(exc: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C (or `Terminated`) behind `exc`: the first KeyboardInterrupt in its chain of causes and
    contexts, None when there is none.

    A SIGINT that lands while a numba kernel's dispatcher is returning (or loading a compiled kernel from
    the cache) comes out as ``SystemError: CPUDispatcher(...) returned a result with an exception set``
    whose cause is the KeyboardInterrupt; such an error is the user's Ctrl-C, not the code's fault.
    """
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            return current
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return None


def raise_interrupt_in(exc: BaseException) -> None:
    """Raise again, of its own kind (Ctrl-C or `Terminated`), the interruption behind `exc` (`interrupt_in`),
    chained to `exc`; return when there is none."""
    interrupt = interrupt_in(exc)
    if interrupt is not None:
        raise type(interrupt)(*interrupt.args) from exc

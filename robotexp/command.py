"""The `robotexp` program: its entry point loads the command line (`robotexp.cli`) and runs it.

Loading the command line imports NumPy and click (a few tenths of a second): a Ctrl-C or a SIGTERM in that
time ends the program as one during a command does, one line and exit status 130 (143), not a traceback.
"""

from __future__ import annotations

import signal
import sys
from typing import Any

__all__ = ["main"]


def _terminate(signum: int, frame: Any) -> None:
    from robotexp.errors import Terminated

    raise Terminated


def main() -> None:
    """Run the `robotexp` command with the process's arguments."""
    guard = signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    try:
        if guard:
            signal.signal(signal.SIGTERM, _terminate)
        from robotexp.cli import main as command
        if guard:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)     # each command installs its own handler
    except KeyboardInterrupt as exc:
        from robotexp.errors import Terminated, stop_line

        line, status = stop_line(isinstance(exc, Terminated))
        sys.stderr.write(line + "\n")
        sys.exit(status)
    command()

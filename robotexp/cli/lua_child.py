"""`python -m robotexp.cli.lua_child ARGS`: `robotexp run ARGS` in-process, for `robotexp.lua.supervise`.

The Lua state is never closed (its __gc finalizers could loop) and the process ends with
`os._exit` once its output is flushed. A crash of the process (a fault in a compiled library) writes the
Python stack it happened in to stderr (`faulthandler`) before the process dies of its signal, which
`robotexp run` then names.
"""

from __future__ import annotations

import faulthandler
import os
import signal
import sys


def main() -> None:
    """Run `robotexp run --child ARGS` and exit with its status without closing the Lua state."""
    faulthandler.enable()
    # the supervisor stops the script with SIGINT: obeyed even when this process started with it ignored (a
    # `robotexp run` started in the background by a shell, whose children ignore Ctrl-C)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    # the supervisor started it with Ctrl-C and SIGTERM blocked: they are heard once the script starts (the
    # script's start unblocks them), and only the first one (the supervisor passes on the one it got, which a
    # terminal or a process manager sent to this process too)
    from robotexp.signals import first_stop_only

    first_stop_only()
    from robotexp.cli import main as cli

    args = sys.argv[1:]
    debug = "--debug" in args
    args = [a for a in args if a != "--debug"]
    try:
        cli.main(args=(["--debug"] if debug else []) + ["run", "--child", *args], prog_name="robotexp")
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


if __name__ == "__main__":
    main()

"""Child processes that die with their parent.

`die_with_parent()` runs in a freshly forked child (a `preexec_fn`, a process pool's initializer):
on Linux it asks the kernel (prctl PR_SET_PDEATHSIG) to send the child SIGKILL when its parent
dies, whatever way the parent goes (kill -9 included), so no worker or script keeps running and
appending to results that nobody watches. Elsewhere it does nothing.

`exit_without_teardown()` makes a worker process end as soon as its exit handlers have run: the
teardown of the interpreter after them (numba's loaded kernels, their LLVM objects, every module)
took 0.5-3.7 s of a campaign's end on a loaded 2-core machine, while its results were all written.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys

__all__ = ["die_with_parent", "exit_without_teardown"]

_PR_SET_PDEATHSIG = 1


def die_with_parent(sig: int = signal.SIGKILL) -> None:
    """Have the kernel send `sig` to this process when its parent dies (Linux; no-op elsewhere).

    If the parent is already gone (the child was re-parented before this ran), exit at once.
    """
    if not sys.platform.startswith("linux"):
        return
    parent = os.getppid()
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)
    except (OSError, AttributeError):     # no prctl: nothing to arm
        return
    if os.getppid() != parent or parent == 1:
        os._exit(1)


_exit_armed = False


def exit_without_teardown() -> None:
    """At interpreter exit, once the exit handlers registered after this call have run, flush the
    logs and the standard streams and end the process (exit status 0) without the module teardown.

    For worker processes whose results are written when they exit (a campaign's pool, a local Dask
    cluster's workers); the exit handlers registered before this call are skipped. Calling it again
    does nothing."""
    global _exit_armed
    if _exit_armed:
        return
    _exit_armed = True
    import atexit

    atexit.register(_exit_now)


def _exit_now() -> None:
    import logging

    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):      # closed or replaced streams
            pass
    os._exit(0)

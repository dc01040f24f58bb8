"""Child processes that die with their parent.

`die_with_parent()` runs in a freshly forked child (a `preexec_fn`, a process pool's initializer):
on Linux it asks the kernel (prctl PR_SET_PDEATHSIG) to send the child SIGKILL when its parent
dies, whatever way the parent goes (kill -9 included), so no worker or script keeps running and
appending to results that nobody watches. Elsewhere it does nothing.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys

__all__ = ["die_with_parent"]

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

"""Signal handlers that never raise inside numba's Python code (`safe_handler`).

A Python signal handler runs at the next bytecode of the main thread, wherever that is. A compiled numba
kernel that returns arrays calls back into numba's Python code while it builds its result
(`numba.core.serialize._numba_unpickle`); an exception raised there by a handler (Ctrl-C's
KeyboardInterrupt, robotexp's `Terminated` on SIGTERM) is not checked by the compiled caller, which hands
back a result with a missing item: ``SystemError: CPUDispatcher(...) returned a result with an exception
set``, or a segmentation fault when the caller unpacks it. The same holds for llvmlite's callbacks while a
kernel is compiled or loaded from the cache (the exception is swallowed, and the Ctrl-C lost).

`safe_handler` wraps a handler: when the signal lands while numba's or llvmlite's Python code is on the
stack, the handler is not called then; the signal is sent again to this process a moment later (1 ms,
doubling up to 50 ms while numba's code is still running), and the handler acts at the first bytecode
outside it. Ctrl-C during a kernel's call or compilation thus ends the program as it does anywhere else.
A kernel's first compilation can take tens of seconds: a second signal that comes when the first has been
held back `CUT_AFTER` seconds or more calls the handler at once, wherever it lands.

`held` keeps Ctrl-C and SIGTERM for the end of a block that must run whole (the standard streams pointed
away and back).

`children_start_deaf` blocks both while a block starts processes: a process started from it (a worker of a
pool) begins with them blocked, so a Ctrl-C from the terminal that reaches it during its Python start-up (its
imports) waits, pending, until the process has put its handlers in place and calls `hear_signals`; a
signal sent to the starting process in the block acts at the block's end. `first_stop_only` makes a process's
handlers take its first Ctrl-C or SIGTERM only (a child that gets a terminal's signal twice: directly, and
passed on by its parent).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

__all__ = ["safe_handler", "install_safe", "in_numba", "held", "children_start_deaf", "hear_signals",
           "first_stop_only"]

Handler = Callable[[int, FrameType | None], Any]

FIRST_RETRY = 0.001     # [s] the first delay before a signal held back is sent again
LAST_RETRY = 0.05       # [s] the longest one (the delay doubles while numba's code is still on the stack)
CUT_AFTER = 1.0         # [s] held back this long, the signal is given at once when another one comes
_PACKAGES = ("numba", "llvmlite")


class _Retry:
    """The signal held back now (the main thread's: handlers run there)."""

    delay = FIRST_RETRY
    since: float | None = None      # [s] (monotonic) when it was first held back
    waiting = 0                     # copies sent again that have not arrived yet
    lock = threading.Lock()


def in_numba(frame: FrameType | None) -> bool:
    """True when numba's or llvmlite's Python code is on the stack of `frame` (an imported numba only)."""
    files = (getattr(sys.modules.get(name), "__file__", None) for name in _PACKAGES)
    roots = tuple(os.path.dirname(f) + os.sep for f in files if isinstance(f, str))
    if not roots:
        return False
    while frame is not None:
        if frame.f_code.co_filename.startswith(roots):
            return True
        frame = frame.f_back
    return False


def _send_later(signum: int, delay: float) -> None:
    def send() -> None:
        with _Retry.lock:
            _Retry.waiting -= 1
        os.kill(os.getpid(), signum)

    with _Retry.lock:
        _Retry.waiting += 1
    timer = threading.Timer(delay, send)
    timer.daemon = True
    timer.start()


class _Once:
    """`first_stop_only`: this process's handlers take its first Ctrl-C or SIGTERM only."""

    on = False
    taken = False


def first_stop_only() -> None:
    """From now on the handlers wrapped by `safe_handler` take this process's first Ctrl-C or SIGTERM only, and
    ignore the later ones: for the script's process of `robotexp run`, which gets a terminal's Ctrl-C (or a
    process manager's SIGTERM to the whole group) twice, once directly and once passed on by its supervisor
    (the second one, raised while the first one's line was said, ended the process in click's "Aborted!").
    Its supervisor kills it when it does not stop in time."""
    _Once.on = True


def _given() -> None:
    """The signal held back was given to its handler: the next one starts afresh."""
    _Retry.delay, _Retry.since = FIRST_RETRY, None


def safe_handler(handler: Handler) -> Handler:
    """`handler`, held back while numba's or llvmlite's Python code runs (see the module). A handler already
    wrapped is returned as it is."""
    if getattr(handler, "_robotexp_safe", False):
        return handler

    def safe(signum: int, frame: FrameType | None) -> Any:
        if in_numba(frame):
            now = time.monotonic()
            if _Retry.since is None:
                _Retry.since = now
            with _Retry.lock:
                another = _Retry.waiting > 0        # not the copy sent again: that one has not gone yet
            if not another:
                _send_later(signum, _Retry.delay)
                _Retry.delay = min(2 * _Retry.delay, LAST_RETRY)
                return None
            if now - _Retry.since < CUT_AFTER:
                return None                         # the first one is still on its way
        _given()
        if _Once.on:
            if _Once.taken:
                return None
            _Once.taken = True
        return handler(signum, frame)

    safe._robotexp_safe = True      # type: ignore[attr-defined]
    safe.__wrapped__ = handler      # type: ignore[attr-defined]
    return safe


def install_safe(signum: int, handler: Handler | None = None) -> None:
    """Install `handler` (None: the one in place) for `signum` through `safe_handler`; in the main thread
    only, and only for a Python handler (not the default action, nor an ignored signal)."""
    if threading.current_thread() is not threading.main_thread():
        return
    current = signal.getsignal(signum) if handler is None else handler
    if callable(current):
        signal.signal(signum, safe_handler(current))


@contextmanager
def held() -> Iterator[None]:
    """Keep a Ctrl-C (SIGINT) or SIGTERM that comes inside the block for its end, where the handler that was in
    place is called (and raises there). A second signal inside calls that handler at once. Only in the main
    thread (elsewhere handlers never run inside the block) and only for Python handlers."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []         # the first signal that came inside
    previous: dict[int, Any] = {}

    def note(signum: int, frame: FrameType | None) -> None:
        if not pending:
            pending.append(signum)
            return
        handler = previous.get(signum)
        if callable(handler):
            handler(signum, frame)

    for signum in (signal.SIGINT, signal.SIGTERM):
        if callable(signal.getsignal(signum)):
            previous[signum] = signal.signal(signum, note)
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        if pending:
            previous[pending[0]](pending[0], None)


_STOPPING = {signal.SIGINT, signal.SIGTERM}


@contextmanager
def children_start_deaf(signals: frozenset[int] | set[int] = frozenset(_STOPPING), pool: bool = False
                        ) -> Iterator[None]:
    """Block `signals` (Ctrl-C (SIGINT) and SIGTERM) in this thread for the block. The processes started in it
    inherit the block through their exec (as do threads started in it, for good: a signal then goes to a thread
    that takes it); each calls `hear_signals` once its handlers are installed and then gets, at once, a signal
    that came while it started (a process that never calls it never hears them: a worker that its parent
    stops). A signal that came to this process in the block is delivered at its end. `pool`: the block starts
    processes through multiprocessing (its resource tracker is started first). Does nothing where signals
    cannot be blocked (Windows)."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    if pool:
        # multiprocessing's resource tracker, started by the first lock or queue a pool makes, unblocks SIGINT
        # and SIGTERM in the thread that starts it: started now, it is not started again inside the block
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()
    before = signal.pthread_sigmask(signal.SIG_BLOCK, signals)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


def hear_signals() -> None:
    """Unblock Ctrl-C and SIGTERM in this thread (a process started inside `children_start_deaf`, once its
    handlers are in place): one that came while they were blocked is handled now."""
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOPPING)

"""Say when numba compiles robotexp's kernels, at once and with progress.

numba compiles a kernel at its first call and caches the machine code; after an install the first
run compiles every kernel it calls: up to two minutes before a real robot with scan matching moves,
with nothing else to see. `CompileWatch` listens to numba's compile events (a cache
hit is no event) and tells its `say` callback, per kernel group (the map, planning, localization):
the start with the expected time, each kernel as it is compiled, the end with the time it took.

    with CompileWatch(say=print):
        run_experiment(...)
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from types import TracebackType
from typing import Any

__all__ = ["CompileWatch", "GROUPS"]

# module of the kernels -> (what the user is told, [s] expected compile time of the group): measured with
# an empty numba cache on a 2-core machine under load, a real robot's warm-up with scan matching
# (`experiment.warm_kernels`, frontier on `dense`): 116 s in all
GROUPS: dict[str, tuple[str, float]] = {
    "robotexp.mapping.kernels": ("map", 20.0),
    "robotexp.planning.kernels": ("planning", 45.0),
    "robotexp.localization.kernels": ("localization", 45.0),
    "robotexp.localization.covariance": ("localization", 45.0),
    "robotexp.world.raycast": ("simulator", 5.0),
}


class CompileWatch:
    """A context manager: while open, numba compiling a kernel of robotexp is told to `say`.

    Args:
        say: called with one line of text: when a group starts compiling ("compiling the localization
            kernels (first run after an install, ~90 s; cached for the next runs)..."), after each
            kernel ("  localization kernels: 3 compiled (search), 41 s"), and when the run moves on.
        clock: wall clock [s].
        busy: called with True when a kernel starts compiling and with False when it and the kernels it
            compiled on the way are done (a step that cannot be interrupted meanwhile).
    """

    def __init__(self, say: Callable[[str], None], clock: Callable[[], float] = time.monotonic,
                 busy: Callable[[bool], None] | None = None) -> None:
        self.say = say
        self.clock = clock
        self.busy = busy
        self.compiled: dict[str, int] = {}        # group label -> kernels compiled
        self._started: dict[str, float] = {}      # group label -> when its first kernel started
        self._open: str | None = None             # the group being compiled
        self._depth = 0                           # nested compiles (a kernel compiles the kernels it calls)
        self._listener: Any = None
        self._lock = threading.Lock()

    # -- numba's events -------------------------------------------------------------------------
    def _group(self, event: Any) -> tuple[str, float] | None:
        dispatcher = event.data.get("dispatcher") if isinstance(event.data, dict) else None
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", "")
        if module in GROUPS:
            return GROUPS[module]
        if module.startswith(("robotexp", "robotexp_plugins", "robotexp_drivers")):
            return module.rsplit(".", 1)[-1], 10.0
        return None

    def on_start(self, event: Any) -> None:
        """A kernel starts compiling: announce its group when it is the first of the group."""
        group = self._group(event)
        if group is None:
            return
        label, expected = group
        with self._lock:
            self._depth += 1
            if self._depth == 1 and self.busy is not None:
                self.busy(True)
            if self._depth == 1 and self._open != label:   # a kernel another one calls is part of the caller
                self._finish()
                self._open = label
                self._started[label] = self.clock()
                self.say(f"compiling the {label} kernels (first run after an install, ~{expected:.0f} s; cached "
                         "for the next runs)...")

    def on_end(self, event: Any) -> None:
        """A kernel is compiled: count it and say the group's progress."""
        group = self._group(event)
        if group is None:
            return
        name = getattr(getattr(event.data.get("dispatcher"), "py_func", None), "__name__", "?")
        with self._lock:
            self._depth = max(self._depth - 1, 0)
            if self._depth == 0 and self.busy is not None:
                self.busy(False)
            if self._depth > 0 or self._open is None:
                return                              # counted with the kernel that called it
            label = self._open
            self.compiled[label] = self.compiled.get(label, 0) + 1
            took = self.clock() - self._started.get(label, self.clock())
            self.say(f"  {label} kernels: {self.compiled[label]} compiled ({name}), {took:.0f} s")

    def _finish(self) -> None:
        if self._open is not None:
            took = self.clock() - self._started.get(self._open, self.clock())
            self.say(f"  {self._open} kernels ready ({self.compiled.get(self._open, 0)} compiled in {took:.0f} s)")
            self._open = None

    # -- context --------------------------------------------------------------------------------
    def __enter__(self) -> CompileWatch:
        from numba.core import event

        watch = self

        class _Listener(event.Listener):     # numba's listener base (numba is taken as Any)
            def on_start(self, ev: Any) -> None:
                watch.on_start(ev)

            def on_end(self, ev: Any) -> None:
                watch.on_end(ev)

        self._listener = _Listener()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        from numba.core import event

        if self._listener is not None:
            event.unregister("numba:compile", self._listener)
            self._listener = None
        with self._lock:
            self._finish()

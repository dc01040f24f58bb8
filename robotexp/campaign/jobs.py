"""One campaign run as a job of a worker process (a local pool or a Dask worker) and its timing."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robotexp.campaign.spec import pose_label
from robotexp.run.record import RunRecord
from robotexp.run.spec import RunSpec
from robotexp.signals import hear_signals, safe_handler

__all__ = ["RunTiming", "timed_run"]

@dataclass(frozen=True)
class RunTiming:
    """Where one run of a campaign spent its time, measured in the process that made it.

    Attributes:
        run: the run's name.
        worker: the process that made it ("pid N" in the pool; the Dask worker's address on a cluster).
        start: [s] time.time() when the worker began the run (before its imports, world and set-up).
        end: [s] time.time() when the run's record and files were done.
        cpu_s: [s] CPU time of the worker process over the run (all its threads).
        loop_s: [s] wall time of the run loop (the record's wall_time_s).
        first_in_worker: the first run this worker made (its imports and numba cache loads are in it).
    """

    run: str
    worker: str
    start: float
    end: float
    cpu_s: float
    loop_s: float
    first_in_worker: bool

    @property
    def wall_s(self) -> float:
        """[s] the run's wall time in its worker, set-up and writing included."""
        return self.end - self.start

    @property
    def setup_s(self) -> float:
        """[s] the wall time outside the run loop: imports (first run), world, ground truth, robot, files."""
        return self.wall_s - self.loop_s


_runs_made = 0                  # in a worker: runs begun so far


_worker_interrupted = False     # in a worker: Ctrl-C came; queued runs are skipped at once


_worker_running = False         # in a worker: a run is being made (Ctrl-C interrupts it)


def worker_init() -> None:
    """Worker start: die with the campaign process (kill -9 included), and remember a Ctrl-C or a SIGTERM so
    that the runs already queued to this worker are skipped instead of run in full; the run in progress ends
    as that signal ends a run (`Terminated` for a SIGTERM: its record says so). A worker is started with both
    signals blocked (`children_start_deaf`): a Ctrl-C from the terminal while it still imports is taken here,
    as one that came while it waited for work (no traceback out of its imports, no queued run made)."""
    from robotexp.errors import Terminated
    from robotexp.lifeline import die_with_parent, exit_without_teardown

    die_with_parent()
    exit_without_teardown()     # the pool's shutdown at the end of a campaign waits for its workers to exit

    def interrupted(signum: int, frame: Any) -> None:
        global _worker_interrupted
        first = not _worker_interrupted
        _worker_interrupted = True
        if first and _worker_running:    # idle (waiting for work): only remember it
            raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt

    signal.signal(signal.SIGINT, safe_handler(interrupted))     # held back while numba's code runs
    signal.signal(signal.SIGTERM, safe_handler(interrupted))
    hear_signals()      # started with both blocked (`children_start_deaf`): one that came in its imports acts now


def record_extra(spec: RunSpec, sweep: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The keys a campaign adds to a run's record: the world and pose as the campaign file gave them,
    and the swept parameter values of a run of a sweep."""
    extra: dict[str, Any] = {"world_spec": spec.world, "pose_spec": pose_label(spec)}
    if sweep:
        extra["sweep"] = dict(sweep)
    return extra


def timed_run(worker: str) -> Callable[[RunRecord], RunTiming]:
    """In a worker: start timing a run; call the result with the run's record when the run is done."""
    global _runs_made
    start, cpu0, first = time.time(), time.process_time(), _runs_made == 0
    _runs_made += 1

    def done(record: RunRecord) -> RunTiming:
        return RunTiming(record.run, worker, start, time.time(), time.process_time() - cpu0,
                         float(record.wall_time_s), first)
    return done


def run_one(spec: RunSpec, out: str, record: bool = False,
             extra: dict[str, Any] | None = None) -> tuple[RunRecord, RunTiming] | None:
    """Worker: one run, written to `out` (record first, then images; with `record` its bag in
    `out/bags`). Returns the record and its timing (None: a run queued after Ctrl-C, not made)."""
    global _worker_running
    if _worker_interrupted:
        return None
    timing = timed_run(f"pid {os.getpid()}")
    from robotexp.experiment import run_experiment

    _worker_running = True
    try:
        observers = []
        if record:
            from robotexp.bag.recorder import BagRecorder

            (Path(out) / "bags").mkdir(exist_ok=True)
            observers.append(BagRecorder(folder=Path(out) / "bags", world=spec.world))
        result = run_experiment(spec, Path(out), observers=observers, record_extra=extra or record_extra(spec))
    finally:
        _worker_running = False
    return result.record, timing(result.record)

"""Running a campaign: its runs in parallel worker processes (or on a Dask cluster, or one at a time on
connected robots), in an order that finishes the long runs early, resumable.

Each finished run is appended to `OUT/results.jsonl` at once; `resume` skips the runs recorded there.
"""

from __future__ import annotations

import contextlib
import os
import signal
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from multiprocessing import get_context
from pathlib import Path

from robotexp.campaign.jobs import RunTiming, record_extra, run_one, worker_init
from robotexp.campaign.robots import Place, run_on_robots
from robotexp.campaign.spec import Campaign, RunKey, record_key
from robotexp.errors import ConfigError, Terminated
from robotexp.run.record import EndReason, RunRecord
from robotexp.run.spec import RunSpec
from robotexp.signals import children_start_deaf

__all__ = ["expected_robot_time", "run_campaign", "run_order"]


def expected_robot_time(spec: RunSpec, area: float | None) -> float:
    """A guess of a run's robot time [s] before it runs, for ordering runs: the world's area [m^2]
    over the run's speed [m/s] (about a metre of path per square metre: the thesis's runs took
    0.5-1.1 m/m^2 in `dense` and `sparse`), at most the run's time limit; the time limit without an area."""
    if area is None or not area > 0:
        return spec.max_time
    return min(spec.max_time, area / spec.speed)


def run_order(campaign: Campaign, runs: Iterable[RunSpec]) -> list[RunSpec]:
    """`runs` longest expected first (`expected_robot_time`), ties in the campaign's own order.

    Longest first (LPT scheduling): the workers take the next run as they come free, so the short runs
    fill the gaps at the end instead of one long run keeping a core busy while the others idle."""
    index = {id(spec): i for i, spec in enumerate(campaign.runs)}
    areas = campaign.areas or {}
    listed = list(runs)
    order = sorted(range(len(listed)), key=lambda i: (-expected_robot_time(listed[i], areas.get(listed[i].world)),
                                                       index.get(id(listed[i]), len(index) + i)))
    return [listed[i] for i in order]


def run_campaign(campaign: Campaign, out: Path, *, jobs: int, resume: bool = False,
                 progress: Callable[[int, int, RunRecord | None], None] | None = None,
                 cluster: str | None = None, place: Place | None = None,
                 timings: list[RunTiming] | None = None) -> list[RunRecord]:
    """Run every run of `campaign` not yet recorded (with `resume`) in `jobs` processes, or on the
    Dask cluster at `cluster` (`robotexp.campaign.cluster`: tcp://HOST:PORT or local:N; `jobs` is then unused).
    The runs start longest expected first (`run_order`); with `timings`, each finished run's
    `RunTiming` is appended to it (benchmarks/speed/bench_thesis_campaign.py reads them).

    Returns the records of the runs made now. Ctrl-C stops the workers (each stops its robot and
    writes its partial run), cancels the queued runs at once and re-raises KeyboardInterrupt. The
    output folder is locked for the campaign (`robotexp.output.safefile.folder_lock`) and the workers die
    with this process.

    A campaign with runs on a robot (`campaign.devices`) makes its runs one after another here, in the
    file's order, whatever `jobs` (`robotexp.campaign.robots.run_on_robots`; `place` is its operator hook).

    Raises:
        ConfigError: --jobs < 1, a bad cluster address or no scheduler there, another campaign is
            writing into `out`, or a cluster for a campaign with runs on a robot.
    """
    if jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, got {jobs}")
    if cluster is not None and campaign.devices:
        raise ConfigError(f"{campaign.source}: runs on a robot (address in a [[set]]) are made here, one after "
                          "another; run without --cluster")
    from robotexp.output.safefile import folder_lock

    if cluster is not None:
        from robotexp.campaign.cluster import check_cluster_address
        check_cluster_address(cluster)
    with folder_lock(out, f"campaign {campaign.name}"):
        return _run_locked(campaign, out, jobs=jobs, resume=resume, progress=progress, cluster=cluster, place=place,
                           timings=timings)


def _run_locked(campaign: Campaign, out: Path, *, jobs: int, resume: bool,  # noqa: C901
                progress: Callable[[int, int, RunRecord | None], None] | None,
                cluster: str | None = None, place: Place | None = None,
                timings: list[RunTiming] | None = None) -> list[RunRecord]:
    from robotexp.output.results import read_records

    results = out / "results.jsonl"
    done: set[RunKey] = set()
    if resume and results.exists():
        done = {record_key(r) for r in read_records(results) if r.end is not EndReason.INTERRUPTED}
    todo = [s for s in campaign.runs if campaign.key(s) not in done]
    if not campaign.devices:        # on a robot: the file's order; else likely-longest first (`run_order`)
        todo = run_order(campaign, todo)
    total = len(todo)
    if progress:
        progress(0, total, None)
    if not todo:
        return []
    out.mkdir(parents=True, exist_ok=True)
    if campaign.devices:
        return run_on_robots(campaign, todo, out, progress=progress, place=place,
                             extra=lambda spec: record_extra(spec, campaign.sweep_of(spec)))
    records: list[RunRecord] = []
    if cluster is not None:
        from robotexp.campaign.cluster import run_on_cluster

        def written(record: RunRecord) -> None:
            records.append(record)
            if progress:
                progress(len(records), total, record)

        run_on_cluster(todo, out, cluster, lambda spec: record_extra(spec, campaign.sweep_of(spec)), written,
                       record=campaign.record, timings=timings)
        return records
    pool = ProcessPoolExecutor(max_workers=min(jobs, total), mp_context=get_context("spawn"),
                               initializer=worker_init)
    try:
        # submitted in order; the pool hands each worker the next one as it comes free
        # (the workers start while Ctrl-C and SIGTERM are blocked, and unblock them once their handlers are in:
        # a Ctrl-C that reaches them while they import waits for those handlers; one to this process acts after)
        with children_start_deaf(pool=True):
            pending: set[Future[tuple[RunRecord, RunTiming] | None]] = {
                pool.submit(run_one, spec, str(out), campaign.record, record_extra(spec, campaign.sweep_of(spec)))
                for spec in todo}
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                made = fut.result()
                if made is None:
                    continue
                record, timing = made
                if timings is not None:
                    timings.append(timing)
                records.append(record)
                if progress:
                    progress(len(records), total, record)
    except KeyboardInterrupt as stop:
        # queued runs are dropped now; the running ones write their partial run and end (the signal is
        # passed on, as it came, for one sent to this process alone; a worker ignores a second one)
        sig = signal.SIGTERM if isinstance(stop, Terminated) else signal.SIGINT
        for proc in list(getattr(pool, "_processes", {}).values()):
            with contextlib.suppress(OSError):
                os.kill(proc.pid, sig)
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return records


# -- report -------------------------------------------------------------------------------------



"""Campaign runs on a Dask distributed cluster (`robotexp campaign FILE --cluster ADDRESS`).

`ADDRESS` is a running scheduler (`tcp://HOST:8786`, e.g. `dask scheduler` on a lab server or a
SLURM job, with `dask worker` processes on the machines that make the runs) or `local:N`, a
LocalCluster of N worker processes of one thread each started here and closed at the end.

Each run is a pure task: a worker makes the run in a temporary folder of its own and returns the
record with the bytes of the run's files (map, images, curves); this process, the client, writes
them into the campaign folder as each run finishes (`as_completed`). The client alone writes
results.jsonl, under the campaign's folder lock, so the workers need no shared file system, and a
run that Dask retries on another worker after its first worker died is still recorded once: only
the finished task's result is ever written.
"""

from __future__ import annotations

import contextlib
import ipaddress
import logging
import re
import signal
import socket
import tempfile
import threading
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robotexp.errors import ConfigError, RobotexpError
from robotexp.run.spec import RunSpec
from robotexp.run.observers import RunObserver
from robotexp.run.record import EndReason, RunRecord
from robotexp.signals import children_start_deaf

if TYPE_CHECKING:
    from robotexp.campaign.jobs import RunTiming
    from robotexp.run.loop import ExplorationRun
    from robotexp.run.observers import StepEvent

__all__ = ["ClusterLost", "check_cluster_address", "run_on_cluster"]

_ADDRESS = re.compile(r"(tcp|tls)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9][A-Za-z0-9_.-]*):(\d{1,5})")
_LOCAL = re.compile(r"local:(\d{1,4})")
PROBE_TIMEOUT = 3.0         # [s] for the scheduler's port to accept a connection (refused: at once)
CONNECT_TIMEOUT = "5s"      # how long the client waits for the scheduler to answer, and to come back when lost

log = logging.getLogger(__name__)


class ClusterLost(RobotexpError):
    """The Dask scheduler went away while the campaign ran (the runs written so far are kept)."""


def check_cluster_address(address: str) -> tuple[str, int] | None:
    """Check the form of a `--cluster` value before any work starts; return its (host, port), or
    None for `local:N`.

    Raises:
        ConfigError: neither `tcp://HOST:PORT` (or `tls://`; HOST a name, an IPv4 address or an IPv6
            address in brackets; PORT 1..65535) nor `local:N` with N >= 1, or Dask is not installed (the
            `cluster` extra).
    """
    from robotexp.extras import require

    local = _LOCAL.fullmatch(address)
    if local:
        if int(local.group(1)) < 1:
            raise ConfigError(f"--cluster {address}: a local cluster needs at least 1 worker (local:N, N >= 1)")
        require("dask", f"--cluster {address}")
        require("distributed", f"--cluster {address}")
        return None
    m = _ADDRESS.fullmatch(address)
    host, port = (m.group(2), int(m.group(3))) if m else ("", 0)
    if m and host.startswith("["):
        try:
            ipaddress.IPv6Address(host[1:-1])
            host = host[1:-1]
        except ValueError:
            m = None
    if not m or not 1 <= port <= 65535:
        raise ConfigError(f"--cluster {address!r}: expected a Dask scheduler address tcp://HOST:PORT with PORT "
                          "1..65535 (e.g. tcp://10.0.0.5:8786 or tcp://[::1]:8786, from `dask scheduler`) or "
                          "local:N (N worker processes here)")
    require("dask", f"--cluster {address}")
    require("distributed", f"--cluster {address}")
    return host, port


def _probe(address: str, host: str, port: int) -> None:
    """Fail fast when nothing accepts connections at the scheduler's address.

    Raises:
        ConfigError: the connection is refused, the host is unknown or nothing answers in PROBE_TIMEOUT s.
    """
    try:
        with socket.create_connection((host, port), timeout=PROBE_TIMEOUT):
            pass
    except OSError as exc:
        why = "no answer" if isinstance(exc, TimeoutError) else exc.strerror or str(exc)
        raise ConfigError(f"--cluster {address}: no Dask scheduler answers there ({why} within {PROBE_TIMEOUT:g} "
                          "s); start one with `dask scheduler` and workers with `dask worker ADDRESS`") from None


class _ReconnectNoise(logging.Filter):
    """Drops distributed's own report of a lost scheduler: `run_on_cluster` says it in one line."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith("Failed to reconnect to scheduler")


class _CancelWatch(RunObserver):
    """On a worker: ends the run (interrupted) soon after the client set the campaign's stop event
    (Ctrl-C), so that a cancelled campaign frees its workers at once instead of finishing its runs
    (Dask cannot stop a task that is executing).

    A thread of the run waits on the event at the scheduler (a long poll renewed every second) and
    raises a flag the run loop reads at each step: asking the scheduler from the loop itself (it did,
    twice a second) held the run for a round trip each time, 25 ms on a loaded 2-core machine (5 % of
    the run's time)."""

    def __init__(self, event: str) -> None:
        self.event_name = event
        self.stopped = threading.Event()        # the campaign was cancelled
        self.done = threading.Event()           # the run ended: the thread ends too

    def on_start(self, run: ExplorationRun) -> None:
        """Start waiting for the stop event (on the worker's client, found here in the task's thread: the
        waiting thread would find none)."""
        from distributed import Event, get_client

        try:
            event = Event(self.event_name, client=get_client())
        except Exception:       # the worker is closing (its connections shut): nothing will stop it but its end
            log.debug("the run cannot watch the campaign's stop event", exc_info=True)
            return
        threading.Thread(target=self._wait, args=(event,), name="robotexp-cancel-watch", daemon=True).start()

    def _wait(self, event: Any) -> None:
        with contextlib.suppress(Exception):        # a worker closing under it: nothing left to stop
            while not self.done.is_set():
                if event.wait(timeout=1.0):
                    self.stopped.set()
                    return

    def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
        """Stop the run once the campaign was cancelled."""
        if self.stopped.is_set():
            run.request_stop("the campaign was cancelled (Ctrl-C on its client)", EndReason.INTERRUPTED)

    def on_end(self, run: ExplorationRun, record: RunRecord) -> None:
        """The run is over: let the waiting thread end."""
        self.done.set()


def _run_task(spec: RunSpec, extra: dict[str, Any], record: bool = False, stop_event: str | None = None,
              local: bool = False) -> tuple[dict[str, Any] | None, dict[str, bytes], str | None, RunTiming | None]:
    """On a worker: make one run in a temporary folder (with `record`, its ROS 2 bag in bags/); return
    its record (as JSON data), the bytes of every file it wrote but results.jsonl (by path relative to
    the folder), the error that ended it (None: none) and its timing (None without a record). A run
    whose explorer or robot failed still returns the record written before the error. Pure: nothing
    is left behind on the worker. `local`: a worker of our own local:N cluster, which then ends without
    the interpreter's teardown when the cluster closes (`robotexp.lifeline.exit_without_teardown`)."""
    from robotexp.campaign.jobs import timed_run

    if local:
        from robotexp.lifeline import exit_without_teardown

        exit_without_teardown()

    timing = timed_run(_worker_name())
    from robotexp.experiment import run_experiment
    from robotexp.output.results import read_jsonl

    with tempfile.TemporaryDirectory(prefix="robotexp-run-") as tmp:
        folder = Path(tmp)
        observers: list[RunObserver] = [_CancelWatch(stop_event)] if stop_event else []
        if record:
            from robotexp.bag.recorder import BagRecorder

            (folder / "bags").mkdir()
            observers.append(BagRecorder(folder=folder / "bags", world=spec.world))
        error = None
        try:
            data: dict[str, Any] | None = run_experiment(spec, folder, observers=observers,
                                                         record_extra=extra).record.as_dict()
        except RobotexpError as exc:
            error = f"{type(exc).__name__}: {exc}"
            written = read_jsonl(folder / "results.jsonl") if (folder / "results.jsonl").exists() else []
            data = written[-1] if written else None
        files = {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
                 if p.is_file() and p.name != "results.jsonl"}
    return data, files, error, None if data is None else timing(RunRecord.from_dict(data))


def _count(results: Path) -> int:
    """Records in a results file (complete lines)."""
    try:
        with open(results, "rb") as f:
            return sum(1 for line in f if line.endswith(b"\n"))
    except OSError:
        return 0


def _worker_name() -> str:
    """The Dask worker this runs on (its address), or this process."""
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        import os

        return f"pid {os.getpid()}"


def _store(out: Path, data: dict[str, Any], files: dict[str, bytes]) -> RunRecord:
    """In the client: write a finished run into `out`, the record first (appended to results.jsonl),
    then its files. The run is renamed (suffix _2, _3, ...) when its name is taken in `out` (a run
    made again after an interrupted one)."""
    from robotexp.output.results import append_jsonl, take_name

    base = str(data["run"])
    name = take_name(out, base)            # taken: a run of another process in `out` cannot get it too
    record = RunRecord.from_dict({**data, "run": name})
    append_jsonl(out / "results.jsonl", record)            # first: the record is never lost
    for rel, blob in files.items():
        parent, _, fname = rel.rpartition("/")
        if fname.startswith(base + "."):
            fname = name + fname[len(base):]
        if name != base and fname.endswith(".yaml"):        # a ROS map's yaml names its image file
            blob = blob.replace(f"{base}.".encode(), f"{name}.".encode())
        target = out / parent / fname if parent else out / fname
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(blob)
    return record


# Dask settings of a local:N cluster (its scheduler, nannies and worker processes). Each was measured to cost
# CPU that a 2-core machine takes from the runs (benchmarks/speed/bench_thesis_campaign.py --cluster local:2):
LOCAL_CONFIG: dict[str, Any] = {
    # the nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536, which also freezes glibc's mmap threshold
    # at 128 KiB: every large numpy temporary of a step is then mmapped and page-faulted afresh (a bvp run
    # in sparse: 18x the page faults, +0.4 s system time on 2.2 s)
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    # a sample of the running task's stack every 10 ms, for the dashboard's profile (which local:N has not)
    "distributed.worker.profile.enabled": False,
    # event-loop health ticks every 20 ms and a psutil system monitor every 500 ms, in the scheduler, each
    # nanny and each worker
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.admin.system-monitor.disk": False,
}


@contextlib.contextmanager
def _client(address: str) -> Iterator[Any]:
    """A dask.distributed Client on `address` (a LocalCluster for local:N, closed at the end).

    Raises:
        ConfigError: no scheduler answers at the address.
    """
    import dask
    from distributed import Client, LocalCluster

    where = check_cluster_address(address)
    local = _LOCAL.fullmatch(address)
    if local:
        cluster = None
        try:
            # the worker processes (and the cluster's threads, which start them) never hear Ctrl-C: a terminal's
            # reaches every process of its group, and this process stops the runs and closes the cluster
            # (a worker's own Ctrl-C printed tracebacks out of Dask's event loop)
            with dask.config.set(LOCAL_CONFIG), children_start_deaf(frozenset({signal.SIGINT}), pool=True):
                # no dashboard; the scheduler's HTTP server (health routes) on a free port: 8787 may be taken
                # by another cluster on a shared machine (a warning, and in the tests an error)
                # (Dask's own log, silenced: on Ctrl-C the runs it makes are cancelled and the cluster closed under its
                # workers, which it reports with warnings and tracebacks; a run's failure reaches the campaign itself)
                cluster = LocalCluster(n_workers=int(local.group(1)), threads_per_worker=1, processes=True,
                                       dashboard_address=":0", scheduler_kwargs={"dashboard": False},
                                       silence_logs=logging.CRITICAL)
            with Client(cluster) as client:
                yield client
        finally:
            if cluster is not None:
                cluster.close()
        return
    assert where is not None
    _probe(address, *where)
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(f"--cluster {address}: no Dask scheduler answers there ({exc}); start one with "
                          "`dask scheduler` and workers with `dask worker ADDRESS`") from None
    try:
        yield client
    finally:
        client.close()


def run_on_cluster(todo: list[RunSpec], out: Path, address: str, extra: Callable[[RunSpec], dict[str, Any]],
                   on_record: Callable[[RunRecord], None], *, record: bool = False,
                   timings: list[RunTiming] | None = None) -> None:
    """Make the runs `todo` on the Dask cluster at `address`, writing each into `out` as it finishes
    (with `record`, each run's ROS 2 bag into `out/bags`) and passing its record to `on_record` (and
    its `RunTiming` to `timings`, when given).

    A worker lost mid-run has its run rescheduled on another worker by the scheduler (up to its
    `allowed-failures`, 3 by default). Ctrl-C (KeyboardInterrupt) cancels every run not yet written
    and closes the client (and a local cluster, whose worker processes stop with it), then re-raises;
    the runs executing on workers end within about a second (a stop event they watch) and are dropped.

    Raises:
        ConfigError: a bad address, or no scheduler there.
        ClusterLost: the scheduler went away mid-campaign (the runs written so far stay in results.jsonl).
        RobotexpError: a run failed (its record, when it has one, is written first).
        KilledWorker: (distributed) a run killed its workers more often than allowed.
    """
    token = uuid.uuid4().hex[:8]       # keys unique on a scheduler that several campaigns share
    noise = _ReconnectNoise()
    logging.getLogger("distributed.client").addFilter(noise)
    silenced: dict[str, int] = {}
    try:
        _run_futures(todo, out, address, extra, on_record, record, timings, token, silenced)
    finally:
        logging.getLogger("distributed.client").removeFilter(noise)
        for name, level in silenced.items():
            logging.getLogger(name).setLevel(level)


def _lost(exc: BaseException, client: Any) -> bool:
    """True when `exc` (raised while waiting for a run) means the client lost its scheduler."""
    from distributed.client import FutureCancelledError
    from distributed.comm import CommClosedError

    if isinstance(exc, FutureCancelledError):
        return "scheduler-connection-lost" in str(exc) or client.status not in ("running", "connecting")
    return isinstance(exc, (CommClosedError, OSError, TimeoutError)) or client.status in ("closed", "closing")


def _run_futures(todo: list[RunSpec], out: Path, address: str, extra: Callable[[RunSpec], dict[str, Any]],
                 on_record: Callable[[RunRecord], None], record: bool, timings: list[RunTiming] | None,
                 token: str, silenced: dict[str, int]) -> None:
    """`run_on_cluster`'s work, on a client of `address`; once the scheduler is lost, distributed's own
    loggers are silenced (their levels before kept in `silenced`) while the client closes."""
    from distributed import Event, as_completed

    with _client(address) as client:
        stop = Event(f"robotexp-stop-{token}", client=client)
        local = _LOCAL.fullmatch(address) is not None
        futures = [client.submit(_run_task, spec, extra(spec), record, stop.name, local, pure=False,
                                 key=f"robotexp-{token}-{i}-{spec.method}") for i, spec in enumerate(todo)]
        try:
            for fut in as_completed(futures):
                data, files, error, timing = fut.result()
                if data is not None:
                    on_record(_store(out, data, files))
                if timing is not None and timings is not None:
                    timings.append(timing)
                if error is not None:
                    raise RobotexpError(f"a run failed on the cluster: {error}")
                fut.release()
        except BaseException as exc:
            lost = isinstance(exc, Exception) and not isinstance(exc, RobotexpError) and _lost(exc, client)
            if lost:            # closing a client whose scheduler is gone logs tracebacks of its cancelled calls
                for name in ("distributed", "distributed.client", "distributed.core", "distributed.comm",
                             "distributed.batched", "distributed.utils", "distributed.event"):
                    silenced.setdefault(name, logging.getLogger(name).level)
                    logging.getLogger(name).setLevel(logging.CRITICAL + 1)
            with contextlib.suppress(Exception):
                stop.set()              # the runs executing on workers end at their next check
            with contextlib.suppress(Exception):
                client.cancel(futures, force=True)
            if lost:
                results = out / "results.jsonl"
                log.debug("the scheduler was lost", exc_info=True)
                raise ClusterLost(f"--cluster {address}: the Dask scheduler went away mid-campaign "
                                  f"({type(exc).__name__}); the {_count(results)} run(s) written are kept in "
                                  f"{results}; start the "
                                  "scheduler and its workers again and run the same command with --resume to make "
                                  "the rest") from None
            raise
        # every run is in: release the runs' watch threads still waiting on the event (a wait left at the
        # scheduler when a local cluster closes is logged as an error)
        with contextlib.suppress(Exception):
            stop.set()

"""Shared fixtures: every test must close the robots it opens."""

from __future__ import annotations

import contextlib
import fcntl
import functools
import json
import re
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import os
import tempfile

import pytest
from hypothesis import settings

from robotexp.robot import Robot

# CI runs the property tests with a fixed seed, so a submission's result does not depend on luck;
# developers' runs keep exploring new examples (set HYPOTHESIS_PROFILE=ci to reproduce CI).
settings.register_profile("ci", derandomize=True, database=None)
if os.environ.get("CI") or os.environ.get("HYPOTHESIS_PROFILE") == "ci":
    settings.load_profile("ci")

# Ctrl-C as a terminal sends it: a suite started in the background by a non-interactive shell (`pytest &`,
# nohup) inherits SIGINT ignored, and so would every process a test starts and then stops with SIGINT (the
# live view, emulators, scripts). Python handles it again here; the processes the tests start then get it
# at its default, as from a terminal.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

pytest_plugins = ["pytester"]

# Robots opened during the current test. Strong references on purpose: a robot dropped without
# close() keeps its link (a pybullet client, a serial port) alive, and must still be found.
_OPENED: list[Robot] = []
_original_init = Robot.__init__


@functools.wraps(_original_init)
def _tracking_init(self: Robot, *args: Any, **kwargs: Any) -> None:
    _original_init(self, *args, **kwargs)
    _OPENED.append(self)        # backends call Robot.__init__ last, once their link is up


Robot.__init__ = _tracking_init  # type: ignore[method-assign]


# Test files whose tests keep time with the wall clock: emulated devices that stream in real time, servers, a
# browser, subprocesses stopped by signals and timeouts. On two processes (pytest-xdist) each such test runs alone:
# its process holds the tests' lock exclusively while the other process's tests each hold it shared. A test of
# these files that keeps no time (bytes, wrong input, a reader) is marked `untimed` and runs beside the others; one
# whose timed part follows an untimed preparation (a compilation, a reference run) may hold the lock exclusively
# for that part only (the `alone` fixture). A file whose wall-time bounds add what its processes waited for a CPU
# (`cpu_wait`), and that otherwise waits for events, not for time, runs beside the others: the campaigns on a Dask
# cluster (campaign/test_cluster*.py) and the campaigns' signal and kill tests (output/test_results_hardening.py).
_REAL_TIME = ("drivers/", "view/", "bag/test_connect_record.py", "bag/test_replay_seek.py", "cli/test_interrupt.py",
              "lua/test_lua_errors.py", "lua/test_lua_hardening.py", "lua/test_lua_integrity.py",
              "lua/test_lua_p3dx.py", "run/test_teamrobots.py", "run/test_warm_kernels.py")
_TESTS = Path(__file__).resolve().parent


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "untimed: a test of a real-time file (tests/conftest.py, _REAL_TIME) that "
                                       "keeps no time with the wall clock: it runs beside other tests")
    worker = getattr(config, "workerinput", None)
    jit = os.environ.get("NUMBA_DISABLE_JIT", "0") in ("", "0")     # the kernels as plain Python: nothing to compile
    if worker is not None and worker["workercount"] >= 2 and jit:
        _fill_kernel_cache(int(worker["workerid"].removeprefix("gw")))


def _fill_kernel_cache(part: int) -> None:
    """Before a test process of an xdist run collects: its part of numba's kernels compiled into numba's cache
    (tests/kernel_warmup.py; the parts of two processes at once take about 40 s on a fresh clone, 4 s when the
    cache is full). A warm-up that fails only leaves the compiling to the tests, where any failure shows."""
    from kernel_warmup import PARTS

    if part >= PARTS:
        return
    proc = subprocess.Popen([sys.executable, str(_TESTS / "kernel_warmup.py"), str(part)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        proc.wait(timeout=600)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _in_real_time_file(item: pytest.Item) -> bool:
    """Whether `item` is a test of a real-time file."""
    try:
        rel = item.path.resolve().relative_to(_TESTS).as_posix()
    except ValueError:
        return False
    return rel.startswith(_REAL_TIME) and not rel.endswith("_codec.py")     # a codec's tests are bytes only


def _real_time(item: pytest.Item) -> bool:
    """Whether `item` keeps time with the wall clock: a test of a real-time file not marked `untimed`."""
    return _in_real_time_file(item) and item.get_closest_marker("untimed") is None


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The real-time files last (each file's tests together, in their order): on two processes the other files
    run beside each other first, then the real-time tests one after another, instead of each real-time test
    waiting for the other process to finish whatever long test it is in."""
    items.sort(key=_in_real_time_file)


class _TestsLock:
    """The lock the processes of one xdist run share (nothing without xdist): a real-time test holds it
    exclusively (`fcntl.LOCK_EX`), any other test shared (`fcntl.LOCK_SH`)."""

    def __init__(self) -> None:
        self._fd: int | None = None
        self.mode = fcntl.LOCK_UN

    def hold(self, mode: int) -> None:
        """Hold the lock in `mode` (waits for it; a change of mode lets go of the lock first, as flock does)."""
        run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
        if run and self._fd is None:
            self._fd = os.open(Path(tempfile.gettempdir()) / f"robotexp-tests-{run}.lock", os.O_RDWR | os.O_CREAT,
                               0o600)
        if self._fd is not None and mode != self.mode:
            fcntl.flock(self._fd, mode)
        self.mode = mode

    def release(self) -> None:
        self.hold(fcntl.LOCK_UN)


_LOCK = _TestsLock()


@pytest.fixture(autouse=True)
def _tests_lock(request: pytest.FixtureRequest) -> _TestsLock:
    """A real-time test runs while no other test does (its fixtures included); any other test beside any other
    but a real-time one."""
    _LOCK.hold(fcntl.LOCK_EX if _real_time(request.node) else fcntl.LOCK_SH)
    return _LOCK


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """Let go of the lock after each test, but between two real-time tests of this process: the other process's
    tests would run between them while this one waits, one processor idle."""
    yield
    if not (_LOCK.mode == fcntl.LOCK_EX and nextitem is not None and _real_time(nextitem)):
        _LOCK.release()


@pytest.fixture
def alone(_tests_lock: _TestsLock) -> Callable[[], contextlib.AbstractContextManager[None]]:
    """`with alone(): ...`: the timed part of an `untimed` test runs while no other test does."""
    @contextlib.contextmanager
    def span() -> Iterator[None]:
        before = _tests_lock.mode
        _tests_lock.hold(fcntl.LOCK_EX)
        try:
            yield
        finally:
            _tests_lock.hold(before)
    return span


@pytest.fixture(autouse=True)
def _robots_closed() -> Iterator[None]:
    """Fail the test when it leaves a robot (SimRobot or any backend) open."""
    _OPENED.clear()
    yield
    leaked = [r for r in _OPENED if not r.closed]
    _OPENED.clear()
    for robot in leaked:        # clean up so one leak does not spill into the next tests
        robot.close()
    if leaked:
        names = ", ".join(f"{type(r).__name__}({r.name})" for r in leaked)
        pytest.fail(f"the test left {len(leaked)} robot(s) open: {names}; close them (use `with`)")


@functools.cache
def _record_validator() -> Any:
    import jsonschema

    from robotexp.run.record import results_schema

    return jsonschema.Draft202012Validator(results_schema())


def check_results_files(folder: Path) -> list[str]:
    """Every record of a results.jsonl under `folder` that carries a `schema_version` checked against
    robotexp/schema/results.schema.json: the errors, one line each (file:line: path: message)."""
    errors: list[str] = []
    for path in folder.rglob("results.jsonl"):
        try:
            lines = path.read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError):
            continue                # a test's deliberately broken file
        for i, line in enumerate(lines, start=1):
            try:
                record = json.loads(line)
            except json.JSONDecodeError:
                continue            # a torn line a test made on purpose
            if not isinstance(record, dict) or "schema_version" not in record:
                continue            # hand-written and earlier-format records
            for error in _record_validator().iter_errors(record):
                where = "/".join(map(str, error.absolute_path)) or "(record)"
                errors.append(f"{path}:{i}: {where}: {error.message}")
    return errors


@pytest.fixture(autouse=True)
def _records_match_their_schema(request: pytest.FixtureRequest) -> Iterator[None]:
    """Fail a test whose runs wrote, under its tmp_path, a record the published schema refuses."""
    yield
    folder = request.node.funcargs.get("tmp_path") if hasattr(request.node, "funcargs") else None
    if isinstance(folder, Path) and folder.is_dir():
        errors = check_results_files(folder)
        if errors:
            pytest.fail("records that do not match robotexp/schema/results.schema.json:\n" + "\n".join(errors[:10]))


class ViewCli:
    """`python -m robotexp.cli ARGS` processes that serve a live view (--view), for end-to-end tests."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen[str]] = []

    def start(self, *args: str, first: bool = True) -> tuple[subprocess.Popen[str], str]:
        """Start the command; returns it and the page's URL, read from its line "view: URL" (its first
        line, unless `first` is False)."""
        proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", *args], stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        self.procs.append(proc)
        assert proc.stdout is not None
        while True:
            line = proc.stdout.readline()
            assert line, "the command ended without serving its view"
            match = re.fullmatch(r"view: (http://127\.0\.0\.1:\d+/)\n", line)
            assert match or not first, f"expected 'view: URL' first, got {line!r}"
            if match:
                return proc, match.group(1)

    @staticmethod
    def interrupt(proc: subprocess.Popen[str]) -> str:
        """Ctrl-C the command (the view ends); returns the rest of its output after checking it exited 0."""
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=20)
        assert proc.returncode == 0, rest
        return rest


# a closed 5 x 4 m room with a wall inside, as a MobileSim map (mm): the world of the team tests
TEAM_ROOM = """2D-Map
LineMinPos: 0 0
LineMaxPos: 5000 4000
NumLines: 5
Cairn: RobotHome 1000 1000 0 "" ICON "start"
LINES
0 0 5000 0
5000 0 5000 4000
5000 4000 0 4000
0 4000 0 0
3000 1500 3000 2800
DATA
"""


def _one_line_error(result: Any, words: Iterable[str], out: Path) -> None:
    """A command's bad input: exit status 2, one line `robotexp: error: ...` holding each of `words`, and no
    results written to `out`."""
    assert result.exit_code == 2, result.output
    lines = [x for x in result.output.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("robotexp: error: "), result.output
    for w in words:
        assert w in lines[0], lines[0]
    assert not (out / "results.jsonl").exists()


@pytest.fixture(scope="session")
def one_line_error() -> Callable[[Any, Iterable[str], Path], None]:
    """The check of a command's bad input (`_one_line_error`): (CliRunner result, words, output folder)."""
    return _one_line_error


@pytest.fixture(scope="session")
def team_room() -> str:
    """The text of the team tests' map (`TEAM_ROOM`)."""
    return TEAM_ROOM


def _shelf_aisles(cell: float) -> tuple[Any, Any, Any]:
    """A 60 x 60 map of `cell` [m] cells: two aisles (rows 5-19 and 31-44, columns 5-39) either side of a
    shelf whose two faces (rows 20 and 30) were seen occupied; its inside (rows 21-29) never seen, the
    aisles' east ends open onto unknown space. Returns (grid, free, wall), the last two bool masks."""
    import numpy as np

    from robotexp.mapping.geometry import GridGeometry
    from robotexp.mapping.grid import OccupancyGrid

    grid = OccupancyGrid(GridGeometry(0.0, 0.0, cell, 60, 60))
    free = np.zeros(grid.shape, bool)
    free[5:20, 5:40] = free[31:45, 5:40] = True
    wall = np.zeros(grid.shape, bool)
    wall[20, 5:40] = wall[30, 5:40] = True
    grid.mark_free(free)
    grid.mark_occupied(wall)
    return grid, free, wall


@pytest.fixture
def shelf_aisles() -> Callable[[float], tuple[Any, Any, Any]]:
    """The wall-face tests' map (`_shelf_aisles`): cell size [m] -> (grid, free, wall)."""
    return _shelf_aisles


@pytest.fixture
def view_cli() -> Iterator[ViewCli]:
    """Start live-view commands; any still running at the end of the test is killed."""
    cli = ViewCli()
    yield cli
    for proc in cli.procs:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def _task_waits(pid: int, into: dict[tuple[int, int], int]) -> None:
    """Put the run-queue wait [ns] of every thread of process `pid` and of its descendants into `into`, by
    (pid, thread id) (Linux: the second field of /proc/PID/task/TID/schedstat)."""
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return
    for tid in tids:
        try:
            into[(pid, int(tid))] = int(Path(f"/proc/{pid}/task/{tid}/schedstat").read_text().split()[1])
            children = Path(f"/proc/{pid}/task/{tid}/children").read_text().split()
        except (OSError, IndexError, ValueError):
            continue
        for child in children:
            _task_waits(int(child), into)


class CpuWait:
    """How long the threads of the test process and of the processes it started waited for a CPU (runnable but
    not running), summed over the threads, sampled every `period` s by a thread of its own.

    A test that bounds a delay in wall time (a silence limit, a watchdog, a Ctrl-C reaching a worker) adds to
    its bound what was waited over that interval: about 0 on an idle machine, where the bound stays as tight
    as written; a loaded machine that kept the threads off the CPUs moves it by that time, not more than
    that (waits that overlapped count once per thread: generous under load). 0 where Linux does not say.
    """

    def __init__(self, period: float = 0.05) -> None:
        self._last: dict[tuple[int, int], int] = {}
        self._total = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._period = period
        self._sample()
        self._thread = threading.Thread(target=self._run, name="cpu-wait", daemon=True)
        self._thread.start()

    def _sample(self) -> None:
        now: dict[tuple[int, int], int] = {}
        _task_waits(os.getpid(), now)
        with self._lock:
            for key, ns in now.items():
                self._total += max(0, ns - self._last.get(key, ns))    # a new thread counts from now on
            self._last = now

    def _run(self) -> None:
        while not self._stop.wait(self._period):
            self._sample()

    def total(self) -> float:
        """Seconds waited so far (a mark for `since`)."""
        self._sample()
        with self._lock:
            return self._total / 1e9

    def since(self, mark: float) -> float:
        """Seconds waited since `mark` (a `total()`)."""
        return self.total() - mark

    def close(self) -> None:
        self._stop.set()
        self._thread.join()


@pytest.fixture
def cpu_wait() -> Iterator[CpuWait]:
    """A `CpuWait` measuring while the test runs: add `cpu_wait.since(mark)` to a wall-time bound."""
    meter = CpuWait()
    yield meter
    meter.close()

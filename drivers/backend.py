"""`StreamBackend`: what the driver backends share (a reader thread, a watchdog, a paced clock).

Every backend here (kobuki, mavlink, p3dx) talks to a robot that streams its state. A background
reader thread decodes the stream and folds it into the backend's state under `_cond` (a
`threading.Condition`) on which readers of that state wait. The parts that are the same in every
backend live here:

- the reader loop (`StreamReader._reader`, which the laser drivers run too): read what the link
  has, hand it to `_on_data`, and fail the link
  when it ends, when nothing valid came for `timeout` s, or when the loop itself breaks (a bug
  must not leave `read()` waiting forever). Silence is judged on the reader's own clock: the link
  is silent when two reads in a row that *started* more than `timeout` s after the last valid
  packet brought none. Bytes that are never a valid packet do not count as life, and a reader
  starved of the interpreter's lock (the main thread in a long numba kernel or numpy call) is not
  silent: what arrived meanwhile waits in the link and its first read after the starvation brings
  it. `_check()` in the caller's thread never judges silence by the wall clock for that reason;
  it only reports what the reader found (or that the reader thread is gone);
- failure: `_fail(exc)` records the first error for `read()` and the clock, wakes the waiters and
  tries once to stop the robot; `_check()` raises it again (a fresh copy, chained), or a silence
  error when the reader has not noticed the silence yet;
- commands: `_command` refuses a motion while the link is broken but always tries a stop (the
  link may still carry it); the command in force and when it came are `_twist` and `_cmd_wall`,
  guarded by `_cmd_lock`, which is also held while a command is written;
- the watchdog `_watch(now)`: no `command()` for `watchdog` s while moving -> a stop;
- robot time: `wait_until(robot_time)` and `make_clock(period)` (a `PacedClock`), so a control
  loop runs in real time on a robot and as fast as an emulator's speed-up allows against one;
- `close()` only logs a final stop that cannot reach the robot any more; `_shutdown()` stops the
  reader and releases the link;
- every state as it arrives: a backend calls `_state_seen(robot_time, pose)` for each state packet
  it decodes, and the reader hands the states of one read to the listeners of
  `add_state_listener` (a laser mounted on the robot pairs its scans with them:
  `robotexp.run.laser_mount`), stamped on the host's `time.monotonic()`: the newest at the read, each
  earlier one as much before as its robot time is older (robot seconds turned into host seconds at
  the rate the stream has been arriving: an emulator at 10x sends ten robot seconds a second).

A backend calls `_init_stream()` first in its `__init__`, sets `address` and its link, starts the
reader with `_start_reader()` and implements the hooks `_on_data`, `_send_twist`,
`_silence_error`, `_robot_time` and `_read`.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from abc import abstractmethod
from collections.abc import Callable, Iterator
from typing import Any, ClassVar, Protocol

from robotexp import Clock, ConfigError, ConnectionLost, PacedClock, Pose, Robot, RobotError, Twist

__all__ = ["StateStamps", "StreamBackend", "StreamLink", "StreamReader", "read_waiting", "require_positive"]

log = logging.getLogger(__name__)


class StreamLink(Protocol):
    """The link a `StreamBackend` reads from: bytes in (b"" after a poll timeout), bytes out."""

    def read_some(self) -> bytes:
        """What arrived, b"" when nothing did within the poll timeout.

        Raises:
            ConnectionLost: the link closed.
        """
        ...

    def write(self, data: bytes) -> None:
        """Send `data`.

        Raises:
            ConnectionLost: the link closed.
        """
        ...

    def close(self) -> None:
        """Release the link; safe to call twice."""
        ...


def reads_until(deadline: float, clock: Callable[[], float] = time.monotonic) -> Iterator[None]:
    """The turns of a loop that reads until `deadline` [s, `clock`]: one more turn while the last one started
    before the deadline, so the last read always starts after it. A thread kept from the interpreter's lock
    until past the deadline (a loaded machine, numba compiling in another thread) still reads once what
    arrived meanwhile, as the reader's silence rule does, instead of giving up on a reply that is there."""
    while True:
        started = clock()
        yield
        if started >= deadline:
            return


def read_waiting(port: Any, timeout: float) -> bytes:
    """What a pyserial `port` (timeout `timeout` [s]) received: wait up to `timeout` for a first byte
    (b"" when none came), then take whatever else is there without waiting (serial_for_url's
    `read(n)` would wait for all n bytes). The port's own errors reach the caller."""
    first = port.read(1)
    if not first:
        return b""
    port.timeout = 0
    try:
        rest: bytes = port.read(65536)
    finally:
        port.timeout = timeout
    return bytes(first) + rest


def require_positive(who: str, **values: float) -> None:
    """Check that every keyword value is finite and > 0.

    Args:
        who: what is configured (the backend's or emulator's name), for the message.
        **values: the parameters by name.

    Raises:
        ConfigError: a value is not finite or not > 0 (the first such one, by name).
    """
    for what, value in values.items():
        if not (value > 0 and math.isfinite(value)):
            raise ConfigError(f"{who}: {what} must be > 0, got {value}")


class StreamReader:
    """The reader thread's loop of a device that streams (a robot backend, a laser driver): read
    what the link has, hand it to `_on_read`, and fail the device (`_fail`) when the link ends, when
    two reads in a row that started after `_silent` says the data stopped brought nothing valid (a
    reader starved of the interpreter's lock finds what arrived meanwhile on its next read), or when
    the loop itself breaks (a bug must not leave a waiting caller waiting forever).

    A user has `name` and `address` and sets `_stop` (a `threading.Event`; set: the loop ends, a link closing
    under it is no error) and `_quiet_reads = 0`, and implements `_receive`, `_on_read`, `_silent`,
    `_silence_error` and `_fail`; `_clock` is the time the loop measures with.
    """

    name: ClassVar[str]
    _stop: threading.Event
    _quiet_reads: int

    def _clock(self) -> float:
        """The time [s] `_on_read` and `_silent` get."""
        return time.perf_counter()

    @abstractmethod
    def _receive(self) -> bytes:
        """What the link has now (b"" after its poll timeout); raises ConnectionLost at its end."""

    @abstractmethod
    def _on_read(self, data: bytes, now: float) -> None:
        """Decode `data` (maybe b"") read at `now` [s, `_clock`]; may raise RobotError."""

    @abstractmethod
    def _silent(self, started: float) -> bool:
        """True when a read that started at `started` [s, `_clock`] started past the silence limit."""

    @abstractmethod
    def _silence_error(self, now: float) -> RobotError:
        """The error for the silence noticed at `now` [s, `_clock`]."""

    @abstractmethod
    def _fail(self, exc: RobotError) -> None:
        """Record `exc` for the device's callers (and stop what must stop)."""

    def _reader(self) -> None:
        try:
            while not self._stop.is_set():
                started = self._clock()
                try:
                    data = self._receive()
                except ConnectionLost:
                    if self._stop.is_set():
                        return      # closing: the link went away under us on purpose
                    raise
                now = self._clock()
                self._on_read(data, now)
                # silent only when reads that began after the limit brought nothing valid: a reader
                # that could not run (the lock held elsewhere) finds the waiting data on its next read
                self._quiet_reads = self._quiet_reads + 1 if self._silent(started) else 0
                if self._quiet_reads >= 2:
                    raise self._silence_error(now)
        except RobotError as exc:
            self._fail(exc)
        except Exception as exc:     # a bug here must not leave a caller waiting forever
            log.exception("%s: reader thread failed", self.name)
            self._fail(RobotError(f"{self.name}: reader thread failed at {getattr(self, 'address', None)!r}: "
                                  f"{exc!r}"))


class StateStamps:
    """Host stamps of the robot states one read brought: the newest at the read's time, each earlier
    one as much before as its robot time is older, in host seconds per robot second as the stream
    has been arriving (a decaying mean over the reads; 1 until two reads have come), none before the
    previous read's newest."""

    def __init__(self) -> None:
        self._sum = [0.0, 0.0]                  # decaying sums of host and robot seconds between reads
        self._last: tuple[float, float] | None = None   # (host, robot) time of the previous read's newest

    @property
    def host_per_robot(self) -> float:
        """Host seconds per robot second (0.1 against an emulator at 10x)."""
        return self._sum[0] / self._sum[1] if self._sum[1] > 0 else 1.0

    def stamps(self, robot_times: list[float], now: float) -> list[float]:
        """The stamps [s] of states at `robot_times` [s] (in order) that a read at `now` [s] brought."""
        if not robot_times:
            return []
        newest = robot_times[-1]
        last = self._last
        if last is not None and newest > last[1] and now > last[0]:
            self._sum[0] = 0.9 * self._sum[0] + (now - last[0])
            self._sum[1] = 0.9 * self._sum[1] + (newest - last[1])
        rate = self.host_per_robot
        floor = -math.inf if last is None else last[0]
        self._last = (now, newest)
        return [max(now - (newest - t) * rate, floor) for t in robot_times]


class StreamBackend(StreamReader, Robot):
    """A `Robot` whose state arrives as a stream decoded by a reader thread (see the module docstring).

    Attributes:
        address: where the robot is (for messages).
        timeout: silence after which the link counts as lost [s].
        watchdog: stop the robot when `command()` was not called for this long [s].
        watchdog_stops: how many times the watchdog stopped the robot.
        command_time: `perf_counter()` when the newest command was written [s].
    """

    address: str
    timeout: float
    watchdog: float
    _link: StreamLink
    _join_timeout = 1.0     # [s] how long closing waits for the reader thread

    def _init_stream(self, timeout: float, watchdog: float) -> None:
        """Set up what the shared parts use (call first in `__init__`, before the reader starts)."""
        self.timeout, self.watchdog = timeout, watchdog
        self._cond = threading.Condition()
        self._cmd_lock = threading.Lock()
        self._error: RobotError | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._twist = Twist.ZERO
        self._cmd_wall = self._last_rx = time.perf_counter()
        self._quiet_reads = 0   # reads in a row that started more than `timeout` s after the last valid data
        self.watchdog_stops = 0
        self.command_time = 0.0
        self._listeners: list[Callable[[float, float, Pose], None]] = []
        self._seen: list[tuple[float, Pose]] = []       # (robot time, pose) of the states of the read in hand
        self._state_stamps = StateStamps()

    def add_state_listener(self, listener: Callable[[float, float, Pose], None]) -> None:
        """Call `listener(stamp, robot_time, pose)` for every state the robot sends, in order, from the
        reader thread (keep it short): `stamp` [s, time.monotonic()] when it arrived (see the module
        docstring), `robot_time` [s] and `pose` as `read()` would report them."""
        self._listeners.append(listener)

    def _state_seen(self, robot_time: float, pose: Pose) -> None:
        """A state packet was decoded (reader thread): its robot time [s] and the pose `read()` reports."""
        if self._listeners:
            self._seen.append((robot_time, pose))

    def _hand_out_states(self, now: float) -> None:
        """Stamp the states of the read just decoded (read at `now` [s, time.monotonic()]) and give
        them to the listeners."""
        seen, self._seen = self._seen, []
        for (robot_time, pose), stamp in zip(seen, self._state_stamps.stamps([t for t, _ in seen], now), strict=True):
            for listener in self._listeners:
                listener(stamp, robot_time, pose)

    def _start_reader(self, name: str) -> None:
        self._last_rx = time.perf_counter()     # the silence timeout runs from here
        self._thread = threading.Thread(target=self._reader, name=name, daemon=True)
        self._thread.start()

    # -- hooks ---------------------------------------------------------------------------
    def _receive(self) -> bytes:
        """What the link has now (b"" after its poll timeout); raises ConnectionLost at its end."""
        return self._link.read_some()

    def _on_read(self, data: bytes, now: float) -> None:
        arrived = time.monotonic()
        self._on_data(data, now)
        if self._seen:
            self._hand_out_states(arrived)

    @abstractmethod
    def _on_data(self, data: bytes, now: float) -> None:
        """Decode `data` (maybe b"") received at `now` [s, perf_counter] and do the periodic sends.

        Updates `_last_rx` when a valid packet (one that carries the robot's state) arrived, never
        for bytes alone. Raises ConnectionLost when a write fails.
        """

    @abstractmethod
    def _send_twist(self, twist: Twist) -> None:
        """Write `twist` as the robot's velocity command (the caller holds `_cmd_lock`)."""

    @abstractmethod
    def _silence_error(self, now: float) -> RobotError:
        """The error for no valid data since `_last_rx` (ProtocolError when only garbage came)."""

    @abstractmethod
    def _robot_time(self) -> float:
        """The robot's time [s] of the newest state (the caller holds `_cond`)."""

    def _time_tolerance(self) -> float:
        """How far [s] short of a target time `wait_until` still counts as there (half a ms)."""
        return 5e-4

    def _silent(self, now: float) -> bool:
        """True when a read that started at `now` [s] started more than `timeout` s after the last valid data."""
        return now - self._last_rx > self.timeout

    # -- reader thread (StreamReader) ----------------------------------------------------
    def _fail(self, exc: RobotError) -> None:
        """Record the error for read() and the clock, and try once to stop the robot."""
        with self._cond:
            if self._error is None:
                self._error = exc
            self._cond.notify_all()
        log.error("%s", exc)
        try:
            with self._cmd_lock:
                self._twist = Twist.ZERO
                self._send_twist(Twist.ZERO)
        except ConnectionLost:
            pass

    def _watch(self, now: float) -> bool:
        """The watchdog: stop when the control loop has been quiet for `watchdog` s; True when it did."""
        with self._cmd_lock:
            quiet = now - self._cmd_wall
            if self._twist == Twist.ZERO or quiet <= self.watchdog:
                return False
            self._twist = Twist.ZERO
            self.watchdog_stops += 1
            log.warning("%s: no command for %.2f s: stopping the robot", self.name, quiet)
            self._send_twist(Twist.ZERO)
        return True

    # -- Robot hooks ---------------------------------------------------------------------
    def _check(self) -> None:
        """Raise the reader's error (caller holds _cond), or ConnectionLost when the reader thread is
        gone without one. Silence is the reader's to judge (see the module docstring)."""
        if self._error is not None:
            raise type(self._error)(str(self._error)) from self._error
        thread = self._thread
        if thread is not None and not thread.is_alive() and not self._stop.is_set():
            raise ConnectionLost(f"{self.name}: the reader thread of {self.address!r} stopped")

    def _command(self, twist: Twist) -> None:
        if twist != Twist.ZERO:      # a stop is always tried: the link may still carry it
            with self._cond:
                self._check()
        with self._cmd_lock:
            self._twist = twist
            self._cmd_wall = time.perf_counter()
            self._send_twist(twist)

    def wait_until(self, robot_time: float) -> float:
        """Block until the robot's time reaches `robot_time` [s]; return the robot time then [s].

        Raises:
            RobotError: the robot is closed.
            ConnectionLost, ProtocolError: the robot fell silent or the link closed meanwhile.
        """
        with self._cond:
            while self._robot_time() < robot_time - self._time_tolerance():
                self._ensure_open()
                self._check()
                left = self._last_rx + self.timeout - time.perf_counter()
                self._cond.wait(min(max(left, 0.0) + 0.02, self.timeout))
            return self._robot_time()

    def make_clock(self, period: float) -> Clock:
        """A clock paced by the robot's stream: a tick waits until the robot's time has advanced by
        `period` [s], so a control loop runs in real time on a robot and as fast as the speed-up
        allows against an emulator."""
        with self._cond:
            start = self._robot_time()
        return PacedClock(period, self.wait_until, start)

    def close(self) -> None:
        """Stop the robot, then release the link. Safe to call twice; a link already lost is only
        logged (the stop cannot reach the robot; its error was raised by `read()` already)."""
        try:
            super().close()
        except ConnectionLost as exc:
            log.warning("%s: could not send the final stop: %s", self.name, exc)

    def _close(self) -> None:
        self._shutdown()

    def _release(self) -> None:
        """Release the link (after the reader stopped)."""
        self._link.close()

    def _shutdown(self) -> None:
        self._stop.set()
        thread = self._thread
        if thread is not None and thread.is_alive() and thread is not threading.current_thread():
            thread.join(timeout=self._join_timeout)
        self._release()
        with self._cond:
            self._cond.notify_all()

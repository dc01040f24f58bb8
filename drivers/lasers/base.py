"""What the laser drivers share: a byte link, a reader thread that publishes stamped scans, and the
emulator base.

- `LaserLink`: pyserial's `serial_for_url` (a device path, `socket://host:port`, "host:port") with
  a poll timeout, baud-rate changes (SICK switches 9600 -> 38400 -> 500 k) and every failure of the
  other side turned into `ConnectionLost`.
- `StreamLaser`: a `Laser` whose device streams; a daemon reader thread (the robot backends' loop,
  `robotexp_drivers.backend.StreamReader`) hands received bytes to the
  driver's `_on_data(data, now)`, which hands the scans one read completed to `_publish_read(scans,
  now)`. A read may hold several scans (the reader waited for the interpreter, or the device streams
  faster than it is read): they are stamped a scan period apart, the newest at `now` (less what
  arrived after it: `after`), the period measured on this host (`scan_period`), so that each is
  paired with the robot pose of its own time. No valid scan for `timeout` s (two reads that began
  past it brought none: a reader starved of the interpreter's lock is not silent), or the link
  ending, fails the laser: `latest()`/`wait_scan()` raise `ConnectionLost` from then on.
- `LaserEmulatorBase`: a `StreamEmulator` (drivers/emulation.py: TCP or pseudo-terminal, serving
  thread, fault injection) that measures with a `ScanSource` instead of owning a simulator.
"""

from __future__ import annotations

import logging
import threading
import time
from abc import abstractmethod

import numpy as np
import serial

from robotexp import ConfigError, ConnectionLost, Laser, LaserScan, RobotError, ScanSource, StampedScan
from robotexp_drivers.backend import StreamReader, read_waiting
from robotexp_drivers.emulation import StreamEmulator
from robotexp_drivers.portio import WRITE_TIMEOUT, stream_url, write_all

__all__ = ["LaserLink", "StreamLaser", "LaserEmulatorBase", "ScanStamps", "laser_url"]

log = logging.getLogger(__name__)

def laser_url(who: str, address: str) -> str:
    """The `serial_for_url` URL of a laser address (`stream_url`): "host:port" or "tcp://host:port" becomes
    `socket://host:port`; a device path or a URL passes as is. Raises ConfigError on an empty address or a
    bad port."""
    return stream_url(who, address, "give a device (/dev/ttyUSB0) or host:port")


class LaserLink:
    """A byte stream to a laser, safe to write from two threads.

    Args:
        who: the driver's name, for messages.
        address: see `laser_url`.
        baudrate: initial line speed [bit/s] (ignored on TCP).
        poll: longest wait of one `read_some` [s].

    Raises:
        ConnectionLost: the port or socket cannot be opened.
    """

    def __init__(self, who: str, address: str, *, baudrate: int, poll: float = 0.02) -> None:
        self.who = who
        self.address = address
        self.url = laser_url(who, address)
        self.poll = poll
        self._write_lock = threading.Lock()
        try:
            self._port = serial.serial_for_url(self.url, baudrate=baudrate, timeout=poll, write_timeout=WRITE_TIMEOUT)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ConnectionLost(f"{who}: cannot open {self.url!r}: {exc}; check the address, that the "
                                 "laser (or its emulator) is on and that the port is not in use") from exc
        self.closed = False

    @property
    def is_serial(self) -> bool:
        """True on a real (or pseudo-terminal) serial port, False on TCP and other URL handlers."""
        return "://" not in self.url

    def read_some(self) -> bytes:
        """The bytes that arrived within the poll timeout (b"" when none).

        Raises:
            ConnectionLost: the other side closed the link or the port failed.
        """
        try:
            return read_waiting(self._port, self.poll)
        except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
            raise ConnectionLost(f"{self.who}: link {self.url!r} lost while reading: {exc}") from exc

    def write(self, data: bytes) -> None:
        """Send `data` whole. Raises ConnectionLost when the link is closed or the write fails."""
        with self._write_lock:
            if self.closed:
                raise ConnectionLost(f"{self.who}: link {self.url!r} is closed")
            try:
                write_all(self._port, data)
                self._port.flush()
            except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
                raise ConnectionLost(f"{self.who}: link {self.url!r} lost while writing: {exc}") from exc

    def set_baudrate(self, baudrate: int) -> None:
        """Change the line speed (no effect on TCP). Raises ConnectionLost when the port refuses."""
        if not self.is_serial:
            return
        try:
            self._port.baudrate = baudrate
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ConnectionLost(f"{self.who}: {self.url!r} cannot switch to {baudrate} baud: {exc}") from exc

    def set_dtr(self, level: bool) -> bool:
        """Set the DTR line (an RPLidar's USB adapter spins the motor while it is low); False where
        the link has none (TCP, a pseudo-terminal)."""
        if not self.is_serial:
            return False
        try:
            self._port.dtr = level
        except (serial.SerialException, OSError):
            return False
        return True

    def reset_input(self) -> None:
        """Drop what was received and not read yet."""
        try:
            self._port.reset_input_buffer()
        except (serial.SerialException, OSError, AttributeError):
            pass

    def close(self) -> None:
        """Release the port; safe to call twice."""
        with self._write_lock:
            if self.closed:
                return
            self.closed = True
        # pyserial's socket:// close() skips socket.close() when shutdown() fails (a peer already
        # gone): close the socket ourselves so that it does not leak
        sock = getattr(self._port, "_socket", None)
        try:
            self._port.close()
        except (serial.SerialException, OSError):
            pass
        if sock is not None:
            sock.close()


class ScanStamps:
    """The stamps of the scans each read completes: the newest ended `after` s before the read's
    time, each earlier one a scan period before the next, none before the previous read's newest;
    the period is measured on this host (a decaying mean: recent reads weigh more).

    Args:
        period: [s] the scan period assumed until two reads have brought scans (the device's nominal one).
    """

    def __init__(self, period: float) -> None:
        self.period = period
        self.newest: float | None = None
        self._sum = self._count = 0.0

    def stamps(self, k: int, now: float, after: float = 0.0) -> list[float]:
        """The stamps [s] of `k` scans completed by a read at `now` [s], in order (oldest first)."""
        if k <= 0:
            return []
        newest = now - max(after, 0.0)
        last = self.newest
        if last is not None:
            newest = max(newest, last + 1e-6)
            self._sum = 0.9 * self._sum + (newest - last)
            self._count = 0.9 * self._count + k
            self.period = self._sum / self._count
        step = self.period if last is None else min(self.period, (newest - last) / k)
        self.newest = newest
        return [newest - (k - 1 - i) * step for i in range(k)]


class StreamLaser(StreamReader, Laser):
    """A `Laser` fed by a reader thread (see the module docstring).

    A driver's `__init__` opens `self._link`, does its handshake synchronously (reading with
    `self._link.read_some()`), sets `geometry`, then calls `_start_reader(timeout)`; it implements
    `_on_data` (decode, `_publish` each complete scan) and `_stop_device` (ask the device to stop its
    output; called once by `close()` while the link is still open, errors ignored).
    """

    _link: LaserLink
    _join_timeout = 1.0     # [s] how long closing waits for the reader thread

    def _start_reader(self, timeout: float) -> None:
        """Start decoding in the background; `timeout` [s] of no valid scan fails the laser."""
        if not timeout > 0:
            raise ConfigError(f"{self.name}: timeout must be > 0 s, got {timeout}")
        self.timeout = timeout
        self._cond = threading.Condition()
        self._latest: StampedScan | None = None
        self._seq = -1
        self._error: RobotError | None = None
        self._stop = threading.Event()
        self._last_scan = time.monotonic()
        self._quiet_reads = 0
        self._stamps = ScanStamps(self.geometry.period)
        self._thread = threading.Thread(target=self._reader, name=f"{self.name} {self.address}", daemon=True)
        self._thread.start()

    # -- hooks ---------------------------------------------------------------------------
    @abstractmethod
    def _on_data(self, data: bytes, now: float) -> None:
        """Decode `data` (maybe b"") received at `now` [s, time.monotonic()]; `_publish` each scan."""

    @abstractmethod
    def _stop_device(self) -> None:
        """Ask the device to stop streaming (the link is still open; ConnectionLost is ignored)."""

    # -- reader ----------------------------------------------------------------------------
    def _publish(self, scan: LaserScan, stamp: float) -> None:
        """Hand out a complete scan stamped `stamp` [s, time.monotonic()]."""
        with self._cond:
            self._seq += 1
            self._latest = StampedScan(scan, stamp, self._seq)
            self._last_scan = time.monotonic()
            self._cond.notify_all()

    @property
    def scan_period(self) -> float:
        """[s] the time between scans as they arrive on this host (`ScanStamps`)."""
        return self._stamps.period

    def _publish_read(self, scans: list[LaserScan], now: float, after: float = 0.0) -> None:
        """Publish the scans one read completed, in order, stamped by `ScanStamps.stamps` (`now`: the
        read's time [s, time.monotonic()]; `after`: what arrived after the newest took that long [s])."""
        for scan, stamp in zip(scans, self._stamps.stamps(len(scans), now, after), strict=True):
            self._publish(scan, stamp)

    # -- the reader loop's hooks (StreamReader) ---------------------------------------------
    def _clock(self) -> float:
        return time.monotonic()         # scans are stamped on it

    def _receive(self) -> bytes:
        return self._link.read_some()

    def _on_read(self, data: bytes, now: float) -> None:
        self._on_data(data, now)

    def _silent(self, started: float) -> bool:
        return started - self._last_scan > self.timeout

    def _silence_error(self, now: float) -> RobotError:
        return ConnectionLost(f"{self.name}: no valid scan from {self.address!r} for {now - self._last_scan:.2f} s; "
                              "check the cable and power")

    def _fail(self, exc: RobotError) -> None:
        with self._cond:
            if self._error is None:
                self._error = exc
            self._cond.notify_all()
        if not self._stop.is_set():
            log.error("%s", exc)

    def _check(self) -> None:
        """Raise the reader's error (a fresh copy, chained); the caller holds `_cond`."""
        if self._error is not None:
            raise type(self._error)(str(self._error)) from self._error

    # -- Laser -----------------------------------------------------------------------------
    def latest(self) -> StampedScan | None:
        with self._cond:
            self._check()
            return self._latest

    def wait_scan(self, after_seq: int = -1, timeout: float = 1.0) -> StampedScan:
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                self._check()
                if self._latest is not None and self._latest.seq > after_seq:
                    return self._latest
                left = deadline - time.monotonic()
                if left <= 0:
                    raise ConnectionLost(f"{self.name}: no scan from {self.address!r} within {timeout:g} s")
                self._cond.wait(left)

    def close(self) -> None:
        if getattr(self, "_closed_laser", False):
            return
        self._closed_laser = True
        stop = getattr(self, "_stop", None)
        if stop is not None:
            stop.set()
        try:
            self._stop_device()
        except (ConnectionLost, OSError):
            pass
        thread = getattr(self, "_thread", None)
        if thread is not None and thread.is_alive() and thread is not threading.current_thread():
            thread.join(timeout=self._join_timeout)
        link = getattr(self, "_link", None)
        if link is not None:
            link.close()
        cond = getattr(self, "_cond", None)
        if cond is not None:
            with cond:
                if self._error is None:
                    self._error = ConnectionLost(f"{self.name}: the laser at {self.address!r} is closed")
                cond.notify_all()


class LaserEmulatorBase(StreamEmulator):
    """A laser emulator: a `StreamEmulator` without a simulator of its own, measuring with `source`.

    A subclass calls `_init_laser(source, speedup)` first, opens its transport (`_open_transport`, or
    `_open_pty()` / `_listen()` and sets `address`), and implements `_period`, `_step` (the bytes to send now: a scan
    when streaming, else b"") and `_on_bytes` (commands).
    """

    def _init_laser(self, source: ScanSource, speedup: float = 1.0) -> None:
        self._init_stream(speedup)
        self.source = source
        # measure once now: a first measurement may compile or load the ray caster (seconds, holding
        # the interpreter), which must not happen while a driver waits for its first scan
        source(np.zeros(1), 1.0)

    def _open_transport(self, pty: bool, port: int | None, host: str) -> None:
        """Serve on a pseudo-terminal (`address` its device path) or TCP `host`:`port` (None or 0: a
        free port; `address` "host:port"); on failure release what was opened and re-raise."""
        try:
            if pty:
                self.address = self._open_pty()
            else:
                bound_host, bound_port = self._listen(host, port or 0)
                self.address = f"{bound_host}:{bound_port}"
        except BaseException:
            self._release()
            raise

    def _halt(self) -> None:
        """A laser has nothing to stop when its client leaves (a subclass may reset its state)."""

    def _release_device(self) -> None:
        """The source belongs to whoever made it."""
